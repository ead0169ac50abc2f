"""The singularity scan's edge pass, compiled: the sign changes of a mechanism's singular fields
along the edges of a block of grid planes (`kinematics.analyses.singularities` places and counts
them).

A block holds K planes of nx x ny grid points, plane-major then row-major (point
(k, i, j) at index (k nx + i) ny + j). An edge joins a point to its next neighbour along x
(index + ny), y (+1) or z (+nx ny); only an edge whose ends differ in the sign of some field can
cross a locus, so each point's signs are packed into bits first and the edges compared by them.
Along an edge a -> b the crossing sits at the linear interpolation t = f_a / (f_a - f_b):

* type I (limb l): disc[:, l] changes sign (>= 0 against < 0), both ends finite; *inner* when
  the end where the limb reaches lies in one of the chosen working modes' workspaces;
* type II (mode m): det[:, m] changes sign (> 0 against <= 0) with every limb reaching at both
  ends, both ends finite (t = 1/2 where the interpolation is not finite); *inner* when both ends
  lie in mode m's workspace.

Crossings come out per direction (x, y, z), within it type I limb by limb, then type II mode by
mode (in the order given), each in ascending edge order.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numba import njit

__all__ = ["edge_crossings", "kernels"]


@njit(cache=True)
def _codes(disc, det):  # pragma: no cover - compiled
    """(N, G) uint64: each point's signs (disc >= 0, then det > 0), 64 to a word."""
    N, L = disc.shape
    M = det.shape[1]
    G = (L + M + 63) // 64
    out = np.zeros((N, G), dtype=np.uint64)
    for n in range(N):
        for j in range(L + M):
            s = disc[n, j] >= 0.0 if j < L else det[n, j - L] > 0.0
            if s:
                out[n, j // 64] |= np.uint64(1) << np.uint64(j % 64)
    return out


@njit(cache=True)
def _differ(code, a, b):  # pragma: no cover - compiled
    d = False
    for w in range(code.shape[1]):
        d |= code[a, w] != code[b, w]
    return d


@njit(cache=True)
def _reaches(disc, a):  # pragma: no cover - compiled
    r = True
    for limb in range(disc.shape[1]):
        r &= disc[a, limb] >= 0.0  # (NaN: not reaching)
    return r


@njit(cache=True)
def _kernel(disc, det, inside, modes, K, nx, ny, z_only):  # pragma: no cover - compiled
    """Crossings of the block (see the module docstring): (kind, which, t, a, b, inner) arrays."""
    code = _codes(disc, det)
    L = disc.shape[1]
    cap = 1024
    kind = np.empty(cap, np.int64)
    which = np.empty(cap, np.int64)
    tt = np.empty(cap)
    ea = np.empty(cap, np.int64)
    eb = np.empty(cap, np.int64)
    inner = np.empty(cap, np.bool_)
    n = 0
    starts = np.empty(K * nx * ny, np.int64)
    for d in range(3):
        if z_only and d < 2:
            continue
        step = ny if d == 0 else (1 if d == 1 else nx * ny)
        m = 0  # the differing edges of this direction, ascending
        for k in range(K - 1 if d == 2 else K):
            for i in range(nx - 1 if d == 0 else nx):
                for j in range(ny - 1 if d == 1 else ny):
                    a = (k * nx + i) * ny + j
                    if _differ(code, a, a + step):
                        starts[m] = a
                        m += 1
        for c in range(L + len(modes)):
            for e in range(m):
                a = starts[e]
                b = a + step
                if c < L:
                    fa, fb = disc[a, c], disc[b, c]
                    if not ((fa >= 0.0) != (fb >= 0.0) and np.isfinite(fa) and np.isfinite(fb)):
                        continue
                    t = fa / (fa - fb)
                    end = a if fa >= 0.0 else b
                    flag = False
                    for mm in modes:
                        flag |= inside[end, mm]
                    what = c
                else:
                    what = modes[c - L]
                    fa, fb = det[a, what], det[b, what]
                    if not ((fa > 0.0) != (fb > 0.0) and np.isfinite(fa) and np.isfinite(fb)
                            and _reaches(disc, a) and _reaches(disc, b)):
                        continue
                    t = fa / (fa - fb)
                    if not np.isfinite(t):
                        t = 0.5
                    flag = inside[a, what] and inside[b, what]
                if n == cap:  # grow every output twofold
                    cap *= 2
                    kind, which, tt = _grow(kind, cap), _grow(which, cap), _grow(tt, cap)
                    ea, eb, inner = _grow(ea, cap), _grow(eb, cap), _grow(inner, cap)
                kind[n] = 1 if c < L else 2
                which[n] = what
                tt[n] = t
                ea[n] = a
                eb[n] = b
                inner[n] = flag
                n += 1
    return kind[:n], which[:n], tt[:n], ea[:n], eb[:n], inner[:n]


@njit(cache=True)
def _grow(x, cap):  # pragma: no cover - compiled
    y = np.empty(cap, x.dtype)
    y[:len(x)] = x
    return y


def edge_crossings(disc: np.ndarray, det: np.ndarray, margin: np.ndarray, modes: Sequence[int], planes: int,
                   nx: int, ny: int, *, z_only: bool = False) -> tuple[np.ndarray, ...]:
    """Sign changes along a block's edges (see the module docstring).

    Args:
        disc: (N, L) per limb's IK discriminant field [m^2] (N = planes nx ny).
        det: (N, M) per mode's type II field.
        margin: (N, M) per mode's margin [m] (>= 0 inside its workspace).
        modes: the chosen modes' columns (type II is looked for in these, in this order).
        planes: the block's number of planes.
        nx: points per plane along x.
        ny: points per plane along y.
        z_only: only the edges between planes (e.g. a block of two planes from two scans).

    Returns:
        kind (1 or 2), which (limb or mode), t (crossing at a + t (b - a)), a, b (the edge's
        ends' indices) and inner, one entry per crossing.
    """
    return _kernel(np.ascontiguousarray(disc, dtype=float), np.ascontiguousarray(det, dtype=float),
                   np.ascontiguousarray(margin >= 0), np.asarray(modes, dtype=np.int64), int(planes), int(nx),
                   int(ny), bool(z_only))


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (_kernel,)
