"""The compiled kernels of the batched closed-loop solver (`kinematics.generic.loop_batch`): the
residual and its Jacobian, Levenberg-Marquardt per row, one block of the block solver at every
target, and the evaluation at given joint values.

**Equations.** The unknowns are all n joint values x (one per degree of freedom, actuated and
passive). The residual stacks, for a target t,

* every closure of the sidecar: p_f1 - p_f2 (3 rows, `point`), plus l o(R_f1, R_f2) (3 more, `6d`);
* the task: the end effector's position along the task axes minus t (d rows), and, for a
  *translational* mechanism, l o(R_ee, R_0): the platform keeps its reference orientation R_0;

with o(A, B) = vee(A B^T - B A^T) / 2 (zero iff A = B near A = B; its derivative there is
w_A - w_B, the world angular velocities) and l the model's characteristic length (`scale`), so
every row is in metres. The Jacobian rows are the differences of the frames' LOCAL_WORLD_ALIGNED
Jacobians (closure rows) and the end effector's own (task rows).

**Solver.** Levenberg-Marquardt on ||r||^2 in compiled kernels, one row (target, start) per
thread at a time: A = J^T J + lam diag(J^T J), dx = -A^-1 J^T r by Cholesky, accepted when ||r||
drops; lam starts at 1e-8 (Gauss-Newton). A slot's first start (a neighbour's end, else the atlas
configuration) updates lam by Nielsen's rule: x max(1/3, 1 - (2 rho - 1)^3) after an accepted
step, rho the actual over the predicted decrease, and x 10, 20, 40, ... (x 2, 4, ... after a first
accepted step) per rejected trial; the atlas retry and the quasi-random restarts divide lam by 10
after each accepted step and multiply it by 10 per rejection (long Gauss-Newton steps: they close
a target's nearly double roots next to a fold and reach more basins). Revolute values are
wrapped to within pi of the middle of their limits. It stops at max|r| <= TOL (a root: the loops
close and the target is met) or when it stalls (a least-squares point: no root near this start;
after 3 steps, an accepted step, or the step the linear model predicts, that lowers ||r||^2 by
less than STALL of it). The kinematics (all joint placements of the tree, frame placements,
Jacobian columns w x (p_f - o_j) / w) are evaluated in the same kernel, not by per-point Pinocchio
calls; a rejected trial evaluates the residual only, an accepted one adds the Jacobian from the
trial's placements.

**Folds.** A start that stalls next to closure usually sits at a least-squares point on a fold of a
limb's reach (the target a little beyond it, or a little inside with the start stalled on the
fold's flat residual). `fold_roots` reads the fold there: the Jacobian's near-null direction v,
the Gauss-Newton step with v held, and a quadratic model of the residual along v, whose roots are
the two nearly double roots when the target is inside and which has none when it is beyond.
`block_kernel` starts from those roots before its quasi-random restarts and, where the model says
beyond and the target's warm starts came from a point closer than FOLD_SOURCE x the continuation
radius (a root refinement's probes), skips the restarts.

Every compiled function that another one calls lives in this file, with its callers: Numba's
on-disk cache (`cache=True`) is invalidated only by a change of the file that defines a kernel, so
a kernel that compiled in a helper from another file would keep the old helper's code after that
file changed. (The joint-limit slack kernels call nothing here: they are in `margins`.)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from kinematics.generic.dense import cholesky_solve

TOL = 1e-12
"""A start has converged when every residual row is <= TOL [m]."""


STALL = 1e-2
"""After 3 iterations a start stops when an accepted step lowers ||r||^2 by less than this fraction
(it is heading for a least-squares point, not a root)."""

REVOLUTE, PRISMATIC = 0, 1

# A model reaches the kernels packed in two flat arrays (`pack`): every array argument of a
# compiled call costs its fields on the stack and every array a function binds costs reference
# counting, which for these small trees took more time than the kinematics itself.
#
# gi (int64): [n, nf, nc, ee, d, orient, o_parent, o_kind, o_fparent, o_anc, o_ctype, o_cf1, o_cf2,
#              o_taxes, 0, 0] then those arrays (anc as nf x n 0/1);
# gf (float64): [scale, axis (n x 3), jR (n x 9), jt (n x 3), fR (nf x 9), ft (nf x 3), R0 (9)];
# ws (float64 scratch): [oR (n x 9), op (n x 3), FR (nf x 9), Fp (nf x 3), pin_R (9), pin_p (3),
#              H_A (9), H_B (9), C (9)].
GI_HEADER = 16


def pack(g: tuple[Any, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' flat (gi, gf) arrays of a model tuple (`LoopBatch._g`, `BlockModel.g`)."""
    parent, kind, axis, jR, jt, fparent, fR, ft, anc, ctype, cf1, cf2, ee, taxes, R0, orient, scale = g
    n, nf, nc = len(parent), len(fparent), len(ctype)
    parts = [parent, kind, fparent, np.asarray(anc, dtype=np.int64).ravel(), ctype, cf1, cf2, taxes]
    offsets = np.cumsum([GI_HEADER] + [len(p) for p in parts])[:-1]
    head = np.zeros(GI_HEADER, dtype=np.int64)
    head[:6] = [n, nf, nc, int(ee), len(taxes), int(bool(orient))]
    head[6:14] = offsets
    gi = np.concatenate([head] + [np.asarray(p, dtype=np.int64).ravel() for p in parts])
    gf = np.concatenate([[float(scale)], np.ravel(axis), np.ravel(jR), np.ravel(jt), np.ravel(fR), np.ravel(ft),
                         np.ravel(np.asarray(R0))]).astype(float)
    return gi, gf


@njit(cache=True)
def _ws_size(gi):  # pragma: no cover - compiled
    return 12 * gi[0] + 12 * gi[1] + 39


