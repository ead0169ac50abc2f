"""Reachable workspace of a frame's position for any serial arm, with guaranteed bounds.

W = f(Q), f the frame position and Q the box of joint limits. The method (derivation in
docs/serial-workspace.md) partitions Q into boxes, evaluates f and its Jacobian J at each box's
centre s with the compiled batched kinematics, and keeps two sets of task-space cells of side h:

* **inside** (a lower bound): (1) Graves' surjection theorem. With sigma = sigma_min(J(s))
  (position rows), M a bound on the second derivative of f over Q (`SerialWorkspace.hessian_bound`)
  and the joint ball B(s, r) inside the limits, f(B(s, r)) contains the task ball
  B(f(s), (sigma - M r) r); r = min(sigma / 2M, distance to the limits). Cells lying wholly in such
  a ball are in W. (2) dW lies in f(limit faces) u f(rank-deficient configurations): the cells met
  by the balls of boxes that may hold such points cover it, and each face-connected component of
  the other cells is wholly in W (if it holds a reached point or a Graves cell) or wholly out.
* **touched** (an upper bound): Taylor, B_ij bounding |d^2 f / dq_i dq_j|. For q in a box of
  half-widths d, |f(q) - f(s)| <= eps = sum_i |J_i(s)| d_i + sum_ij B_ij d_i d_j / 2, so the box's
  image lies in B(f(s), eps). A box whose ball lies inside the certified cells is settled; the
  others are split (along the joints that dominate eps) until eps <= h / 2, and the cells their
  balls meet are marked.

W lies between the two cell sets whatever the sampling: lower <= |W| <= upper, up to rounding
(~1e-15 relative). The estimate is their midpoint, the error estimate their half-gap. Reductions
(exact): joints that never move the point are fixed; when the first joint of the chain is a
revolution about a fixed axis with a full turn of range, W is a solid of revolution and the
measure is 2 pi int rho d(rho) dz over the reachable (rho, z) profile (Pappus); a planar arm's
measure is the area in its plane.

Dexterity (Yoshikawa index, condition number, smallest radius of the position Jacobian's
ellipsoid) is aggregated per cell as the best over the evaluated configurations reaching it.
Boxes with sigma_min(J(s)) <= sum_i d_i |dJ/dq_i| may contain a configuration where J loses rank
(sigma_min is 1-Lipschitz in the matrix); the others are singular-free. The singular set's image lies within the
reported balls.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from itertools import product
from typing import Any, Literal

import numpy as np
from numba import njit

from kinematics.chunks import slices
from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.batched import PRISMATIC, BatchedKinematics, configurations
from kinematics.generic.serial import plane
from kinematics.model.robot import Robot

Mode = Literal["planar", "revolved", "spatial"]

LEAF = 0.5
"""A box is a leaf once its image ball's radius eps is at most LEAF x the cell side."""

SPLIT = 0.5
"""A box is halved along every joint contributing at least SPLIT x the largest share of eps."""

_DEAD_TOL = 1e-12
"""A joint whose position-Jacobian column is below this [m/rad] at every probe never moves the point."""


@dataclass(frozen=True, eq=False)
class CellGrid:
    """A regular grid of task-space cells (side `cell` [m]) from `origin`: cell (i, j[, k]) spans
    origin + (i, j[, k]) * cell to origin + (i + 1, j + 1[, k + 1]) * cell. Coordinates are the
    plane axes (planar), (rho, z) about the base axis (revolved) or x, y, z (spatial)."""

    origin: np.ndarray
    cell: float
    shape: tuple[int, ...]

    def centres(self, index: np.ndarray) -> np.ndarray:
        """Centres [m] of cells given as (K, d) integer indices."""
        return self.origin + (np.asarray(index) + 0.5) * self.cell


