"""A batched closed-loop solver for any URDF tree + loop sidecar: every working mode of many
task-space targets at once, their joint-limit margins and their singularity measures.

**Equations.** The unknowns are all n joint values x (one per degree of freedom, actuated and
passive). The residual stacks, for a target t,

* every closure of the sidecar: p_f1 - p_f2 (3 rows, `point`), plus l o(R_f1, R_f2) (3 more, `6d`);
* the task: the end effector's position along the task axes minus t (d rows), and, for a
  *translational* mechanism, l o(R_ee, R_0): the platform keeps its reference orientation R_0;

with o(A, B) = vee(A B^T - B A^T) / 2 (zero iff A = B near A = B; its derivative there is
w_A - w_B, the world angular velocities) and l the model's characteristic length (`scale`), so
every row is in metres. The Jacobian rows are the differences of the frames' LOCAL_WORLD_ALIGNED
Jacobians (closure rows) and the end effector's own (task rows).

**Task.** At the sidecar's reference configuration the constrained Jacobian (Pinocchio,
`ClosedLoop.constrained_jacobian`) tells what the actuators move: if they never turn the end
effector the mechanism is translational (task = position, orientation held at R_0: the 3-[P2(US)],
the Delta); otherwise the task is the d = (number of actuators) position axes best determined by
them (the planar five-bar: x, y). Mechanisms whose actuators drive a rotation of the end effector
(a task that needs orientation coordinates) raise UnsupportedRobotError: not done yet.

**Solver.** Levenberg-Marquardt on ||r||^2, vectorised over rows (target, start) in one compiled
kernel (prange over blocks): A = J^T J + lam diag(J^T J), dx = -A^-1 J^T r by Cholesky, accept and
lam /= 10 when ||r|| drops, else lam *= 10; revolute values are wrapped to within pi of the middle
of their limits. It stops at max|r| <= TOL (a root: the loops close and the target is met) or when
it stalls (a least-squares point: no root near this start). The kinematics (all joint placements
of the tree, frame placements, Jacobian columns w x (p_f - o_j) / w) are evaluated in the same
kernel, not by per-point Pinocchio calls.

**Branches (working modes).** With the end effector fixed the equations split into blocks
(`blocks`): groups of rows (a closure, the task) that determine a set of unknowns on their own,
found once from the Jacobian's sparsity (a greedy block-triangular ordering over single rows
groups, then pairs, then triples). A square block that contains an actuated joint decides that
actuator's working mode: the sign of its determinant cannot change without the block losing rank
(a type I singularity), so the vector of those signs labels a branch and is stable across each
singularity-free region of the workspace. The *atlas* of branches is found once, at the end
effector's reference position, from `seeds` random starts within the joint limits (converged,
deduplicated by the positions of every joint origin, labelled). For a batch of targets each
branch is then sought from (1) a solved neighbour (a cache of earlier batches and a coarse subset
of this batch solved first: continuation), (2) the atlas configuration of that label, (3)
`restarts` random starts where a target has some branches but not all.

A passive sub-chain can reach one position in several ways that are the same mechanism pose (a
universal joint's (a, b) and (a + pi, pi - b), a spherical joint's two Euler triples); they are
merged (same joint-origin positions) and the one closest to the reference configuration is kept,
so the labels and the reported joint values use one representation throughout.

**What the search can miss.** A branch that exists at a target but is reached from none of the
three starts (its basin missed by the neighbour, the atlas configuration and the random starts) is
reported absent (margin < 0): most likely in a branch region that does not contain the reference
position's branch of the same label and is far from the batch's other points. A target where no
start converges at all is reported as having no branch; random restarts are not tried there (they
would cost most of the time outside the workspace). Solutions whose label is not in the atlas
(assembly modes absent at the reference position) are counted in `BranchSolutions.unlabelled`,
not returned. Two physically different poses with the same label at one target keep only the one
nearest the reference (counted in `conflicts`).

**Margins.** Per branch, the smallest joint-limit slack in metres (prismatic: the distance to the
limit; revolute: the angle times `scale`), over every joint with a finite range narrower than
2 pi; >= 0 inside. Where the branch has no solution, minus the least-squares residual [m] reached
from its best start (< 0). The union is the largest branch margin.

**Singularities** (Gosselin & Angeles), from the Jacobian U of all rows (closures, orientation,
task) at a solution, U_a / U_p its actuated / passive columns, and P the task rows:

* type I (an actuator rate undetermined by the platform's): iota_I = sigma_min((I - U_p U_p^+) U_a D^-1)
  with D the norms of U_a's columns: 0 iff some actuator can move with the end effector fixed;
  in [0, 1]; a passive freedom that moves no actuator (a gimbal-locked universal joint) is ignored;
* type II (locked actuators do not hold the platform): iota_II = min over passive rates v with
  P v != 0 of |A v| / |P v|, A the closure and orientation rows: 0 iff the end effector can move
  with the actuators locked; dimensionless (rows in metres), not bounded by 1;
* type III: both. A pose is singular when a measure is <= SINGULAR_TOL.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
from numba import njit, prange

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.singularity import SINGULAR_TOL as SINGULAR_TOL
from kinematics.generic.singularity import SINGULARITY_TYPES as SINGULARITY_TYPES
from kinematics.model.robot import Robot

TOL = 1e-12
"""A start has converged when every residual row is <= TOL [m]."""


STALL = 1e-2
"""After 3 iterations a start stops when an accepted step lowers ||r||^2 by less than this fraction
(it is heading for a least-squares point, not a root)."""

WARM_RADIUS_FACTOR = 0.1
"""A solved point warm-starts another when closer than this x `scale` [m]."""

CACHE_POINTS = 100_000
"""Solved points kept for warm starts (the most recent first)."""

LIMITS = ("all", "actuators")
"""Which joint limits the margins apply."""

REVOLUTE, PRISMATIC = 0, 1


class Block(NamedTuple):
    """Rows that determine some unknowns once the earlier blocks' unknowns are known.

    Attributes:
        rows: residual rows (structurally zero rows left out).
        cols: the unknowns this block determines (degree-of-freedom indices).
        actuated: the block contains an actuated joint.
    """

    rows: tuple[int, ...]
    cols: tuple[int, ...]
    actuated: bool

    @property
    def square(self) -> bool:
        return len(self.rows) == len(self.cols)


class BranchSolutions(NamedTuple):
    """IK of a batch of targets in every branch of the atlas.

    Attributes:
        x: (N, B, n) joint values per target and branch (NaN where not found), model order.
        found: (N, B) the branch has a solution there (loops closed, target met to TOL).
        residual: (N, B) least-squares residual [m] of the best start (0-ish where found).
        margin: (N, B) joint-limit margin [m] where found, minus the residual elsewhere.
        unlabelled: converged solutions whose label is not in the atlas (not returned).
        conflicts: physically different solutions that shared a label at one target.
        end: (N, B, n) where each branch's best start ended: the solution, or the least-squares
            point where there is none (the next targets' warm starts).
    """

    x: np.ndarray
    found: np.ndarray
    residual: np.ndarray
    margin: np.ndarray
    unlabelled: int
    conflicts: int
    end: np.ndarray


class Singularities(NamedTuple):
    """Singularity measures per target and branch (NaN where the branch is absent).

    Attributes:
        iota_I, iota_II: (N, B) the scale-free measures (see the module docstring).
        types: (N, B) 0 none, 1 type I, 2 type II, 3 type III (-1 absent), SINGULARITY_TYPES.
    """

    iota_I: np.ndarray
    iota_II: np.ndarray
    types: np.ndarray


# -- compiled kernels ------------------------------------------------------------------------------
@njit(cache=True)
def _fk(x, parent, kind, axis, jR, jt, oR, op, pin_j, pin_R, pin_p):  # pragma: no cover - compiled
    """World rotation oR[j] and origin op[j] of every joint frame of the tree at values x; joint
    pin_j (if >= 0) is placed at (pin_R, pin_p) instead, its descendants following it."""
    nj = parent.shape[0]
    for j in range(nj):
        p = parent[j]
        if j == pin_j:
            for a in range(3):
                op[j, a] = pin_p[a]
                for b in range(3):
                    oR[j, a, b] = pin_R[a, b]
            continue
        if p < 0:
            for a in range(3):
                op[j, a] = jt[j, a]
                for b in range(3):
                    oR[j, a, b] = jR[j, a, b]
        else:
            for a in range(3):
                op[j, a] = op[p, a] + oR[p, a, 0] * jt[j, 0] + oR[p, a, 1] * jt[j, 1] + oR[p, a, 2] * jt[j, 2]
                for b in range(3):
                    oR[j, a, b] = oR[p, a, 0] * jR[j, 0, b] + oR[p, a, 1] * jR[j, 1, b] + oR[p, a, 2] * jR[j, 2, b]
        ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
        v = x[j]
        if kind[j] == 1:
            for a in range(3):
                op[j, a] += v * (oR[j, a, 0] * ax + oR[j, a, 1] * ay + oR[j, a, 2] * az)
        else:
            c, s = math.cos(v), math.sin(v)
            d = 1.0 - c
            e00, e01, e02 = c + d * ax * ax, d * ax * ay - s * az, d * ax * az + s * ay
            e10, e11, e12 = d * ay * ax + s * az, c + d * ay * ay, d * ay * az - s * ax
            e20, e21, e22 = d * az * ax - s * ay, d * az * ay + s * ax, c + d * az * az
            for a in range(3):
                a0, a1, a2 = oR[j, a, 0], oR[j, a, 1], oR[j, a, 2]
                oR[j, a, 0] = a0 * e00 + a1 * e10 + a2 * e20
                oR[j, a, 1] = a0 * e01 + a1 * e11 + a2 * e21
                oR[j, a, 2] = a0 * e02 + a1 * e12 + a2 * e22


@njit(cache=True)
def _frames(fparent, fR, ft, oR, op, FR, Fp):  # pragma: no cover - compiled
    for f in range(fparent.shape[0]):
        j = fparent[f]
        for a in range(3):
            Fp[f, a] = op[j, a] + oR[j, a, 0] * ft[f, 0] + oR[j, a, 1] * ft[f, 1] + oR[j, a, 2] * ft[f, 2]
            for b in range(3):
                FR[f, a, b] = oR[j, a, 0] * fR[f, 0, b] + oR[j, a, 1] * fR[f, 1, b] + oR[j, a, 2] * fR[f, 2, b]


@njit(cache=True)
def _orient(A, B, scale, out, k, H_A, H_B, jac):  # pragma: no cover - compiled
    """Orientation error of A against B: out[k:k+3] = 2 l v / (1 + T), C = A B^T, v = vee(C - C^T),
    T = tr C: l tan(angle/2) axis x 2, ~ l angle axis near A = B, infinite at a half-turn (which
    vee(C - C^T) alone would take for a root). Its rate is H_A w_A - H_B w_B with
    H = 2 l / (1 + T) (2 G + v v^T / (1 + T)), G_A = (T I - C)/2, G_B = (T I - C^T)/2 (from
    vee([w] C + C^T [w]) = (T I - C) w and dT = -v . (w_A - w_B))."""
    C = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            C[a, b] = A[a, 0] * B[b, 0] + A[a, 1] * B[b, 1] + A[a, 2] * B[b, 2]
    T = C[0, 0] + C[1, 1] + C[2, 2]
    v0, v1, v2 = C[2, 1] - C[1, 2], C[0, 2] - C[2, 0], C[1, 0] - C[0, 1]
    d = max(1.0 + T, 1e-9)
    f = 2.0 * scale / d
    out[k], out[k + 1], out[k + 2] = f * v0, f * v1, f * v2
    if jac:
        v = (v0, v1, v2)
        for a in range(3):
            for b in range(3):
                vv = v[a] * v[b] / d
                H_A[a, b] = f * ((T if a == b else 0.0) - C[a, b] + vv)
                H_B[a, b] = f * ((T if a == b else 0.0) - C[b, a] + vv)


@njit(cache=True)
def _pin_pose(g, target, pin_R, pin_p):  # pragma: no cover - compiled
    """The placement (pin_R, pin_p) of the end effector's parent joint that puts the end effector
    at `target` (every position axis) with orientation R0: R = R0 fR[ee]^T, p = target - R ft[ee].
    Returns that joint's index."""
    fparent, fR, ft, ee, taxes, R0 = g[5], g[6], g[7], g[12], g[13], g[14]
    for a in range(3):
        for b in range(3):
            pin_R[a, b] = R0[a, 0] * fR[ee, b, 0] + R0[a, 1] * fR[ee, b, 1] + R0[a, 2] * fR[ee, b, 2]
    for a in range(3):
        pin_p[taxes[a]] = target[a]
    for a in range(3):
        pin_p[a] -= pin_R[a, 0] * ft[ee, 0] + pin_R[a, 1] * ft[ee, 1] + pin_R[a, 2] * ft[ee, 2]
    return fparent[ee]


@njit(cache=True)
def _residual(x, target, g, oR, op, FR, Fp, r, J, jac, pin_j, pin_R, pin_p):  # pragma: no cover - compiled
    """Residual r (m,) and, if jac, its Jacobian J (m, n) at joint values x for one target.

    pin_j >= 0 (`_pin_pose`): the end effector's body is placed at the target with orientation R0
    whatever x says, so its frames are constants (task and orientation rows vanish; the Jacobian
    is then only meaningful for joints that are not its ancestors)."""
    (parent, kind, axis, jR, jt, fparent, fR, ft, anc, ctype, cf1, cf2, ee, taxes, R0, orient, scale) = g
    _fk(x, parent, kind, axis, jR, jt, oR, op, pin_j, pin_R, pin_p)
    _frames(fparent, fR, ft, oR, op, FR, Fp)
    n = parent.shape[0]
    k = 0
    nc = ctype.shape[0]
    GA = np.empty((3, 3))
    GB = np.empty((3, 3))
    # rows: closures, orientation (if held), task position
    for c in range(nc + 2):
        if c < nc:
            f1, f2, rot = cf1[c], cf2[c], ctype[c] == 1
            for a in range(3):
                r[k + a] = Fp[f1, a] - Fp[f2, a]
            if rot:
                _orient(FR[f1], FR[f2], scale, r, k + 3, GA, GB, jac)
        elif c == nc:
            if not orient:
                continue
            f1, f2, rot = ee, -1, True
            _orient(FR[ee], R0, scale, r, k, GA, GB, jac)
        else:
            f1, f2, rot = ee, -1, False
            for a in range(taxes.shape[0]):
                r[k + a] = Fp[ee, taxes[a]] - target[a]
        if jac:
            rows = (3 if c < nc else 0) + (3 if rot else 0) if c <= nc else taxes.shape[0]
            for i in range(rows):
                for j in range(n):
                    J[k + i, j] = 0.0
            ko = k + 3 if c < nc else k  # first orientation row
            for side in range(2):
                f = f1 if side == 0 else f2
                if f < 0:
                    continue
                sg = 1.0 if side == 0 else -1.0
                for j in range(n):
                    if not anc[f, j]:
                        continue
                    wx = oR[j, 0, 0] * axis[j, 0] + oR[j, 0, 1] * axis[j, 1] + oR[j, 0, 2] * axis[j, 2]
                    wy = oR[j, 1, 0] * axis[j, 0] + oR[j, 1, 1] * axis[j, 1] + oR[j, 1, 2] * axis[j, 2]
                    wz = oR[j, 2, 0] * axis[j, 0] + oR[j, 2, 1] * axis[j, 1] + oR[j, 2, 2] * axis[j, 2]
                    if kind[j] == 1:
                        lx, ly, lz = wx, wy, wz
                    else:
                        dx, dy, dz = Fp[f, 0] - op[j, 0], Fp[f, 1] - op[j, 1], Fp[f, 2] - op[j, 2]
                        lx, ly, lz = wy * dz - wz * dy, wz * dx - wx * dz, wx * dy - wy * dx
                        if rot:
                            G = GA if side == 0 else GB
                            for a in range(3):
                                J[ko + a, j] += sg * (G[a, 0] * wx + G[a, 1] * wy + G[a, 2] * wz)
                    if c < nc:
                        J[k, j] += sg * lx
                        J[k + 1, j] += sg * ly
                        J[k + 2, j] += sg * lz
                    elif c > nc:
                        lin = (lx, ly, lz)
                        for a in range(taxes.shape[0]):
                            J[k + a, j] += lin[taxes[a]]
        if c < nc:
            k += 6 if rot else 3
        elif c == nc:
            k += 3
        else:
            k += taxes.shape[0]


@njit(cache=True)
def _orient_trace(g, FR):  # pragma: no cover - compiled
    """Smallest tr(R_1 R_2^T) over the orientation equations: vee(C - C^T) also vanishes at half-turns
    (C symmetric), which a root must not be: tr C = 1 + 2 cos(angle) >= 1 keeps the angle within 90 deg."""
    ctype, cf1, cf2, ee, R0, orient = g[9], g[10], g[11], g[12], g[14], g[15]
    best = 3.0
    for c in range(ctype.shape[0]):
        if ctype[c] == 1:
            t = 0.0
            for a in range(3):
                for b in range(3):
                    t += FR[cf1[c], a, b] * FR[cf2[c], a, b]
            best = min(best, t)
    if orient:
        t = 0.0
        for a in range(3):
            for b in range(3):
                t += FR[ee, a, b] * R0[a, b]
        best = min(best, t)
    return best


@njit(cache=True, inline="always")
def _wrap(x, kind, centre):  # pragma: no cover - compiled
    for j in range(x.shape[0]):
        if kind[j] == 0:
            x[j] = (x[j] - centre[j] + math.pi) % (2 * math.pi) + centre[j] - math.pi


@njit(cache=True, inline="always")
def _weigh(w, r, J, jac):  # pragma: no cover - compiled
    for i in range(r.shape[0]):
        if w[i] != 1.0:
            r[i] *= w[i]
            if jac:
                for j in range(J.shape[1]):
                    J[i, j] *= w[i]


@njit(cache=True, inline="always")
def _maxabs(r):  # pragma: no cover - compiled
    m = 0.0
    for i in range(r.shape[0]):
        m = max(m, abs(r[i]))
    return m


@njit(cache=True)
def _cholesky_solve(A, b, out):  # pragma: no cover - compiled
    """Solve A out = b for symmetric positive definite A (overwritten); False if not PD."""
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        A[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = s / d
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= A[i, k] * out[k]
        out[i] = s / A[i, i]
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= A[k, i] * out[k]
        out[i] = s / A[i, i]
    return True


@njit(cache=True, parallel=True)
def _lm_kernel(targets, x0, g, m, nzc, nzn, centre, free, roww, iters, tol, x_out, res_out, it_out, pinned):  # pragma: no cover - compiled
    """Levenberg-Marquardt from every row's start x0 towards its target (see the module docstring)."""
    kind = g[1]
    nrows = targets.shape[0]
    n = g[0].shape[0]
    nf = g[5].shape[0]
    BLK = 16
    for blk in prange((nrows + BLK - 1) // BLK):
        oR = np.empty((n, 3, 3))
        op = np.empty((n, 3))
        FR = np.empty((nf, 3, 3))
        Fp = np.empty((nf, 3))
        r = np.empty(m)
        rt = np.empty(m)
        J = np.empty((m, n))
        A = np.empty((n, n))
        D = np.empty((n, n))
        gr = np.empty(n)
        dx = np.empty(n)
        x = np.empty(n)
        xt = np.empty(n)
        pin_R = np.empty((3, 3))
        pin_p = np.empty(3)
        for row in range(blk * BLK, min(nrows, (blk + 1) * BLK)):
            t = targets[row]
            pin_j = _pin_pose(g, t, pin_R, pin_p) if pinned else -1
            for j in range(n):
                x[j] = x0[row, j]
            _wrap(x, kind, centre)
            _residual(x, t, g, oR, op, FR, Fp, r, J, True, pin_j, pin_R, pin_p)
            _weigh(roww, r, J, True)
            cost = 0.0
            for i in range(m):
                cost += r[i] * r[i]
            lam = 1e-8
            it = 0
            while it < iters and _maxabs(r) > tol:
                it += 1
                # J^T J and -J^T r over each row's structurally non-zero columns only
                for a in range(n):
                    gr[a] = 0.0
                    for b in range(a + 1):
                        A[a, b] = 0.0
                for i in range(m):
                    ri = r[i]
                    for u in range(nzn[i]):
                        a = nzc[i, u]
                        ja = J[i, a]
                        gr[a] -= ja * ri
                        for v in range(nzn[i]):
                            b = nzc[i, v]
                            if b <= a:
                                A[a, b] += ja * J[i, b]
                trace = 0.0
                for a in range(n):
                    for b in range(a):
                        A[b, a] = A[a, b]
                    trace += A[a, a]
                for a in range(n):
                    if not free[a]:  # frozen unknown: dx[a] = 0
                        for b in range(n):
                            A[a, b] = 0.0
                            A[b, a] = 0.0
                        A[a, a] = 1.0
                        gr[a] = 0.0
                accepted = False
                c2 = cost
                while lam < 1e10:
                    for a in range(n):
                        for b in range(n):
                            D[a, b] = A[a, b]
                        D[a, a] += lam * A[a, a] + 1e-14 * trace / n + 1e-300
                    if not _cholesky_solve(D, gr, dx):
                        lam *= 10.0
                        continue
                    for j in range(n):
                        xt[j] = x[j] + dx[j]
                    _wrap(xt, kind, centre)
                    _residual(xt, t, g, oR, op, FR, Fp, rt, J, False, pin_j, pin_R, pin_p)
                    _weigh(roww, rt, J, False)
                    c2 = 0.0
                    for i in range(m):
                        c2 += rt[i] * rt[i]
                    if c2 < cost:
                        accepted = True
                        break
                    lam *= 10.0
                if not accepted:
                    break
                lam = max(lam * 0.1, 1e-12)
                step = 0.0
                for j in range(n):
                    step = max(step, abs(dx[j]))
                    x[j] = xt[j]
                drop = cost - c2
                cost = c2
                _residual(x, t, g, oR, op, FR, Fp, r, J, True, pin_j, pin_R, pin_p)
                _weigh(roww, r, J, True)
                # a least-squares point, not a root: the cost stalls (near a root Newton's quadratic
                # convergence drops it by far more than this each step)
                if step < 1e-15 or drop <= 1e-16 * cost or (it >= 3 and drop <= STALL * cost):
                    break
            for j in range(n):
                x_out[row, j] = x[j]
            res_out[row] = _maxabs(r)
            _residual(x, t, g, oR, op, FR, Fp, rt, J, False, pin_j, pin_R, pin_p)
            if _orient_trace(g, FR) < 1.0:  # a half-turn, not a root
                res_out[row] = max(res_out[row], 1.0) if res_out[row] <= tol else res_out[row]
            it_out[row] = it


@njit(cache=True)
def _eval_kernel(targets, x, g, r_out, J_out, pos_out):  # pragma: no cover - compiled
    """Residuals, Jacobians and joint-origin positions at rows of joint values."""
    n = g[0].shape[0]
    nf = g[5].shape[0]
    oR = np.empty((n, 3, 3))
    op = np.empty((n, 3))
    FR = np.empty((nf, 3, 3))
    Fp = np.empty((nf, 3))
    pin_R = np.empty((3, 3))
    pin_p = np.empty(3)
    for row in range(x.shape[0]):  # serial: cheap next to the solves, and compiles faster
        _residual(x[row], targets[row], g, oR, op, FR, Fp, r_out[row], J_out[row], True, -1, pin_R, pin_p)
        for j in range(n):
            for a in range(3):
                pos_out[row, j, a] = op[j, a]
        for f in range(nf):
            for a in range(3):
                pos_out[row, n + f, a] = Fp[f, a]


# -- the mechanism ---------------------------------------------------------------------------------
def _rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


@dataclass(eq=False)
class LoopBatch:
    """Every working mode of a closed-loop mechanism (URDF tree + loop sidecar), batched.

    Capabilities (all vectorised over targets, task points of shape (N, d)):

    * `task_dim`, `task_axes`, `translational`, `bounding_box()`: the task space;
    * `ik(points)`: joint values of every branch (`BranchSolutions`), `labels` names the branches;
    * `margin(points)`: (N, B + 1) joint-limit margins per branch and their union (the last
      column), the callable `kinematics.analyses.columns.column_volume` takes; `margin_function(branches)`
      selects branches;
    * `jacobians(points, x)`: forward (task rate per actuator rate) and inverse (actuator rate per
      task rate) Jacobians; `singularities(points, x)`: Gosselin-Angeles measures and types.

    Not thread-safe (it keeps a cache of solved points for warm starts); make one per thread.
    Build with `LoopBatch.from_robot`.
    """

    robot: Robot
    task_axes: tuple[int, ...]
    translational: bool
    scale: float
    labels: tuple[tuple[int, ...], ...] = ()
    atlas: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    blocks: tuple[Block, ...] = ()
    restarts: int = 8
    frames: tuple[str, ...] = ()
    _g: tuple[Any, ...] = ()
    _m: int = 0
    _nzc: np.ndarray = field(default_factory=lambda: np.empty((0, 0), dtype=np.int64))
    _nzn: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    _centre: np.ndarray = field(default_factory=lambda: np.empty(0))
    _reference: np.ndarray = field(default_factory=lambda: np.empty(0))
    _anchor: np.ndarray = field(default_factory=lambda: np.empty(0))
    _cache: tuple[np.ndarray, np.ndarray] | None = None

    # -- construction ----------------------------------------------------------------------------
    @classmethod
    def from_robot(cls, robot: Robot, *, task_axes: tuple[int, ...] | None = None, seeds: int = 512,
                   restarts: int = 8, rng: int | np.random.Generator | None = 0) -> LoopBatch:
        """Compile a closed-loop robot and find its branches at the reference position.

        Args:
            task_axes: world position axes of the task (default: chosen at the reference, see the
                module docstring).
            seeds: random starts of the branch search at the reference position.
            restarts: random starts per target that misses some branch (`ik`).
            rng: seed of the random starts (the result is deterministic for a fixed seed).

        Raises:
            UnsupportedRobotError: no sidecar, a joint with several degrees of freedom, or a task
                that needs orientation coordinates.
        """
        from kinematics.generic.closedloop import ClosedLoop

        if robot.loops is None:
            raise UnsupportedRobotError(robot.name, "no loop-closure sidecar (<name>.loops.yaml) next to its URDF")
        model = robot.model
        for jid in range(1, model.njoints):
            if model.joints[jid].nv != 1:
                raise UnsupportedRobotError(robot.name, f"joint {model.names[jid]!r} has {model.joints[jid].nv} "
                                            "degrees of freedom; the batched loop solver takes 1-DOF joints")
        loop = ClosedLoop(robot)
        q, err, _ = loop.newton(loop.reference)
        if err > 1e-9:
            raise UnsupportedRobotError(robot.name, f"the sidecar's reference configuration does not close "
                                        f"(residual {err:.2e} m)")
        G = loop.constrained_jacobian(q)  # 6 x n_actuated
        n_act = len(loop.actuated_dofs)
        lin, ang = G[:3], G[3:]
        size = max(float(np.linalg.norm(lin)), 1e-300)
        translational = float(np.linalg.norm(ang)) * _length(robot, q) <= 1e-9 * size
        if task_axes is None:
            best, axes = -1.0, None
            for comb in itertools.combinations(range(3), n_act):
                s = np.linalg.svd(lin[list(comb)], compute_uv=False)
                if s[-1] > best:
                    best, axes = float(s[-1]), comb
            if axes is None or best <= 1e-9 * size:
                raise UnsupportedRobotError(robot.name, "its actuators drive the end effector's orientation; "
                                            "the batched solver handles position tasks only")
            task_axes = tuple(axes)
        self = cls(robot=robot, task_axes=tuple(int(a) for a in task_axes), translational=translational,
                   scale=_length(robot, q), restarts=restarts)
        self._compile(q)
        self._reference = robot.values_from_configuration(q)
        pin.framesForwardKinematics(model, robot.data, q)
        ee_pos = np.array(robot.data.oMf[robot.frame_id(robot.loops.end_effector)].translation)
        self._anchor = ee_pos[list(self.task_axes)]
        self.blocks = self._find_blocks()
        self._find_atlas(seeds, _rng(rng))
        return self

    def _compile(self, q: np.ndarray) -> None:
        robot, model, spec = self.robot, self.robot.model, self.robot.loops
        if spec is None:
            raise UnsupportedRobotError(robot.name, "the batched closed-loop solver needs a loop sidecar")
        n = model.njoints - 1
        parent = np.array([int(model.parents[j]) - 1 for j in range(1, n + 1)], dtype=np.int64)
        kind, axes = [], []
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        for j in range(1, n + 1):
            S = np.asarray(data.joints[j].S).reshape(6)
            prismatic = float(np.linalg.norm(S[:3])) > 0.5
            a = S[:3] if prismatic else S[3:]
            kind.append(PRISMATIC if prismatic else REVOLUTE)
            axes.append(a / np.linalg.norm(a))
        jR = np.array([model.jointPlacements[j].rotation for j in range(1, n + 1)], dtype=float).reshape(n, 3, 3)
        jt = np.array([model.jointPlacements[j].translation for j in range(1, n + 1)], dtype=float).reshape(n, 3)
        frames = []
        for c in spec.closures:
            frames += [c.frame1, c.frame2]
        frames.append(spec.end_effector)
        frames = list(dict.fromkeys(frames))
        self.frames = tuple(frames)
        fids = [robot.frame_id(f) for f in frames]
        fparent = np.array([int(model.frames[f].parentJoint) - 1 for f in fids], dtype=np.int64)
        fR = np.array([model.frames[f].placement.rotation for f in fids], dtype=float).reshape(-1, 3, 3)
        ft = np.array([model.frames[f].placement.translation for f in fids], dtype=float).reshape(-1, 3)
        anc = np.zeros((len(fids), n), dtype=np.bool_)
        for i, fp in enumerate(fparent):
            j = int(fp)
            while j >= 0:
                anc[i, j] = True
                j = int(parent[j])
        ctype = np.array([0 if c.type == "point" else 1 for c in spec.closures], dtype=np.int64)
        cf1 = np.array([frames.index(c.frame1) for c in spec.closures], dtype=np.int64)
        cf2 = np.array([frames.index(c.frame2) for c in spec.closures], dtype=np.int64)
        ee = frames.index(spec.end_effector)
        pin.framesForwardKinematics(model, data, q)
        R0 = np.array(data.oMf[fids[ee]].rotation, dtype=float)
        self._g = (parent, np.array(kind, dtype=np.int64), np.array(axes, dtype=float).reshape(n, 3), jR, jt,
                   fparent, fR, ft, anc, ctype, cf1, cf2, int(ee), np.array(self.task_axes, dtype=np.int64), R0,
                   bool(self.translational), float(self.scale))
        self._m = int(sum(3 if t == 0 else 6 for t in ctype) + (3 if self.translational else 0) + len(self.task_axes))
        lo, hi = robot.lower, robot.upper
        self._centre = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0)
        # structural pattern: the columns each residual row can depend on
        cols = [np.flatnonzero(row) for row in self.row_dependencies()]
        width = max(len(c) for c in cols)
        self._nzn = np.array([len(c) for c in cols], dtype=np.int64)
        self._nzc = np.array([np.pad(c, (0, width - len(c)), constant_values=-1) for c in cols], dtype=np.int64)

    # -- basic properties ------------------------------------------------------------------------
    @property
    def task_dim(self) -> int:
        """Dimension d of the task space (platform position coordinates)."""
        return len(self.task_axes)

    @property
    def n(self) -> int:
        """Number of joint values (degrees of freedom of the tree)."""
        return self.robot.nv

    @functools.cached_property
    def actuated(self) -> np.ndarray:
        """Degree-of-freedom indices of the actuated joints (sidecar order)."""
        loops = self.robot.loops
        if loops is None:
            raise UnsupportedRobotError(self.robot.name, "the batched closed-loop solver needs a loop sidecar")
        return np.array([self.robot.joint_names.index(a) for a in loops.actuated])

    @functools.cached_property
    def passive(self) -> np.ndarray:
        """Degree-of-freedom indices of the passive joints."""
        return np.array([i for i in range(self.n) if i not in set(self.actuated.tolist())])

    @functools.cached_property
    def limited(self) -> np.ndarray:
        """Joints whose limits bind: finite and (revolute) narrower than a full turn."""
        lo, hi = self.robot.lower, self.robot.upper
        kind = self._g[1]
        return np.isfinite(lo) & np.isfinite(hi) & ((kind == PRISMATIC) | (hi - lo < 2 * math.pi - 1e-9))

    @property
    def branch_names(self) -> tuple[str, ...]:
        """Readable branch labels: one +/- per labelling block."""
        return tuple("".join("+" if s > 0 else "-" for s in lab) for lab in self.labels)

    def _points(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=float)
        if p.ndim == 1 and p.shape[0] == self.task_dim:
            p = p[None]
        if p.ndim != 2 or p.shape[1] != self.task_dim:
            raise InvalidInputError("points", f"expected shape (N, {self.task_dim}), got {np.shape(points)}")
        if not np.all(np.isfinite(p)):
            raise InvalidInputError("points", "must be finite")
        return np.ascontiguousarray(p)

    # -- kernels ---------------------------------------------------------------------------------
    def newton(self, targets: np.ndarray, x0: np.ndarray, iters: int = 40, tol: float = TOL,
               free: np.ndarray | None = None, rows: np.ndarray | None = None, pinned: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Levenberg-Marquardt rows: (R, d) targets, (R, n) starts -> (x, max |residual| [m], iterations).

        free: (n,) bool, the unknowns that may move (default: all); rows: (m,) bool, the equations
        solved (default: all); pinned: place the end effector's body at each target (orientation
        R_0) whatever its ancestors' values (translational mechanisms with a 3D task only): the
        other closures are then solved against the platform where it must be, even where the
        chain that carries it in the tree cannot put it there.

        Raises:
            UnsupportedRobotError: pinned on a mechanism that is not translational with a 3D task.
        """
        if pinned and not self.can_pin:
            raise UnsupportedRobotError(self.robot.name, "pinning the end effector needs a translational "
                                                         "mechanism with a 3D position task")
        free = np.ones(self.n, dtype=np.bool_) if free is None else np.asarray(free, dtype=np.bool_)
        roww = np.ones(self._m) if rows is None else np.asarray(rows, dtype=float)
        t = np.ascontiguousarray(targets, dtype=float)
        x0 = np.ascontiguousarray(x0, dtype=float)
        x = np.empty_like(x0)
        res = np.empty(len(t))
        its = np.empty(len(t), dtype=np.int64)
        if len(t):
            _lm_kernel(t, x0, self._g, self._m, self._nzc, self._nzn, self._centre, free, roww, iters, tol, x, res, its,
                       bool(pinned))
        return x, res, its

    def evaluate(self, targets: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals (R, m), Jacobians (R, m, n) and positions [m] (R, n + F, 3): every joint origin
        (model order), then the frames of `frames` (closure frames, end effector)."""
        t = np.ascontiguousarray(targets, dtype=float)
        x = np.ascontiguousarray(x, dtype=float)
        R = len(t)
        r = np.empty((R, self._m))
        J = np.empty((R, self._m, self.n))
        pos = np.empty((R, self.n + self._g[5].shape[0], 3))
        if R:
            _eval_kernel(t, x, self._g, r, J, pos)
        return r, J, pos

    # -- structure -------------------------------------------------------------------------------
    @property
    def can_pin(self) -> bool:
        """`newton(pinned=True)` applies: translational, with every position axis as the task."""
        return self.translational and self.task_dim == 3

    @functools.cached_property
    def task_rows(self) -> tuple[int, ...]:
        """Residual rows of the task: the end effector's orientation (if held) and position."""
        k = len(self.task_axes) + (3 if self.translational else 0)
        return tuple(range(self._m - k, self._m))

    def row_dependencies(self, pinned: bool = False) -> np.ndarray:
        """(m, n) bool: the unknowns each residual row can depend on (its frames' ancestors).

        With pinned (`newton(pinned=True)`) the end effector's body is placed by the target, so
        frames on it or below it no longer depend on its ancestors, and the task rows on nothing."""
        parent, fparent, anc, ctype, cf1, cf2, ee = (self._g[i] for i in (0, 5, 8, 9, 10, 11, 12))
        anc = anc.copy()
        if pinned:
            above = np.zeros(self.n, dtype=bool)  # the end effector's joint and its ancestors
            j = int(fparent[ee])
            while j >= 0:
                above[j] = True
                j = int(parent[j])
            below = anc[:, int(fparent[ee])]  # frames carried by the end effector's joint
            anc[below] &= ~above
        out = []
        for k, t in enumerate(ctype):
            out += [anc[cf1[k]] | anc[cf2[k]]] * (3 if t == 0 else 6)
        out += [anc[ee]] * len(self.task_rows)
        return np.array(out, dtype=bool).reshape(self._m, self.n)

    def _row_groups(self) -> list[tuple[int, ...]]:
        groups, k = [], 0
        for t in self._g[9]:
            size = 3 if t == 0 else 6
            groups.append(tuple(range(k, k + size)))
            k += size
        if self.translational:
            groups.append(tuple(range(k, k + 3)))
            k += 3
        groups.append(tuple(range(k, k + self.task_dim)))
        return groups

    def _find_blocks(self) -> tuple[Block, ...]:
        """Greedy block-triangular ordering of the row groups (closures, orientation, task) from the
        Jacobian's pattern at random configurations (entries below 1e-12 x scale count as zero)."""
        rng = np.random.default_rng(12345)
        lo = np.where(self.limited, self.robot.lower, -math.pi)
        hi = np.where(self.limited, self.robot.upper, math.pi)
        x = rng.uniform(lo, hi, (6, self.n))
        _, J, _ = self.evaluate(np.zeros((6, self.task_dim)), x)
        pattern = np.any(np.abs(J) > 1e-12 * max(self.scale, 1e-300), axis=0)  # (m, n)
        live = pattern.any(axis=1)
        groups = [tuple(i for i in g if live[i]) for g in self._row_groups()]
        groups = [g for g in groups if g]
        act = set(self.actuated.tolist())
        known: set[int] = set()
        blocks: list[Block] = []
        remaining = list(range(len(groups)))
        while remaining:
            chosen = None
            for size in (1, 2, 3):
                best = None
                for comb in itertools.combinations(remaining, size):
                    rows = tuple(i for k in comb for i in groups[k])
                    cols = set(np.flatnonzero(pattern[list(rows)].any(axis=0)).tolist()) - known
                    if len(cols) <= len(rows):
                        key = (len(cols) != len(rows), len(rows))  # square first, then small
                        if best is None or key < best[0]:
                            best = (key, comb, rows, cols)
                if best is not None:
                    chosen = best[1:]
                    break
            if chosen is None:
                rows = tuple(i for k in remaining for i in groups[k])
                cols = set(range(self.n)) - known
                chosen = (tuple(remaining), rows, cols)
            comb, rows, cols = chosen
            blocks.append(Block(tuple(rows), tuple(sorted(cols)), bool(cols & act)))
            known |= cols
            remaining = [k for k in remaining if k not in comb]
        return tuple(blocks)

    @property
    def label_blocks(self) -> tuple[Block, ...]:
        """The square blocks with an actuated joint: the sign of each one's determinant labels a
        working mode."""
        return tuple(b for b in self.blocks if b.actuated and b.square and b.cols)

    def label_of(self, J: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(R, L) branch labels at solutions x with Jacobians J: per labelling block, the sign of its
        determinant times sign(cos b) of every concurrent group's middle angle b in the block. A
        group contributes exactly a factor cos b to the determinant (its joints' columns are a
        fixed map of their angular-velocity axes, whose determinant is +-cos b), so the product
        does not depend on the group's representation and keeps its sign through the group's own
        gimbal lock; 0 where the block is singular (type I)."""
        out = np.empty((len(J), len(self.label_blocks)), dtype=np.int8)
        for k, b in enumerate(self.label_blocks):
            sub = J[:, list(b.rows)][:, :, list(b.cols)]
            sign = np.sign(np.linalg.det(sub))
            for grp in self.concurrent_groups:
                if grp[1] in b.cols:
                    sign = sign * np.sign(np.cos(x[:, grp[1]]))
            out[:, k] = sign.astype(np.int8)
        return out

    # -- branch search ---------------------------------------------------------------------------
    def random_configurations(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """(count, n) joint values uniform within the limits (unlimited revolute: a full turn)."""
        lo = np.where(self.limited, self.robot.lower, self._centre - math.pi)
        hi = np.where(self.limited, self.robot.upper, self._centre + math.pi)
        return rng.uniform(lo, hi, (count, self.n))

    def seed_configurations(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """(count, n) random starts of the branch search: uniform over each limited joint's range
        widened by half its span on both sides (roots just outside the limits still attract
        starts), a full turn for the other revolute joints."""
        lo, hi = self.robot.lower, self.robot.upper
        span = np.where(self.limited, hi - lo, 0.0)
        lo = np.where(self.limited, lo - 0.5 * span, self._centre - math.pi)
        hi = np.where(self.limited, hi + 0.5 * span, self._centre + math.pi)
        return rng.uniform(lo, hi, (count, self.n))

    @functools.cached_property
    def concurrent_groups(self) -> tuple[tuple[int, ...], ...]:
        """Pairs and triples of revolute joints, each the only child of the previous one, with a
        common origin and mutually perpendicular axes, no closure or end-effector frame on their
        inner links: universal joints and Euler-angle spherical joints. (a, b[, c]) and
        (a + pi, pi - b[, c + pi]) place every link after the group identically."""
        parent, kind, axis, jR, jt, fparent = (self._g[i] for i in range(6))
        children: dict[int, list[int]] = {}
        for j, p in enumerate(parent):
            children.setdefault(int(p), []).append(j)
        framed = set(int(f) for f in fparent)

        def follows(j1: int, j2: int) -> bool:
            """j2 is j1's only child, revolute, at j1's origin, its axis perpendicular to j1's."""
            if children.get(j1, []) != [j2] or kind[j2] != REVOLUTE or j1 in framed:
                return False
            a2 = jR[j2] @ axis[j2]  # in j1's frame
            return float(np.linalg.norm(jt[j2])) <= 1e-12 and abs(float(axis[j1] @ a2)) <= 1e-9

        groups: list[tuple[int, ...]] = []
        used: set[int] = set()
        for j1 in range(len(parent)):
            if kind[j1] != REVOLUTE or j1 in used or j1 in self.actuated:
                continue
            (j2,) = children.get(j1, [-1]) if len(children.get(j1, [])) == 1 else (-1,)
            if j2 < 0 or j2 in self.actuated or not follows(j1, j2):
                continue
            group = [j1, j2]
            kids = children.get(j2, [])
            if len(kids) == 1 and kids[0] not in self.actuated and j2 not in framed:
                j3 = kids[0]
                # axes in j2's frame: j1's axis is R2^T a1 (j2's own rotation does not turn its axis)
                a1 = jR[j2].T @ axis[j1]
                if kind[j3] == REVOLUTE and float(np.linalg.norm(jt[j3])) <= 1e-12:
                    a3 = jR[j3] @ axis[j3]
                    if abs(float(a3 @ a1)) <= 1e-9 and abs(float(a3 @ axis[j2])) <= 1e-9:
                        group.append(j3)
            groups.append(tuple(group))
            used.update(group)
        return tuple(groups)

    @functools.cached_property
    def flippable_groups(self) -> tuple[tuple[int, ...], ...]:
        """The concurrent groups whose other representation is the same pose of every link after
        them: triples (Euler), and pairs (a, b) -> (a + pi, pi - b), which spin the child link by
        pi about u1 x u2, when the child carries no joint and only point-closure frames on that
        axis (a rod between a universal and a spherical joint)."""
        parent, _, axis, jR, _, fparent, _, ft = (self._g[i] for i in range(8))
        point_frames = set(int(f) for f, t in zip(self._g[10], self._g[9], strict=True) if t == 0)
        point_frames |= set(int(f) for f, t in zip(self._g[11], self._g[9], strict=True) if t == 0)
        out: list[tuple[int, ...]] = []
        for grp in self.concurrent_groups:
            if len(grp) == 3:
                out.append(grp)
                continue
            j1, j2 = grp
            if np.any(parent == j2):
                continue
            u3 = np.cross(jR[j2].T @ axis[j1], axis[j2])  # in j2's frame
            frames = np.flatnonzero(fparent == j2)
            if all(int(f) in point_frames and float(np.linalg.norm(np.cross(ft[f], u3))) <= 1e-12 for f in frames):
                out.append(grp)
        return tuple(out)

    def canonical(self, x: np.ndarray) -> np.ndarray:
        """One representation per pose where the model allows it exactly: every flippable group's
        middle angle b within [-pi/2, pi/2] ((a, b[, c]) -> (a + pi, pi - b[, c + pi]) where
        cos b < 0), angles wrapped as the solver."""
        x = np.array(x, dtype=float)
        for grp in self.flippable_groups:
            flip = np.cos(x[..., grp[1]]) < 0
            x[..., grp[0]] = np.where(flip, x[..., grp[0]] + math.pi, x[..., grp[0]])
            x[..., grp[1]] = np.where(flip, math.pi - x[..., grp[1]], x[..., grp[1]])
            if len(grp) == 3:
                x[..., grp[2]] = np.where(flip, x[..., grp[2]] + math.pi, x[..., grp[2]])
        revolute = self._g[1] == REVOLUTE
        c = self._centre[revolute]
        x[..., revolute] = (x[..., revolute] - c + math.pi) % (2 * math.pi) + c - math.pi
        return x

    def _distance_to_reference(self, x: np.ndarray) -> np.ndarray:
        d = x - self._reference
        revolute = self._g[1] == REVOLUTE
        d[..., revolute] = (d[..., revolute] + math.pi) % (2 * math.pi) - math.pi
        return np.sum(d * d, axis=-1)

    def _find_atlas(self, seeds: int, rng: np.random.Generator) -> None:
        x0 = np.vstack([self._reference, self.seed_configurations(seeds, rng)])
        t = np.repeat(self._anchor[None], len(x0), axis=0)
        x, res, _ = self.newton(t, x0, iters=100)
        ok = res <= TOL
        if not ok.any():
            raise UnsupportedRobotError(self.robot.name, "no start closed the loops at the reference position")
        x, t = self.canonical(x[ok]), t[ok]
        _, J, _ = self.evaluate(t, x)
        lab = self.label_of(J, x)
        keep = np.all(lab != 0, axis=1)
        x, lab = x[keep], lab[keep]
        dist = self._distance_to_reference(x)
        best: dict[tuple[int, ...], int] = {}
        for i in np.argsort(dist):
            key = tuple(int(v) for v in lab[i])
            best.setdefault(key, int(i))
        keys = sorted(best, reverse=True)
        self.labels = tuple(keys)
        self.atlas = np.array([x[best[k]] for k in keys])

    def ik(self, points: np.ndarray, *, warm: bool = True) -> BranchSolutions:
        """Every atlas branch at every task point (see the module docstring for the search).

        Args:
            points: (N, d) task coordinates [m].
            warm: use (and update) the cache of earlier batches' solutions as starts.
        """
        p = self._points(points)
        N = len(p)
        if N > 64:
            # continuation inside the batch: a coarse subset first, the rest from its ends
            first = np.arange(0, N, 8)
            sub = self._solve(p[first], warm)
            rest = np.setdiff1d(np.arange(N), first)
            other = self._solve(p[rest], warm, extra=(p[first], sub.end))
            out = _merge(N, (first, sub), (rest, other))
        else:
            out = self._solve(p, warm)
        if warm:
            self._remember(p, out.end)
        return out

    def _remember(self, p: np.ndarray, end: np.ndarray) -> None:
        if self._cache is not None:
            p = np.vstack([p, self._cache[0]])[:CACHE_POINTS]
            end = np.vstack([end, self._cache[1]])[:CACHE_POINTS]
        self._cache = (p, end)

    def forget(self) -> None:
        """Drop the warm-start cache."""
        self._cache = None

    def _solve(self, p: np.ndarray, warm: bool,
               extra: tuple[np.ndarray, np.ndarray] | None = None) -> BranchSolutions:
        from scipy.spatial import cKDTree

        N, B, n = len(p), len(self.labels), self.n
        best_x = np.full((N, B, n), np.nan)
        best_d = np.full((N, B), np.inf)
        residual = np.full((N, B), np.inf)
        end_x = np.full((N, B, n), np.nan)  # where each slot's best start ended (root or least-squares point)
        counters = [0, 0]
        codes = (np.array(self.labels, dtype=np.int64) + 1) @ (3 ** np.arange(len(self.labels[0]), dtype=np.int64))
        code_slot = np.argsort(codes)
        codes_sorted = codes[code_slot]

        def attempt(idx: np.ndarray, slot: np.ndarray, x0: np.ndarray, iters: int) -> None:
            if not len(idx):
                return
            x, res, _ = self.newton(p[idx], x0, iters=iters)
            better = res < residual[idx, slot]
            order = np.argsort(-res[better])  # ties: the smallest residual is written last
            end_x[idx[better][order], slot[better][order]] = x[better][order]
            np.minimum.at(residual, (idx, slot), res)
            ok = res <= TOL
            if not ok.any():
                return
            i, x, slot = idx[ok], self.canonical(x[ok]), slot[ok]
            _, J, _ = self.evaluate(p[i], x)
            lab = self.label_of(J, x)
            # label -> slot through the labels' codes in base 3 (-1, 0, +1 -> 0, 1, 2)
            key = (lab.astype(np.int64) + 1) @ (3 ** np.arange(lab.shape[1], dtype=np.int64))
            target = np.full(len(key), -1)
            pos = np.searchsorted(codes_sorted, key)
            hit = (pos < len(codes_sorted)) & (codes_sorted[np.minimum(pos, len(codes_sorted) - 1)] == key)
            target[hit] = code_slot[pos[hit]]
            counters[0] += int(np.sum(target < 0))
            good = target >= 0
            i, x, target = i[good], x[good], target[good]
            d = self._distance_to_reference(x)
            # per (target, slot): the candidate nearest the reference beats the one in place
            order = np.lexsort((d, target, i))
            i, x, target, d = i[order], x[order], target[order], d[order]
            first = np.ones(len(i), dtype=bool)
            first[1:] = (i[1:] != i[:-1]) | (target[1:] != target[:-1])
            dup = ~first & ~np.all(np.abs(x[:, self.actuated] - np.repeat(x[first][:, self.actuated],
                                   np.diff(np.r_[np.flatnonzero(first), len(i)]), axis=0)) <= 1e-9, axis=1)
            counters[1] += int(np.sum(dup))
            i, x, target, d = i[first], x[first], target[first], d[first]
            better = d < best_d[i, target]
            i, x, target, d = i[better], x[better], target[better], d[better]
            best_d[i, target], best_x[i, target], end_x[i, target] = d, x, x
            residual[i, target] = 0.0

        # (1) neighbours (earlier batches, this batch's coarse subset): each slot from the same
        # slot's root or least-squares point there (continuation)
        tried = np.zeros((N, B), dtype=bool)
        for src in (self._cache if warm else None, extra):
            if src is None or not len(src[0]):
                continue
            tree = cKDTree(src[0])
            dist, j = tree.query(p, distance_upper_bound=WARM_RADIUS_FACTOR * self.scale)
            near = np.isfinite(dist)
            has = np.isfinite(src[1][np.minimum(j, len(src[0]) - 1), :, 0])
            idx, slot = np.nonzero(near[:, None] & has & ~np.isfinite(best_d))
            attempt(idx, slot, src[1][j[idx], slot], 20)
            tried[idx, slot] = True
        # (2) the atlas configuration of each label not started from a neighbour
        idx, slot = np.nonzero(~tried & ~np.isfinite(best_d))
        attempt(idx, slot, self.atlas[slot], 40)
        # (3) block by block, where some but not all branches were found
        some = np.isfinite(best_d).any(axis=1) & ~np.isfinite(best_d).all(axis=1)
        idx, slot = np.nonzero(some[:, None] & ~np.isfinite(best_d))
        if self.restarts and len(idx):
            attempt(idx, slot, self.blockwise(p[idx], slot, np.random.default_rng(len(p))), 20)
        found = np.isfinite(best_d)
        residual = np.where(found, 0.0, np.where(np.isfinite(residual), residual, np.nan))
        margin = np.where(found, self.limit_margin(np.nan_to_num(best_x)),
                          -np.maximum(np.nan_to_num(residual, nan=1.0), 1e-300))
        return BranchSolutions(best_x, found, residual, margin, counters[0], counters[1], end_x)

    def blockwise(self, targets: np.ndarray, slot: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Starts for branch `slot` at each target, built block by block in the triangular order:
        each block's unknowns are solved from its own equations (the earlier blocks' unknowns
        held), from the atlas values of that branch and, for a labelling block that lands on the
        wrong sign, from `restarts` random values of its unknowns; the best candidate is kept."""
        x = np.array(self.atlas[slot], dtype=float)
        want = np.array(self.labels, dtype=np.int8)[slot]  # (R, L)
        lab_index = {b: k for k, b in enumerate(self.label_blocks)}
        R = len(x)
        for blk in self.blocks:
            if not blk.cols:
                continue
            rows = np.zeros(self._m, dtype=bool)
            rows[list(blk.rows)] = True
            free = np.zeros(self.n, dtype=bool)
            free[list(blk.cols)] = True
            k = lab_index.get(blk)
            tries = 1 + (self.restarts if k is not None else 0)
            starts = np.repeat(x[None], tries, axis=0)  # (tries, R, n)
            if tries > 1:
                rnd = self.seed_configurations(R * (tries - 1), rng).reshape(tries - 1, R, self.n)
                starts[1:, :, list(blk.cols)] = rnd[:, :, list(blk.cols)]
            flat = starts.reshape(-1, self.n)
            tt = np.tile(targets, (tries, 1))
            y, res, _ = self.newton(tt, flat, iters=30, free=free, rows=rows)
            y = self.canonical(y)
            score = res.copy()
            if k is not None:
                _, J, _ = self.evaluate(tt, y)
                sign = self.label_of(J, y)[:, list(self.label_blocks).index(blk)]
                score = np.where(sign == np.tile(want[:, k], tries), score, score + 10.0)
            score = score.reshape(tries, R)
            best = np.argmin(score, axis=0)
            x = y.reshape(tries, R, self.n)[best, np.arange(R)]
        return x

    # -- margins ---------------------------------------------------------------------------------
    def limit_margin(self, x: np.ndarray, limits: str = "all") -> np.ndarray:
        """Smallest joint-limit slack [m] of joint values x (..., n): prismatic distance to the
        limit, revolute angle x `scale`; joints without binding limits are ignored.

        limits: "all" (every joint) or "actuators" (the actuated joints only)."""
        if limits not in LIMITS:
            from kinematics.errors import UnknownChoiceError

            raise UnknownChoiceError(limits, LIMITS)
        lo, hi = self.robot.lower, self.robot.upper
        k = self.limited.copy()
        if limits == "actuators":
            k[self.passive] = False
        unit = np.where(self._g[1] == PRISMATIC, 1.0, self.scale)
        x = np.asarray(x, dtype=float)
        slack = np.where(k, np.minimum(x - lo, hi - x) * unit, np.inf)
        for j1, j2 in self.free_pairs:
            # (a + pi, pi - b) is the same pose up to unlimited joints below: take the better one
            c = self._centre
            a2 = (x[..., j1] + math.pi - c[j1] + math.pi) % (2 * math.pi) + c[j1] - math.pi
            b2 = (math.pi - x[..., j2] - c[j2] + math.pi) % (2 * math.pi) + c[j2] - math.pi
            s1 = np.minimum(slack[..., j1], slack[..., j2])
            s2 = np.minimum(np.where(k[j1], np.minimum(a2 - lo[j1], hi[j1] - a2) * unit[j1], np.inf),
                            np.where(k[j2], np.minimum(b2 - lo[j2], hi[j2] - b2) * unit[j2], np.inf))
            better = s2 > s1
            slack[..., j1] = np.where(better, s2, slack[..., j1])
            slack[..., j2] = np.where(better, s2, slack[..., j2])
        out = slack.min(axis=-1)
        return np.where(np.isfinite(out), out, np.inf)

    @functools.cached_property
    def free_pairs(self) -> tuple[tuple[int, int], ...]:
        """Concurrent pairs that are not flippable but whose other representation changes only
        joints without binding limits below them (a universal joint carrying a platform through an
        Euler spherical joint): the margin takes the better of the two representations."""
        flippable = set(self.flippable_groups)
        out = []
        for grp in self.concurrent_groups:
            if len(grp) != 2 or grp in flippable:
                continue
            below = [j for j in range(self.n) if self._descends(j, grp[1]) and j != grp[1]]
            if not any(self.limited[j] for j in below):
                out.append((grp[0], grp[1]))
        return tuple(out)

    def _descends(self, j: int, ancestor: int) -> bool:
        parent = self._g[0]
        while j >= 0:
            if j == ancestor:
                return True
            j = int(parent[j])
        return False

    def margin(self, points: np.ndarray, limits: str = "all") -> np.ndarray:
        """(N, B + 1) margins [m]: every branch (order of `labels`), then their union (max).

        limits: "all" or "actuators" (`limit_margin`)."""
        return self.margin_function(None, limits)(points)

    def margin_function(self, branches: Sequence[int] | None = None, limits: str = "all"
                        ) -> Callable[[np.ndarray], np.ndarray]:
        """points (N, d) -> (N, len(branches) + 1): the chosen branches' margins [m], then their
        union, for `kinematics.analyses.columns.column_volume`."""
        cols = list(range(len(self.labels))) if branches is None else list(branches)
        self.limit_margin(np.zeros((1, self.n)), limits)  # validates `limits`

        def margin(points: np.ndarray) -> np.ndarray:
            sol = self.ik(points)
            m = np.where(sol.found, self.limit_margin(np.nan_to_num(sol.x), limits), sol.margin)[:, cols]
            return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

        return margin

    def bounding_box(self, samples: int = 20_000, rng: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """A box [m] around the end effector's reachable task coordinates: the end effector's own
        chain sampled within its joint limits (loops ignored: a superset), padded by 5 %. A
        heuristic: a sampled box can miss the chain's extreme poses by about the padding."""
        x = self.random_configurations(samples, np.random.default_rng(rng))
        _, _, pos = self.evaluate(np.zeros((samples, self.task_dim)), x)
        ee = pos[:, self.n + self._g[12], list(self.task_axes)]
        lo, hi = ee.min(axis=0), ee.max(axis=0)
        pad = 0.05 * (hi - lo) + 1e-3 * self.scale
        return lo - pad, hi + pad

    # -- velocities and singularities -----------------------------------------------------------
    def _split(self, points: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = self._points(points)
        x = np.asarray(x, dtype=float)
        if x.shape[:1] != (len(p),) or x.shape[-1] != self.n:
            raise InvalidInputError("x", f"expected ({len(p)}, [B,] {self.n}) joint values, got {x.shape}")
        xb = x.reshape(len(p), -1, self.n)
        B = xb.shape[1]
        ok = np.all(np.isfinite(xb), axis=-1)
        t = np.repeat(p, B, axis=0)
        _, J, _ = self.evaluate(t, np.nan_to_num(xb.reshape(-1, self.n)))
        return J.reshape(len(p), B, self._m, self.n), ok, xb

    def jacobians(self, points: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(forward, inverse) Jacobians at solutions x (N, [B,] n) of targets (N, d).

        forward: (N, B, d, a): task velocity per actuator rate (locked-actuator passive rates
        eliminated by least squares; meaningless at type II). inverse: (N, B, a, d): actuator
        rates per task velocity (meaningless at type I). NaN where x is NaN.
        """
        J, ok, _ = self._split(points, x)
        a, pa = self.actuated, self.passive
        c = self._m - self.task_dim
        U_inv = np.linalg.pinv(J, rcond=1e-13)  # (N, B, n, m)
        inverse = U_inv[..., a, c:]
        A = J[..., :c, :]
        Pm = J[..., c:, :]
        vp = -np.linalg.pinv(A[..., pa], rcond=1e-13) @ A[..., a]  # (N, B, np, a)
        forward = Pm[..., a] + Pm[..., pa] @ vp
        nan = ~ok[..., None, None]
        return np.where(nan, np.nan, forward), np.where(nan, np.nan, inverse)

    def singularities(self, points: np.ndarray, x: np.ndarray, tol: float = SINGULAR_TOL) -> Singularities:
        """Gosselin-Angeles measures and types at solutions x (N, [B,] n) (module docstring)."""
        J, ok, _ = self._split(points, x)
        a, pa = self.actuated, self.passive
        c = self._m - self.task_dim
        Ua, Up = J[..., a], J[..., pa]
        Ua = Ua / np.maximum(np.linalg.norm(Ua, axis=-2, keepdims=True), 1e-300)
        proj = Ua - Up @ (np.linalg.pinv(Up, rcond=1e-10) @ Ua)
        iota_I = np.linalg.svd(proj, compute_uv=False)[..., -1]
        A, P = J[..., :c, :][..., pa], J[..., c:, :][..., pa]
        _, s, Vt = np.linalg.svd(P, full_matrices=True)
        r = int(np.max(np.sum(s > 1e-10 * np.maximum(s[..., :1], 1e-300), axis=-1)))
        V = np.swapaxes(Vt, -1, -2)
        Y, Z = V[..., :r], V[..., r:]
        AY, AZ = A @ Y, A @ Z
        QAY = AY - AZ @ (np.linalg.pinv(AZ, rcond=1e-10) @ AY)
        iota_II = np.linalg.svd(QAY / s[..., None, :r], compute_uv=False)[..., -1]
        iota_I = np.where(ok, iota_I, np.nan)
        iota_II = np.where(ok, iota_II, np.nan)
        types = np.where(ok, (iota_I <= tol).astype(np.int8) + 2 * (iota_II <= tol).astype(np.int8), -1)
        return Singularities(iota_I, iota_II, types.astype(np.int8))


def _merge(N: int, *parts: tuple[np.ndarray, BranchSolutions]) -> BranchSolutions:
    first = parts[0][1]
    x = np.empty((N,) + first.x.shape[1:])
    found = np.empty((N,) + first.found.shape[1:], dtype=bool)
    residual = np.empty(found.shape)
    margin = np.empty(found.shape)
    end = np.empty_like(x)
    for idx, s in parts:
        x[idx], found[idx], residual[idx], margin[idx], end[idx] = s.x, s.found, s.residual, s.margin, s.end
    return BranchSolutions(x, found, residual, margin, sum(s.unlabelled for _, s in parts),
                           sum(s.conflicts for _, s in parts), end)


def _length(robot: Robot, q: np.ndarray) -> float:
    """Characteristic length [m]: the largest distance of a joint origin from the world origin at q."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    d = [float(np.linalg.norm(data.oMi[j].translation)) for j in range(1, robot.model.njoints)]
    return max(max(d, default=0.0), 1e-3)


@functools.lru_cache(maxsize=16)
def loop_batch(robot: Robot) -> LoopBatch:
    """`LoopBatch.from_robot(robot)`, cached per robot."""
    return LoopBatch.from_robot(robot)