@njit(cache=True)
def _pin_pose(gi, gf, ws, target):  # pragma: no cover - compiled
    """The placement (pin_R, pin_p in ws) of the end effector's parent joint that puts the end
    effector at `target` (every position axis) with orientation R0: R = R0 fR[ee]^T,
    p = target - R ft[ee]. Returns that joint's index."""
    n, nf, ee = gi[0], gi[1], gi[3]
    fR0, ft0, R00 = 1 + 15 * n, 1 + 15 * n + 9 * nf, 1 + 15 * n + 12 * nf
    PR, PP = 12 * n + 12 * nf, 12 * n + 12 * nf + 9
    for a in range(3):
        for b in range(3):
            s = 0.0
            for c in range(3):
                s += gf[R00 + 3 * a + c] * gf[fR0 + 9 * ee + 3 * b + c]
            ws[PR + 3 * a + b] = s
    for a in range(3):
        ws[PP + gi[gi[13] + a]] = target[a]
    for a in range(3):
        s = 0.0
        for c in range(3):
            s += ws[PR + 3 * a + c] * gf[ft0 + 3 * ee + c]
        ws[PP + a] -= s
    return gi[gi[8] + ee]


@njit(cache=True, inline="always")
def _placements(x, gi, gf, ws, pin_j):  # pragma: no cover - compiled
    """World rotation and origin of every joint frame of the tree at values x (ws oR, op), then of
    every frame (ws FR, Fp); joint pin_j (if >= 0) is placed at (pin_R, pin_p) instead, its
    descendants following it."""
    n, nf = gi[0], gi[1]
    oP, oK, oF = gi[6], gi[7], gi[8]
    AX, JR, JT = 1, 1 + 3 * n, 1 + 12 * n
    FR0, FT0 = 1 + 15 * n, 1 + 15 * n + 9 * nf
    WP, WFR, WFP = 9 * n, 12 * n, 12 * n + 9 * nf
    PR, PP = 12 * n + 12 * nf, 12 * n + 12 * nf + 9
    for j in range(n):
        p = gi[oP + j]
        R, P = 9 * j, WP + 3 * j
        if j == pin_j:
            for a in range(9):
                ws[R + a] = ws[PR + a]
            for a in range(3):
                ws[P + a] = ws[PP + a]
            continue
        if p < 0:
            for a in range(9):
                ws[R + a] = gf[JR + 9 * j + a]
            for a in range(3):
                ws[P + a] = gf[JT + 3 * j + a]
        else:
            Rp, Pp = 9 * p, WP + 3 * p
            for a in range(3):
                ws[P + a] = (ws[Pp + a] + ws[Rp + 3 * a] * gf[JT + 3 * j] + ws[Rp + 3 * a + 1] * gf[JT + 3 * j + 1]
                             + ws[Rp + 3 * a + 2] * gf[JT + 3 * j + 2])
                for b in range(3):
                    ws[R + 3 * a + b] = (ws[Rp + 3 * a] * gf[JR + 9 * j + b] + ws[Rp + 3 * a + 1] * gf[JR + 9 * j + 3 + b]
                                         + ws[Rp + 3 * a + 2] * gf[JR + 9 * j + 6 + b])
        ax, ay, az = gf[AX + 3 * j], gf[AX + 3 * j + 1], gf[AX + 3 * j + 2]
        v = x[j]
        if gi[oK + j] == PRISMATIC:
            for a in range(3):
                ws[P + a] += v * (ws[R + 3 * a] * ax + ws[R + 3 * a + 1] * ay + ws[R + 3 * a + 2] * az)
        else:
            c, s = math.cos(v), math.sin(v)
            d = 1.0 - c
            e00, e01, e02 = c + d * ax * ax, d * ax * ay - s * az, d * ax * az + s * ay
            e10, e11, e12 = d * ay * ax + s * az, c + d * ay * ay, d * ay * az - s * ax
            e20, e21, e22 = d * az * ax - s * ay, d * az * ay + s * ax, c + d * az * az
            for a in range(3):
                a0, a1, a2 = ws[R + 3 * a], ws[R + 3 * a + 1], ws[R + 3 * a + 2]
                ws[R + 3 * a] = a0 * e00 + a1 * e10 + a2 * e20
                ws[R + 3 * a + 1] = a0 * e01 + a1 * e11 + a2 * e21
                ws[R + 3 * a + 2] = a0 * e02 + a1 * e12 + a2 * e22
    for f in range(nf):
        j = gi[oF + f]
        R, P = 9 * j, WP + 3 * j
        for a in range(3):
            ws[WFP + 3 * f + a] = (ws[P + a] + ws[R + 3 * a] * gf[FT0 + 3 * f] + ws[R + 3 * a + 1] * gf[FT0 + 3 * f + 1]
                                   + ws[R + 3 * a + 2] * gf[FT0 + 3 * f + 2])
            for b in range(3):
                ws[WFR + 9 * f + 3 * a + b] = (ws[R + 3 * a] * gf[FR0 + 9 * f + b]
                                               + ws[R + 3 * a + 1] * gf[FR0 + 9 * f + 3 + b]
                                               + ws[R + 3 * a + 2] * gf[FR0 + 9 * f + 6 + b])


