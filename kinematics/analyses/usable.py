"""Usable workspace: the largest axis-aligned cube, vertical cylinder and sphere (in a plane: the
largest axis-aligned square and disk) inside a region where the robot is both reachable and well
conditioned.

The region is {p : u(p) >= 0} for a *usable field* u. For any `Mechanism` in one branch (working
mode, elbow), `usable_field` builds

    u(p) = min(margin(p), 1/kappa(p) - 1/kappa_max),

margin [m] the branch's workspace margin (`Mechanism.margin`, >= 0 inside every limit) and
kappa = sigma_max / sigma_min of the forward Jacobian J (`Mechanism.branch_velocity`; for the
3-[P2(US)] J = J_x^-1 diag(J_q), dimensionless; for the Delta m/rad, a common unit, so kappa is
still scale-free). A singular pose (iota_I or iota_II <= SINGULAR_TOL) gets u < 0. Only the sign
of u is used. The union of the branches is u = max over branches.

Method (any field, `largest_shape`): (1) sample u on a grid of step h over a box; distance
transforms of the usable voxels give, at every voxel, the largest sphere (Euclidean), cube
(chessboard) and vertical cylinder (per-slice 2D Euclidean, sliding minimum along z) centred there,
and an upper bound on the volume of any such shape whose centre lies in the voxel's cell (in a
plane the same with pixels: the square by the chessboard, the disk by the Euclidean transform, areas
for volumes).
(2) Global search: the few best well-separated centres are sized by bisection against the
membership test; cells whose bound exceeds the best shape found are sampled again at h/2 (three grids
by default), and again sized; (3) the best is refined by a pattern search of the centre (steps h
down to h/8) and, for the cylinder, the volume-preserving aspect ratio. (4) The membership test
(`contains`) samples the shape's solid on a grid of spacing `spacing` and its surface at spacing/2;
the shape is accepted if u >= 0 at every sample. The result reports the largest bound left
(`volume_bound`): no shape inside the region as sampled on the finest grid is larger. What the
method can miss: an unusable pocket thinner than the spacing lying between samples (e.g. a singular
surface crossing only a corner between two samples); the bound likewise speaks of the region as
sampled.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from kinematics.errors import InvalidInputError, UnknownChoiceError
from kinematics.sizes import check_points, grid_points

if TYPE_CHECKING:
    from kinematics.mechanisms.base import Mechanism

Field = Callable[[np.ndarray], np.ndarray]
MarginOf = Callable[[Sequence[str]], Field]
"""Branches -> their margin (points -> a column per branch, then any others)."""
Shape = Literal["cube", "cylinder", "sphere", "square", "disk"]
SPATIAL: tuple[str, ...] = ("cube", "cylinder", "sphere")
"""The shapes of a 3-D task space (volumes, m^3)."""
PLANAR: tuple[str, ...] = ("square", "disk")
"""The shapes of a 2-D task space (areas, m^2)."""
SHAPES: tuple[str, ...] = SPATIAL + PLANAR
EMPTY = "no grid point is usable (reached, collision-free where checked, non-singular, kappa <= kappa_max) at this step"
"""The problem text of the InvalidInputError `largest_shape` raises when nothing is usable."""
KAPPA_MAX = 10.0
"""Default bound on the condition number sigma_max / sigma_min."""


@dataclass(frozen=True)
class UsableShape:
    """A shape inside the usable region.

    Attributes:
        shape: "cube", "cylinder" or "sphere"; in a plane "square" or "disk".
        center: (3,) its centre [m] ((2,) in a plane).
        size: (edge,) for a cube or a square, (radius, height) for a cylinder, (radius,) for a
            sphere or a disk [m].
        samples: points of the final membership test; spacing: its solid-grid spacing [m].
        min_field: the smallest u over those samples (>= 0).
        larger_fails: the same shape 1 % larger fails the test at the centre and the 26 (in a plane
            8) neighbouring centres (offsets of half a grid step); False when not tested (no search).
        volume_bound: an upper bound [m^3] (in a plane an area [m^2]) on the volume of any such
            shape inside the region as sampled on the finest grid (`largest_shape`); the answer is
            within 1 - volume / volume_bound of the optimum. Cylinders: among those at least one
            grid step tall.
    """

    shape: str
    center: np.ndarray
    size: tuple[float, ...]
    samples: int
    spacing: float
    min_field: float
    larger_fails: bool
    volume_bound: float = math.inf

    @property
    def volume(self) -> float:
        """Volume [m^3] (a square's or a disk's area [m^2])."""
        return shape_volume(self.shape, self.size)

    @property
    def planar(self) -> bool:
        """Whether the shape is a square or a disk (its `volume` an area)."""
        return self.shape in PLANAR

    @property
    def optimality_gap(self) -> float:
        """1 - volume / volume_bound: how much larger (relative, in volume) the optimum can be."""
        return 1.0 - self.volume / self.volume_bound


def shape_volume(shape: str, size: Sequence[float]) -> float:
    """edge^3, pi r^2 h or 4/3 pi r^3 [m^3]; a square's edge^2 or a disk's pi r^2 [m^2]."""
    if shape == "cube":
        return float(size[0] ** 3)
    if shape == "cylinder":
        return float(math.pi * size[0] ** 2 * size[1])
    if shape == "square":
        return float(size[0] ** 2)
    if shape == "disk":
        return float(math.pi * size[0] ** 2)
    return float(4.0 / 3.0 * math.pi * size[0] ** 3)


def _check_shape(shape: str, d: int | None = None) -> str:
    """`shape`, one of SHAPES, or of the d-dimensional ones (SPATIAL, PLANAR) when d is given."""
    valid = SHAPES if d is None else PLANAR if d == 2 else SPATIAL
    if shape not in valid:
        raise UnknownChoiceError(shape, valid)
    return shape


def _axis(a: float, b: float, spacing: float) -> np.ndarray:
    return np.linspace(a, b, max(2, math.ceil((b - a) / spacing) + 1))


def shape_samples(shape: str, center: np.ndarray, size: Sequence[float], spacing: float) -> np.ndarray:
    """Points of the shape's solid on a grid of `spacing` [m] (boundary included) and of its
    surface at spacing / 2, shape (N, 3) ((N, 2) for a square or a disk: its area and outline)."""
    c = np.asarray(center, dtype=float)
    fine = spacing / 2
    if shape == "square":
        a = size[0] / 2
        g = _axis(-a, a, spacing)
        solid = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        f = _axis(-a, a, fine)
        edges = [np.column_stack([np.full_like(f, sgn * a), f]) for sgn in (-1, 1)]
        return c + np.concatenate([solid, *edges, *(e[:, ::-1] for e in edges)])
    if shape == "disk":
        r = size[0]
        g = _axis(-r, r, spacing)
        solid = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        solid = solid[np.einsum("ij,ij->i", solid, solid) <= r * r]
        t = np.linspace(0, 2 * math.pi, max(8, math.ceil(2 * math.pi * r / fine)), endpoint=False)
        return c + np.concatenate([solid, r * np.column_stack([np.cos(t), np.sin(t)])])
    if shape == "cube":
        a = size[0] / 2
        g = _axis(-a, a, spacing)
        solid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        f = _axis(-a, a, fine)
        u, v = (x.ravel() for x in np.meshgrid(f, f, indexing="ij"))
        faces = [np.stack([s * a * np.ones_like(u), u, v], -1) for s in (-1, 1)]
        surf = np.concatenate([np.roll(fc, k, axis=1) for fc in faces for k in range(3)])
        return c + np.concatenate([solid, surf])
    if shape == "sphere":
        r = size[0]
        g = _axis(-r, r, spacing)
        solid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        solid = solid[np.einsum("ij,ij->i", solid, solid) <= r * r]
        n = max(8, math.ceil(4 * math.pi * r * r / fine**2))
        k = np.arange(n) + 0.5  # a Fibonacci lattice: near-uniform points on the sphere
        z = 1 - 2 * k / n
        phi = math.pi * (1 + math.sqrt(5)) * k
        rho = np.sqrt(1 - z * z)
        surf = r * np.stack([rho * np.cos(phi), rho * np.sin(phi), z], -1)
        return c + np.concatenate([solid, surf])
    r, h = size
    g = _axis(-r, r, spacing)
    gz = _axis(-h / 2, h / 2, spacing)
    solid = np.stack(np.meshgrid(g, g, gz, indexing="ij"), -1).reshape(-1, 3)
    solid = solid[solid[:, 0] ** 2 + solid[:, 1] ** 2 <= r * r]
    na = max(8, math.ceil(2 * math.pi * r / fine))
    t = np.linspace(0, 2 * math.pi, na, endpoint=False)
    zs = _axis(-h / 2, h / 2, fine)
    side = np.stack([np.repeat(r * np.cos(t)[None], len(zs), 0), np.repeat(r * np.sin(t)[None], len(zs), 0),
                     np.repeat(zs[:, None], na, 1)], -1).reshape(-1, 3)
    d = _axis(-r, r, fine)
    cap = np.stack(np.meshgrid(d, d, indexing="ij"), -1).reshape(-1, 2)
    cap = cap[cap[:, 0] ** 2 + cap[:, 1] ** 2 <= r * r]
    caps = np.concatenate([np.column_stack([cap, np.full(len(cap), s * h / 2)]) for s in (-1, 1)])
    return c + np.concatenate([solid, side, caps])


def contains(field: Field, shape: str, center: np.ndarray, size: Sequence[float], spacing: float) -> float:
    """The smallest field value over `shape_samples` (the shape is accepted if >= 0)."""
    pts = shape_samples(shape, center, size, spacing)
    check_points("spacing", len(pts), hint="use a larger spacing")
    return float(np.min(field(pts)))


FIT_CHUNK = 4096
"""Samples per field call of `shape_fits` (a chunk spread over the whole shape)."""


def shape_fits(field: Field, shape: str, center: np.ndarray, size: Sequence[float], spacing: float) -> bool:
    """Whether `contains(...) >= 0`, the samples evaluated in chunks that stop at the first
    negative (or NaN) value: each chunk takes every k-th sample, so it spreads over the whole shape
    and a shape that does not fit is usually rejected after one chunk, where `contains` evaluates
    every sample. The same answer."""
    pts = shape_samples(shape, center, size, spacing)
    check_points("spacing", len(pts), hint="use a larger spacing")
    chunks = max(1, -(-len(pts) // FIT_CHUNK))
    return all(bool(np.min(field(pts[k::chunks])) >= 0) for k in range(chunks))


def _per_voxel(shape: str, ok: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per voxel of a sampled region (`ok`: the field >= 0 at the voxel centres, grid step h [m]):
    the largest size found by distance transforms centred there, its volume, an upper bound on the
    volume of any shape inside the region whose centre lies in the voxel's cell, and the half-extent
    [m] of the shapes that bound allows (how far from the cell such a shape can reach).

    The bounds hold for the sampled region (every voxel inside a shape inside the region is `ok`):
    with v the voxel nearest the shape's centre (at most h/2 per axis away), every unusable voxel
    lies outside the shape, so its distance from v exceeds the shape's half-size less the offset:

    * sphere: r < h (e + sqrt(3)/2), e the Euclidean distance transform at v (voxels); a disk
      (pixels): r < h (e + sqrt(2)/2);
    * cube, square: edge < h (2 c + 1), c the chessboard distance transform;
    * vertical cylinder at least one step tall: over the 2m + 1 slices centred at v, all inside the
      cylinder's height H < (2m + 3) h, the disk radius r < h (e_m + sqrt(2)/2), e_m the smallest
      per-slice 2-D Euclidean distance transform at v's column over those slices; the bound is the
      largest pi r^2 H over m.
    """
    from scipy import ndimage

    d = ok.ndim
    padded = np.pad(ok, 1)  # the box's outside counts as unusable
    inner = (slice(1, -1),) * d
    if shape in ("sphere", "disk"):
        e = ndimage.distance_transform_edt(padded)[inner]
        size = np.maximum(e - 1.0, 0.0)[..., None] * h
        r_up = h * (e + math.sqrt(d) / 2)
        ball = 4 / 3 * math.pi if d == 3 else math.pi  # r^d times this
        return size, ball * size[..., 0] ** d, ball * r_up**d, r_up
    if shape in ("cube", "square"):
        c = ndimage.distance_transform_cdt(padded, metric="chessboard")[inner].astype(float)
        size = 2 * np.maximum(c - 1.0, 0.0)[..., None] * h
        s_up = h * (2 * c + 1)
        return size, size[..., 0] ** d, s_up**d, s_up / 2 * math.sqrt(d)
    e2 = np.stack([ndimage.distance_transform_edt(padded[:, :, k]) for k in range(padded.shape[2])], -1)
    e2 = e2[1:-1, 1:-1, 1:-1]
    size = np.zeros((*ok.shape, 2))
    vol = np.zeros(ok.shape)
    bound = np.zeros(ok.shape)
    reach = np.zeros(ok.shape)
    for m in range(ok.shape[2] // 2 + 1):
        em = ndimage.minimum_filter1d(e2, 2 * m + 1, axis=2, mode="constant", cval=0.0)
        r, height = np.maximum(em - 1.0, 0.0) * h, max(2 * m, 1) * h
        better = math.pi * r**2 * height > vol
        size[better] = np.stack([r[better], np.full(int(better.sum()), height)], -1)
        vol = np.where(better, math.pi * r**2 * height, vol)
        r_up, h_up = h * (em + math.sqrt(2) / 2), (2 * m + 3) * h
        v_up = np.where(em > 0, math.pi * r_up**2 * h_up, 0.0)
        reach = np.where(v_up > 0, np.maximum(reach, np.hypot(r_up, h_up / 2)), reach)
        bound = np.maximum(bound, v_up)
    return size, vol, bound, reach


@dataclass(frozen=True)
class _Level:
    """A sampled grid of one refinement level: points origin + j h, the voxels whose cells may hold
    the optimum's centre (`region`) and their per-voxel results (`_per_voxel`)."""

    origin: np.ndarray
    h: float
    region: np.ndarray
    size: np.ndarray
    vol: np.ndarray
    bound: np.ndarray
    reach: np.ndarray

    def point(self, j: np.ndarray) -> np.ndarray:
        return self.origin + np.asarray(j) * self.h


def _level(field: Field, shape: str, origin: np.ndarray, h: float, n: tuple[int, ...],
           region: np.ndarray | None) -> _Level:
    d = len(n)
    axes = [origin[k] + h * np.arange(n[k]) for k in range(d)]
    check_points("step", math.prod(n), hint="use a larger step")
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    ok = (field(grid.reshape(-1, d)) >= 0).reshape(n)
    size, vol, bound, reach = _per_voxel(shape, ok, h)
    return _Level(origin, h, ok.copy() if region is None else region, size, vol, bound, reach)


def _finer(field: Field, shape: str, lv: _Level, best: float) -> _Level | None:
    """The next level at h/2 over the cells whose bound exceeds `best` (None if none does): each
    cell holds 2 x 2 x 2 (in a plane 2 x 2) finer voxels (at +-h/4), so a centre in the cell is
    within h/4 of one."""
    keep = lv.region & (lv.bound > best)
    if not keep.any():
        return None
    idx = np.argwhere(keep)
    pad = math.ceil(float(lv.reach[keep].max()) / lv.h) + 1  # shapes reach this far from their cells
    lo_j = np.maximum(idx.min(axis=0) - pad, 0)
    hi_j = np.minimum(idx.max(axis=0) + pad + 1, keep.shape)
    region = keep[tuple(slice(a, b) for a, b in zip(lo_j, hi_j, strict=True))]
    for k in range(keep.ndim):
        region = region.repeat(2, k)
    return _level(field, shape, lv.point(lo_j) - lv.h / 4, lv.h / 2, region.shape, region)


def _starts(lv: _Level, count: int) -> list[np.ndarray]:
    """Up to `count` centres of the level, largest found size first, each at least 2 steps (per
    axis) from those already taken."""
    cand = np.argwhere(lv.region & (lv.vol > 0))
    if not len(cand):
        cand = np.argwhere(lv.region)
    order = np.argsort(-lv.vol[tuple(cand.T)], kind="stable")
    taken: list[np.ndarray] = []
    for j in cand[order]:
        if all(np.abs(j - t).max() >= 2 for t in taken):
            taken.append(j)
            if len(taken) == count:
                break
    return taken


def largest_shape(field: Field, lo: ArrayLike, hi: ArrayLike, shape: str, *, step: float,
                  spacing: float | None = None, search: bool = True, levels: int = 3,
                  starts: int = 4) -> UsableShape:
    """The largest `shape` inside {field >= 0} within the box `[lo, hi]` [m] (see the module doc):
    a cube, cylinder or sphere in a 3-D box, a square or disk in a 2-D one.

    Global search: the field sampled every `step`, distance transforms give at every voxel the
    shape centred there and an upper bound on any shape centred in its cell (`_per_voxel`); the
    `starts` best-separated centres are sized by bisection against the membership test; cells whose
    bound exceeds the best tested shape are sampled again at half the step (`levels` grids in all),
    and the best start of the last level is refined by a pattern search. `volume_bound` is the
    largest bound left (or the best volume, if larger).

    Args:
        step: grid step of the coarsest search [m].
        spacing: membership-test spacing [m] (default step / 2).
        search: False skips the pattern search and the finer levels (the coarse optimum's centre,
            the size still bisected and checked): a checked lower bound, several times cheaper.
        levels: grids sampled (step, step/2, ...), at least 1.
        starts: centres sized per level.
    """
    lo_, hi_ = np.asarray(lo, float), np.asarray(hi, float)
    if lo_.shape != hi_.shape or lo_.shape not in ((2,), (3,)):
        raise InvalidInputError("lo, hi", f"expected a 2-D or 3-D box, got shapes {lo_.shape} and {hi_.shape}")
    d = len(lo_)
    _check_shape(shape, d)
    if not (step > 0 and math.isfinite(step)):
        raise InvalidInputError("step", f"must be a positive number of metres, got {step!r}")
    if levels < 1 or starts < 1:
        raise InvalidInputError("levels" if levels < 1 else "starts", "must be at least 1")
    spacing = step / 2 if spacing is None else spacing
    if not (spacing > 0 and math.isfinite(spacing)):
        raise InvalidInputError("spacing", f"must be a positive number of metres, got {spacing!r}")
    check_points("step", grid_points(lo_.tolist(), hi_.tolist(), step), hint="use a larger step")
    n = tuple(len(np.arange(a, b + step / 2, step)) for a, b in zip(lo_, hi_, strict=True))
    lv = _level(field, shape, lo_, step, n, None)
    if not lv.region.any():
        raise InvalidInputError("usable region", EMPTY)  # any of its conditions may empty it, not only kappa

    def fits(c: np.ndarray, size: Sequence[float]) -> bool:
        return shape_fits(field, shape, c, size, spacing)

    def max_scale(c: np.ndarray, base: tuple[float, ...], above: float = 0.0) -> float:
        """The largest t (to 1e-3 relative) with t x base fitting at c; `above` when t x base
        does not fit for t = above (one test: a pattern-search move that cannot improve)."""
        if above > 0 and not fits(c, [above * s for s in base]):
            return above
        lo_t, hi_t = 0.0, 1.0
        while fits(c, [hi_t * s for s in base]):
            lo_t, hi_t = hi_t, hi_t * 1.25
            if hi_t > 1e3:
                break
        if lo_t == 0.0:
            lo_t = hi_t / 2
            while lo_t > 1e-3 and not fits(c, [lo_t * s for s in base]):
                hi_t, lo_t = lo_t, lo_t / 2
            if lo_t <= 1e-3:
                return 0.0
        while hi_t - lo_t > 1e-3 * lo_t:
            mid = (lo_t + hi_t) / 2
            lo_t, hi_t = (mid, hi_t) if fits(c, [mid * s for s in base]) else (lo_t, mid)
        return lo_t

    tested: list[tuple[float, np.ndarray, tuple[float, ...]]] = []  # (volume, centre, size) of each start
    bound = 0.0
    grids = levels if search else 1  # without the search: the coarse grid's best start only
    for level in range(grids):
        for j in _starts(lv, starts if search else 1):
            base = tuple(float(x) for x in lv.size[tuple(j)])
            if min(base) <= 0:
                base = (lv.h / 4,) * len(base)
            t = max_scale(lv.point(j), base)
            tested.append((shape_volume(shape, [t * x for x in base]), lv.point(j), tuple(t * x for x in base)))
        best = max(v for v, _, _ in tested)
        bound = float(lv.bound[lv.region].max())
        if level + 1 < grids:
            finer = _finer(field, shape, lv, best)
            if finer is None:  # no cell can beat the best: the best is the bound
                bound = best
                break
            lv = finer

    def polish(center: np.ndarray, size0: tuple[float, ...]) -> tuple[np.ndarray, tuple[float, ...]]:
        """Pattern search of the centre (and the cylinder's aspect) from a tested start."""

        def sized(aspect: float) -> tuple[float, ...]:
            if shape != "cylinder":
                return size0
            return (size0[0] * aspect, size0[1] / aspect**2)  # same volume for every aspect

        aspect, t = 1.0, 1.0
        delta = step if search else 0.0
        while delta >= step / 8 and delta > 0:
            improved = False
            moves = [(ax, s) for ax in range(d) for s in (-1, 1)]
            if shape == "cylinder":
                moves += [(d, s) for s in (-1, 1)]
            for ax, s in moves:
                c, a = center.copy(), aspect
                if ax < d:
                    c[ax] += s * delta
                else:
                    a *= (1 + delta / max(size0[0], step)) ** s
                t_new = max_scale(c, sized(a), above=t * (1 + 1e-4))
                if t_new > t * (1 + 1e-4):
                    center, aspect, t, improved = c, a, t_new, True
            if not improved:
                delta /= 2
        return center, tuple(t * x for x in sized(aspect))

    # the two best starts at least a step apart are polished: they can lie in different basins
    tested.sort(key=lambda r: -r[0])
    firsts = [tested[0]]
    firsts += [r for r in tested[1:] if np.abs(r[1] - tested[0][1]).max() >= step][: 1 if search else 0]
    center, size = max((polish(c, sz) for _, c, sz in firsts), key=lambda r: shape_volume(shape, r[1]))
    final = contains(field, shape, center, size, spacing)
    if not final >= 0:  # every size the search kept passed this test: the field changed between calls
        import warnings

        from kinematics.errors import KinematicsWarning

        warnings.warn(KinematicsWarning(
            f"the {shape} found fails its final inside check (smallest usable field {final:.3g} over its samples): "
            "the field gave other values during the search (e.g. a closed loop whose solver returns either pose "
            "of an unlabelled elbow, docs/design.md); the shape is not verified"), stacklevel=2)
    bigger = [1.01 * s for s in size]
    offs = np.stack(np.meshgrid(*[[-step / 2, 0, step / 2]] * d, indexing="ij"), -1).reshape(-1, d)
    # (without the search the result is a lower bound, not claimed near-maximal: not tested)
    larger_fails = search and not any(shape_fits(field, shape, center + o, bigger, spacing) for o in offs)
    n_samples = len(shape_samples(shape, center, size, spacing))
    return UsableShape(shape, center, size, n_samples, spacing, final, larger_fails,
                       max(bound, shape_volume(shape, size)))


# -- any mechanism ------------------------------------------------------------------------------------
def inverse_condition(J: np.ndarray) -> np.ndarray:
    """1/kappa = sigma_min / sigma_max of each (N, d, a) Jacobian (dimensionless, in [0, 1]);
    0 where J is not finite (a type II pose: the forward map blows up) or zero."""
    J = np.asarray(J, dtype=float)
    finite = np.isfinite(J).all(axis=(-2, -1))
    out = np.zeros(J.shape[:-2])
    # only the finite rows: outside a branch (NaN rows, most of a union's) the SVD is wasted
    out[finite] = singular_ratio(np.linalg.svd(J[finite], compute_uv=False))
    return out


def singular_ratio(sv: np.ndarray) -> np.ndarray:
    """sigma_min / sigma_max of each row of singular values (..., k), largest first (numpy's
    order): 1/kappa, 0 where sigma_max is 0."""
    top = sv[..., 0]
    return np.where(top > 0, sv[..., -1] / np.where(top > 0, top, 1.0), 0.0)


def condition_slack_of(v: Any, inside: np.ndarray, kappa_max: float) -> np.ndarray:
    """1/kappa - 1/kappa_max per point from a `Velocity` (dimensionless): >= 0 iff kappa <= kappa_max;
    -1 outside the branch (`inside` False) and at singular poses (type I, II or III)."""
    from kinematics.mechanisms.base import SINGULAR_TOL

    with np.errstate(invalid="ignore"):
        singular = ~(v.iota_I > SINGULAR_TOL) | ~(v.iota_II > SINGULAR_TOL)
    inv = inverse_condition(v.J)
    return np.where(~inside | singular | ~(inv > 0), -1.0, inv - 1.0 / kappa_max)


def _check_kappa(kappa_max: float) -> float:
    if not (kappa_max >= 1 and math.isfinite(kappa_max)):
        raise InvalidInputError("kappa_max", f"must be a finite number >= 1, got {kappa_max!r}")
    return float(kappa_max)


def usable_field(mech: Mechanism, branch: str, kappa_max: float = KAPPA_MAX, limits: str = "all",
                 margin_of: MarginOf | None = None) -> Field:
    """u(p) of a mechanism in one branch (working mode, elbow), or "union" (the best branch at each
    point): min(margin, 1/kappa - 1/kappa_max) with kappa the 2-norm condition number of the forward
    Jacobian J (`Mechanism.branch_velocity`); singular poses get u < 0 (module docstring).

    kappa of J and of J^-1 agree for a square J; it is scale-free as long as J's columns share a
    unit (every actuator prismatic, or every one revolute), true of the built-in families.

    margin_of: builds the margin of the branches (points -> a column per branch first) instead of
    `mech.margin(branches, limits)`, e.g. the collision-aware one (`analyses.collisions`).
    """
    _check_kappa(kappa_max)
    mech.check_limits(limits)
    branches = mech.check_target(branch)
    margin = mech.margin(branches, limits) if margin_of is None else margin_of(branches)

    def field(points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=float)
        m = margin(points)
        out = np.full(len(points), -np.inf)
        for k, (v, inside) in enumerate(mech.branch_velocities(points, branches, limits)):
            out = np.maximum(out, np.minimum(m[:, k], condition_slack_of(v, inside, kappa_max)))
        return out

    return field


def usable(mech: Mechanism, shape: str, *, branch: str | None = None, kappa_max: float = KAPPA_MAX,
           limits: str = "all", step: float = 0.01, spacing: float | None = None,
           search: bool = True, levels: int = 3, margin_of: MarginOf | None = None) -> UsableShape:
    """The largest `shape` in the usable workspace of a mechanism (module docstring): a cube,
    cylinder or sphere for a spatial task space, a square or disk for a planar one (a SCARA, a
    five-bar: the task coordinates its `task_axes` name).

    Args:
        branch: a branch label or "union" (default: "---" where the mechanism has it, else its
            first branch).
        search: False skips the pattern search of the centre (the coarse optimum's centre, the
            size still bisected and checked): faster, a lower bound on the optimum.
        levels: grids of the global search (step, step/2, ...; `largest_shape`).
        margin_of: the branches' margin instead of the mechanism's (`usable_field`).
    """
    from kinematics.mechanisms.base import check_mechanism

    check_mechanism(mech, "usable")
    from kinematics.errors import UnsupportedRobotError

    _check_shape(shape)
    for need in ("margin", "ik", "velocity"):
        mech.require(need, "a usable workspace")
    if mech.task_dim not in (2, 3):
        raise UnsupportedRobotError(mech.name, "usable shapes need a planar or spatial task space (square, disk; "
                                    f"cube, cylinder, sphere); this mechanism's is {mech.task_dim}-dimensional")
    valid = PLANAR if mech.task_dim == 2 else SPATIAL
    if shape not in valid:
        raise UnsupportedRobotError(mech.name, f"a {shape} needs a {5 - mech.task_dim}-D task space; this one is "
                                    f"{mech.task_dim}-D ({', '.join(mech.task_axes)}): use {' or '.join(valid)}")
    field = usable_field(mech, default_branch(mech) if branch is None else branch, kappa_max, limits, margin_of)
    lo, hi = mech.bounding_box(limits)
    return largest_shape(field, lo, hi, shape, step=step, spacing=spacing, search=search, levels=levels)


def default_branch(mech: Mechanism) -> str:
    """ "---" (the usual working mode of the 3-[P2(US)] and the Delta) where it exists, else the first
    branch; "union" for a mechanism without branches (which then lacks the margin the usable
    workspace needs: `usable` says so)."""
    if not mech.branches:
        return "union"
    return "---" if "---" in mech.branches else mech.branches[0]
