"""Compiled reachability search for a serial chain: the smallest distance from target points to
the image of the joint box, by bounded Levenberg-Marquardt from several seeds.

Per target t the search minimises c(q) = |t - f(q)|^2 / 2 over the box lo <= q <= hi (f the
frame's position; joints with an infinite range are unbounded). One step on the free joints F
(those not held at a bound by the gradient g = J^T (t - f), i.e. not at lo with g < 0 or at hi
with g > 0):

    (J_F^T J_F + lambda (1 + diag J_F^T J_F)) d = J_F^T (t - f),   q <- clip(q + d, lo, hi),

accepted when c decreases (then lambda / 3), otherwise lambda x 8 (Marquardt's scaled damping).
A run stops when |t - f| <= `tol` (the target is reached), when no damping decreases c, when a
step's decrease of the distance is below 5 % of its excess over tol, or after `iters` steps.
A target whose first two descents end farther than `far` from it is not searched further (the
other seeds are for targets near the boundary, where the sign is at stake). Seeds are tried in order and the search for a target
stops at its first reached seed; an unreached target keeps the smallest distance over all seeds.

A fixed tool orientation adds residual rows: for each tool vector v_a (the frame's z axis for a
tool axis; its x and z axes for a whole rotation), s (d_a - R(q) v_a), d_a its world direction
and s a length [m] that weighs radians against metres; the cost is the squared norm of the whole
residual and a target is reached when that norm is <= tol (position and direction both matched).
`reach_all` descends every seed to its end (the dexterity's configurations; with the position's
weight 0, the projection of samples onto the orientation).

The kernel takes targets in chunks of consecutive rows (a column of the volume engine is one
run of rows): the first seed of each target after the chunk's first is the previous target's
solution (a warm start), so along a column most targets are reached in a few steps.

The forward kinematics is the batched kernel's composition (`kinematics.generic.batched`) per
configuration: p += R t_k, R <- R M_k, then the joint's motion (Rodrigues about its axis, or a
translation along it); the position Jacobian's column k is w_k x (p - p_k) (revolute) or w_k.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from kinematics.generic.dense import cholesky_solve

CHUNK = 32
"""Consecutive targets searched by one work item (warm starts run along it)."""


@njit(cache=True)
def _fk(q, kind, axis, rot, tra, fp, R, T, W, P, x, J):  # pragma: no cover - compiled
    """Frame position into x (3,) at chain values q (n,) and its position Jacobian into J (3, n);
    R, T (3, 3), W, P (n, 3) are scratch (no allocation: this runs inside the search's loops)."""
    n = kind.shape[0]
    for i in range(3):
        x[i] = 0.0
        for j in range(3):
            R[i, j] = 1.0 if i == j else 0.0
    for k in range(n):
        for i in range(3):
            x[i] += R[i, 0] * tra[k, 0] + R[i, 1] * tra[k, 1] + R[i, 2] * tra[k, 2]
        for i in range(3):
            for j in range(3):
                T[i, j] = R[i, 0] * rot[k, 0, j] + R[i, 1] * rot[k, 1, j] + R[i, 2] * rot[k, 2, j]
        a0, a1, a2 = axis[k, 0], axis[k, 1], axis[k, 2]
        for i in range(3):
            W[k, i] = T[i, 0] * a0 + T[i, 1] * a1 + T[i, 2] * a2
            P[k, i] = x[i]
        if kind[k] == 2:
            for i in range(3):
                x[i] += q[k] * W[k, i]
                for j in range(3):
                    R[i, j] = T[i, j]
        else:
            c, s = math.cos(q[k]), math.sin(q[k])
            d = 1.0 - c
            e00, e01, e02 = c + d * a0 * a0, d * a0 * a1 - s * a2, d * a0 * a2 + s * a1
            e10, e11, e12 = d * a1 * a0 + s * a2, c + d * a1 * a1, d * a1 * a2 - s * a0
            e20, e21, e22 = d * a2 * a0 - s * a1, d * a2 * a1 + s * a0, c + d * a2 * a2
            for i in range(3):
                t0, t1, t2 = T[i, 0], T[i, 1], T[i, 2]
                R[i, 0] = t0 * e00 + t1 * e10 + t2 * e20
                R[i, 1] = t0 * e01 + t1 * e11 + t2 * e21
                R[i, 2] = t0 * e02 + t1 * e12 + t2 * e22
    f0, f1, f2 = fp[0], fp[1], fp[2]
    for i in range(3):
        x[i] += R[i, 0] * f0 + R[i, 1] * f1 + R[i, 2] * f2
    for k in range(n):
        if kind[k] == 2:
            for i in range(3):
                J[i, k] = W[k, i]
        else:
            dx, dy, dz = x[0] - P[k, 0], x[1] - P[k, 1], x[2] - P[k, 2]
            J[0, k] = W[k, 1] * dz - W[k, 2] * dy
            J[1, k] = W[k, 2] * dx - W[k, 0] * dz
            J[2, k] = W[k, 0] * dy - W[k, 1] * dx


@njit(cache=True, parallel=True)
def chain_fk_many(Q, kind, axis, rot, tra, fp):  # pragma: no cover - compiled
    """(N, 3) frame positions at chain values Q (N, n)."""
    N, n = Q.shape
    out = np.empty((N, 3))
    for b in prange((N + 255) // 256):
        R, T = np.empty((3, 3)), np.empty((3, 3))
        W, P, J = np.empty((n, 3)), np.empty((n, 3)), np.empty((3, n))
        for i in range(b * 256, min(N, (b + 1) * 256)):
            _fk(Q[i], kind, axis, rot, tra, fp, R, T, W, P, out[i], J)
    return out


@njit(cache=True)
def _boxed_step(A, g, free, lam, q, lo, hi, M, d, qn):  # pragma: no cover - compiled
    """The damped step of the box-constrained Gauss-Newton descent: (A + lam diag(1 + A_kk)) d = g
    over the free joints (a joint at a bound pushed outwards is held: its row is the identity and
    g_k = 0), then qn = q + d clipped into [lo, hi]. False where the damped matrix is not positive
    definite to working precision (the caller damps more)."""
    n = q.shape[0]
    for k in range(n):
        for j in range(n):
            M[k, j] = A[k, j]
        M[k, k] += lam * (1.0 + A[k, k]) if free[k] else 1.0
    if not cholesky_solve(M, g, d):
        return False
    for k in range(n):
        qn[k] = min(max(q[k] + d[k], lo[k]), hi[k])
    return True


@njit(cache=True)
def _residual(t, q, kind, axis, rot, tra, fp, vec, dirs, scale, wp, S, r, F):  # pragma: no cover - compiled
    """Residual r (3 + 3m,) and its Jacobian F (3 + 3m, n) at q; returns c = |r|^2. Rows 0-2:
    wp (t - f(q)); rows 3a .. 3a + 2 for each tool vector a: scale (dirs_a - R(q) vec_a), whose
    derivative along revolute joint k is -scale w_k x (R vec_a) (a prismatic joint turns nothing)."""
    R, T, W, P, x = S[0], S[1], S[2], S[3], S[4]
    n = q.shape[0]
    _fk(q, kind, axis, rot, tra, fp, R, T, W, P, x, F[:3])  # the position rows in place
    c = 0.0
    for i in range(3):
        r[i] = wp * (t[i] - x[i])
        c += r[i] * r[i]
        if wp != 1.0:
            for k in range(n):
                F[i, k] *= wp
    for a in range(vec.shape[0]):
        u0 = R[0, 0] * vec[a, 0] + R[0, 1] * vec[a, 1] + R[0, 2] * vec[a, 2]
        u1 = R[1, 0] * vec[a, 0] + R[1, 1] * vec[a, 1] + R[1, 2] * vec[a, 2]
        u2 = R[2, 0] * vec[a, 0] + R[2, 1] * vec[a, 1] + R[2, 2] * vec[a, 2]
        b = 3 + 3 * a
        r[b] = scale * (dirs[a, 0] - u0)
        r[b + 1] = scale * (dirs[a, 1] - u1)
        r[b + 2] = scale * (dirs[a, 2] - u2)
        c += r[b] * r[b] + r[b + 1] * r[b + 1] + r[b + 2] * r[b + 2]
        for k in range(n):
            if kind[k] == 2:
                F[b, k] = F[b + 1, k] = F[b + 2, k] = 0.0
            else:
                F[b, k] = scale * (W[k, 1] * u2 - W[k, 2] * u1)
                F[b + 1, k] = scale * (W[k, 2] * u0 - W[k, 0] * u2)
                F[b + 2, k] = scale * (W[k, 0] * u1 - W[k, 1] * u0)
    return c


@njit(cache=True)
def scratch(n, m):  # pragma: no cover - compiled
    """The work arrays of `_descend` for n chain joints and m tool vectors."""
    rows = 3 + 3 * m
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(3),
            np.empty((3, n)), np.empty(rows), np.empty((rows, n)), np.empty(rows), np.empty((rows, n)),
            np.empty(n), np.empty(n), np.empty((n, n)), np.empty((n, n)), np.empty(n), np.empty(n, np.bool_))


@njit(cache=True)
def _descend(t, q, lo, hi, kind, axis, rot, tra, fp, vec, dirs, scale, wp, tol, iters, S):  # pragma: no cover - compiled
    """Bounded LM from q (modified in place) towards target t and the tool vectors' directions:
    returns the distance |r| (the residual of `_residual`). S: `scratch`."""
    r, F, rn, Fn, qn, g, A, M, d, free = S[6], S[7], S[8], S[9], S[10], S[11], S[12], S[13], S[14], S[15]
    n = q.shape[0]
    c = _residual(t, q, kind, axis, rot, tra, fp, vec, dirs, scale, wp, S, r, F)
    rows = r.shape[0]
    lam = 1e-3
    for _ in range(iters):
        if c <= tol * tol:
            break
        for k in range(n):
            v = r[0] * F[0, k] + r[1] * F[1, k] + r[2] * F[2, k]  # (the position rows unrolled: the common case)
            for i in range(3, rows):
                v += r[i] * F[i, k]
            g[k] = v
            free[k] = not ((q[k] <= lo[k] and g[k] < 0.0) or (q[k] >= hi[k] and g[k] > 0.0))
        for k in range(n):
            for j in range(n):
                v = 0.0
                if free[k] and free[j]:
                    v = F[0, k] * F[0, j] + F[1, k] * F[1, j] + F[2, k] * F[2, j]
                    for i in range(3, rows):
                        v += F[i, k] * F[i, j]
                A[k, j] = v
            if not free[k]:
                g[k] = 0.0
        accepted = False
        cn = c
        while lam < 1e10:
            if not _boxed_step(A, g, free, lam, q, lo, hi, M, d, qn):
                lam *= 8.0
                continue
            cn = _residual(t, qn, kind, axis, rot, tra, fp, vec, dirs, scale, wp, S, rn, Fn)
            if cn < c:
                accepted = True
                break
            lam *= 8.0
        if not accepted:
            break
        # a reached target stops at tol; an unreached one once the step's decrease is below 5 % of
        # what separates it from tol: with linear convergence at a rate below 0.95 the rest of the
        # descent cannot bring it within tol (its sign is settled)
        dc, dn = math.sqrt(c), math.sqrt(cn)
        q[:] = qn
        r[:] = rn
        F[:, :] = Fn
        c = cn
        lam = max(lam / 3.0, 1e-9)
        if dn > tol and dc - dn <= 0.05 * (dn - tol):
            break
    return math.sqrt(c)


@njit(cache=True)
def _descend_position(t, q, lo, hi, kind, axis, rot, tra, fp, tol, iters, S):  # pragma: no cover - compiled
    """`_descend` for a position alone (no tool vectors, weight 1), the margin's hot loop, written for
    three residual rows (20 % faster than the general one). S: the scratch tuple of `search`."""
    R, T, W, P, x, J, xn, Jn, qn, g, A, M, d, free, G = S
    n = q.shape[0]
    _fk(q, kind, axis, rot, tra, fp, R, T, W, P, x, J)
    c = 0.0
    for i in range(3):
        c += (t[i] - x[i]) ** 2
    lam = 1e-3
    for _ in range(iters):
        if c <= tol * tol:
            break
        for k in range(n):
            g[k] = (t[0] - x[0]) * J[0, k] + (t[1] - x[1]) * J[1, k] + (t[2] - x[2]) * J[2, k]
            free[k] = not ((q[k] <= lo[k] and g[k] < 0.0) or (q[k] >= hi[k] and g[k] > 0.0))
        for k in range(n):
            for j in range(n):
                A[k, j] = J[0, k] * J[0, j] + J[1, k] * J[1, j] + J[2, k] * J[2, j] if free[k] and free[j] else 0.0
            if not free[k]:
                g[k] = 0.0
        accepted = False
        while lam < 1e10:
            if not _boxed_step(A, g, free, lam, q, lo, hi, M, d, qn):
                lam *= 8.0
                continue
            _fk(qn, kind, axis, rot, tra, fp, R, T, W, P, xn, Jn)
            cn = 0.0
            for i in range(3):
                cn += (t[i] - xn[i]) ** 2
            if cn < c:
                accepted = True
                break
            lam *= 8.0
        if not accepted:
            break
        # a reached target stops at tol; an unreached one once the step's decrease is below 5 % of
        # what separates it from tol: with linear convergence at a rate below 0.95 the rest of the
        # descent cannot bring it within tol (its sign is settled)
        dc, dn = math.sqrt(c), math.sqrt(cn)
        q[:] = qn
        x[:] = xn
        J[:, :] = Jn
        c = cn
        lam = max(lam / 3.0, 1e-9)
        if dn > tol and dc - dn <= 0.05 * (dn - tol):
            break
    dist = math.sqrt(c)
    if dist > tol:
        return dist, 0.0
    # reached: sigma_min(J) (the smallest eigenvalue of the Gram matrix of size min(3, n)) times
    # the smallest slack, a positive local size of the reachable neighbourhood
    m = min(3, n)
    for i in range(m):
        for j in range(m):
            v = 0.0
            if n >= 3:
                for k in range(n):
                    v += J[i, k] * J[j, k]
            else:
                for k in range(3):
                    v += J[k, i] * J[k, j]
            G[i, j] = v
    smin = math.sqrt(max(np.linalg.eigvalsh(np.ascontiguousarray(G[:m, :m]))[0], 0.0))
    slack = 1.0
    for k in range(n):
        if lo[k] > -np.inf:
            slack = min(slack, q[k] - lo[k], hi[k] - q[k])
    return dist, smin * slack


@njit(cache=True, parallel=True)
def search(targets, seeds, lo, hi, kind, axis, rot, tra, fp, vec, dirs, scale, tol, iters, chunk, far):  # pragma: no cover - compiled
    """Per target (N, 3) from seeds (N, K, n): margin (N,) = tol - distance + room (> 0 iff
    reached within tol; room 0 with tool vectors (m, 3), m > 0) and the best configuration (N, n).
    A target still farther than `far` [m] after two seeds (the warm start and the nearest sample's)
    is left there: far from W. A position alone runs `_descend_position`, tool vectors `_descend`."""
    N, K, n = seeds.shape
    margin = np.empty(N)
    best = np.empty((N, n))
    for blk in prange((N + chunk - 1) // chunk):
        S = scratch(n, vec.shape[0])
        S3 = (np.empty((3, 3)), np.empty((3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(3),
              np.empty((3, n)), np.empty(3), np.empty((3, n)), np.empty(n), np.empty(n), np.empty((n, n)),
              np.empty((n, n)), np.empty(n), np.empty(n, np.bool_), np.empty((3, 3)))
        q = np.empty(n)
        for i in range(blk * chunk, min(N, (blk + 1) * chunk)):
            dmin = np.inf
            inner = 0.0
            for s in range(-1, K):
                if s < 0:
                    if i == blk * chunk:
                        continue
                    q[:] = best[i - 1]
                else:
                    q[:] = seeds[i, s]
                if vec.shape[0] == 0:
                    d, e = _descend_position(targets[i], q, lo, hi, kind, axis, rot, tra, fp, tol, iters, S3)
                else:
                    d = _descend(targets[i], q, lo, hi, kind, axis, rot, tra, fp, vec, dirs, scale, 1.0, tol, iters, S)
                    e = 0.0
                if d < dmin:
                    dmin = d
                    inner = e
                    best[i] = q
                if d <= tol or (s >= 1 and dmin > far):
                    break
            margin[i] = tol - dmin + inner
    return margin, best


@njit(cache=True, parallel=True)
def reach_all(targets, seeds, lo, hi, kind, axis, rot, tra, fp, vec, dirs, scale, wp, tol, iters):  # pragma: no cover - compiled
    """Every seed descended on its own (no warm start, no early stop): the configurations (N, K, n)
    and whether each reached its target within tol (N, K). With wp = 0 the position is free and only
    the tool vectors are matched (the orientation mode's projection of samples)."""
    N, K, n = seeds.shape
    out = np.empty((N, K, n))
    ok = np.zeros((N, K), np.bool_)
    for blk in prange((N + CHUNK - 1) // CHUNK):
        S = scratch(n, vec.shape[0])
        for i in range(blk * CHUNK, min(N, (blk + 1) * CHUNK)):
            for s in range(K):
                out[i, s] = seeds[i, s]
                d = _descend(targets[i], out[i, s], lo, hi, kind, axis, rot, tra, fp, vec, dirs, scale, wp, tol, iters,
                             S)
                ok[i, s] = d <= tol
    return out, ok


@njit(cache=True, parallel=True)
def chain_jacobian_many(Q, kind, axis, rot, tra, fp):  # pragma: no cover - compiled
    """(N, 3, n) position Jacobians of the frame at chain values Q (N, n)."""
    N, n = Q.shape
    out = np.empty((N, 3, n))
    for b in prange((N + 255) // 256):
        R, T = np.empty((3, 3)), np.empty((3, 3))
        W, P, x = np.empty((n, 3)), np.empty((n, 3)), np.empty(3)
        for i in range(b * 256, min(N, (b + 1) * 256)):
            _fk(Q[i], kind, axis, rot, tra, fp, R, T, W, P, x, out[i])
    return out


@njit(cache=True, parallel=True)
def chain_task_jacobian_many(Q, kind, axis, rot, tra, fp, vec):  # pragma: no cover - compiled
    """(N, 3 + 3m, n) at chain values Q (N, n): the frame position's Jacobian, then for each tool
    vector v_a (m, 3) the derivative of its world direction R(q) v_a (w_k x R v_a for revolute k)."""
    N, n = Q.shape
    m = vec.shape[0]
    out = np.empty((N, 3 + 3 * m, n))
    for b in prange((N + 255) // 256):
        S = scratch(n, m)
        t, dirs, r = np.zeros(3), np.zeros((m, 3)), np.empty(3 + 3 * m)
        for i in range(b * 256, min(N, (b + 1) * 256)):
            _residual(t, Q[i], kind, axis, rot, tra, fp, vec, dirs, 1.0, 1.0, S, r, out[i])
    return out