@dataclass(frozen=True, eq=False)
class SerialWorkspace:
    """Reachable set of a frame's position, with guaranteed bounds and per-cell dexterity.

    Attributes:
        robot, frame: what was measured.
        mode: "planar" (area in the plane axes `axes`, m^2), "revolved" (solid of revolution
            about the first joint's axis, m^3) or "spatial" (m^3).
        axes: world axes of the plane (planar); for revolved, `axis_origin` and `axis_direction`.
        measure: the estimate, (lower + upper) / 2 [m^2 or m^3].
        lower, upper: guaranteed bounds on the measure.
        error_estimate: (upper - lower) / 2, a bound on |measure - true|.
        rtol: the requested relative tolerance; converged: error_estimate <= rtol * measure.
        points_evaluated: configurations at which FK and the Jacobian were evaluated.
        seconds: wall time.
        joints: the degrees of freedom sampled; fixed: those that never move the point.
        lipschitz: bound on |df/dq_i| per sampled joint [m/rad or m/m].
        hessian_bound: M, bound on the second derivative of the position over the joint box.
        grid: the cells; inside: cells certified in W; touched: cells that may meet W (a
            superset of W's cells; inside implies touched).
        yoshikawa, condition_number, smallest_radius: per cell, best over the configurations
            evaluated there (max, min, max); NaN where none was.
        singular_points: (K, d) task coordinates of boxes that may hold a rank-deficient
            Jacobian; singular_radius: (K,) the box's image lies within this distance [m];
            singular_configurations: (K, nv) the boxes' centres (joint values).
    """

    robot: str
    frame: str
    mode: Mode
    measure: float
    lower: float
    upper: float
    error_estimate: float
    rtol: float
    converged: bool
    points_evaluated: int
    seconds: float
    joints: tuple[str, ...]
    fixed: tuple[str, ...]
    lipschitz: np.ndarray
    hessian_bound: float
    grid: CellGrid
    inside: np.ndarray
    touched: np.ndarray
    yoshikawa: np.ndarray
    condition_number: np.ndarray
    smallest_radius: np.ndarray
    singular_points: np.ndarray
    singular_radius: np.ndarray
    singular_configurations: np.ndarray
    axes: tuple[int, ...] = ()
    axis_origin: np.ndarray | None = None
    axis_direction: np.ndarray | None = None
    levels: tuple[dict[str, float], ...] = field(default=())
    plane_offset: float = 0.0

    @property
    def planar(self) -> bool:
        """The measure is an area in the plane `axes`."""
        return self.mode == "planar"

    def world_points(self, which: Literal["inside", "touched", "band", "singular"] = "inside",
                     turns: int = 48) -> np.ndarray:
        """(K, 3) world points [m] for views: centres of the certified cells ("inside"), of the
        cells that may meet W ("touched"), of the uncertain band between them ("band"), or the
        images of the possibly singular boxes ("singular"). A revolved profile is swept about the
        base axis at `turns` angles; a planar arm's points lie in its plane (at `plane_offset`)."""
        if which == "singular":
            pts = self.singular_points
        else:
            masks = {"inside": self.inside, "touched": self.touched, "band": self.touched & ~self.inside}
            if which not in masks:
                raise InvalidInputError("which", f"expected one of inside, touched, band, singular; got {which!r}")
            pts = self.grid.centres(np.argwhere(masks[which]))
        if self.mode == "spatial":
            return np.asarray(pts, dtype=float).reshape(-1, 3)
        if self.mode == "planar":
            out = np.full((len(pts), 3), self.plane_offset)
            out[:, list(self.axes)] = pts
            return out
        if self.axis_direction is None or self.axis_origin is None:
            raise UnsupportedRobotError(self.robot, f"a {self.mode!r} workspace has no revolution axis")
        a = self.axis_direction
        u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(a, u)
        phi = np.linspace(0, 2 * np.pi, max(1, turns), endpoint=False)
        rho, z = pts[:, 0, None], pts[:, 1, None]
        ring = (self.axis_origin + rho[..., None] * (np.cos(phi)[None, :, None] * u + np.sin(phi)[None, :, None] * v)
                + z[..., None] * a)
        return ring.reshape(-1, 3)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary with the issue's stable keys (volume_m3 or area_m2,
        error_estimate, points_evaluated, seconds)."""
        key = "area_m2" if self.planar else "volume_m3"
        out: dict[str, Any] = {
            "robot": self.robot,
            "frame": self.frame,
            "mode": self.mode,
            key: self.measure,
            "error_estimate": self.error_estimate,
            "bounds": [self.lower, self.upper],
            "rtol": self.rtol,
            "converged": self.converged,
            "points_evaluated": self.points_evaluated,
            "seconds": self.seconds,
            "cell_m": self.grid.cell,
            "joints": list(self.joints),
            "fixed_joints": list(self.fixed),
            "singular_boxes": len(self.singular_radius),
            "levels": list(self.levels),
        }
        if self.axis_direction is not None and self.axis_origin is not None:
            out["axis"] = {"origin": self.axis_origin.tolist(), "direction": self.axis_direction.tolist()}
        if self.axes:
            out["plane_axes"] = list(self.axes)
        return out


# -- bounds on the derivatives -------------------------------------------------------------------
def _distal_lengths(kin: BatchedKinematics, robot: Robot) -> np.ndarray:
    """R_k >= |p - p_k| over the joint box, p the frame point, p_k chain joint k's origin:
    the lengths of the fixed offsets after joint k plus the travel of the prismatic joints after it."""
    n = len(kin.kind)
    seg = np.linalg.norm(kin.translation, axis=1)
    travel = np.zeros(n)
    for k in range(n):
        if kin.kind[k] == PRISMATIC:
            d = robot.dofs[_dof_of(robot, int(kin.idx_v[k]))]
            travel[k] = max(abs(d.lower), abs(d.upper))
    tail = float(np.linalg.norm(kin.frame_translation))
    R = np.empty(n)
    for k in range(n):
        R[k] = tail + seg[k + 1 :].sum() + travel[k + 1 :].sum()
    return R


def _dof_of(robot: Robot, idx_v: int) -> int:
    for i, d in enumerate(robot.dofs):
        if d.idx_v == idx_v:
            return i
    raise InvalidInputError("joint", f"no degree of freedom at velocity index {idx_v}")  # pragma: no cover


def _hessian_bound(prismatic: np.ndarray, R: np.ndarray) -> float:
    return float(np.linalg.norm(_hessian_matrix(prismatic, R), 2)) if len(R) else 0.0


def _hessian_matrix(prismatic: np.ndarray, R: np.ndarray) -> np.ndarray:
    """M >= |d^2 f (u, v)| / (|u| |v|) over the box for the chain joints given (root first).

    For revolute i <= j: d^2 p / dq_i dq_j = w_i x (w_j x (p - p_j)), norm <= R_j; a revolute
    before a prismatic gives w_i x w_j (<= 1), a prismatic before anything 0 (taken as 1 when
    mixed, to be safe), two prismatics 0. M is the spectral norm of that nonnegative matrix."""
    n = len(R)
    B = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            a, b = min(i, j), max(i, j)
            if not prismatic[a] and not prismatic[b]:
                B[i, j] = R[b]
            elif prismatic[a] != prismatic[b]:
                B[i, j] = 1.0
    return B


# -- cell kernels ------------------------------------------------------------------------------------
@njit(cache=True)
def _span(c, r, o, h, n, inner):  # pragma: no cover - compiled
    """Cells [o + jh, o + (j+1)h] of a row of n within distance r of coordinate c: all of the
    cell within r (inner) or any of it (not inner). Returns (first, last), last < first if none."""
    if inner:
        lo = math.ceil((c - r - o) / h)
        hi = math.floor((c + r - o) / h) - 1
    else:
        lo = math.ceil((c - r - o) / h) - 1
        hi = math.floor((c + r - o) / h)
    return max(lo, 0), min(hi, n - 1)


@njit(cache=True)
def _mark(y, rad, origin, h, d, grid, inner):  # pragma: no cover - compiled
    """Set the cells wholly inside (inner) or meeting (not inner) the closed balls B(y_k, rad_k),
    one row span at a time."""
    nx, ny, nz = grid.shape
    for k in range(y.shape[0]):
        r = rad[k]
        if not r > 0.0 and (inner or r != 0.0):  # a point still touches its own cell
            continue
        i0, i1 = _span(y[k, 0], r, origin[0], h, nx, False)
        for i in range(i0, i1 + 1):
            x0 = origin[0] + i * h - y[k, 0]
            dx = max(abs(x0), abs(x0 + h)) if inner else max(0.0, x0, -(x0 + h))
            ry2 = r * r - dx * dx
            if ry2 < 0.0:
                continue
            ry = math.sqrt(ry2)
            if d == 2:
                j0, j1 = _span(y[k, 1], ry, origin[1], h, ny, inner)
                for j in range(j0, j1 + 1):
                    grid[i, j, 0] = 1
                continue
            j0, j1 = _span(y[k, 1], ry, origin[1], h, ny, False)
            for j in range(j0, j1 + 1):
                y0 = origin[1] + j * h - y[k, 1]
                dy = max(abs(y0), abs(y0 + h)) if inner else max(0.0, y0, -(y0 + h))
                rz2 = ry2 - dy * dy
                if rz2 < 0.0:
                    continue
                m0, m1 = _span(y[k, 2], math.sqrt(rz2), origin[2], h, nz, inner)
                for m in range(m0, m1 + 1):
                    grid[i, j, m] = 1


def _mark_within(y: np.ndarray, rad: np.ndarray, origin: np.ndarray, h: float, d: int, grid: np.ndarray) -> None:
    """Set grid cells lying wholly inside the ball B(y_k, rad_k)."""
    _mark(y, rad, origin, h, d, grid, True)


def _mark_touching(y: np.ndarray, rad: np.ndarray, origin: np.ndarray, h: float, d: int, grid: np.ndarray) -> None:
    """Set grid cells that meet the closed ball B(y_k, rad_k)."""
    _mark(y, rad, origin, h, d, grid, False)


@njit(cache=True)
def _stats(J, Ja, half, B, sig_min, sig_max, yosh, eps):  # pragma: no cover - compiled
    """Per configuration: singular values of the m x k position Jacobian J (m = 2 or 3) and the
    image-ball radius eps = sum_i |Ja_i| d_i + sum_ij B_ij d_i d_j / 2 of its box.

    det(J J^T) and e2 (sum of its 2 x 2 principal minors) come from Cauchy-Binet as sums of
    squared minors of J (no cancellation); lambda_max from the trigonometric solution (m = 3) or
    the quadratic (m = 2); lambda_min = det / (product of the others), accurate near a singularity."""
    N, m, k = J.shape
    for t in range(N):
        tr = 0.0
        for r in range(m):
            for c in range(k):
                tr += J[t, r, c] * J[t, r, c]
        if m == 2:
            det = 0.0
            for i in range(k):
                for j in range(i + 1, k):
                    mnr = J[t, 0, i] * J[t, 1, j] - J[t, 0, j] * J[t, 1, i]
                    det += mnr * mnr
            a = 0.0
            b = 0.0
            c2 = 0.0
            for c in range(k):
                a += J[t, 0, c] * J[t, 0, c]
                b += J[t, 0, c] * J[t, 1, c]
                c2 += J[t, 1, c] * J[t, 1, c]
            lmax = 0.5 * (a + c2) + math.sqrt(0.25 * (a - c2) ** 2 + b * b)
            lmin = det / lmax if lmax > 0 else 0.0
        else:
            det = 0.0
            for i in range(k):
                for j in range(i + 1, k):
                    for l in range(j + 1, k):
                        mnr = (J[t, 0, i] * (J[t, 1, j] * J[t, 2, l] - J[t, 1, l] * J[t, 2, j])
                               - J[t, 0, j] * (J[t, 1, i] * J[t, 2, l] - J[t, 1, l] * J[t, 2, i])
                               + J[t, 0, l] * (J[t, 1, i] * J[t, 2, j] - J[t, 1, j] * J[t, 2, i]))
                        det += mnr * mnr
            e2 = 0.0
            for r1 in range(3):
                for r2 in range(r1 + 1, 3):
                    for i in range(k):
                        for j in range(i + 1, k):
                            mnr = J[t, r1, i] * J[t, r2, j] - J[t, r1, j] * J[t, r2, i]
                            e2 += mnr * mnr
            A = np.zeros((3, 3))
            for r1 in range(3):
                for r2 in range(3):
                    acc = 0.0
                    for c in range(k):
                        acc += J[t, r1, c] * J[t, r2, c]
                    A[r1, r2] = acc
            q = tr / 3.0
            p1 = A[0, 1] ** 2 + A[0, 2] ** 2 + A[1, 2] ** 2
            p2 = (A[0, 0] - q) ** 2 + (A[1, 1] - q) ** 2 + (A[2, 2] - q) ** 2 + 2 * p1
            pp = math.sqrt(p2 / 6.0)
            if pp > 0:
                C = (A - q * np.eye(3)) / pp
                hdet = 0.5 * (C[0, 0] * (C[1, 1] * C[2, 2] - C[1, 2] * C[2, 1])
                              - C[0, 1] * (C[1, 0] * C[2, 2] - C[1, 2] * C[2, 0])
                              + C[0, 2] * (C[1, 0] * C[2, 1] - C[1, 1] * C[2, 0]))
                phi = math.acos(min(1.0, max(-1.0, hdet))) / 3.0
                lmax = q + 2 * pp * math.cos(phi)
                l1 = q + 2 * pp * math.cos(phi + 2 * math.pi / 3)
            else:
                lmax = q
                l1 = q
            l1 = max(l1, 0.0)
            rest = e2 - l1 * (tr - l1)  # product of the two larger eigenvalues
            lmin = det / rest if rest > 0 else 0.0
        # det and e2 are sums of squares (relative error ~ k eps) and so is lambda_min = det / rest:
        # a relative margin of 1e-10 keeps sigma_min from being overstated by rounding.
        lmin = max(lmin * (1.0 - 1e-10), 0.0)
        sig_min[t] = math.sqrt(lmin)
        sig_max[t] = math.sqrt(max(lmax, 0.0))
        yosh[t] = math.sqrt(det)
        e = 0.0
        h2 = 0.0
        for c in range(Ja.shape[2]):
            n2 = 0.0
            for r in range(m):
                n2 += Ja[t, r, c] * Ja[t, r, c]
            e += math.sqrt(n2) * half[t, c]
            for c2 in range(Ja.shape[2]):
                h2 += half[t, c] * B[c, c2] * half[t, c2]
        eps[t] = e + 0.5 * h2


def radii(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smallest and largest singular values and Yoshikawa's index of a stack of 2 x k or 3 x k
    position Jacobians (N, m, k), by the kernel the workspace uses (sigma_min is lowered by a
    relative 5e-11 against rounding, never raised).

    Returns:
        sigma_min, sigma_max [m/rad], w = sqrt(det(J J^T)), each (N,).
    """
    J = np.ascontiguousarray(J, dtype=float)
    if J.ndim != 3 or J.shape[1] not in (2, 3) or J.shape[2] < J.shape[1]:
        raise InvalidInputError("jacobian", f"expected (N, 2 or 3, k >= rows), got shape {J.shape}")
    out = [np.empty(len(J)) for _ in range(4)]
    _stats(J, J, np.zeros((len(J), J.shape[2])), np.zeros((J.shape[2], J.shape[2])), *out)
    return out[0], out[1], out[2]


