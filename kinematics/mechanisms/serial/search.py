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
def _cholesky_solve(A, b, out):  # pragma: no cover - compiled
    """Solve A out = b for a symmetric positive definite A (n, n), overwriting A with its factor."""
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        s = math.sqrt(max(s, 1e-300))
        A[j, j] = s
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= A[i, k] * A[j, k]
            A[i, j] = t / s
    for i in range(n):
        t = b[i]
        for k in range(i):
            t -= A[i, k] * out[k]
        out[i] = t / A[i, i]
    for i in range(n - 1, -1, -1):
        t = out[i]
        for k in range(i + 1, n):
            t -= A[k, i] * out[k]
        out[i] = t / A[i, i]


@njit(cache=True)
def _descend(t, q, lo, hi, kind, axis, rot, tra, fp, tol, iters, S):  # pragma: no cover - compiled
    """Bounded LM from q (modified in place) towards target t: returns (distance, room), room =
    sigma_min(J) x the smallest joint slack where reached (else 0). S: the scratch tuple."""
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
            for k in range(n):
                for j in range(n):
                    M[k, j] = A[k, j]
                M[k, k] += lam * (1.0 + A[k, k]) if free[k] else 1.0
            _cholesky_solve(M, g, d)
            for k in range(n):
                qn[k] = min(max(q[k] + d[k], lo[k]), hi[k])
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
def search(targets, seeds, lo, hi, kind, axis, rot, tra, fp, tol, iters, chunk, far):  # pragma: no cover - compiled
    """Per target (N, 3) from seeds (N, K, n): margin (N,) = tol - distance + room (> 0 iff
    reached within tol) and the best configuration (N, n). A target still farther than `far` [m]
    after two seeds (the warm start and the nearest sample's) is left there: far from W."""
    N, K, n = seeds.shape
    margin = np.empty(N)
    best = np.empty((N, n))
    for blk in prange((N + chunk - 1) // chunk):
        S = (np.empty((3, 3)), np.empty((3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(3),
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
                d, e = _descend(targets[i], q, lo, hi, kind, axis, rot, tra, fp, tol, iters, S)
                if d < dmin:
                    dmin = d
                    inner = e
                    best[i] = q
                if d <= tol or (s >= 1 and dmin > far):
                    break
            margin[i] = tol - dmin + inner
    return margin, best
