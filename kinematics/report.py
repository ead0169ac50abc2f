"""Output helpers for the CLI: strict JSON and plain-text tables. No heavy imports."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

Out = Callable[[argparse.Namespace, dict[str, Any], Callable[[], str]], None]
"""The CLI's output callback: (args, JSON payload, human-readable report thunk)."""


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


OUTPUT_SUFFIXES: dict[str, tuple[str, ...]] = {
    "figure": (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff"),
    "csv": (".csv",),
    "points": (".npy", ".csv", ".txt"),
    "html": (".html", ".htm"),
    "urdf": (".urdf",),
    "poses": (".csv", ".npy"),
    "mesh": (".stl", ".ply", ".glb"),
}
"""The suffixes each kind of output file may have (the writer is chosen by the suffix)."""


def check_output(path: str, option: str, kind: str) -> None:
    """Refuse an output path before any work is done: its directory must exist and be writable,
    the path must not be a directory, and its suffix must be one `kind` can be written as.
    Raises InvalidInputError naming the CLI `option`."""
    import os

    from .errors import InvalidInputError

    suffixes = OUTPUT_SUFFIXES[kind]
    ext = os.path.splitext(path)[1].lower()
    if not path or path.endswith(os.sep) or os.path.isdir(path):
        raise InvalidInputError(option, f"{path!r} is a directory; give a file name ({'/'.join(suffixes)})")
    if ext not in suffixes:
        raise InvalidInputError(option, f"{path!r}: unknown suffix {ext or '(none)'!r}; use one of {', '.join(suffixes)}")
    parent = os.path.dirname(path) or "."
    if not os.path.isdir(parent):
        raise InvalidInputError(option, f"{path!r}: directory {parent!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InvalidInputError(option, f"{path!r}: directory {parent!r} is not writable")


def write_atomic(path: str, content: str | bytes | Callable[[str], None], option: str) -> None:
    """Write `content` to `path` through a temporary file beside it and a rename, so no reader
    ever sees a half-written file and nothing is left behind on any failure (an interrupt
    included). `content` is text, bytes, or a function that writes a given path (the temporary
    path keeps the suffix, so suffix-driven writers such as savefig and numpy.save work). An
    OSError becomes an InvalidInputError naming the CLI `option`."""
    import os
    import secrets

    from .errors import InvalidInputError

    parent, name = os.path.split(path)
    ext = os.path.splitext(name)[1]
    tmp = os.path.join(parent, f".{name}.{os.getpid()}.{secrets.token_hex(4)}.tmp{ext}")
    try:
        if callable(content):
            content(tmp)
        elif isinstance(content, bytes):
            with open(tmp, "xb") as fb:
                fb.write(content)
        else:
            with open(tmp, "x", encoding="utf-8") as f:
                f.write(content)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise InvalidInputError(option, f"cannot write {path}: {exc.strerror or exc}") from None
        raise


def show_progress(args: argparse.Namespace) -> bool:
    """Progress bars in the CLI: only on a terminal, and never with --json."""
    import sys

    return not getattr(args, "json", False) and sys.stderr.isatty()