@njit(cache=True)
def _aggregate(idx, w, cond, rmin, gw, gc, gr):  # pragma: no cover - compiled
    for k in range(idx.shape[0]):
        i, j, m = idx[k, 0], idx[k, 1], idx[k, 2]
        if not gw[i, j, m] >= w[k]:
            gw[i, j, m] = w[k]
        if not gc[i, j, m] <= cond[k]:
            gc[i, j, m] = cond[k]
        if not gr[i, j, m] >= rmin[k]:
            gr[i, j, m] = rmin[k]


# -- the measurement -----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Setup:
    mode: Mode
    rows: tuple[int, ...]
    active: np.ndarray  # dof indices sampled
    lo: np.ndarray
    hi: np.ndarray
    periodic: np.ndarray
    base: np.ndarray  # (nv,) values of the joints not sampled
    L: np.ndarray
    M: float
    B: np.ndarray  # (k, k) bounds on |d^2 f / dq_i dq_j| over the sampled joints
    Bcol: np.ndarray  # (k,) bounds on |dJ / dq_i| (spectral <= Frobenius) over the sampled joints
    graves_cols: np.ndarray  # velocity columns entering sigma_min (active, + the base yaw when revolved)
    sample_cols: np.ndarray  # velocity columns of the sampled joints
    axes: tuple[int, ...]
    axis_origin: np.ndarray | None
    axis_direction: np.ndarray | None
    fixed: tuple[str, ...]
    reach_centre: np.ndarray  # in task coordinates: |y - reach_centre| <= reach over the joint box
    reach: float


