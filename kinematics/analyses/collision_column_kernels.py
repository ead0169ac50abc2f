"""Compiled kernels of the collision-free exact columns (`kinematics.analyses.collision_columns`):
the samples' curvatures, the gap test, the cut of the kinematic intervals at the pre-scan's cells
and the union of the collision-free pieces per column."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange

from kinematics.generic.capsules import PARALLEL_MIN
from kinematics.jit import on_cores

_PRIME = np.uint64(1099511628211)


@njit(cache=True)
def curvature_kernel(d, k, n, h, out):  # pragma: no cover - compiled
    """out (N, P): each pair's |second difference| / h^2 [1/m] at the samples d (N, P), the
    samples k = 0..n of each sub-interval in order, spacing h (an end sample takes its
    neighbour's; +inf where not finite)."""
    N, P = d.shape
    for i in range(N):
        j = i + 1 if k[i] == 0 else (i - 1 if k[i] == n[i] else i)
        for p in range(P):
            c = abs(d[j - 1, p] - 2.0 * d[j, p] + d[j + 1, p]) / (h[j] * h[j])
            out[i, p] = c if np.isfinite(c) else np.inf


@njit(cache=True)
def ambiguous_gaps(d, curv, ia, ib, safety, w, s, s_min, watched, out):  # pragma: no cover - compiled
    """Per gap g (its ends' pair distances d[ia[g]], d[ib[g]] (P,), width w [m], the pairs'
    curvature bound safety x the larger of curv's at its ends): whether it may hold a root of
    the smallest distance or of a watched pair's that its ends do not show. A pair stays on one
    side of zero over the gap when its curvature bound kk says so (it sags at most kk w^2 / 8
    from its chord) or its slope s_p does (|d(a)| + |d(b)| > s_p w); the smallest distance,
    negative at both ends, stays negative when some pair provably does, or by the largest slope;
    where it changes sign (its root is sought on one pair), every pair clear at both ends must
    provably stay clear."""
    G, P = len(ia), d.shape[1]
    kk = np.empty(P)
    for g in range(G):
        da, db = d[ia[g]], d[ib[g]]
        for p in range(P):
            kk[p] = safety * max(curv[ia[g], p], curv[ib[g], p])
        wg = w[g]
        sag = wg * wg / 8.0
        fa, fb = np.inf, np.inf
        for p in range(P):
            fa = min(fa, da[p])
            fb = min(fb, db[p])
        amb = False
        if fa > 0.0 and fb > 0.0:
            for p in range(P):
                a, b = da[p], db[p]
                if min(a, b) - kk[p] * sag > 0.0 or a + b > s[p] * wg:
                    continue
                amb = True
                break
        elif fa < 0.0 and fb < 0.0 and -fa - fb <= s_min * wg:
            amb = True
            for p in range(P):
                if max(da[p], db[p]) + kk[p] * sag < 0.0:
                    amb = False
                    break
        elif (fa >= 0.0) != (fb >= 0.0):
            # a sign change: its root is sought on the pair that collides at one end; a pair clear
            # at both ends must stay clear over the gap, or it may dip into contact and out again
            # inside it, a collision that root does not see
            for p in range(P):
                a, b = da[p], db[p]
                if a > 0.0 and b > 0.0 and not (min(a, b) - kk[p] * sag > 0.0 or a + b > s[p] * wg):
                    amb = True
                    break
        for j in range(len(watched)):
            if amb:
                break
            p = watched[j]
            a, b = da[p], db[p]
            if a * b <= 0.0:
                continue
            sure = (min(a, b) - kk[p] * sag > 0.0) if a > 0.0 else (max(a, b) + kk[p] * sag < 0.0)
            amb = not sure and abs(a) + abs(b) <= s[p] * wg
        out[g] = amb


@njit(cache=True)
def split_close(col, a, e, cells, lo, g):  # pragma: no cover - compiled
    """The intervals [a, e] of columns col cut at the pre-scan cells' faces into runs of close
    (checked) and clear cells: col, start, end, checked."""
    n_cells = cells.shape[1]
    cap = len(col) * (n_cells + 2)
    oc = np.empty(cap, np.int64)
    ou = np.empty(cap)
    ov = np.empty(cap)
    ok = np.empty(cap, np.bool_)
    n = 0
    for i in range(len(col)):
        c = col[i]
        start = a[i]
        k = min(max(int(np.floor((start - lo) / g)), 0), n_cells - 1)
        state = cells[c, k]
        while True:
            face = lo + (k + 1) * g
            if k >= n_cells - 1 or face >= e[i]:
                break
            nxt = cells[c, k + 1]
            if nxt != state:
                oc[n], ou[n], ov[n], ok[n] = c, start, face, state
                n += 1
                start, state = face, nxt
            k += 1
        oc[n], ou[n], ov[n], ok[n] = c, start, e[i], state
        n += 1
    return oc[:n], ou[:n], ov[:n], ok[:n]


@njit(cache=True)
def union_pieces(col, order, a, e, ca, ce, f, t, last, root_tol, by_pair, hashed, length, err, ends, sig,
                 zbox):  # pragma: no cover - compiled
    """Target t's union of function f's pieces k = order[0], order[1], ... (sorted by column
    col[k], then start a[f, k]; rows of a, e, ca, ce (F, K) per function; empty pieces, e <= a,
    skipped): its length, ends, the collision ends' errors (root_tol each), and (`hashed`) their
    binding pairs hashed into the signature; the extent for the last target."""
    n = len(order)
    i = 0
    while i < n:
        k = order[i]
        if e[f, k] <= a[f, k]:
            i += 1
            continue
        c = col[k]
        rank = 0
        cur_a, cur_e, code_a, code_e = a[f, k], e[f, k], ca[f, k], ce[f, k]
        j = i + 1
        while True:
            while j < n and e[f, order[j]] <= a[f, order[j]]:
                j += 1
            if j < n and col[order[j]] == c and a[f, order[j]] <= cur_e:
                kj = order[j]
                if e[f, kj] > cur_e:
                    cur_e, code_e = e[f, kj], ce[f, kj]
                j += 1
                continue
            length[c, t] += cur_e - cur_a
            ends[c, t] += 2
            for code in (code_a, code_e):
                if code > 0:
                    err[c, t] += root_tol
                    if hashed:
                        sig[c] = (sig[c] ^ np.uint64(((t + 1) * 4096 + rank) * 65536 + (code if by_pair else 1))) * _PRIME
                rank += 1
            if last:
                zbox[c, 0] = min(zbox[c, 0], cur_a)
                zbox[c, 1] = max(zbox[c, 1], cur_e)
            if j < n and col[order[j]] == c:
                kj = order[j]
                cur_a, cur_e, code_a, code_e = a[f, kj], e[f, kj], ca[f, kj], ce[f, kj]
                j += 1
                continue
            break
        i = j


@njit(cache=True, parallel=True)
def smallest_kernel(d, watched, fn, arg):  # pragma: no cover - compiled
    """Per row n of d (N, P): fn[n, 0] its smallest entry (+inf if none), fn[n, 1 + w] entry
    watched[w], arg[n] the first column holding the smallest (0 if none is below +inf), as
    numpy's min and argmin along rows (d holds no NaN), in blocks of 1024 rows on every core."""
    N, P = d.shape
    for blk in prange((N + 1023) // 1024):
        for n in range(blk * 1024, min(N, blk * 1024 + 1024)):
            best, at = np.inf, 0
            for p in range(P):
                if d[n, p] < best:
                    best, at = d[n, p], p
            fn[n, 0], arg[n] = best, at
            for w in range(watched.shape[0]):
                fn[n, 1 + w] = d[n, watched[w]]


def smallest(d: np.ndarray, watched: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 1 + W) each row's smallest distance, then each watched pair's, and (N,) the pair of the
    smallest (`smallest_kernel`; numpy's min and argmin along rows, strided passes over an (N, P)
    array, took ~1.3 s of a 13.9 s p2us-results profile; this pass is ~6x faster on such arrays)."""
    d = np.ascontiguousarray(d, dtype=float)
    fn, arg = np.empty((len(d), 1 + len(watched))), np.empty(len(d), np.int64)
    on_cores(smallest_kernel, len(d), PARALLEL_MIN, d, np.ascontiguousarray(watched, dtype=np.int64), fn, arg)
    return fn, arg


def curvatures(d: np.ndarray, k: np.ndarray, n: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(N, P) each pair's |second difference| / h^2 [1/m] at the samples (an end sample takes
    its neighbour's; +inf where not finite), the samples k = 0..n of each sub-interval in order,
    spacing h."""
    out = np.empty_like(d)
    curvature_kernel(d, k, n, h, out)
    return out


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (curvature_kernel, ambiguous_gaps, smallest_kernel, split_close, union_pieces)


__all__ = ["ambiguous_gaps", "curvature_kernel", "curvatures", "smallest", "smallest_kernel", "split_close", "union_pieces"]
