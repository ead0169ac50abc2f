"""Volume (or area) of {x : f(x) >= 0} with error bounds, refining only the boundary cells.

The region is given by a continuous *margin* f (positive inside), sampled at the corners of a
regular grid of cells over a box. Per cell:

* all corners inside: the cell counts wholly (it enters the lower bound);
* all corners outside: it is dropped;
* mixed: a *boundary* cell. It enters the upper bound whole, and the estimate with the fraction
  of the cell where the linear interpolant of f is >= 0 (Kuhn triangulation into d! simplices,
  the exact fraction per simplex from the divided difference of t_+^d at the corner values).

Boundary cells are split in 2^d children and resampled, level after level, so a tight answer
costs surface work (~ area / h^2 samples), not volume work (~ volume / h^3). The interpolated
boundary is second-order accurate, so the error of level k is estimated as
|E_k - E_{k-1}| / 3 (Richardson); refinement stops once that is <= rtol * E_k.

Assumption (as for any sampling method): the starting step resolves the region, i.e. no part of
the boundary slips between the corners of a cell that looks wholly inside or outside.
Volumes are sums of integer cell counts per level plus per-cell fractions in a fixed order, so
the result does not depend on the evaluation chunk size.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from kinematics.chunks import slices
from kinematics.errors import InvalidInputError
from kinematics.sizes import MAX_POINTS, check_points, grid_points, refinement_points

# MAX_POINTS (kinematics.sizes) caps the sampled points: the refinement stops there with
# converged = False, and a starting grid or a tolerance that would need more is refused.

CELL_CHUNK = 1 << 17
"""Boundary cells refined per batch (bounds memory at ~ 27 x this many sampled points)."""


@dataclass(frozen=True)
class Level:
    """One refinement level: cell size, boundary cells, running figures per target."""

    step: float
    boundary_cells: int
    points: int
    estimate: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]


@dataclass(frozen=True)
class VolumeEstimate:
    """Measure of {f_t >= 0} for each target t (volume [m^3] in 3D, area [m^2] in 2D).

    Attributes:
        estimate, lower, upper, error: per target; error is the Richardson estimate (inf when only
            one level ran).
        step: starting cell size [m]; finest_step: that of the last level [m].
        levels: the history, coarse to fine (for convergence plots).
        points_evaluated: margin evaluations in all.
        converged: every target met rtol.
        box: (2, d) [min, max] of the sampled points inside the last target (NaN if none).
    """

    estimate: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    error: np.ndarray
    step: float
    finest_step: float
    rtol: float
    levels: tuple[Level, ...]
    points_evaluated: int
    converged: bool
    box: np.ndarray


def check_step(step: float) -> None:
    """Raise InvalidInputError unless `step` is a positive, finite grid step [m]."""
    if not (math.isfinite(step) and step > 0):
        raise InvalidInputError("step", f"must be a positive length [m], got {step}")


def _kuhn_simplices(d: int) -> np.ndarray:
    """(d!, d+1) corner indices (bit k of an index = offset along axis k) of the Kuhn simplices."""
    out = []
    for perm in itertools.permutations(range(d)):
        v = 0
        idx = [v]
        for axis in perm:
            v |= 1 << axis
            idx.append(v)
        out.append(idx)
    return np.array(out)


@njit(cache=True)
def _fraction(v, table, hom):  # pragma: no cover - compiled
    """Divided difference of t_+^d at the values v (sorted descending, d + 1 of them).

    table[j] holds the divided difference over v_j..v_{j+w}, hom[j, m] the complete homogeneous
    polynomial h_m of the same nodes (the divided difference of t^d when all are >= 0).
    """
    n = v.shape[0]
    d = n - 1
    if v[d] >= 0.0:
        return 1.0
    if v[0] < 0.0:
        return 0.0
    for j in range(n):
        table[j] = v[j] ** d if v[j] >= 0.0 else 0.0
        hom[j, 0] = 1.0
        for m in range(1, d + 1):
            hom[j, m] = hom[j, m - 1] * v[j]
    for width in range(1, n):
        for j in range(n - width):
            lo, hi = v[j], v[j + width]
            # h_m(v_j..v_{j+w}) = h_m(v_j..v_{j+w-1}) + v_{j+w} h_{m-1}(v_j..v_{j+w})
            for m in range(1, d - width + 1):
                hom[j, m] = hom[j, m] + hi * hom[j, m - 1]
            if hi >= 0.0:
                table[j] = hom[j, d - width]
            elif lo < 0.0:
                table[j] = 0.0
            else:  # lo >= 0 > hi: the division is by a strictly negative number
                table[j] = (table[j + 1] - table[j]) / (hi - lo)
    return min(1.0, max(0.0, table[0]))


@njit(cache=True, parallel=True)
def _classify_cells(cv, simplices, active, boundary, frac):  # pragma: no cover - compiled
    """Per cell and target: all-inside -> frac 1; mixed -> boundary, frac = mean simplex fraction."""
    M, C, T = cv.shape
    S, n = simplices.shape
    for k in prange(M):
        v = np.empty(n)
        table = np.empty(n)
        hom = np.empty((n, n))
        for t in range(T):
            boundary[k, t] = False
            frac[k, t] = 0.0
            if not active[k, t]:
                continue
            pos = 0
            for c in range(C):
                if cv[k, c, t] >= 0.0:
                    pos += 1
            if pos == C:
                frac[k, t] = 1.0
            elif pos > 0:
                boundary[k, t] = True
                acc = 0.0
                for s in range(S):
                    for j in range(n):
                        v[j] = -cv[k, simplices[s, j], t]
                    v.sort()
                    for j in range(n):
                        v[j] = -v[j]
                    acc += _fraction(v, table, hom)
                frac[k, t] = acc / S


def simplex_fraction(values: np.ndarray) -> np.ndarray:
    """Fraction of a d-simplex where the linear interpolant of its vertex values is >= 0.

    values: (..., d+1). The fraction is the divided difference of t_+^d at the values, evaluated
    with the values sorted descending so that every division is by (negative - positive) < 0:
    no cancellation, exactly 0 and 1 on one-signed simplices.
    """
    values = np.asarray(values, dtype=float)
    flat = values.reshape(-1, values.shape[-1])
    out = np.empty(len(flat))
    n = flat.shape[1]
    table, hom = np.empty(n), np.empty((n, n))
    for k, row in enumerate(flat):
        out[k] = _fraction(-np.sort(-row), table, hom)
    return out.reshape(values.shape[:-1])


def adaptive_volume(
    margin: Callable[[np.ndarray], np.ndarray],
    lo: np.ndarray,
    hi: np.ndarray,
    step: float,
    rtol: float | None = 1e-3,
    *,
    max_levels: int = 12,
    max_points: int = MAX_POINTS,
    progress: bool = False,
) -> VolumeEstimate:
    """Measure {x : margin(x)[:, t] >= 0} for every target t inside the box [lo, hi].

    Args:
        margin: (N, d) points [m] -> (N, T) margins, continuous, > 0 inside.
        lo: the box's lower corner [m]; the box must contain the region.
        hi: the box's upper corner [m].
        step: starting cell size [m].
        rtol: relative tolerance on the estimate; None: one uniform grid, no refinement.
        max_levels: refinement budget in levels; when it runs out, converged is False.
        max_points: refinement budget in margin evaluations; when it runs out, converged is False.
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    d = lo.shape[0]
    check_step(step)
    if rtol is not None and not (math.isfinite(rtol) and rtol > 0):
        raise InvalidInputError("rtol", f"must be positive, got {rtol}")
    if not np.all(hi > lo):
        raise InvalidInputError("box", f"empty box {lo.tolist()} .. {hi.tolist()}")
    check_points("step", grid_points(lo, hi, step), limit=max_points, hint=f"{step:g} m is too fine a step")
    dims = np.ceil((hi - lo) / step).astype(np.int64)
    box: list[np.ndarray] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(desc="volume", unit="pt", unit_scale=True, delay=1.0, leave=False)

    def margin_and_box(x: np.ndarray) -> np.ndarray:
        values = np.asarray(margin(x), dtype=float)
        if not np.all(np.isfinite(values)):
            raise InvalidInputError("margin", "returned NaN or inf")
        inside = x[values[:, -1] >= 0]
        lo_t = inside.min(axis=0) if len(inside) else np.full(x.shape[1], np.inf)
        hi_t = inside.max(axis=0) if len(inside) else np.full(x.shape[1], -np.inf)
        if box:
            box[0] = np.minimum(box[0], lo_t)
            box[1] = np.maximum(box[1], hi_t)
        else:
            box.extend([lo_t, hi_t])
        if bar is not None:
            bar.update(len(x))
        return values

    offsets = np.array(list(itertools.product((0, 1), repeat=d)))[:, ::-1]  # bit k -> axis k
    simplices = _kuhn_simplices(d)

    # level 0: the whole grid, slab by slab along axis 0 (bounded memory; a slab's last plane is
    # evaluated again as the next one's first)
    plane = int(np.prod(dims[1:] + 1))
    per_slab = max(1, (1 << 20) // plane)
    h = step
    points = 0
    cell_parts, mask_parts = [], []
    inside_count: np.ndarray | int = 0
    frac_parts: list[np.ndarray] = []
    bcount: np.ndarray | int = 0
    for a0 in range(0, int(dims[0]), per_slab):
        a1 = min(a0 + per_slab, int(dims[0]))
        shape = np.array([a1 - a0 + 1, *(dims[1:] + 1)])
        idx = _unravel(slice(0, int(np.prod(shape))), shape)
        idx[:, 0] += a0
        values = margin_and_box(lo + step * idx)
        points += len(idx)
        T = values.shape[1]
        grid = values.reshape(*shape, T)
        cdims = shape - 1
        views = [grid[tuple(slice(o[k], o[k] + cdims[k]) for k in range(d))].reshape(-1, T) for o in offsets]
        mn = np.minimum.reduce(views)
        mx = np.maximum.reduce(views)
        all_in = mn >= 0
        mixed = (mx >= 0) & ~all_in
        inside_count = inside_count + all_in.sum(axis=0)
        rows = np.flatnonzero(mixed.any(axis=1))
        cv = np.stack([v[rows] for v in views], axis=1)
        boundary, f, _ = _classify(cv, simplices, mixed[rows])
        frac_parts.append(f)
        bcount = bcount + boundary.sum(axis=0)
        cells0 = np.stack(np.unravel_index(rows, tuple(cdims)), axis=-1)
        cells0[:, 0] += a0
        cell_parts.append(cells0)
        mask_parts.append(boundary)
    inside_volume = np.asarray(inside_count) * h**d
    levels: list[Level] = [_record(h, d, points, inside_volume, _exact_sum(frac_parts, T), np.asarray(bcount))]
    cells = np.concatenate(cell_parts)
    mask = np.concatenate(mask_parts)
    keep = mask.any(axis=1)
    cells, mask = cells[keep], mask[keep]

    if rtol is not None:  # refuse a tolerance the budget cannot reach, before refining
        check_points("rtol", refinement_points(points, len(cells), d, rtol), limit=max_points,
                     hint=f"{rtol:g} is too tight a tolerance at step {step:g} m")
    estimate = np.array(levels[-1].estimate)
    error = np.full(T, np.inf)
    converged = False
    # the 3^d points of a cell's 2^d children, and each child's corners among them
    local = np.array(list(itertools.product((0, 1, 2), repeat=d)))[:, ::-1]
    child_corner = np.array([[_local_index(c + o, d) for o in offsets] for c in offsets])  # (2^d, 2^d)
    while rtol is not None and len(levels) <= max_levels and len(cells):
        if points + len(cells) * 3**d > max_points:
            break
        h /= 2
        new_cells, new_mask = [], []
        fparts, icount, btotal = [], np.zeros(T, np.int64), np.zeros(T, np.int64)
        for s in slices(len(cells), CELL_CHUNK):
            parents, pmask = cells[s], mask[s]
            values = margin_and_box(lo + h * (2 * parents[:, None, :] + local[None]).reshape(-1, d))
            points += values.shape[0]
            values = values.reshape(len(parents), 3**d, T)
            cv = values[:, child_corner, :].reshape(-1, 2**d, T)  # (parents * 2^d children, 2^d, T)
            cmask = np.repeat(pmask, 2**d, axis=0)
            boundary, f, ic = _classify(cv, simplices, cmask)
            fparts.append(f)
            icount += ic
            btotal += boundary.sum(axis=0)
            keep = boundary.any(axis=1)
            children = (2 * parents[:, None, :] + offsets[None]).reshape(-1, d)
            new_cells.append(children[keep])
            new_mask.append(boundary[keep])
        inside_volume += icount * h**d
        levels.append(_record(h, d, points, inside_volume, _exact_sum(fparts, T), btotal))
        cells = np.concatenate(new_cells)
        mask = np.concatenate(new_mask)
        previous = estimate
        estimate = np.array(levels[-1].estimate)
        error = np.abs(estimate - previous) / 3.0
        if np.all(error <= rtol * np.maximum(estimate, np.finfo(float).tiny)):
            converged = True
            break
    if rtol is not None and len(cells) == 0:  # nothing left to refine: exact for the sampling
        error = np.zeros(T)
        converged = True
    if bar is not None:
        bar.close()
    last = levels[-1]
    return VolumeEstimate(
        estimate=np.array(last.estimate),
        lower=np.array(last.lower),
        upper=np.array(last.upper),
        error=error,
        step=step,
        finest_step=last.step,
        rtol=math.nan if rtol is None else rtol,
        levels=tuple(levels),
        points_evaluated=points,
        converged=converged,
        box=np.where(np.isfinite(np.stack(box)), np.stack(box), np.nan),
    )


def _classify(
    cv: np.ndarray, simplices: np.ndarray, active: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corner values (M, 2^d, T) -> boundary mask (M, T), boundary fractions (M, T), inside count (T,).

    Only (cell, target) pairs marked `active` count: a cell refined for one target's boundary may
    lie wholly inside another target, which counted it already at the coarser level.
    """
    M, _, T = cv.shape
    if M == 0:
        return np.zeros((0, T), bool), np.zeros((0, T)), np.zeros(T, np.int64)
    boundary = np.empty((M, T), dtype=bool)
    frac = np.empty((M, T))
    _classify_cells(np.ascontiguousarray(cv), simplices, np.ascontiguousarray(active), boundary, frac)
    inside = (frac == 1.0) & ~boundary
    return boundary, np.where(boundary, frac, 0.0), inside.sum(axis=0)


def _exact_sum(parts: list[np.ndarray], T: int) -> np.ndarray:
    """Column sums of stacked (M_k, T) arrays, correctly rounded (math.fsum), hence independent of
    how the rows were split into chunks."""
    if not parts:
        return np.zeros(T)
    allrows = np.concatenate(parts)
    return np.array([math.fsum(allrows[:, t]) for t in range(T)])


def _record(h: float, d: int, points: int, inside: np.ndarray, fsum: np.ndarray, boundary: np.ndarray) -> Level:
    cell = h**d
    return Level(
        step=h,
        boundary_cells=int(boundary.max()) if boundary.size else 0,
        points=points,
        estimate=tuple((inside + fsum * cell).tolist()),
        lower=tuple(inside.tolist()),
        upper=tuple((inside + boundary * cell).tolist()),
    )


def _local_index(v: np.ndarray, d: int) -> int:
    """Index of local point v (entries 0..2, axis 0 fastest) in the 3^d block."""
    return int(sum(int(v[k]) * 3**k for k in range(d)))


def _unravel(s: slice, shape: np.ndarray) -> np.ndarray:
    return np.stack(np.unravel_index(np.arange(s.start, s.stop), tuple(shape)), axis=-1)