def _setup(robot: Robot, kin: BatchedKinematics) -> _Setup:
    nv = robot.nv
    chain_v = [int(v) for v in kin.idx_v]
    dof_idx = [_dof_of(robot, v) for v in chain_v]
    # Joints that never move the point: a zero position column at every probe configuration.
    rng = np.random.default_rng(0)
    lo_all = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi_all = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    probe = rng.uniform(lo_all, hi_all, (64, nv))
    Jp = kin.jacobian(configurations(robot, probe))[:, :3, :]
    moving = np.abs(Jp).max(axis=(0, 1)) > _DEAD_TOL
    R = _distal_lengths(kin, robot)
    prismatic = kin.kind == PRISMATIC
    pl = plane(robot)
    base = np.clip(np.zeros(nv), lo_all, hi_all)
    fixed = tuple(robot.dofs[i].name for i, v in zip(dof_idx, chain_v, strict=True) if not moving[v])
    keep = [k for k, v in enumerate(chain_v) if moving[v]]
    if not keep:
        raise UnsupportedRobotError(robot.name, f"no joint moves frame {kin.frame!r}: its workspace is a point")
    # every joint that moves the point is an actuator: a workspace needs its range (a continuous
    # joint's is a full turn)
    robot.require_ranges([robot.dofs[dof_idx[k]].name for k in keep], "a workspace")
    lo = np.array([lo_all[dof_idx[k]] for k in keep])
    hi = np.array([hi_all[dof_idx[k]] for k in keep])
    kinds = [robot.dofs[dof_idx[k]].kind for k in keep]
    periodic = np.array([kd == "continuous" or (kd == "revolute" and h - l >= 2 * math.pi - 1e-9)
                         for kd, l, h in zip(kinds, lo, hi, strict=True)])
    hi = np.where(periodic, lo + 2 * math.pi, hi)  # f is 2 pi periodic in these: one turn suffices
    M = _hessian_bound(prismatic[keep], R[keep])
    Bfull = _hessian_matrix(prismatic[keep], R[keep])
    Bcol = np.sqrt((Bfull**2).sum(axis=0))
    L = np.where(prismatic[keep], 1.0, R[keep])
    active = np.array([dof_idx[k] for k in keep])
    first = robot.dofs[dof_idx[0]]
    reach = float(R[0] + (max(abs(first.lower), abs(first.upper)) if kin.kind[0] == PRISMATIC else 0.0))
    o1 = kin.translation[0].copy()  # the first joint's origin, fixed in the world
    cols = np.array([chain_v[k] for k in keep])
    if pl is not None:
        return _Setup("planar", pl, active, lo, hi, periodic, base, L, M, Bfull, Bcol, cols, cols, pl, None, None, fixed,
                      o1[list(pl)], reach)
    if keep[0] == 0 and kin.kind[0] != PRISMATIC and periodic[0]:
        direction = kin.rotation[0] @ kin.axis[0]
        origin = kin.translation[0].copy()
        return _Setup("revolved", (0, 1, 2), active[1:], lo[1:], hi[1:], periodic[1:], base, L[1:], M, Bfull[1:, 1:], Bcol[1:], cols,
                      cols[1:], (), origin, direction, fixed, np.zeros(2), reach)
    return _Setup("spatial", (0, 1, 2), active, lo, hi, periodic, base, L, M, Bfull, Bcol, cols, cols, (), None, None, fixed, o1, reach)