@njit(cache=True)
def _orient(A, a0, B, b0, scale, out, k, ws, H0, jac):  # pragma: no cover - compiled
    """Orientation error of A (3 x 3 at A[a0:a0+9]) against B (at B[b0:b0+9]): out[k:k+3] =
    2 l v / (1 + T), C = A B^T, v = vee(C - C^T), T = tr C: l tan(angle/2) axis x 2, ~ l angle axis
    near A = B, infinite at a half-turn (which vee(C - C^T) alone would take for a root). Its rate
    is H_A w_A - H_B w_B (ws[H0:H0+9], ws[H0+9:H0+18]) with H = 2 l / (1 + T) (2 G + v v^T / (1 + T)),
    G_A = (T I - C)/2, G_B = (T I - C^T)/2 (from vee([w] C + C^T [w]) = (T I - C) w and
    dT = -v . (w_A - w_B))."""
    C0 = H0 + 18
    for a in range(3):
        for b in range(3):
            ws[C0 + 3 * a + b] = (A[a0 + 3 * a] * B[b0 + 3 * b] + A[a0 + 3 * a + 1] * B[b0 + 3 * b + 1]
                                  + A[a0 + 3 * a + 2] * B[b0 + 3 * b + 2])
    T = ws[C0] + ws[C0 + 4] + ws[C0 + 8]
    v0, v1, v2 = ws[C0 + 7] - ws[C0 + 5], ws[C0 + 2] - ws[C0 + 6], ws[C0 + 3] - ws[C0 + 1]
    d = max(1.0 + T, 1e-9)
    f = 2.0 * scale / d
    out[k], out[k + 1], out[k + 2] = f * v0, f * v1, f * v2
    if jac:
        for a in range(3):
            va = v0 if a == 0 else (v1 if a == 1 else v2)
            for b in range(3):
                vb = v0 if b == 0 else (v1 if b == 1 else v2)
                vv = va * vb / d
                diag = T if a == b else 0.0
                ws[H0 + 3 * a + b] = f * (diag - ws[C0 + 3 * a + b] + vv)
                ws[H0 + 9 + 3 * a + b] = f * (diag - ws[C0 + 3 * b + a] + vv)


@njit(cache=True, inline="always")
def _residual(x, target, gi, gf, ws, r, J, jac, pin_j, fk):  # pragma: no cover - compiled
    """Residual r (m,) and, if jac, its Jacobian J (m, n) at joint values x for one target; fk False
    reuses the placements in ws that the last call left for these x.

    pin_j >= 0 (`_pin_pose`): the end effector's body is placed at the target with orientation R0
    whatever x says, so its frames are constants (task and orientation rows vanish; the Jacobian
    is then only meaningful for joints that are not its ancestors)."""
    if fk:
        _placements(x, gi, gf, ws, pin_j)
    n, nf, nc, ee, d, orient = gi[0], gi[1], gi[2], gi[3], gi[4], gi[5]
    oK, oA, oC, o1, o2, oT = gi[7], gi[9], gi[10], gi[11], gi[12], gi[13]
    scale = gf[0]
    AX, R00 = 1, 1 + 15 * n + 12 * nf
    WP, WFR, WFP = 9 * n, 12 * n, 12 * n + 9 * nf
    H0 = 12 * n + 12 * nf + 12
    k = 0
    # rows: closures, orientation (if held), task position
    for c in range(nc + 2):
        if c < nc:
            f1, f2, rot = gi[o1 + c], gi[o2 + c], gi[oC + c] == 1
            for a in range(3):
                r[k + a] = ws[WFP + 3 * f1 + a] - ws[WFP + 3 * f2 + a]
            if rot:
                _orient(ws, WFR + 9 * f1, ws, WFR + 9 * f2, scale, r, k + 3, ws, H0, jac)
        elif c == nc:
            if not orient:
                continue
            f1, f2, rot = ee, -1, True
            _orient(ws, WFR + 9 * ee, gf, R00, scale, r, k, ws, H0, jac)
        else:
            f1, f2, rot = ee, -1, False
            for a in range(d):
                r[k + a] = ws[WFP + 3 * ee + gi[oT + a]] - target[a]
        if jac:
            rows = (3 if c < nc else 0) + (3 if rot else 0) if c <= nc else d
            for i in range(rows):
                for j in range(n):
                    J[k + i, j] = 0.0
            ko = k + 3 if c < nc else k  # first orientation row
            for side in range(2):
                f = f1 if side == 0 else f2
                if f < 0:
                    continue
                sg = 1.0 if side == 0 else -1.0
                G = H0 + 9 * side
                for j in range(n):
                    if gi[oA + f * n + j] == 0:
                        continue
                    R = 9 * j
                    ax, ay, az = gf[AX + 3 * j], gf[AX + 3 * j + 1], gf[AX + 3 * j + 2]
                    wx = ws[R] * ax + ws[R + 1] * ay + ws[R + 2] * az
                    wy = ws[R + 3] * ax + ws[R + 4] * ay + ws[R + 5] * az
                    wz = ws[R + 6] * ax + ws[R + 7] * ay + ws[R + 8] * az
                    if gi[oK + j] == PRISMATIC:
                        lx, ly, lz = wx, wy, wz
                    else:
                        dx = ws[WFP + 3 * f] - ws[WP + 3 * j]
                        dy = ws[WFP + 3 * f + 1] - ws[WP + 3 * j + 1]
                        dz = ws[WFP + 3 * f + 2] - ws[WP + 3 * j + 2]
                        lx, ly, lz = wy * dz - wz * dy, wz * dx - wx * dz, wx * dy - wy * dx
                        if rot:
                            for a in range(3):
                                J[ko + a, j] += sg * (ws[G + 3 * a] * wx + ws[G + 3 * a + 1] * wy + ws[G + 3 * a + 2] * wz)
                    if c < nc:
                        J[k, j] += sg * lx
                        J[k + 1, j] += sg * ly
                        J[k + 2, j] += sg * lz
                    elif c > nc:
                        for a in range(d):
                            ta = gi[oT + a]
                            J[k + a, j] += lx if ta == 0 else (ly if ta == 1 else lz)
        if c < nc:
            k += 6 if rot else 3
        elif c == nc:
            k += 3
        else:
            k += d


