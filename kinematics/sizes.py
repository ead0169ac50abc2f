"""One budget for every size a caller sets: grid steps, angle steps, control periods, sweep
counts, volume tolerances, worker counts.

Each of these decides how much work (and memory) a call does, and a mistyped exponent can ask
for terabytes or hours. Every such size is turned into the count of points (samples, steps,
designs x points, processes) it implies and checked here, before anything is allocated, so the
refusal names the count and the limit in one line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from kinematics.errors import InvalidInputError

if TYPE_CHECKING:  # numpy stays unimported for `kinematics --help`
    import numpy as np

MAX_POINTS = 200_000_000
"""Sampled points one call may evaluate (a few GB of bookkeeping and minutes of work)."""

MAX_LISTED_POINTS = 50_000_000
"""Grid points a points file may list (1.2 GB as an array, several as CSV text)."""

MAX_VIEW_POINTS = 2_000_000
"""Grid points a Meshcat view may sample (a browser draws a few million points at most)."""

MAX_COLLISION_VIEW_POINTS = 200_000
"""Grid points a serial arm's collision-aware view or figure may search (each reached point costs
a search and every pair's distance: ~0.25 ms on the ur5's 20 mesh pairs, so ~15 s where a
quarter of the box is reached, more for arms with more pairs or under load)."""

MAX_STEPS = 2_000_000
"""Control steps of one guidance simulation (a Python loop: ~ a minute at this length)."""


def check_count(name: str, value: object, minimum: int, what: str = "", note: str = "") -> None:
    """Raise InvalidInputError unless `value` is a whole number (an int, not a bool) >= `minimum`:
    "must be a whole number{what} >= {minimum}{note}", e.g. what " of slices"."""
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise InvalidInputError(name, f"must be a whole number{what} >= {minimum}{note}, got {value!r}")


def check_points(what: str, count: float, *, limit: int = MAX_POINTS, unit: str = "points",
                 hint: str = "") -> int:
    """Return `count` as an int if 1 <= count <= limit, else raise one InvalidInputError that
    states the count and the limit.

    Args:
        what: the input responsible (a parameter or CLI option name).
        count: what it implies; a float so that absurd sizes do not overflow an int64.
        hint: what to change, e.g. "use a larger step".
    """
    tail = f"; {hint}" if hint else ""
    if not math.isfinite(count) or count > limit:
        shown = "more than 1e308" if not math.isfinite(count) else f"{count:,.0f}"
        raise InvalidInputError(what, f"needs {shown} {unit}, over the {limit:,} limit{tail}")
    if count < 1:
        raise InvalidInputError(what, f"gives {count:,.0f} {unit}; at least 1 is needed{tail}")
    return int(count)


def grid_points(lo: Sequence[float] | np.ndarray, hi: Sequence[float] | np.ndarray, step: float) -> float:
    """Corner points of a regular grid of cell size `step` over the box [lo, hi] (a float)."""
    return math.prod(math.ceil((b - a) / step) + 1 for a, b in zip(lo, hi, strict=True))


def cell_centres(lo: Sequence[float] | np.ndarray, hi: Sequence[float] | np.ndarray, step: float) -> np.ndarray:
    """Centres (N, d) of the cells of size `step` tiling the box [lo, hi] from `lo` (the last axis
    fastest): the grid a points file, a view or a count samples; check its size first
    (`check_points` with `grid_points`)."""
    import numpy as np

    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(len(lo))]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(lo))


def refinement_points(grid: float, boundary_cells: int, d: int, rtol: float) -> float:
    """Estimate of the points an adaptive volume refined to `rtol` evaluates in all, from its
    starting grid (`grid` corner points, `boundary_cells` of its cells on the boundary, dimension d).

    Model: n = grid^(1/d) points per side; the interpolated boundary is second-order, so the
    relative error of level k is ~ C / (n^2 4^k) (C = 64 bounds what the 3-[P2(US)] and SCARA
    regions show). Reaching rtol takes k = log4(C / (n^2 rtol)) levels, and level j resamples
    3^d points in each of boundary_cells 2^((d-1) j) cells. Within a factor
    of 2 of the p2us and SCARA runs from rtol 1e-2 to 1e-8.
    """
    n = max(grid ** (1.0 / d), 2.0)
    k = max(0, math.ceil(math.log(64.0 / (n * n * rtol), 4)))
    return grid + sum(3**d * boundary_cells * 2.0 ** ((d - 1) * j) for j in range(1, k + 1))