def serial_workspace(
    robot: Robot,
    frame: str | None = None,
    *,
    rtol: float = 0.02,
    cell: float | None = None,
    resolution: int | None = None,
    max_points: int = 20_000_000,
    progress: bool = False,
) -> SerialWorkspace:
    """Reachable set of `frame`'s origin (default: the tool) within the joint limits.

    Args:
        robot: a loaded serial robot (`kinematics.model.robot.load_robot`).
        frame: the frame whose position is measured.
        rtol: the accuracy asked for: `converged` says whether error_estimate <= rtol * measure.
            (The refinement itself is set by the cell: the error estimate falls linearly with h.)
        cell: task-space cell side h [m]; default: the bounding box's largest side / resolution.
        resolution: cells along that side (default 400 for a plane or profile, 128 in space).
        max_points: budget of configurations; when it runs out the remaining boxes are counted
            with their (larger) balls, so the bounds stay valid but widen.
        progress: show a bar on stderr (for the CLI on a terminal).

    Returns:
        A `SerialWorkspace` with guaranteed bounds (see the module docstring).

    Raises:
        UnsupportedRobotError: closed-loop robots, joints the batched kinematics cannot compile,
            unbounded prismatic joints, a frame no joint moves.
        InvalidInputError: rtol, cell, resolution or max_points out of range.
    """
    t0 = time.perf_counter()
    if robot.loops is not None:
        raise UnsupportedRobotError(robot.name, "closed-loop robot: the serial workspace needs an open chain")
    if not (rtol > 0 and math.isfinite(rtol)):
        raise InvalidInputError("rtol", f"must be positive, got {rtol}")
    if cell is not None and not (cell > 0 and math.isfinite(cell)):
        raise InvalidInputError("cell", f"must be a positive length [m], got {cell}")
    if resolution is not None and resolution < 4:
        raise InvalidInputError("resolution", f"must be at least 4 cells, got {resolution}")
    if max_points < 1000:
        raise InvalidInputError("max_points", f"must be at least 1000, got {max_points}")
    kin = BatchedKinematics.from_robot(robot, frame)
    s = _setup(robot, kin)
    d = 2 if s.mode in ("planar", "revolved") else 3
    n = len(s.active)
    rows = list(s.rows)

    def evaluate(centre: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, ...]:
        """Task point y, sigma_min, sigma_max, Yoshikawa index, image-ball radius eps and the
        sampled joints' column norms at the box centres, in chunks (memory stays bounded)."""
        N = len(centre)
        y = np.empty((N, 2 if s.mode != "spatial" else 3))
        stats = [np.empty(N) for _ in range(4)]
        norms = np.empty((N, len(s.sample_cols)))
        for sl in slices(N, 1 << 18):
            values = np.repeat(s.base[None, :], sl.stop - sl.start, axis=0)
            values[:, s.active] = centre[sl]
            poses, J = kin.fk_jacobian(configurations(robot, values))
            p = poses.position
            Jt = J[:, rows, :]
            if s.mode == "planar":
                y[sl] = p[:, rows]
            elif s.mode == "revolved":
                if s.axis_origin is None or s.axis_direction is None:
                    raise UnsupportedRobotError("revolved workspace", "the revolution axis was not found")
                rel = p - s.axis_origin
                z = rel @ s.axis_direction
                y[sl, 0] = np.linalg.norm(rel - z[:, None] * s.axis_direction, axis=1)
                y[sl, 1] = z
            else:
                y[sl] = p
            Ja = np.ascontiguousarray(Jt[:, :, s.sample_cols])
            _stats(np.ascontiguousarray(Jt[:, :, s.graves_cols]), Ja, np.ascontiguousarray(half[sl]), s.B,
                   *(a[sl] for a in stats))
            norms[sl] = np.linalg.norm(Ja, axis=1)
        return (y, *stats, norms)

    # Level 0: boxes whose images span about a quarter of the reach along each joint.
    span = s.hi - s.lo
    per = np.maximum(2, np.ceil(s.L * span / (s.reach / 4))).astype(int)
    axes_1d = [s.lo[i] + (np.arange(per[i]) + 0.5) * span[i] / per[i] for i in range(n)]
    centre = np.array(list(product(*axes_1d)), dtype=float).reshape(-1, n)
    half = np.repeat((span / per / 2)[None, :], len(centre), axis=0)

    y, sig_min, sig_max, yosh, eps, norms = evaluate(centre, half)
    plane_offset = 0.0
    if s.mode == "planar":  # the tool's constant coordinate along the plane's normal
        normal = ({0, 1, 2} - set(s.axes)).pop()
        values = s.base.copy()
        values[s.active] = centre[0]
        plane_offset = float(kin.fk(configurations(robot, values[None, :])).position[0, normal])
    # W lies in the level-0 balls and in the reach ball: the grid covers their common box.
    lo_box = np.maximum((y - eps[:, None]).min(axis=0), s.reach_centre - s.reach)
    hi_box = np.minimum((y + eps[:, None]).max(axis=0), s.reach_centre + s.reach)
    if s.mode == "revolved":
        lo_box[0] = 0.0
    side = float((y.max(axis=0) - y.min(axis=0)).max())  # the reached extent sets the cell
    if cell is None:
        res = resolution if resolution is not None else (400 if d == 2 else 128)
        h = side / res
    else:
        h = float(cell)
    origin = lo_box - h if s.mode != "revolved" else np.array([0.0, lo_box[1] - h])
    shape3 = tuple(math.ceil((hi_box[a] + h - origin[a]) / h) + 1 if a < d else 1 for a in range(3))
    if np.prod(shape3) > 400_000_000:
        raise InvalidInputError("cell", f"{h:.3g} m makes {np.prod(shape3):.3g} cells; choose a larger cell")
    inside = np.zeros(shape3, np.uint8)
    touched = np.zeros(shape3, np.uint8)
    gw = np.full(shape3, np.nan)
    gc = np.full(shape3, np.nan)
    gr = np.full(shape3, np.nan)
    origin3 = np.zeros(3)
    origin3[:d] = origin
    weight_cells = _cell_measure(s.mode, origin, h, shape3)

    from scipy.ndimage import distance_transform_edt, label

    boundary_leaves = np.zeros(shape3, np.uint8)  # balls of final boxes that may map onto the boundary

    def fill_components(current_y3: np.ndarray, current_eps: np.ndarray) -> None:
        # dW lies in f(limit faces) u f(rank-deficient set): inside the balls of the boxes that
        # may hold such points. A face-connected component of the other cells is disjoint from dW,
        # hence wholly in W or wholly out; it is in W if it holds a reached point.
        cover = boundary_leaves.copy()
        _mark_touching(current_y3, current_eps, origin3, h, d, cover)
        free = cover == 0
        labels, _ = label(free if d == 3 else free[:, :, 0])
        if d == 2:
            labels = labels[:, :, None]
        seeds = np.unique(labels[(inside == 1) | ~np.isnan(gw)])
        seeds = seeds[seeds > 0]
        inside[np.isin(labels, seeds)] = 1

    sing_pts: list[np.ndarray] = []
    sing_rad: list[np.ndarray] = []
    sing_cfg: list[np.ndarray] = []
    points = 0
    levels: list[dict[str, float]] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max_points, desc="workspace", unit="cfg", unit_scale=True, delay=1.0, leave=False)
    try:
        while True:
            points += len(centre)
            if bar is not None:
                bar.update(len(centre))
            y3 = np.zeros((len(y), 3))
            y3[:, :d] = y
            # Graves: the largest certified task ball at each centre.
            r_lim = _room(centre, s)
            if s.M > 0:
                r = np.minimum(sig_min / (2 * s.M), r_lim)
            else:
                r = np.where(np.isfinite(r_lim), r_lim, 1.0)
            ball = (sig_min - s.M * r) * r
            # Cap the marking to what settling this box needs (keeps the work ~ one cover per level).
            _mark_within(y3, np.minimum(ball, eps + 2 * h * math.sqrt(d)), origin3, h, d, inside)
            idx = np.clip(np.floor((y3 - origin3) / h).astype(np.int64), 0, np.array(shape3) - 1)
            idx[:, d:] = 0
            with np.errstate(divide="ignore"):
                cond = np.where(sig_min > 0, sig_max / np.where(sig_min > 0, sig_min, 1.0), np.inf)
            _aggregate(idx, yosh, cond, sig_min, gw, gc, gr)
            # Boxes that may hold a limit-face or rank-deficient configuration (sigma_min is
            # Lipschitz in q: sigma_min(J(s)) > sum_i d_i |dJ/dq_i| rules out a singular point in the box).
            maybe_singular = sig_min <= half @ s.Bcol  # |J(q) - J(s)| <= sum_i d_i |dJ/dq_i|
            on_face = _on_face(centre, half, s)
            critical = maybe_singular | on_face
            fill_components(y3[critical], eps[critical])
            # Which boxes are settled (image ball inside the certified cells)?
            pad = np.pad(inside.astype(bool), 1)
            dist = distance_transform_edt(pad)[1:-1, 1:-1, 1:-1] if d == 3 else \
                distance_transform_edt(pad[:, :, 1])[1:-1, 1:-1][:, :, None]
            room_task = dist[idx[:, 0], idx[:, 1], idx[:, 2]] * h - h * math.sqrt(d)
            settled = (inside[idx[:, 0], idx[:, 1], idx[:, 2]] == 1) & (eps <= room_task)
            leaf = ~settled & (eps <= LEAF * h)
            rest = ~settled & ~leaf
            children = None
            if rest.any():
                # Within the budget, split the boxes with the largest balls first; the others
                # become leaves counted by their balls (the bounds stay valid, only wider).
                mask = _split_mask(half[rest], norms[rest], s.B)
                count = 2 ** mask.sum(axis=1)
                order = np.argsort(-eps[rest], kind="stable")
                fits = np.cumsum(count[order]) <= max_points - points
                chosen = np.flatnonzero(rest)[order[fits]]
                leaf |= rest
                leaf[chosen] = False
                if len(chosen):
                    children = _split(centre[chosen], half[chosen], _split_mask(half[chosen], norms[chosen], s.B))
            final = settled | leaf
            maybe_singular &= final
            _mark_touching(y3[leaf & critical], eps[leaf & critical], origin3, h, d, boundary_leaves)
            if maybe_singular.any():
                sing_pts.append(y[maybe_singular])
                sing_rad.append(eps[maybe_singular])
                cfg = np.repeat(s.base[None, :], int(maybe_singular.sum()), axis=0)
                cfg[:, s.active] = centre[maybe_singular]
                sing_cfg.append(cfg)
            _mark_touching(y3[leaf], eps[leaf], origin3, h, d, touched)
            levels.append({"boxes": float(len(centre)), "settled": float(settled.sum()), "leaves": float(leaf.sum()),
                           "max_eps_m": float(eps.max()),
                           "lower": float((weight_cells * inside).sum()),
                           "upper_so_far": float((weight_cells * (touched | inside)).sum())})
            if children is None:
                break
            centre, half = children
            y, sig_min, sig_max, yosh, eps, norms = evaluate(centre, half)
    finally:
        if bar is not None:
            bar.close()

    fill_components(np.zeros((0, 3)), np.zeros(0))
    touched &= _meets_ball(origin, h, shape3, d, s.reach_centre, s.reach)  # W lies in the reach ball
    touched |= inside
    lower = float((weight_cells * inside).sum())
    upper = float((weight_cells * touched).sum())
    measure = 0.5 * (lower + upper)
    err = 0.5 * (upper - lower)
    sl = (slice(None), slice(None), 0) if d == 2 else (slice(None),) * 3
    return SerialWorkspace(
        robot=robot.name,
        frame=kin.frame,
        mode=s.mode,
        measure=measure,
        lower=lower,
        upper=upper,
        error_estimate=err,
        rtol=rtol,
        converged=bool(err <= rtol * measure),
        points_evaluated=points,
        seconds=time.perf_counter() - t0,
        joints=tuple(robot.dofs[i].name for i in s.active),
        fixed=s.fixed,
        lipschitz=s.L.copy(),
        hessian_bound=s.M,
        grid=CellGrid(origin=origin.copy(), cell=h, shape=tuple(shape3[:d])),
        inside=inside[sl].astype(bool),
        touched=touched[sl].astype(bool),
        yoshikawa=gw[sl],
        condition_number=gc[sl],
        smallest_radius=gr[sl],
        singular_points=np.concatenate(sing_pts) if sing_pts else np.zeros((0, d)),
        singular_radius=np.concatenate(sing_rad) if sing_rad else np.zeros(0),
        singular_configurations=np.concatenate(sing_cfg) if sing_cfg else np.zeros((0, robot.nv)),
        axes=s.axes,
        axis_origin=s.axis_origin,
        axis_direction=s.axis_direction,
        levels=tuple(levels),
        plane_offset=plane_offset,
    )