@njit(cache=True)
def _orient_trace(gi, gf, ws, roww):  # pragma: no cover - compiled
    """Smallest tr(R_1 R_2^T) over the orientation equations solved (weight roww != 0; rows are
    closures, each position then for a 6D one orientation, then the held orientation): vee(C - C^T)
    also vanishes at half-turns (C symmetric), which a root must not be: tr C = 1 + 2 cos(angle) >= 1
    keeps the angle within 90 deg."""
    n, nf, nc, ee, orient = gi[0], gi[1], gi[2], gi[3], gi[5]
    oC, o1, o2 = gi[10], gi[11], gi[12]
    WFR, R00 = 12 * n, 1 + 15 * n + 12 * nf
    best = 3.0
    k = 0
    for c in range(nc):
        if gi[oC + c] == 1:
            if roww[k + 3] != 0.0 or roww[k + 4] != 0.0 or roww[k + 5] != 0.0:
                t = 0.0
                for a in range(9):
                    t += ws[WFR + 9 * gi[o1 + c] + a] * ws[WFR + 9 * gi[o2 + c] + a]
                best = min(best, t)
            k += 6
        else:
            k += 3
    if orient and (roww[k] != 0.0 or roww[k + 1] != 0.0 or roww[k + 2] != 0.0):
        t = 0.0
        for a in range(9):
            t += ws[WFR + 9 * ee + a] * gf[R00 + a]
        best = min(best, t)
    return best


@njit(cache=True)
def _has_orientation(gi):  # pragma: no cover - compiled
    found = gi[5] != 0
    for c in range(gi[2]):
        found = found or gi[gi[10] + c] == 1  # numba: no generator expressions here
    return found


@njit(cache=True, inline="always")
def _wrap(x, gi, centre):  # pragma: no cover - compiled
    """Revolute values to within pi of their centre (floor, not fmod: this runs every step)."""
    oK = gi[7]
    for j in range(x.shape[0]):
        if gi[oK + j] == REVOLUTE:
            d = x[j] - centre[j]
            if d > math.pi or d < -math.pi:
                x[j] = d - 2 * math.pi * math.floor((d + math.pi) / (2 * math.pi)) + centre[j]


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
    """max |r_i|; inf if some r_i is NaN (a NaN row is no root; max() alone would skip it)."""
    m = 0.0
    for i in range(r.shape[0]):
        a = abs(r[i])
        if not a <= m:
            m = a if a == a else np.inf
            if m == np.inf:
                return m
    return m


@njit(cache=True)
def scratch(gi, m):  # pragma: no cover - compiled
    """Scratch arrays of one Levenberg-Marquardt row (`_lm_row`) for model gi and m residual rows."""
    n = gi[0]
    return (np.empty(_ws_size(gi)), np.empty(m), np.empty(m), np.empty((m, n)), np.empty((m, n)), np.empty((n, n)),
            np.empty((n, n)), np.empty(n), np.empty(n), np.empty(n))


@njit(cache=True, inline="always")
def _lm_row(t, x, gi, gf, m, nzc, nzn, centre, free, roww, iters, tol, pinned, ws, r, rt, J, Jt, A, D, gr, dx,
            xt, settle, final_jac, adapt):  # pragma: no cover - compiled
    """Levenberg-Marquardt from x (overwritten with where it ends) towards target t (see the module
    docstring). Returns (max |weighted residual| [m], iterations); r and J then hold the weighted
    residual and Jacobian at x (J: unless final_jac is False and the last step converged, when it
    is the previous step's); the other arrays are scratch (`scratch`). The stall rule applies
    from step `settle` on. adapt: Nielsen's damping update (a descent towards the nearest root or
    least-squares point); else lam / 10 after every accepted step (long Gauss-Newton steps)."""
    n = x.shape[0]
    pin_j = _pin_pose(gi, gf, ws, t) if pinned else -1
    _wrap(x, gi, centre)
    _residual(x, t, gi, gf, ws, r, J, True, pin_j, True)
    _weigh(roww, r, J, True)
    cost = 0.0
    for i in range(m):
        cost += r[i] * r[i]
    lam = 1e-8
    up = 10.0  # lam's factor at the next rejected trial
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
        step = 0.0
        while lam < 1e10:
            for a in range(n):
                for b in range(n):
                    D[a, b] = A[a, b]
                D[a, a] += lam * A[a, a] + 1e-14 * trace / n + 1e-300
            if not cholesky_solve(D, gr, dx):
                lam *= up
                up *= 2.0 if adapt else 1.0
                continue
            # the decrease of ||r||^2 the linear model predicts, 2 dx.g - dx^T A dx: where it is
            # nil (a stationary point) or, after 3 steps, a small fraction of the cost (the start
            # stalls at a least-squares point) no trial can be accepted for more; stop without
            # the ~20 damping increases that would otherwise end the loop
            pred = 0.0
            step = 0.0
            for a in range(n):
                step = max(step, abs(dx[a]))
                q = 0.0
                for b in range(n):
                    q += A[a, b] * dx[b]
                pred += dx[a] * (2.0 * gr[a] - q)
            if step < 1e-15 or pred <= 1e-16 * cost or (it >= settle and pred <= STALL * cost):
                break
            for j in range(n):
                xt[j] = x[j] + dx[j]
            _wrap(xt, gi, centre)
            _residual(xt, t, gi, gf, ws, rt, Jt, False, pin_j, True)
            _weigh(roww, rt, Jt, False)
            c2 = 0.0
            for i in range(m):
                c2 += rt[i] * rt[i]
            if c2 < cost:
                accepted = True
                break
            lam *= up
            up *= 2.0 if adapt else 1.0
        if not accepted:
            break
        if adapt:
            # Nielsen (1999): lam follows the gain ratio rho = actual / predicted decrease
            # (x max(1/3, 1 - (2 rho - 1)^3)), the rejection factor doubles from 2: from a start at
            # a least-squares point (singular J, overlong Gauss-Newton steps) lam / 10 after each
            # step costs a rejected trial at the next, about one in two steps
            g = 2.0 * (cost - c2) / pred - 1.0
            lam = max(lam * max(1.0 / 3.0, 1.0 - g * g * g), 1e-12)
            up = 2.0
        else:
            lam = max(lam * 0.1, 1e-12)
        for j in range(n):
            x[j] = xt[j]
        if final_jac or _maxabs(rt) > tol:
            # the Jacobian at the accepted trial from the placements its residual left (no second FK)
            _residual(x, t, gi, gf, ws, r, J, True, pin_j, False)
            _weigh(roww, r, J, True)
        else:  # converged, and nobody reads the Jacobian at the root
            for i in range(m):
                r[i] = rt[i]
        drop = cost - c2
        cost = c2
        # a least-squares point, not a root: the cost stalls (near a root Newton's quadratic
        # convergence drops it by far more than this each step)
        if step < 1e-15 or drop <= 1e-16 * cost or (it >= settle and drop <= STALL * cost):
            break
    res = _maxabs(r)
    # ws holds x's placements: a converged row's last evaluation was its accepted step (or its start)
    if res <= max(tol, TOL) and _has_orientation(gi) and _orient_trace(gi, gf, ws, roww) < 1.0:
        res = 1.0  # a half-turn, not a root
    return res, it


