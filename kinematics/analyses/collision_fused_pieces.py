"""The 3-[P2(US)]'s collision-free pieces of close sub-intervals in one compiled pass per
sub-interval (`kinematics.analyses.collision_columns`, `FUSED`): the samples, their curvatures,
the gap tests and halvings, and each final gap's roots (a pair's own, the free end's check, the
smallest distance's where another pair takes over), on every core, with no (N, P) array of
samples between NumPy passes.

Each sub-interval does the batched path's operations (`CollisionColumns._checked_pieces`) in the
same order on the same values, so its pieces are the same to the last bit; only their order
differs (each sub-interval's gaps in z order, where the batched path keeps them by refinement
level), and the targets' unions sort them by column and start. A sub-interval where a pair needs
coal (a rod beside a plate), whose halvings outgrow the buffers, or whose pieces outgrow their
room, is flagged and the batched path takes it whole, so the evaluation counts are the batched
path's too."""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numba import njit, prange

from kinematics.analyses.collision_column_kernels import gap_may_hold_root
from kinematics.analyses.collision_fused import illinois_point, illinois_update, pair_root
from kinematics.generic.capsule_kernels import joint_pose, pair_value, place, scratch
from kinematics.generic.capsules import PLATE
from kinematics.jit import on_cores
from kinematics.mechanisms.p2us.configurations import configurations_kernel

EXTRA_ROWS = 512
"""Midpoint samples a sub-interval may add to its first ones before the batched path takes it."""

PARALLEL_SUBS = 64
"""Fewest sub-intervals for a launch on every core."""


@njit(cache=True, inline="always")
def _all_pairs(bx, by, z, others, ax, kd, cf, sc, pt, q, out, row):  # pragma: no cover - compiled
    """Every pair's closed form at the point z of the column (bx, by) into out[row] (+inf where
    the point has no configuration), as `collision_fused.distances_kernel`; True where a pair
    needs coal (sc: `scratch`'s arrays; pt (1, 3), q (1, nq) work arrays)."""
    Rm, pj, centre, gaxis, o, good = sc
    e, w, t, geometry, roots, code, limb = kd
    parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, radius, half, pairs, kinds = cf
    pt[0, others[0]], pt[0, others[1]], pt[0, ax] = bx, by, z
    configurations_kernel(pt, e, w, t, geometry, roots, code, limb, q)
    if not np.isfinite(q[0]).all():
        for k in range(pairs.shape[0]):
            out[row, k] = math.inf
        return False
    for j in range(parent.shape[0]):
        joint_pose(q, 0, j, parent[j], kind[j], axis, iq[j], rot, tra, Rm, pj)
    for m in range(used.shape[0]):
        place(0, used[m], of_geometry[m], Rm, pj, local_p, local_axis, centre, gaxis)
    need = False
    for k in range(pairs.shape[0]):
        pair_value(0, k, centre, gaxis, radius, half, pairs, kinds, o, good)
        out[row, k] = o[0, k]
        if not (good[0, k] or (kinds[k] == PLATE and o[0, k] > 0.0)):
            need = True
    return need


_all_pairs_apart = njit(cache=True, error_model="numpy")(_all_pairs.py_func)
"""`_all_pairs` compiled on its own, for the rarer full evaluations (a root's free end, the
smallest distance's steps): each inlined copy of the closed forms in the parallel kernel costs
compile time, and a call outside it about twice the time of an inlined one."""


@njit(cache=True, inline="always")
def _row_min(d, row):  # pragma: no cover - compiled
    """NumPy's min (initial +inf) and argmin of d[row]: a NaN wins, at its first place."""
    m, arg = math.inf, 0
    for p in range(d.shape[1]):
        x = d[row, p]
        if math.isnan(x):
            return x, p
        if x < m:
            m, arg = x, p
    if m == math.inf:  # argmin of a row of +inf: its first place
        arg = 0
    return m, arg