def _meets_ball(origin: np.ndarray, h: float, shape3: tuple[int, ...], d: int, centre: np.ndarray,
                radius: float) -> np.ndarray:
    """uint8 grid: 1 where the cell meets the closed ball B(centre, radius)."""
    gap2 = np.zeros(shape3)
    for a in range(d):
        lo = origin[a] + np.arange(shape3[a]) * h - centre[a]
        g = np.maximum(0.0, np.maximum(lo, -(lo + h))) ** 2
        shape = [1, 1, 1]
        shape[a] = shape3[a]
        gap2 = gap2 + g.reshape(shape)
    return (gap2 <= radius * radius).astype(np.uint8)


def _room(centre: np.ndarray, s: _Setup) -> np.ndarray:
    """Radius of the largest joint-space ball around each centre inside the limits (periodic
    joints have none; in revolved mode the base joint is periodic)."""
    if not (~s.periodic).any():
        return np.full(len(centre), np.inf)
    c = centre[:, ~s.periodic]
    return np.minimum(c - s.lo[~s.periodic], s.hi[~s.periodic] - c).min(axis=1)


def _on_face(centre: np.ndarray, half: np.ndarray, s: _Setup) -> np.ndarray:
    """Boxes whose closure meets a face of a (non-periodic) joint limit."""
    np_ = ~s.periodic
    if not np_.any():
        return np.zeros(len(centre), bool)
    tol = 1e-9 * (s.hi - s.lo)[np_]
    c, d = centre[:, np_], half[:, np_]
    return ((c - d <= s.lo[np_] + tol) | (c + d >= s.hi[np_] - tol)).any(axis=1)