RESTART_ROUNDS = 4
"""A slot still missing after its `restarts` quasi-random starts, where a start aimed at it closed
on a root of the other sign in the slot's assembly (same held joints, same locked-joint code: the
slot's roots exist there in general, its basin was missed), gets up to this many rounds of
`restarts` starts in all. On Gepetto's five-bar, chain 2's 8 restarts all closed on the other
elbow at about 3 % of the sequence's offsets (each elbow's basin takes about half the starts:
0.5^8 = 0.4 % were they independent; consecutive points of the sequence are not); 32, in four
rounds as correlated within and as independent between, ~0.03^4 ~ 1e-6. Elsewhere the rounds are
not run (iso five-bars, Delta, 3-[P2(US)]: the same time as 8 restarts)."""


@njit(cache=True, inline="always")
def restart_base(t, k, K, S, per_slot):  # pragma: no cover - compiled
    """The index in the quasi-random sequence before block k's first restart at target t (a slot
    s uses the next per_slot indices after base + s x per_slot): a function of the target's
    coordinates, not of its row in the batch, so that a target gets the same restarts whatever
    batch it is solved in. The window (one of 2^20) is the fractional part of
    sum_a (t_a mod 1024 m) alpha_a, alpha_a = 7919.618... + 1061.414... a [1/m] (a Weyl sum:
    equidistributed over lattices of points as over random ones, neighbours 1e-4 m apart in
    unrelated windows). (An integer hash reduced at each coordinate kept only the low bits: every
    point of a 2^-10 m lattice shared one window.)"""
    u = 0.0
    for a in range(t.shape[0]):
        u += (t[a] % 1024.0) * (7919.618033988749 + 1061.4142135623731 * a)
    h = int((u - math.floor(u)) * 1048576.0)
    return ((h * K + k) * S) * per_slot


FOLD_SINGULAR = 1e-3
"""A stalled start is at a fold when the smallest eigenvalue of J^T J (its free unknowns) is below
this fraction of their mean (`fold_roots`)."""

FOLD_SOURCE = 1e-2
"""A fold's verdict that the target lies beyond it replaces the restarts only where the target's
warm starts came from a point within this fraction of the continuation radius (`block_kernel`):
a root refinement's probes. Farther (a column's samples, a step apart) the verdict was wrong for
0.3-2 % of the slots the restarts then found (the iso five-bar), closer for 8 in 95,000."""

FOLD_STEP = 1e-3
"""Step [rad or m] of the central difference that gives the residual's curvature along the fold."""


@njit(cache=True)
def fold_roots(t, x, gi, gf, m, centre, free, roww, pinned, ws, r, rt, J, Jt, A, D, gr, dx, v, s12):  # pragma: no cover - compiled
    """Where a start that stalled at x (next to a least-squares point at a fold of the reach) finds
    its roots, if any. v: the near-null direction of the Jacobian J (inverse iteration on J^T J);
    x moves by the Gauss-Newton step with v held (what the other directions can close), to x1 where
    the residual r1 is normal to J's range; along v, r(x1 + s v) ~ r1 + s J v + s^2 c / 2 (c by
    central differences), whose component along r1 vanishes where |r1|^2 + s r1.Jv + s^2 r1.c / 2
    = 0. Returns 0 where J is not near-singular (not a fold: nothing is said), 1 where that
    quadratic has no real root (the target lies beyond the fold: no root next to x), 2 with its
    roots in s12, x1 in x and v (unit) written: the starts x1 + s v."""
    n = x.shape[0]
    pin_j = _pin_pose(gi, gf, ws, t) if pinned else -1
    _wrap(x, gi, centre)
    _residual(x, t, gi, gf, ws, r, J, True, pin_j, True)
    _weigh(roww, r, J, True)
    trace = 0.0
    nfree = 0
    for a in range(n):
        for b in range(a + 1):
            q = 0.0
            if free[a] and free[b]:
                for i in range(m):
                    q += J[i, a] * J[i, b]
            A[a, b] = q
            A[b, a] = q
        if free[a]:
            trace += A[a, a]
            nfree += 1
    if not trace > 0.0:
        return 0
    for a in range(n):
        v[a] = (1.0 + 0.37 * a) if free[a] else 0.0
        if not free[a]:
            A[a, a] = trace  # a frozen unknown: far from the smallest eigenvalue
    for _ in range(6):
        for a in range(n):
            for b in range(n):
                D[a, b] = A[a, b]
            D[a, a] += 1e-12 * trace + 1e-300
        if not cholesky_solve(D, v, dx):
            return 0
        norm = 0.0
        for a in range(n):
            norm += dx[a] * dx[a]
        norm = math.sqrt(norm)
        if not norm > 0.0:
            return 0
        for a in range(n):
            v[a] = dx[a] / norm if free[a] else 0.0
    lam = 0.0
    for a in range(n):
        for b in range(n):
            lam += v[a] * A[a, b] * v[b]
    if lam > FOLD_SINGULAR * trace / nfree:
        return 0
    for a in range(n):
        q = 0.0
        if free[a]:
            for i in range(m):
                q -= J[i, a] * r[i]
        gr[a] = q
        for b in range(n):
            D[a, b] = A[a, b] + trace * v[a] * v[b]
        D[a, a] += 1e-12 * trace + 1e-300
    if not cholesky_solve(D, gr, dx):
        return 0
    for a in range(n):
        x[a] += dx[a]
    _wrap(x, gi, centre)
    _residual(x, t, gi, gf, ws, r, J, True, pin_j, True)
    _weigh(roww, r, J, True)
    # r(x +- h v) into rt and Jt's first column
    for side in range(2):
        sg = FOLD_STEP if side == 0 else -FOLD_STEP
        for a in range(n):
            dx[a] = x[a] + sg * v[a]
        _wrap(dx, gi, centre)
        _residual(dx, t, gi, gf, ws, rt, Jt, False, pin_j, True)
        _weigh(roww, rt, Jt, False)
        if side == 0:
            for i in range(m):
                Jt[i, 0] = rt[i]
    c0, b1, a2 = 0.0, 0.0, 0.0
    for i in range(m):
        jv = 0.0
        for a in range(n):
            jv += J[i, a] * v[a]
        c0 += r[i] * r[i]
        b1 += r[i] * jv
        a2 += r[i] * (Jt[i, 0] + rt[i] - 2.0 * r[i]) / (FOLD_STEP * FOLD_STEP)
    disc = b1 * b1 - 2.0 * a2 * c0
    if a2 == 0.0 or not disc >= 0.0:
        return 1
    root = math.sqrt(disc)
    s12[0] = (-b1 + root) / a2
    s12[1] = (-b1 - root) / a2
    return 2