@njit(cache=True, error_model="numpy")
def _smallest_root(bx, by, others, ax, a, c, ya, yc, pair, root_tol, steps, kd, cf, sc, pt, q, row
                   ):  # pragma: no cover - compiled
    """`collision_fused.illinois` on the smallest distance over every pair (`CollisionColumns.
    _smallest_roots`, function 0), the binding pair taken where it is negative: root, pair,
    evaluations, failed (row: a (1, P) buffer)."""
    side, n = 0, 0
    for step in range(steps):
        if not c - a > root_tol:
            break
        x = illinois_point(a, c, ya, yc, step, root_tol)
        n += 1
        if _all_pairs_apart(bx, by, x, others, ax, kd, cf, sc, pt, q, row, 0):
            return 0.0, pair, n, True
        y, arg = _row_min(row, 0)
        if y < 0.0:
            pair = arg
        a, c, ya, yc, side = illinois_update(a, c, ya, yc, side, x, y)
    return 0.5 * (a + c), pair, n, False


@njit(cache=True, inline="always")
def _gap_pieces(bx, by, others, ax, za, zb, D, ia, ib, watched, root_tol, steps, kd, cf, pk, sc, work, outs, slot
                ):  # pragma: no cover - compiled
    """A final gap's free piece per function (`CollisionColumns._pieces` and `_roots` on one gap)
    into slot of outs' oa, oe, oca, oce (F, room): evaluations, failed (work: `pieces_kernel`'s
    arrays). Calls take fewer than 30 arguments: more compile to *args, which Numba cannot inline."""
    pt, q, row, fa, fb, cache_pair, cache = work
    oa, oe, oca, oce = outs[1], outs[2], outs[3], outs[4]
    F = fa.shape[0]
    fa[0], pa = _row_min(D, ia)
    fb[0], pb = _row_min(D, ib)
    for m in range(F - 1):
        fa[1 + m], fb[1 + m] = D[ia, watched[m]], D[ib, watched[m]]
    xa, xb = D[ia, pb], D[ib, pa]
    evaluations, cached = 0, 0
    for f in range(F):
        oa[f, slot], oe[f, slot], oca[f, slot], oce[f, slot] = za, zb, 0, 0
        if (fa[f] >= 0.0) == (fb[f] >= 0.0):
            if fa[f] < 0.0 and fb[f] < 0.0:
                oe[f, slot] = za  # colliding throughout: empty
            continue
        lower = fa[f] < 0.0  # colliding at the lower end: the piece starts at the root
        if f > 0:
            pair, va, vb = watched[f - 1], fa[f], fb[f]
        elif lower:
            pair, va, vb = pa, fa[0], xb
        else:
            pair, va, vb = pb, xa, fb[0]
        hit = -1
        for m in range(cached):  # a pair's root shared by several functions: refined once
            if cache_pair[m] == pair:
                hit = m
        if hit < 0:
            lo, hi, ylo, n, failed = pair_root(bx, by, others, ax, za, zb, va, vb, pair, root_tol, steps, kd, pk, sc,
                                                pt, q)
            evaluations += n
            if failed:
                return evaluations, True
            hit, cached = cached, cached + 1
            cache_pair[hit], cache[hit, 0], cache[hit, 1], cache[hit, 2] = pair, lo, hi, ylo
        lo, hi, ylo = cache[hit, 0], cache[hit, 1], cache[hit, 2]
        root, code = 0.5 * (lo + hi), pair
        if f == 0:  # the smallest distance's root is the pair's when every pair is clear at the free end
            evaluations += 1
            if _all_pairs_apart(bx, by, lo if ylo >= 0.0 else hi, others, ax, kd, cf, sc, pt, q, row, 0):
                return evaluations, True
            if not _row_min(row, 0)[0] >= 0.0:
                root, code, n, failed = _smallest_root(bx, by, others, ax, za, zb, fa[0], fb[0], pair, root_tol, steps,
                                                       kd, cf, sc, pt, q, row)
                evaluations += n
                if failed:
                    return evaluations, True
        if lower:
            oa[f, slot], oca[f, slot] = root, code + 1
        else:
            oe[f, slot], oce[f, slot] = root, code + 1
    return evaluations, False


