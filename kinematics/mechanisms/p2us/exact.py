"""Exact 3-[P2(US)] columns: the inside set of every working mode along an axis-parallel line, from
the roots of quadratics, compiled with Numba and run on every core.

Along a line p(z) = p0 + z e_k (k = the column axis) every quantity of limb i is a polynomial of
degree <= 2 in z or the square root of one: with v = p + (d - b) e_i, A = v.w_i (linear in z) and
the IK discriminant D = A^2 - |v|^2 + L^2 (quadratic), the roots are q = A +/- sqrt(D). Every
constraint slack of the fused scan kernel (`p2us_scan`) is linear in q and in the rod direction
n = (v - q w_i) / L, hence of the form

    tau(z) = r(z) +/- gamma sqrt(D(z)),   r linear in z, gamma constant

(strokes: q - q_min, q_max - q; theta under either convention and phi: L times a linear form in
n, see `p2us_scan._root`). tau changes sign only where r^2 = gamma^2 D: a quadratic in z, the same
for both roots "+" and "-". The reach slack D / 2L changes sign at D's roots. A mode's margin is
the minimum of its limbs' slacks and the union's the maximum over modes, so every target's margin
keeps its sign between consecutive roots of these <= 7 quadratics per limb: sort them, evaluate
the scan kernel's own margin at each gap's midpoint, and add the gaps that are inside. Nothing
shorter than a sampling step can be missed; the ends are exact up to the rounding of the
quadratic formula (~1e-15 m away from tangencies).

Each column also returns a *signature*: a hash of, per target, the constraint (limb, slack) that
ends each inside interval. Between two columns of equal signature the column length is smooth;
where it changes the length has a kink (another constraint takes over an end), a square-root edge
(an interval appears, vanishes, or two merge) or a jump (a face parallel to the column axis).
`kinematics.analyses.columns` locates those changes and integrates the smooth pieces with Gauss rules.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from kinematics.mechanisms.p2us.closed_form import P2USParams
from kinematics.mechanisms.p2us.scan import check_limits, kernel_geometry, limb_kernel
from kinematics.mechanisms.three_limb.column_ends import (
    PARALLEL_COLUMNS,
    SIGNATURE_SEED,
    add_gap,
    close_column,
    other_axes,
)
from kinematics.mechanisms.three_limb.margin import column_buffers

ROOT_ERROR = 1e-13
"""Error [m] charged per interval end (the quadratic formula's rounding, with margin)."""


@njit(cache=True)
def _quadratic(a, b, c, lo, hi, out, ids, n, cid):  # pragma: no cover - compiled
    """Append the real roots of a z^2 + b z + c inside (lo, hi) to out[n:], tagged cid."""
    if a == 0.0:
        if b != 0.0:
            z = -c / b
            if lo < z < hi:
                out[n] = z
                ids[n] = cid
                n += 1
        return n
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        # a (near) double root lost to rounding: keep it as a candidate (an extra split is harmless)
        if -disc <= 1e-10 * (b * b + abs(4.0 * a * c)):
            z = -0.5 * b / a
            if lo < z < hi:
                out[n] = z
                ids[n] = cid
                n += 1
        return n
    s = math.sqrt(disc)
    qq = -0.5 * (b + s if b >= 0.0 else b - s)
    if qq == 0.0:
        z = 0.0
        if lo < z < hi:
            out[n] = z
            ids[n] = cid
            n += 1
        return n
    for z in (qq / a, c / qq):
        if lo < z < hi:
            out[n] = z
            ids[n] = cid
            n += 1
    return n


@njit(cache=True)
def _limb_constraints(g, i, passive, k):  # pragma: no cover - compiled
    """(alpha0, alpha (3), gamma) per slack of limb i: slack = alpha0 + alpha.v + gamma q (zero set)."""
    ex, ey, wx, wy, wz = g[5 * i], g[5 * i + 1], g[5 * i + 2], g[5 * i + 3], g[5 * i + 4]
    L, q_lo, q_hi = g[15], g[17], g[18]
    out = np.zeros((6, 5))
    # strokes: q - q_lo, q_hi - q
    out[0, 0], out[0, 4] = -q_lo, 1.0
    out[1, 0], out[1, 4] = q_hi, -1.0
    if not passive:
        return out, 2
    # passive slacks k.n + k0 with n = (v - q w) / L: alpha = k / L, gamma = -(k.w) / L
    if g[26] > 0.5:  # rod-rail: n.w - c_hi, c_lo - n.w
        ks = ((wx, wy, wz, -g[28]), (-wx, -wy, -wz, g[27]))
    else:  # elevation arc: g19 se - g20 ce and ce g22 - se g21, ce = -(n.e), se = -n_z
        ks = ((g[20] * ex, g[20] * ey, -g[19], 0.0), (-g[22] * ex, -g[22] * ey, g[21], 0.0))
    ks2 = ks + ((ey, -ex, 0.0, -g[24]), (-ey, ex, 0.0, g[25]))  # sin(phi) - s_lo, s_hi - sin(phi)
    for j in range(4):
        kx, ky, kz, k0 = ks2[j]
        out[2 + j, 0] = k0
        out[2 + j, 1] = kx / L
        out[2 + j, 2] = ky / L
        out[2 + j, 3] = kz / L
        out[2 + j, 4] = -(kx * wx + ky * wy + kz * wz) / L
    return out, 6


@njit(cache=True)
def _one_column(p0, ax, z0, z1, g, passive, modes, cons, ncons, out_len, out_err, out_ends, zbox, c,
                cand, ids, Dc, prev_in, pm, pt):  # pragma: no cover - compiled
    """Inside length per target of the column p0 + z e_ax, z in [z0, z1]; returns its signature.
    cand, ids (64,), Dc (3, 3), prev_in (T,), pm (8,), pt (3,): work buffers."""
    L, off = g[15], g[16]
    h = SIGNATURE_SEED
    empty = np.int64(h >> np.uint64(1))
    lo, hi = z0, z1
    lo_id, hi_id = -1, -2
    # reach: D_i(z) = D0 + D1 z + D2 z^2 >= 0 for every limb (concave: an interval)
    for i in range(3):
        ex, ey, wx, wy, wz = g[5 * i], g[5 * i + 1], g[5 * i + 2], g[5 * i + 3], g[5 * i + 4]
        v0x, v0y, v0z = p0[0] + off * ex, p0[1] + off * ey, p0[2]
        wa = wx if ax == 0 else (wy if ax == 1 else wz)
        va = v0x if ax == 0 else (v0y if ax == 1 else v0z)
        A0 = v0x * wx + v0y * wy + v0z * wz
        Dc[i, 0] = A0 * A0 - (v0x * v0x + v0y * v0y + v0z * v0z) + L * L
        Dc[i, 1] = 2.0 * A0 * wa - 2.0 * va
        Dc[i, 2] = wa * wa - 1.0
        a, b, cc = Dc[i, 2], Dc[i, 1], Dc[i, 0]
        if a < 0.0:
            disc = b * b - 4.0 * a * cc
            if disc <= 0.0:
                return empty
            s = math.sqrt(disc)
            qq = -0.5 * (b + s if b >= 0.0 else b - s)
            r1, r2 = qq / a, cc / qq
            if min(r1, r2) > lo:
                lo, lo_id = min(r1, r2), 8 * i + 7
            if max(r1, r2) < hi:
                hi, hi_id = max(r1, r2), 8 * i + 7
        elif a == 0.0 and b != 0.0:
            r = -cc / b
            if b > 0.0 and r > lo:
                lo, lo_id = r, 8 * i + 7
            elif b < 0.0 and r < hi:
                hi, hi_id = r, 8 * i + 7
        elif a == 0.0 and cc < 0.0:
            return empty
    if not lo < hi:
        return empty
    n = 0
    cand[n] = lo
    ids[n] = lo_id
    n += 1
    for i in range(3):
        ex, ey, wx, wy, wz = g[5 * i], g[5 * i + 1], g[5 * i + 2], g[5 * i + 3], g[5 * i + 4]
        v0x, v0y, v0z = p0[0] + off * ex, p0[1] + off * ey, p0[2]
        for j in range(ncons):
            a0 = cons[i, j, 0]
            gam = cons[i, j, 4]
            cx = cons[i, j, 1] + gam * wx
            cy = cons[i, j, 2] + gam * wy
            cz = cons[i, j, 3] + gam * wz
            r0 = a0 + cx * v0x + cy * v0y + cz * v0z
            r1 = cx if ax == 0 else (cy if ax == 1 else cz)
            g2 = gam * gam
            if g2 == 0.0:  # slack linear in z (phi: n.t does not involve q, as w.t = 0)
                n = _quadratic(0.0, r1, r0, lo, hi, cand, ids, n, 8 * i + j)
                continue
            n = _quadratic(r1 * r1 - g2 * Dc[i, 2], 2.0 * r0 * r1 - g2 * Dc[i, 1], r0 * r0 - g2 * Dc[i, 0],
                           lo, hi, cand, ids, n, 8 * i + j)
        # the other limbs' reach roots inside (lo, hi) cannot occur (hull of the intersection)
    cand[n] = hi
    ids[n] = hi_id
    n += 1
    # insertion sort (n <= 44, nearly sorted per limb): no allocation
    for k in range(1, n):
        zk, ik = cand[k], ids[k]
        j = k - 1
        while j >= 0 and cand[j] > zk:
            cand[j + 1] = cand[j]
            ids[j + 1] = ids[j]
            j -= 1
        cand[j + 1] = zk
        ids[j + 1] = ik
    prev_in[:] = False
    for k in range(n - 1):
        za, zb = cand[k], cand[k + 1]
        if zb <= za:
            continue
        pt[0], pt[1], pt[2] = p0[0], p0[1], p0[2]
        pt[ax] = 0.5 * (za + zb)
        p_0, m_0, _ = limb_kernel(pt[0], pt[1], pt[2], g, 0, passive)
        p_1, m_1, _ = limb_kernel(pt[0], pt[1], pt[2], g, 1, passive)
        p_2, m_2, _ = limb_kernel(pt[0], pt[1], pt[2], g, 2, passive)
        for m in range(8):
            s0 = m_0[0] if (m >> 2) & 1 else p_0[0]
            s1 = m_1[0] if (m >> 1) & 1 else p_1[0]
            s2 = m_2[0] if m & 1 else p_2[0]
            pm[m] = min(s0, s1, s2)
        # the end between the previous gap and this one is cand[k] (constraint ids[k])
        h = add_gap(c, pm, modes, za, zb, ids[k], ROOT_ERROR, prev_in, out_len, out_err, out_ends, zbox, h)
    return close_column(c, prev_in, -2, ROOT_ERROR, out_err, out_ends, h)


@njit(cache=True, parallel=True)
def _columns_kernel(base, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig, zbox):  # pragma: no cover
    M = base.shape[0]
    chunks = min(M, 64)
    for ch in prange(chunks):
        _columns_range(base, ch * M // chunks, (ch + 1) * M // chunks, ax, z0, z1, g, passive, modes, out_len, out_err,
                       out_ends, out_sig, zbox)


@njit(cache=True)
def _columns_serial(base, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig, zbox):  # pragma: no cover
    """`_columns_kernel` on one core (small batches: no parallel launch)."""
    _columns_range(base, 0, base.shape[0], ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig, zbox)


@njit(cache=True, inline="always")
def _columns_range(base, c0, c1, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig,
                   zbox):  # pragma: no cover - compiled
    """Columns c0..c1 - 1 of `_columns_kernel`."""
    cons = np.zeros((3, 6, 5))
    ncons = 2
    for i in range(3):
        ci, ncons = _limb_constraints(g, i, passive, 0)
        cons[i] = ci
    o0, o1 = other_axes(ax)
    T = modes.shape[0] + 1
    p0 = np.zeros(3)
    cand = np.empty(64)
    ids = np.empty(64, np.int64)
    Dc = np.empty((3, 3))
    prev_in = np.zeros(T, np.bool_)
    pm = np.empty(8)
    pt = np.zeros(3)
    for c in range(c0, c1):
        p0[o0] = base[c, 0]
        p0[o1] = base[c, 1]
        p0[ax] = 0.0
        out_sig[c] = _one_column(p0, ax, z0, z1, g, passive, modes, cons, ncons, out_len, out_err, out_ends,
                                 zbox, c, cand, ids, Dc, prev_in, pm, pt)


class ExactColumns:
    """Exact columns of the 3-[P2(US)]'s per-mode and union margins (see the module docstring).

    Call it as `columns(base, axis, z0, z1)` with base (M, 2) the columns' other coordinates [m]:
    returns lengths (M, T) [m], their errors (M, T) [m], interval ends (M, T), signatures (M,)
    int64 and the inside extent along the axis of the last target (M, 2) (NaN where empty).
    """

    def __init__(self, params: P2USParams, modes: np.ndarray, limits: str) -> None:
        self.passive = check_limits(limits)
        self.g = kernel_geometry(params)
        self.modes = np.ascontiguousarray(modes, dtype=np.int64)

    def __call__(self, base: np.ndarray, axis: int, z0: float, z1: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        base = np.ascontiguousarray(base, dtype=float)
        length, err, ends, sig, zbox = column_buffers(base.shape[0], len(self.modes) + 1)
        (_columns_kernel if len(base) >= PARALLEL_COLUMNS else _columns_serial)(
            base, int(axis), float(z0), float(z1), self.g, self.passive, self.modes, length, err, ends, sig, zbox)
        zbox[~np.isfinite(zbox)] = np.nan
        return length, err, ends, sig, zbox


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (_columns_kernel, _columns_serial)
