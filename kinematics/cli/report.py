"""Output helpers for the CLI: strict JSON and plain-text tables. No heavy imports."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

Out = Callable[[argparse.Namespace, dict[str, Any], Callable[[], str]], None]
"""The CLI's output callback: (args, JSON payload, human-readable report thunk)."""


def with_plane(robot: Any, out: Out) -> Out:
    """`out` with the JSON key "plane" added: the end effector's plane of motion
    (`kinematics.mechanisms.plane_of`, the one decision every command reports) or null (spatial)."""

    def wrapped(args: argparse.Namespace, payload: dict[str, Any], human: Callable[[], str]) -> None:
        from kinematics.mechanisms import plane_of

        found = plane_of(robot)
        out(args, {**payload, "plane": None if found is None else found.as_dict()}, human)

    return wrapped


def jsonable(obj: Any) -> Any:
    """Convert numpy arrays/scalars, tuples and NamedTuples into strict-JSON values.

    inf and NaN become null (strict JSON has neither); -0.0 becomes 0.0.
    """
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return jsonable(obj.tolist())
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, float):
        return None if not math.isfinite(obj) else obj + 0.0
    raise TypeError(f"cannot convert {type(obj).__name__} to JSON")


def dumps(obj: Any) -> str:
    """Strict JSON text (allow_nan=False) of `jsonable(obj)`, indented."""
    return json.dumps(jsonable(obj), indent=2, allow_nan=False)


def fmt(x: Any, digits: int | None = 6) -> str:
    """Compact number formatting for tables; sequences are bracketed. digits=None: shortest repr."""
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return str(x)
    if isinstance(x, (int,)):
        return str(x)
    if isinstance(x, float):
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x + 0.0) if digits is None else f"{x + 0.0:.{digits}g}"
    if hasattr(x, "tolist"):
        return fmt(x.tolist(), digits)
    if isinstance(x, Sequence):
        return "[" + ", ".join(fmt(v, digits) for v in x) + "]"
    return str(x)


def table(headers: Sequence[str], rows: Iterable[Sequence[Any]], digits: int = 6) -> str:
    """A plain-text table with a header rule; cells go through `fmt`."""
    cells = [[fmt(c, digits) for c in row] for row in rows]
    widths = [len(h) for h in headers]
    for row in cells:
        widths = [max(w, len(c)) for w, c in zip(widths, row, strict=True)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True))
    rule = "  ".join("-" * w for w in widths)
    body = ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in cells]
    return "\n".join([line.rstrip(), rule, *[b.rstrip() for b in body]])


def key_values(pairs: Iterable[tuple[str, Any]], digits: int | None = 6) -> str:
    """Aligned `key: value` lines."""
    items = [(k, fmt(v, digits)) for k, v in pairs]
    width = max((len(k) for k, _ in items), default=0)
    return "\n".join(f"{k.ljust(width)} : {v}" for k, v in items)


def matrix(rows: Any, digits: int = 6) -> str:
    """A matrix as aligned rows."""
    values = [[fmt(float(v), digits) for v in row] for row in rows]
    width = max((len(v) for row in values for v in row), default=0)
    return "\n".join("  [" + "  ".join(v.rjust(width) for v in row) + "]" for row in values)


def emit(args: argparse.Namespace, payload: dict[str, Any], human: Callable[[], str]) -> None:
    """The CLI's `Out`: the payload as strict JSON with --json, else the human-readable report."""
    print(dumps(payload) if args.json else human())


def show_progress(args: argparse.Namespace) -> bool:
    """Progress bars in the CLI: only on a terminal, and never with --json."""
    import sys

    return not getattr(args, "json", False) and sys.stderr.isatty()


def compile_notice(args: argparse.Namespace, kernels: Sequence[Any]) -> None:
    """On a terminal (as the progress bars), "compiling kernels (first run only)" on stderr before
    a wait for Numba kernels its cache does not hold (a generic closed loop's solver: minutes)."""
    if kernels and show_progress(args):
        import sys

        from kinematics import jit

        if not jit.cached(kernels):
            print("compiling kernels (first run only)", file=sys.stderr, flush=True)