@njit(cache=True, inline="always")
def _sub_interval(c, u, v, nn, bx, by, others, ax, opts, kd, cf, pk, sc, work, bufs, outs, off, room
                  ):  # pragma: no cover - compiled
    """Sub-interval [u, v] of column c (nn + 1 samples): its pieces into slots off.. of the
    outputs (`CollisionColumns._checked_pieces`): count, evaluations, failed."""
    s, s_min, watched, safety, max_refine, edge, root_tol, steps = opts
    D, C0, zs, st_z, st_i, st_cm, kk = bufs
    pt, q = work[0], work[1]
    P = D.shape[1]
    evaluations = 0
    h = (v - u) / nn
    nudge = min(edge, (v - u) / 4)
    for k in range(nn + 1):
        z = u + (v - u) * (k / nn) if k < nn else v
        zs[k] = z
        evaluations += 1
        if _all_pairs(bx, by, min(max(z, u + nudge), v - nudge), others, ax, kd, cf, sc, pt, q, D, k):
            return 0, evaluations, True
    for i in range(nn + 1):  # curvatures (`collision_column_kernels.curvature_kernel`)
        j = i + 1 if i == 0 else (i - 1 if i == nn else i)
        for p in range(P):
            cv = abs(D[j - 1, p] - 2.0 * D[j, p] + D[j + 1, p]) / (h * h)
            C0[i, p] = cv if np.isfinite(cv) else np.inf
    top = 0
    for k in range(nn - 1, -1, -1):  # a stack of gaps: za, zb; ia, ib, level; curvature bound / safety
        st_z[top, 0], st_z[top, 1] = zs[k], zs[k + 1]
        st_i[top, 0], st_i[top, 1], st_i[top, 2] = k, k + 1, 0
        for p in range(P):
            st_cm[top, p] = max(C0[k, p], C0[k + 1, p])
        top += 1
    rows, count = nn + 1, 0
    while top > 0:
        top -= 1
        za, zb = st_z[top, 0], st_z[top, 1]
        ia, ib, level = st_i[top, 0], st_i[top, 1], st_i[top, 2]
        for p in range(P):
            kk[p] = safety * st_cm[top, p]
        if level < max_refine and gap_may_hold_root(D[ia], D[ib], kk, zb - za, s, s_min, watched):
            if rows >= D.shape[0] or top + 2 > st_z.shape[0]:
                return 0, evaluations, True
            zm = 0.5 * (za + zb)
            evaluations += 1
            if _all_pairs(bx, by, zm, others, ax, kd, cf, sc, pt, q, D, rows):
                return 0, evaluations, True
            for half in range(2):  # the upper half below the lower one: the lower is taken first
                st_z[top, 0], st_z[top, 1] = (zm, zb) if half == 0 else (za, zm)
                st_i[top, 0], st_i[top, 1], st_i[top, 2] = (rows, ib, level + 1) if half == 0 else (ia, rows, level + 1)
                for p in range(P):
                    st_cm[top, p] = kk[p] / safety
                top += 1
            rows += 1
            continue
        if count >= room:
            return 0, evaluations, True
        slot = off + count
        outs[0][slot] = c
        n, failed = _gap_pieces(bx, by, others, ax, za, zb, D, ia, ib, watched, root_tol, steps, kd, cf, pk, sc, work,
                                outs, slot)
        evaluations += n
        if failed:
            return 0, evaluations, True
        if count > 0 and _extends(outs, slot):
            continue
        count += 1
    return count, evaluations, False


@njit(cache=True, inline="always")
def _extends(outs, slot):  # pragma: no cover - compiled
    """Whether every function's piece in slot starts where the one in slot - 1 ends (no root
    between them: a union merges them); then slot - 1 takes slot's ends."""
    oa, oe, oce = outs[1], outs[2], outs[4]
    for f in range(oa.shape[0]):
        if oe[f, slot - 1] != oa[f, slot]:
            return False
    for f in range(oa.shape[0]):
        oe[f, slot - 1], oce[f, slot - 1] = oe[f, slot], oce[f, slot]
    return True