def _split_mask(half: np.ndarray, norms: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The joints to halve: those contributing at least SPLIT x the largest share of eps."""
    contrib = norms * half + 0.5 * half * (half @ B)
    return contrib >= SPLIT * contrib.max(axis=1, keepdims=True)


def _split(centre: np.ndarray, half: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Halve each box along the joints its mask row selects."""
    n = centre.shape[1]
    codes = mask @ (1 << np.arange(n))
    out_c, out_h = [], []
    for code in np.unique(codes):
        sel = codes == code
        dims = [i for i in range(n) if code >> i & 1]
        c0, h0 = centre[sel], half[sel].copy()
        h0[:, dims] /= 2
        for signs in product((-1.0, 1.0), repeat=len(dims)):
            c = c0.copy()
            c[:, dims] += np.array(signs) * h0[:, dims]
            out_c.append(c)
            out_h.append(h0)
    return np.concatenate(out_c), np.concatenate(out_h)


def _cell_measure(mode: Mode, origin: np.ndarray, h: float, shape3: tuple[int, ...]) -> np.ndarray:
    """Measure of each cell: h^2 (planar), h^3 (spatial), 2 pi rho_c h^2 (revolved: the cell's
    ring, exact since the grid starts at rho = 0)."""
    if mode == "planar":
        return np.full(shape3, h * h)
    if mode == "spatial":
        return np.full(shape3, h**3)
    rho_c = origin[0] + (np.arange(shape3[0]) + 0.5) * h
    return np.broadcast_to((2 * math.pi * rho_c * h * h)[:, None, None], shape3).copy()
