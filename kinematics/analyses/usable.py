"""Usable workspace: the largest axis-aligned cube, vertical cylinder and sphere inside a region
where the robot is both reachable and well conditioned.

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
(chessboard) and vertical cylinder (per-slice 2D Euclidean, sliding minimum along z) centred there:
the coarse optimum. (2) Refinement: for a centre, the largest scale that passes the membership test
is bisected (to 1e-3 relative), and a pattern search moves the centre (steps h down to h/8) and, for
the cylinder, the volume-preserving aspect ratio. (3) The membership test (`contains`) samples the
shape's solid on a grid of spacing `spacing` and its surface at spacing/2; the shape is accepted if
u >= 0 at every sample. What it can miss: an unusable pocket thinner than the spacing lying
between samples (e.g. a singular surface crossing only a corner between two samples).
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
Shape = Literal["cube", "cylinder", "sphere"]
SHAPES: tuple[str, ...] = ("cube", "cylinder", "sphere")
EMPTY = "no grid point is usable: the usable region is empty at this step"
"""The problem text of the InvalidInputError `largest_shape` raises when nothing is usable."""
KAPPA_MAX = 10.0
"""Default bound on the condition number sigma_max / sigma_min."""


@dataclass(frozen=True)
class UsableShape:
    """A shape inside the usable region.

    Attributes:
        shape: "cube", "cylinder" or "sphere".
        center: (3,) its centre [m].
        size: (edge,) for a cube, (radius, height) for a cylinder, (radius,) for a sphere [m].
        samples: points of the final membership test; spacing: its solid-grid spacing [m].
        min_field: the smallest u over those samples (>= 0).
        larger_fails: the same shape 1 % larger fails the test at the centre and the 26
            neighbouring centres (offsets of half a grid step); False when not tested (no search).
    """

    shape: str
    center: np.ndarray
    size: tuple[float, ...]
    samples: int
    spacing: float
    min_field: float
    larger_fails: bool

    @property
    def volume(self) -> float:
        """Volume [m^3]."""
        return shape_volume(self.shape, self.size)


def shape_volume(shape: str, size: Sequence[float]) -> float:
    """edge^3, pi r^2 h or 4/3 pi r^3 [m^3]."""
    if shape == "cube":
        return float(size[0] ** 3)
    if shape == "cylinder":
        return float(math.pi * size[0] ** 2 * size[1])
    return float(4.0 / 3.0 * math.pi * size[0] ** 3)


def _check_shape(shape: str) -> str:
    if shape not in SHAPES:
        raise UnknownChoiceError(shape, SHAPES)
    return shape


def _axis(a: float, b: float, spacing: float) -> np.ndarray:
    return np.linspace(a, b, max(2, math.ceil((b - a) / spacing) + 1))


def shape_samples(shape: str, center: np.ndarray, size: Sequence[float], spacing: float) -> np.ndarray:
    """Points of the shape's solid on a grid of `spacing` [m] (boundary included) and of its
    surface at spacing / 2, shape (N, 3)."""
    c = np.asarray(center, dtype=float)
    fine = spacing / 2
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


def _coarse(shape: str, ok: np.ndarray, h: float) -> tuple[tuple[int, ...], tuple[float, ...]]:
    """Voxel index of the best centre and the conservative size there, from distance transforms."""
    from scipy import ndimage

    padded = np.pad(ok, 1)  # the box's outside counts as unusable
    if shape == "sphere":
        d = ndimage.distance_transform_edt(padded)[1:-1, 1:-1, 1:-1]
        idx = np.unravel_index(np.argmax(d), d.shape)
        return tuple(int(i) for i in idx), (max(d[idx] - 1.0, 0.0) * h,)
    if shape == "cube":
        d = ndimage.distance_transform_cdt(padded, metric="chessboard")[1:-1, 1:-1, 1:-1]
        idx = np.unravel_index(np.argmax(d), d.shape)
        return tuple(int(i) for i in idx), (2 * max(d[idx] - 1.0, 0.0) * h,)
    r2 = np.stack([ndimage.distance_transform_edt(padded[:, :, k]) for k in range(padded.shape[2])], -1)
    r2 = np.maximum(r2[1:-1, 1:-1, 1:-1] - 1.0, 0.0)
    best = -1.0
    arg: tuple[tuple[int, ...], tuple[float, ...]] = ((0, 0, 0), (0.0, 0.0))
    for k in range(ok.shape[2] // 2 + 1):
        rk = ndimage.minimum_filter1d(r2, 2 * k + 1, axis=2, mode="constant", cval=0.0)
        i = np.unravel_index(np.argmax(rk), rk.shape)
        vol = rk[i] ** 2 * max(2 * k, 1)
        if rk[i] > 0 and vol > best:
            best, arg = vol, (tuple(int(j) for j in i), (rk[i] * h, max(2 * k, 1) * h))
    return arg


def largest_shape(field: Field, lo: ArrayLike, hi: ArrayLike, shape: str, *, step: float,
                  spacing: float | None = None, search: bool = True) -> UsableShape:
    """The largest `shape` inside {field >= 0} within the box [lo, hi] [m] (see the module doc).

    Args:
        step: grid step of the coarse search [m]; spacing: membership-test spacing (default step / 2).
        search: False skips the pattern search (centre and aspect stay at the coarse optimum's):
            a checked lower bound, several times cheaper.
    """
    _check_shape(shape)
    if not (step > 0 and math.isfinite(step)):
        raise InvalidInputError("step", f"must be a positive number of metres, got {step!r}")
    spacing = step / 2 if spacing is None else spacing
    lo_, hi_ = np.asarray(lo, float), np.asarray(hi, float)
    check_points("step", grid_points(lo_.tolist(), hi_.tolist(), step), hint="use a larger step")
    axes = [np.arange(a, b + step / 2, step) for a, b in zip(lo_, hi_, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    ok = (field(grid.reshape(-1, 3)) >= 0).reshape(grid.shape[:-1])
    if not ok.any():
        raise InvalidInputError("kappa_max", EMPTY)
    idx, size0 = _coarse(shape, ok, step)
    center = grid[idx]
    if min(size0) <= 0:
        size0 = tuple(step / 4 for _ in size0)

    def fits(c: np.ndarray, size: Sequence[float]) -> bool:
        return contains(field, shape, c, size, spacing) >= 0

    def max_scale(c: np.ndarray, base: tuple[float, ...]) -> float:
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

    def sized(aspect: float) -> tuple[float, ...]:
        if shape != "cylinder":
            return size0
        return (size0[0] * aspect, size0[1] / aspect**2)  # same volume for every aspect

    aspect = 1.0
    t = max_scale(center, sized(aspect))
    delta = step if search else 0.0
    while delta >= step / 8 and delta > 0:
        improved = False
        moves = [(ax, s) for ax in range(3) for s in (-1, 1)]
        if shape == "cylinder":
            moves += [(3, s) for s in (-1, 1)]
        for ax, s in moves:
            c, a = center.copy(), aspect
            if ax < 3:
                c[ax] += s * delta
            else:
                a *= (1 + delta / max(size0[0], step)) ** s
            t_new = max_scale(c, sized(a))
            if t_new > t * (1 + 1e-4):
                center, aspect, t, improved = c, a, t_new, True
        if not improved:
            delta /= 2
    size = tuple(t * s for s in sized(aspect))
    final = contains(field, shape, center, size, spacing)
    bigger = [1.01 * s for s in size]
    offs = np.stack(np.meshgrid(*[[-step / 2, 0, step / 2]] * 3, indexing="ij"), -1).reshape(-1, 3)
    # (without the search the result is a lower bound, not claimed near-maximal: not tested)
    larger_fails = search and all(contains(field, shape, center + o, bigger, spacing) < 0 for o in offs)
    n = len(shape_samples(shape, center, size, spacing))
    return UsableShape(shape, center, size, n, spacing, final, larger_fails)


# -- any mechanism ------------------------------------------------------------------------------------
def inverse_condition(J: np.ndarray) -> np.ndarray:
    """1/kappa = sigma_min / sigma_max of each (N, d, a) Jacobian (dimensionless, in [0, 1]);
    0 where J is not finite (a type II pose: the forward map blows up) or zero."""
    J = np.asarray(J, dtype=float)
    finite = np.isfinite(J).all(axis=(-2, -1))
    sv = np.linalg.svd(np.where(finite[..., None, None], J, 0.0), compute_uv=False)
    top = sv[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(finite & (top > 0), sv[..., -1] / np.where(top > 0, top, 1.0), 0.0)
    return out


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


def usable_field(mech: Mechanism, branch: str, kappa_max: float = KAPPA_MAX, limits: str = "all") -> Field:
    """u(p) of a mechanism in one branch (working mode, elbow), or "union" (the best branch at each
    point): min(margin, 1/kappa - 1/kappa_max) with kappa the 2-norm condition number of the forward
    Jacobian J (`Mechanism.branch_velocity`); singular poses get u < 0 (module docstring).

    kappa of J and of J^-1 agree for a square J; it is scale-free as long as J's columns share a
    unit (every actuator prismatic, or every one revolute), true of the built-in families.
    """
    from kinematics.mechanisms.base import UNION

    _check_kappa(kappa_max)
    mech.check_limits(limits)
    branches = mech.branches if branch == UNION else mech.check_branches([branch])
    margin = mech.margin(branches, limits)

    def field(points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=float)
        m = margin(points)
        out = np.full(len(points), -np.inf)
        for k, b in enumerate(branches):
            v, inside = mech.branch_velocity(points, b, limits)
            out = np.maximum(out, np.minimum(m[:, k], condition_slack_of(v, inside, kappa_max)))
        return out

    return field


def usable(mech: Mechanism, shape: str, *, branch: str | None = None, kappa_max: float = KAPPA_MAX,
           limits: str = "all", step: float = 0.01, spacing: float | None = None,
           search: bool = True) -> UsableShape:
    """The largest `shape` in the usable workspace of a spatial mechanism (module docstring).

    Args:
        branch: a branch label or "union" (default: "---" where the mechanism has it, else its
            first branch).
        search: False skips the pattern search of the centre (the coarse optimum's centre, the
            size still bisected and checked): faster, a lower bound on the optimum.
    """
    from kinematics.errors import UnsupportedRobotError

    _check_shape(shape)
    for need in ("margin", "ik", "velocity"):
        mech.require(need, "a usable workspace")
    if mech.task_dim != 3:
        raise UnsupportedRobotError(mech.name, "usable shapes (cube, cylinder, sphere) need a spatial task "
                                    f"space; this mechanism's is {mech.task_dim}-dimensional")
    field = usable_field(mech, default_branch(mech) if branch is None else branch, kappa_max, limits)
    lo, hi = mech.bounding_box(limits)
    return largest_shape(field, lo, hi, shape, step=step, spacing=spacing, search=search)


def default_branch(mech: Mechanism) -> str:
    """ "---" (the usual working mode of the 3-[P2(US)] and the Delta) where it exists, else the first
    branch; "union" for a mechanism without branches (which then lacks the margin the usable
    workspace needs: `usable` says so)."""
    if not mech.branches:
        return "union"
    return "---" if "---" in mech.branches else mech.branches[0]
