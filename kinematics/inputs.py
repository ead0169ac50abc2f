"""Checked array inputs: a batch of task points as every margin and batched solver takes it.

A margin is the volume engine's inner loop, and a NaN point would come back as a NaN margin that
the engine reads as "outside"; so a user's batch is checked where it enters, once per call (the
test costs ~1 ns a point, under 1 % of the cheapest margin: 0.26 us a point for the 3-[P2(US)]'s,
0.5 us for the SCARA's, measured on 1e6 points).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.errors import InvalidInputError

if TYPE_CHECKING:  # numpy stays unimported for `kinematics --help`
    import numpy as np


def _floats(value: object, name: str, shape: str) -> np.ndarray:
    """`value` as floats; InvalidInputError for text, None, complex numbers (numpy would drop the
    imaginary part with a warning), ragged lists and integers beyond a float's range."""
    import numpy as np

    try:
        a = np.asarray(value)
        if a.dtype.kind in "biuf":
            return a.astype(float, copy=False)
        if a.dtype.kind == "O":  # Python ints too large for int64, Decimals, ...: numbers if floats take them
            return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        pass
    raise InvalidInputError(name, f"expected real numbers of shape {shape}, got {value!r:.80}")


def finite_vectors(value: object, size: int, name: str, noun: str = "") -> np.ndarray:
    """`value` as a float array of shape S + (size,) (one vector or a batch); InvalidInputError
    naming `name` if it is not numbers, not of that shape, or not finite (a NaN in would come out
    as a NaN answer said to exist); `noun` says what a vector holds, e.g. "actuator angles"."""
    import numpy as np

    v = _floats(value, name, f"(..., {size})")
    if v.shape[-1:] != (size,):
        held = f" ({size} {noun} each)" if noun else ""
        raise InvalidInputError(name, f"expected shape (..., {size}){held}, got {v.shape}")
    if not np.isfinite(v).all():
        raise InvalidInputError(name, "must be finite")
    return v


def task_points(points: object, d: int, name: str = "points") -> np.ndarray:
    """`points` as a C-contiguous float array of shape (N, d) [m]; InvalidInputError naming `name`
    if it is not numbers, not of that shape, or not finite."""
    import numpy as np

    p = _floats(points, name, f"(N, {d})")
    if p.ndim != 2 or p.shape[1] != d:
        raise InvalidInputError(name, f"expected shape (N, {d}), got {p.shape}")
    if not np.isfinite(p).all():
        row = int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])
        raise InvalidInputError(name, f"must be finite; row {row} is {p[row].tolist()}")
    return np.ascontiguousarray(p)


__all__ = ["finite_vectors", "task_points"]