@njit(cache=True, parallel=True)
def pieces_kernel(col, u, v, n, bx, by, others, ax, s, s_min, watched, safety, max_refine, edge, root_tol, steps, kd,
                  cf, pk, extra_rows, off, room, oc, oa, oe, oca, oce, count, evaluations, failed
                  ):  # pragma: no cover - compiled
    """Sub-interval i ([u[i], v[i]] of column col[i] at (bx, by)[col[i]], n[i] + 1 first
    samples): its pieces into slots off[i].. off[i] + count[i] - 1 of oc (room,), oa, oe, oca, oce
    (F, room), the evaluations made; failed[i] where the batched path must take it (the
    outputs then not final), in blocks of 16 sub-intervals on every core."""
    S, P, F = col.shape[0], s.shape[0], 1 + watched.shape[0]
    nmax = 2
    for i in range(S):
        nmax = max(nmax, n[i])
    parent, radius, pairs = cf[0], cf[10], cf[12]
    for blk in prange((S + 15) // 16):
        sc = scratch(parent.shape[0], radius.shape[0], pairs.shape[0])
        pt, q, row = np.empty((1, 3)), np.empty((1, kd[5].shape[0])), np.empty((1, P))
        D, C0, zs = np.empty((nmax + 1 + extra_rows, P)), np.empty((nmax + 1, P)), np.empty(nmax + 1)
        depth = nmax + max_refine + 2
        st_z, st_i, st_cm = np.empty((depth, 2)), np.empty((depth, 3), np.int64), np.empty((depth, P))
        work = (pt, q, row, np.empty(F), np.empty(F), np.empty(F, np.int64), np.empty((F, 3)))
        bufs = (D, C0, zs, st_z, st_i, st_cm, np.empty(P))
        opts = (s, s_min, watched, safety, max_refine, edge, root_tol, steps)
        outs = (oc, oa, oe, oca, oce)
        for i in range(blk * 16, min(S, blk * 16 + 16)):
            c = col[i]
            count[i], evaluations[i], failed[i] = _sub_interval(c, u[i], v[i], n[i], bx[c], by[c], others, ax, opts, kd,
                                                                cf, pk, sc, work, bufs, outs, off[i], room[i])


def fused_pieces(kernel_data: tuple[np.ndarray, ...], dist: Any, base: np.ndarray, ax: int, col: np.ndarray,
                 u: np.ndarray, v: np.ndarray, n: np.ndarray, slopes: np.ndarray, watched: np.ndarray,
                 safety: float, max_refine: int, edge: float, root_tol: float, steps: int
                 ) -> tuple[tuple[np.ndarray, ...], int, np.ndarray]:
    """`pieces_kernel` on the sub-intervals [u, v] of columns col (base (M, 2), n + 1 first
    samples each; `kernel_data`: `p2us.configurations.kernel_data` of the branch; `dist`: the
    `AnalyticDistances`): (col, starts, ends, start codes, end codes) as
    `CollisionColumns._checked_pieces`', the evaluations made, and the sub-intervals the
    batched path must take instead (bool)."""
    S, F = len(col), 1 + len(watched)
    room = 2 * n + 16
    off = np.cumsum(room) - room
    total = int(room.sum())
    oc = np.empty(total, np.int64)
    oa, oe = np.empty((F, total)), np.empty((F, total))
    oca, oce = np.empty((F, total), np.int64), np.empty((F, total), np.int64)
    count, evaluations = np.zeros(S, np.int64), np.zeros(S, np.int64)
    failed = np.zeros(S, np.bool_)
    others = np.array([k for k in range(3) if k != ax], np.int64)
    s = np.ascontiguousarray(slopes, dtype=float)
    with numba.parallel_chunksize(1):  # blocks taken one at a time: a busy core holds up no others'
        on_cores(pieces_kernel, S, PARALLEL_SUBS, np.ascontiguousarray(col, dtype=np.int64),
                 np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(v, dtype=float),
                 np.ascontiguousarray(n, dtype=np.int64), np.ascontiguousarray(base[:, 0], dtype=float),
                 np.ascontiguousarray(base[:, 1], dtype=float), others, ax, s, float(s.max(initial=0.0)),
                 np.ascontiguousarray(watched, dtype=np.int64), float(safety), int(max_refine), float(edge),
                 float(root_tol), int(steps), tuple(kernel_data), dist.closed_form_data(), dist.pair_kernel_data(),
                 EXTRA_ROWS, off, room, oc, oa, oe, oca, oce, count, evaluations, failed)
    count[failed] = 0
    kept = int(count.sum())
    slots = np.repeat(off - (np.cumsum(count) - count), count) + np.arange(kept)
    return (oc[slots], oa[:, slots], oe[:, slots], oca[:, slots], oce[:, slots]), int(evaluations[~failed].sum()), failed


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (pieces_kernel,)


__all__ = ["EXTRA_ROWS", "PARALLEL_SUBS", "fused_pieces", "pieces_kernel"]