# lm_kernel calls `_lm_row` compiled on its own rather than inlined: inlining it into both parallel
# kernels doubled the solver's first compilation (lm_kernel ~110 of ~280 s under load, ~40 s this
# way) for no measurable gain in lm_kernel's callers (Gepetto's five-bar workspace: the same CPU
# time, 1 thread); block_kernel, the hot path, keeps it inlined (not inlining it there cost 20 %).
_lm_row_called = njit(cache=True)(_lm_row.py_func)


@njit(cache=True, parallel=True)
def lm_kernel(targets, x0, gi, gf, m, nzc, nzn, centre, free, roww, iters, tol, x_out, res_out, it_out, pinned):  # pragma: no cover - compiled
    """`_lm_row` from every row's start x0 towards its target."""
    nrows = targets.shape[0]
    n = gi[0]
    BLK = 16
    for blk in prange((nrows + BLK - 1) // BLK):
        ws, r, rt, J, Jt, A, D, gr, dx, xt = scratch(gi, m)
        x = np.empty(n)
        for row in range(blk * BLK, min(nrows, (blk + 1) * BLK)):
            for j in range(n):
                x[j] = x0[row, j]
            res, it = _lm_row_called(targets[row], x, gi, gf, m, nzc, nzn, centre, free, roww, iters, tol, pinned, ws, r,
                                     rt, J, Jt, A, D, gr, dx, xt, 3, True, False)
            for j in range(n):
                x_out[row, j] = x[j]
            res_out[row] = res
            it_out[row] = it


@njit(cache=True)
def _det_sign(J, rows, cols, nc, M):  # pragma: no cover - compiled
    """Sign of det J[rows][:, cols] (nc x nc, Gaussian elimination with partial pivoting); 0 if singular."""
    for a in range(nc):
        for b in range(nc):
            M[a, b] = J[rows[a], cols[b]]
    sign = 1
    for c in range(nc):
        p, best = c, abs(M[c, c])
        for a in range(c + 1, nc):
            if abs(M[a, c]) > best:
                p, best = a, abs(M[a, c])
        if best == 0.0:
            return 0
        if p != c:
            sign = -sign
            for b in range(nc):
                M[c, b], M[p, b] = M[p, b], M[c, b]
        if M[c, c] < 0.0:
            sign = -sign
        for a in range(c + 1, nc):
            f = M[a, c] / M[c, c]
            for b in range(c + 1, nc):
                M[a, b] -= f * M[c, b]
    return sign


@njit(cache=True, inline="always")
def _flip(x, flips, nflip, k):  # pragma: no cover - compiled
    """Block k's flippable groups to their middle angle's cos >= 0 (`LoopBatch.canonical`)."""
    for q in range(nflip[k]):
        a, b, c3 = flips[k, q, 0], flips[k, q, 1], flips[k, q, 2]
        if math.cos(x[b]) < 0.0:
            x[a] += math.pi
            x[b] = math.pi - x[b]
            if c3 >= 0:
                x[c3] += math.pi


@njit(cache=True, parallel=True)
def block_kernel(k, targets, gi, gf, m, nzc, nzn, centre, free, weights, T, nslot, bslot, atlas, warm, source, lo, hi, alpha,
                  restarts, near, alive, found, dist, res, end, counts):  # pragma: no cover - compiled
    """Block k of the block solver (`LoopBatch._solve_slots`) at every target row.

    Each slot still needed by a live branch gets one start: its warm start, else its atlas start;
    a warm start that failed less than `near` [m] from closure gets the atlas start too; then,
    where another slot of the block's same assembly (its locked joints' half-turn bits) was found,
    `restarts` quasi-random starts for each slot still missing (`restart_base`: a function of the
    target), the locked joints held at the slot's atlas angles, and up to RESTART_ROUNDS x
    `restarts` where a start aimed at the slot closed on a root of the other sign in its
    assembly. A start's held joints come from the earlier blocks' solutions of its slot's
    branch choice; its root (if any) goes to the slot of its label (its determinant's sign and its
    locked joints' half-turn bits), the one nearest the reference kept. A branch dies (`alive`) with the first block slot it needs that is not found.
    (One call site per solver step: every compiled call binds its array arguments with reference
    counting, which at this size costs as much as the kinematics.)"""
    N = targets.shape[0]
    B = bslot.shape[0]
    n = gi[0]
    (pinned, ncol, cols, rows_det, label, middles, nmid, flips, nflip, held, nheld, held_owner, held_pos, held_slot,
     land, ref, act, held_by_others, lock_idx, lock_ref, nlock, slot_lock) = T
    nc = ncol[k]
    # a block whose values later blocks hold is solved past TOL (Newton's last step squares the
    # error): a held value within TOL of its root can leave an over-determined block (a second
    # rod) unable to close to TOL itself
    tol = TOL * 1e-2 if held_by_others[k] else TOL
    S = nslot[k]
    oK = gi[7]
    BLK = 16
    for chunk in prange((N + BLK - 1) // BLK):
        ws, r, rt, J, Jt, A, D, gr, dx, xt = scratch(gi, m)
        x = np.empty(n)
        t = np.empty(targets.shape[1])
        M = np.empty((nc, nc))
        need = np.empty(S, dtype=np.bool_)
        again = np.empty(S, dtype=np.bool_)  # the slot gets restarts
        sibling = np.empty(S, dtype=np.bool_)  # a start aimed at the slot closed on another slot's root
        fold = np.zeros(S, dtype=np.int64)  # `fold_roots`'s verdict per slot (0: none)
        fold_x = np.empty((S, n))  # the stalled point
        fold_v = np.empty((S, n))  # its fold direction
        fold_s = np.empty((S, 2))  # the predicted roots along it
        s12 = np.empty(2)
        held_locks = free.copy()  # restarts hold the locked joints at their slot's angles
        for q in range(nlock[k]):
            held_locks[lock_idx[k, q]] = False
        for i in range(chunk * BLK, min(N, (chunk + 1) * BLK)):
            for a in range(t.shape[0]):
                t[a] = targets[i, a]
            for s in range(S):
                need[s] = False
            for b in range(B):
                if alive[i, b]:
                    need[bslot[b, k]] = True
            per_slot = RESTART_ROUNDS * restarts
            idx0 = restart_base(t, k, nslot.shape[0], S, per_slot)
            for s in range(S):
                sibling[s] = False
            for attempt in range(S * (4 + per_slot)):
                if S <= attempt < 2 * S:
                    # a warm start that stalled within `near` of closure gets its slot's atlas
                    # start too: the neighbour's end can lie across a fold (the neighbour outside,
                    # a limb stretched) or in the other root's basin
                    s = attempt - S
                    if not need[s] or found[i, k, s] or not np.isfinite(warm[i, k, s, 0]) or not res[i, k, s] < near:
                        continue
                if attempt == 2 * S:
                    # restarts only where the block has some root, or where the blocks it builds on
                    # closed (a target a limb cannot reach would otherwise cost restarts) and a
                    # missing slot has no neighbour's verdict that it is absent: its start came from
                    # no neighbour, or from one where the slot was found (the last entry of a warm
                    # start: 1 found there, 0 tried and not found, NaN not tried). A closure that
                    # cannot close where a neighbour within the continuation radius could not either
                    # (the five-bar's second chain outside its reach) is not restarted: a region
                    # entered from outside is found from the neighbour's least-squares end (at the
                    # fold) or the atlas start. A block that holds no earlier joints (the iso
                    # five-bars' single block) also restarts where a neighbour found a missing slot
                    # or a start stalled within near / 10 of closure: next to a fold of the reach
                    # the neighbour's end and the atlas start can both stall there (0.2 % of the
                    # iso five-bar's inside points were missed, the column integration refining
                    # around each), while random starts close in about half the tries.
                    # All of this per assembly (the slots of one locked-joint code; one group
                    # where the block has no locked joints): a root in one plane of the iso
                    # five-bars says nothing about the other plane, whose region differs
                    some = False
                    for g in range(S):
                        again[g] = False
                    for g in range(S):
                        grp = False
                        for q in range(S):
                            if slot_lock[k, q] != slot_lock[k, g]:
                                continue
                            grp = grp or found[i, k, q]
                            verdict = warm[i, k, q, warm.shape[3] - 1]
                            if not need[q] or found[i, k, q]:
                                continue
                            if nheld[k] > 0:
                                grp = grp or verdict != 0.0  # NaN (not tried there) restarts too
                            else:
                                grp = grp or verdict == 1.0 or res[i, k, q] < 0.1 * near
                        again[g] = grp
                        some = some or (grp and need[g] and not found[i, k, g])
                    if not some:
                        break
                    # a missing slot whose best start stalled next to closure while no slot of its
                    # assembly closed: the fold model at the stalled point (`fold_roots`) gives two
                    # starts where it predicts roots, and, where it predicts none and the start
                    # stalled within near / 10, replaces the quasi-random restarts (on the iso
                    # five-bars 99.8 % of these restarts found nothing: the target was outside)
                    for g in range(S):
                        fold[g] = 0
                        if not (again[g] and need[g] and not found[i, k, g] and res[i, k, g] < near):
                            continue
                        grp = False
                        for q in range(S):
                            grp = grp or (slot_lock[k, q] == slot_lock[k, g] and found[i, k, q])
                        if grp:
                            continue
                        usable = True
                        for j in range(n):
                            fold_x[g, j] = 0.0
                        for c in range(nc):
                            fold_x[g, cols[k, c]] = end[i, k, g, c]
                        for h in range(nheld[k]):
                            o, so = held_owner[k, h], held_slot[k, g, h]
                            fold_x[g, held[k, h]] = end[i, o, so, held_pos[k, h]]
                            usable = usable and found[i, o, so]
                        if not usable:
                            continue
                        fold[g] = fold_roots(t, fold_x[g], gi, gf, m, centre, free, weights, pinned[k], ws, r, rt, J, Jt,
                                              A, D, gr, dx, fold_v[g], s12)
                        fold_s[g, 0], fold_s[g, 1] = s12[0], s12[1]
                        if fold[g] == 1 and res[i, k, g] < 0.1 * near and source[i] <= FOLD_SOURCE * near:
                            again[g] = False
                if 2 * S <= attempt < 4 * S:
                    s = (attempt - 2 * S) // 2
                    if fold[s] != 2 or not need[s] or found[i, k, s]:
                        continue
                if attempt < 2 * S:
                    s = attempt % S
                elif attempt >= 4 * S:
                    s = (attempt - 4 * S) // per_slot
                if not need[s] or found[i, k, s] or (attempt >= 4 * S and not again[s]):
                    continue
                if attempt >= 4 * S and (attempt - 4 * S) % per_slot >= restarts and not sibling[s]:
                    continue  # the later rounds only where the slot's basin was missed, not absent
                # the start: the block's unknowns, then the held joints of this slot's branch choice
                for j in range(n):
                    x[j] = 0.0
                iters = 20
                settle = 3
                if 2 * S <= attempt < 4 * S:
                    # the fold's predicted root (held joints as at the stalled point)
                    for j in range(n):
                        x[j] = fold_x[s, j] + fold_s[s, (attempt - 2 * S) % 2] * fold_v[s, j]
                elif attempt < 2 * S:
                    cold = attempt >= S or not np.isfinite(warm[i, k, s, 0])
                    iters = 40 if cold else 20
                    # from a neighbour's end Newton converges at once or the start is stalling
                    settle = 3 if cold else 2
                    for c in range(nc):
                        x[cols[k, c]] = atlas[k, s, c] if cold else warm[i, k, s, c]
                else:
                    q = idx0 + attempt - 4 * S + 1
                    for c in range(nc):
                        x[cols[k, c]] = lo[k, c] + ((0.5 + q * alpha[k, c]) % 1.0) * (hi[k, c] - lo[k, c])
                    # a locked joint (`LoopStructure.locked_joints`) at its slot's assembly angle,
                    # held there: a restart seeks this slot's assembly only, in fewer unknowns
                    # (a random angle of it mostly led to the other assembly's roots, or to none)
                    for c in range(nc):
                        for q2 in range(nlock[k]):
                            if cols[k, c] == lock_idx[k, q2]:
                                x[cols[k, c]] = atlas[k, s, c]
                usable = True
                for h in range(nheld[k]):
                    o, so = held_owner[k, h], held_slot[k, s, h]
                    x[held[k, h]] = end[i, o, so, held_pos[k, h]]
                    usable = usable and found[i, o, so]
                if not usable:  # an earlier block of this branch choice has no root here
                    continue
                # a labelling block's root is labelled by the sign of its Jacobian's determinant there;
                # a slot's first start descends (Nielsen); the atlas retry (a target next to a fold,
                # its roots nearly double) and the restarts (exploration) keep lam / 10 per step,
                # whose long Gauss-Newton steps close near-double roots and reach more basins
                rr, _ = _lm_row(t, x, gi, gf, m, nzc, nzn, centre, held_locks if attempt >= 4 * S else free, weights,
                                iters, tol, pinned[k], ws, r, rt, J, Jt, A, D, gr, dx, xt, settle, label[k] >= 0,
                                attempt < S)
                if rr < res[i, k, s]:
                    res[i, k, s] = rr
                    for c in range(nc):
                        end[i, k, s, c] = x[cols[k, c]]
                if not rr <= TOL:
                    continue
                s2 = s
                if label[k] >= 0:
                    sg = _det_sign(J, rows_det[k], cols[k], nc, M)
                    for q in range(nmid[k]):
                        if math.cos(x[middles[k, q]]) < 0.0:
                            sg = -sg
                    # the locked joints' bits in the pose's one representation (a spherical
                    # joint's triple can hold a locked joint half a turn off: the same pose)
                    _flip(x, flips, nflip, k)
                    code = 0
                    for q in range(nlock[k]):
                        if math.cos(x[lock_idx[k, q]] - lock_ref[k, q]) < 0.0:
                            code += 1 << q
                    s2 = land[k, s, sg + 1, code]
                if s2 < 0:
                    counts[i, 0] += 1
                    continue
                if s2 != s and slot_lock[k, s2] == slot_lock[k, s]:
                    # a root of the other sign in the slot's assembly: the slot's roots exist too,
                    # in general (revolute unknowns map a torus, a map of degree 0: at a regular
                    # target as many roots of each sign)
                    sibling[s] = True
                _flip(x, flips, nflip, k)  # one representation per pose (`LoopBatch.canonical`)
                _wrap(x, gi, centre)
                d = 0.0
                for c in range(nc):
                    e = x[cols[k, c]] - ref[k, c]
                    if gi[oK + cols[k, c]] == REVOLUTE:
                        e = (e + math.pi) % (2 * math.pi) - math.pi
                    d += e * e
                if found[i, k, s2]:
                    for c in range(nc):
                        if act[k, c] and abs(x[cols[k, c]] - end[i, k, s2, c]) > 1e-9:
                            counts[i, 1] += 1
                            break
                    if d >= dist[i, k, s2]:
                        continue
                found[i, k, s2] = True
                dist[i, k, s2] = d
                res[i, k, s2] = 0.0
                for c in range(nc):
                    end[i, k, s2, c] = x[cols[k, c]]
            for b in range(B):
                if not found[i, k, bslot[b, k]]:
                    alive[i, b] = False


@njit(cache=True)
def eval_kernel(targets, x, gi, gf, r_out, J_out, pos_out):  # pragma: no cover - compiled
    """Residuals, Jacobians and joint-origin positions at rows of joint values."""
    n, nf = gi[0], gi[1]
    ws = np.empty(_ws_size(gi))
    WP, WFP = 9 * n, 12 * n + 9 * nf
    for row in range(x.shape[0]):  # serial: cheap next to the solves, and compiles faster
        _residual(x[row], targets[row], gi, gf, ws, r_out[row], J_out[row], True, -1, True)
        for j in range(n):
            for a in range(3):
                pos_out[row, j, a] = ws[WP + 3 * j + a]
        for f in range(nf):
            for a in range(3):
                pos_out[row, n + f, a] = ws[WFP + 3 * f + a]
