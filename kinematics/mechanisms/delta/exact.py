"""Exact Delta columns: the inside set of every working mode along an axis-parallel line, from the
real roots of polynomials of degree <= 6, compiled with Numba and run on every core.

Along a line p(s) = p0 + s e_k (k = the column axis) limb i's in-plane coordinates
x = v.e_i, y = v.t_i, h = v.z (v = p + (r - R) e_i) are linear in s, and so are rho^2 = x^2 + h^2
and K = (|v|^2 + l_a^2 - l_b^2) / (2 l_a) quadratic. The IK x cos(theta) - h sin(theta) = K
(`closed_form`) has, with S = sqrt(D), D = rho^2 - K^2 (quartic in s),

    cos(theta) = (K x + sigma h S) / rho^2,   sin(theta) = (-K h + sigma x S) / rho^2,

sigma = +/-1 the two roots. Every slack of the scan kernel (`scan.limb_kernel`) changes sign only
where one of these polynomials in s vanishes (both roots at once, as the squares take both signs):

* reach: D (degree 4); the reach slack min(l_b - near, far - l_b) has D's sign, as
  (l_b^2 - near^2)(far^2 - l_b^2) = 4 l_a^2 D;
* actuator bound theta = theta_lim: x cos(theta_lim) - h sin(theta_lim) - K (degree 2) (the
  wrap to within pi of the range's middle keeps the slack negative on both sides of the cut);
* elbow cone, n.d(theta + c_E) = cos(cone): lb n.d(theta + c_E) = K cos c_E - sigma S sin c_E - l_a
  cos c_E, so P^2 - sin^2(c_E) D with P = (K - l_a) cos c_E - l_b cos(cone) (degree 4);
* platform cone, -n.s_P = cos(cone): rho^2 (-v.s_P - l_b cos(cone)) + l_a (cos(theta) (e.s_P)
  - sin(theta) s_Pz) rho^2 = P + sigma Q S with P = rho^2 (-v.s_P - l_b cos(cone)) + l_a K
  (x e.s_P + h s_Pz), Q = l_a (h e.s_P - x s_Pz), so P^2 - Q^2 D (degree 6).

A mode's margin is the minimum of its limbs' slacks and the union's the maximum over modes, so
every target's margin keeps its sign between consecutive real roots: the reach quartics first
(the columns' hull where every limb reaches), then the other polynomials' roots inside it, sorted;
the scan kernel's own margin at each gap's midpoint says which gaps are inside. Nothing shorter
than a sampling step can be missed. Real roots in an interval come from Bernstein subdivision
(`roots.real_roots`: no sign variation, no root; one, exactly one, found by safeguarded Newton),
so none is lost to a sampling grid; the reach and elbow quartics of a column along which y is
constant (every vertical column) are quadratics in K, solved in closed form (`_through_rho2`).
Each end is charged the rounding of its polynomial's evaluation over its slope,
32 eps sum_k |a_k s^k| / |p'(s)| (at least ROOT_ERROR): large only at near-tangencies.

Each column also returns a *signature*, a hash of, per target, the constraint (limb, polynomial)
that ends each inside interval, which `kinematics.analyses.columns` uses as the 3-[P2(US)]'s
(`kinematics.mechanisms.p2us.exact`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from kinematics.mechanisms.delta.closed_form import DeltaParams
from kinematics.mechanisms.delta.roots import (
    DEG,
    ROOT_ERROR,
    poly_mul,
    poly_value,
    quadratic_roots,
    real_roots,
    roots_of_quadratic,
)
from kinematics.mechanisms.delta.scan import kernel_geometry, limb_kernel, scan
from kinematics.mechanisms.three_limb.column_ends import (
    PARALLEL_COLUMNS,
    SIGNATURE_SEED,
    add_gap,
    close_column,
    other_axes,
)
from kinematics.mechanisms.three_limb.margin import ThreeLimbMargin, column_buffers

__all__ = ["ROOT_ERROR", "ExactColumns", "delta_margin", "kernels"]

_DEG = DEG
_NPOLY = 5  # per limb: reach, actuator low, actuator high, elbow cone, platform cone
_CAP = 3 * (4 + 2 + 2 + 4 + 6) + 2


@njit(cache=True)
def _through_rho2(b1, b0, rho2, c, lo, hi, out, err, ids, n_out, cid):  # pragma: no cover - compiled
    """`real_roots` of the quartic c = q(K(s)) when K is a function of rho^2 alone (y constant
    along the column): the roots u of q(u) = u^2 + b1 u + b0, then rho^2(s) = 2 l_a u - c_K for
    each, quadratics both (rho2 (_DEG + 1): rho^2(s), with rho2[_DEG] holding 2 l_a and
    rho2[_DEG - 1] c_K)."""
    disc = b1 * b1 - 4.0 * b0
    if not disc > 0.0:
        return n_out
    sq = math.sqrt(disc)
    q = -0.5 * (b1 + sq if b1 >= 0.0 else b1 - sq)
    a2, a1, a0 = rho2[2], rho2[1], rho2[0]
    for u in (q, b0 / q):
        r = rho2[_DEG] * u - rho2[_DEG - 1]
        n_out = roots_of_quadratic(a2, a1, a0 - r, c, 4, lo, hi, out, err, ids, n_out, cid)
    return n_out


@njit(cache=True)
def _lin_mul(a0, a1, b0, b1, out):  # pragma: no cover - compiled
    """out[0:3] = (a0 + a1 s)(b0 + b1 s)."""
    out[0] = a0 * b0
    out[1] = a0 * b1 + a1 * b0
    out[2] = a1 * b1


@njit(cache=True)
def _limb_polys(p0, ax, g, i, passive, P, t):  # pragma: no cover - compiled
    """P[0:_NPOLY]: limb i's polynomials in s along p0 + s e_ax (see the module docstring);
    t (4, _DEG + 1): a buffer."""
    ex, ey, tx, ty = g[7 * i], g[7 * i + 1], g[7 * i + 2], g[7 * i + 3]
    spx, spy, spz = g[7 * i + 4], g[7 * i + 5], g[7 * i + 6]
    off, la, lb = g[21], g[22], g[23]
    vx, vy, vz = p0[0] + off * ex, p0[1] + off * ey, p0[2]
    ux, uy, uz = (1.0 if ax == 0 else 0.0), (1.0 if ax == 1 else 0.0), (1.0 if ax == 2 else 0.0)
    x0, x1 = vx * ex + vy * ey, ux * ex + uy * ey  # x = x0 + x1 s, likewise y and h
    y0, y1 = vx * tx + vy * ty, ux * tx + uy * ty
    h0, h1 = vz, uz
    rho2, K = t[0], t[1]
    rho2[:] = 0.0
    K[:] = 0.0
    rho2[0], rho2[1], rho2[2] = x0 * x0 + h0 * h0, 2.0 * (x0 * x1 + h0 * h1), x1 * x1 + h1 * h1
    inv = 0.5 / la
    K[0] = (rho2[0] + y0 * y0 + la * la - lb * lb) * inv
    K[1] = (rho2[1] + 2.0 * y0 * y1) * inv
    K[2] = (rho2[2] + y1 * y1) * inv
    # y constant (y1 = 0): K depends on rho^2 alone, and so do the reach and elbow quartics
    # (quadratics in u = K, see `_through_rho2`): row _NPOLY holds rho^2, row _NPOLY + 1 those quadratics
    cK = y0 * y0 + la * la - lb * lb
    P[_NPOLY, :] = 0.0
    P[_NPOLY, 0], P[_NPOLY, 1], P[_NPOLY, 2] = rho2[0], rho2[1], rho2[2]
    P[_NPOLY, _DEG - 1], P[_NPOLY, _DEG] = cK, 2.0 * la
    aux = P[_NPOLY + 1]
    aux[0] = 1.0 if y1 == 0.0 else 0.0
    aux[1], aux[2] = -2.0 * la, cK
    D = P[0]
    poly_mul(K, K, D)
    for k in range(5):
        D[k] = (rho2[k] if k < 3 else 0.0) - D[k]
    for j in (1, 2):
        cs, sn = (g[32], g[33]) if j == 1 else (g[34], g[35])
        P[j, :] = 0.0
        P[j, 0] = cs * x0 - sn * h0 - K[0]
        P[j, 1] = cs * x1 - sn * h1 - K[1]
        P[j, 2] = -K[2]
    if not passive:
        return
    cc = g[36]
    # elbow: ((K - l_a) cos c_E - l_b cos(cone))^2 - sin^2(c_E) D
    a = t[2]
    cE, sE2 = g[37], g[38]
    a[:] = 0.0
    for k in range(3):
        a[k] = K[k] * cE
    a[0] -= la * cE + lb * cc
    poly_mul(a, a, P[3])
    for k in range(5):
        P[3, k] -= sE2 * D[k]
    m = la * cE + lb * cc
    aux[3], aux[4] = -2.0 * cE * m - 2.0 * la * sE2, m * m + sE2 * cK
    # platform: P^2 - Q^2 D, P = rho^2 (-v.s_P - l_b cos(cone)) + l_a K (x e.s_P + h s_Pz)
    se = spx * ex + spy * ey
    st = spx * tx + spy * ty
    b = t[3]
    b[:] = 0.0
    b[0] = -(se * x0 + st * y0 + spz * h0) - lb * cc
    b[1] = -(se * x1 + st * y1 + spz * h1)
    poly_mul(rho2, b, a)
    b[0] = la * (se * x0 + spz * h0)
    b[1] = la * (se * x1 + spz * h1)
    pp = P[4]
    poly_mul(K, b, pp)  # l_a K (x e.s_P + h s_Pz)
    for k in range(4):
        a[k] += pp[k]
    poly_mul(a, a, pp)  # P^2
    q0, q1 = la * (se * h0 - spz * x0), la * (se * h1 - spz * x1)  # Q
    _lin_mul(q0, q1, q0, q1, b)
    b[3:] = 0.0
    poly_mul(b, D, a)
    for k in range(_DEG + 1):
        pp[k] -= a[k]


@njit(cache=True)
def _one_column(p0, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, zbox, c, polys, cand, err, ids,
                work, crit, prev_in, pm, pt, a, b, d, tbuf):  # pragma: no cover - compiled
    """Inside length per target of the column p0 + s e_ax, s in [z0, z1]; returns its signature."""
    h = SIGNATURE_SEED
    empty = np.int64(h >> np.uint64(1))
    for i in range(3):
        _limb_polys(p0, ax, g, i, passive, polys[i], tbuf)
    # the hull where every limb reaches: the reach quartics' roots, tested at the gaps' midpoints
    n = 0
    cand[n], err[n], ids[n] = z0, 0.0, -1
    n += 1
    for i in range(3):
        if polys[i, _NPOLY + 1, 0] != 0.0:
            n = _through_rho2(polys[i, _NPOLY + 1, 1], polys[i, _NPOLY + 1, 2], polys[i, _NPOLY], polys[i, 0], z0, z1,
                              cand, err, ids, n, 8 * i)
        else:
            n = real_roots(polys[i, 0], z0, z1, cand, err, ids, n, 8 * i, work, crit)
    cand[n], err[n], ids[n] = z1, 0.0, -2
    n += 1
    _sort(cand, err, ids, n)
    lo, hi = np.inf, -np.inf
    lo_k, hi_k = -1, -1
    for k in range(n - 1):
        if not cand[k + 1] > cand[k]:
            continue
        zm = 0.5 * (cand[k] + cand[k + 1])
        ok = True
        for i in range(3):
            if poly_value(polys[i, 0], 4, zm) < 0.0:
                ok = False
        if ok:
            if lo_k < 0:
                lo, lo_k = cand[k], k
            hi, hi_k = cand[k + 1], k + 1
    if lo_k < 0:
        return empty
    # every root inside the hull: the reach roots found above (sorted), then the other polynomials'
    lo_e, lo_id, hi_e, hi_id = err[lo_k], ids[lo_k], err[hi_k], ids[hi_k]
    n = 1
    cand[0], err[0], ids[0] = lo, lo_e, lo_id
    for k in range(lo_k + 1, hi_k):
        if lo < cand[k] < hi:
            cand[n], err[n], ids[n] = cand[k], err[k], ids[k]
            n += 1
    for i in range(3):
        for j in range(1, _NPOLY if passive else 3):
            if j < 3:  # actuator bounds: quadratics with leading coefficient -1 / (2 l_a) (of -K)
                n = quadratic_roots(polys[i, j], lo, hi, cand, err, ids, n, 8 * i + j)
            elif j == 3 and polys[i, _NPOLY + 1, 0] != 0.0:
                n = _through_rho2(polys[i, _NPOLY + 1, 3], polys[i, _NPOLY + 1, 4], polys[i, _NPOLY], polys[i, 3], lo, hi,
                                  cand, err, ids, n, 8 * i + j)
            else:
                n = real_roots(polys[i, j], lo, hi, cand, err, ids, n, 8 * i + j, work, crit)
    cand[n], err[n], ids[n] = hi, hi_e, hi_id
    n += 1
    _sort(cand, err, ids, n)
    prev_in[:] = False
    # a limb's slacks change sign only at its own roots: re-evaluate only the limbs whose roots were
    # passed since the last gap (bit i of dirty: limb i)
    dirty = 7
    for k in range(n - 1):
        if ids[k] >= 0:
            dirty |= 1 << (ids[k] // 8)
        za, zb = cand[k], cand[k + 1]
        if zb <= za:
            continue
        pt[0], pt[1], pt[2] = p0[0], p0[1], p0[2]
        pt[ax] += 0.5 * (za + zb)
        if dirty & 1:
            limb_kernel(pt[0], pt[1], pt[2], g, 0, passive, a)
        if dirty & 2:
            limb_kernel(pt[0], pt[1], pt[2], g, 1, passive, b)
        if dirty & 4:
            limb_kernel(pt[0], pt[1], pt[2], g, 2, passive, d)
        dirty = 0
        for m in range(8):
            pm[m] = min(a[(m >> 2) & 1], b[(m >> 1) & 1], d[m & 1])
        # an end at za is made by the constraint ids[k]
        h = add_gap(c, pm, modes, za, zb, ids[k], err[k], prev_in, out_len, out_err, out_ends, zbox, h)
    return close_column(c, prev_in, ids[n - 1], err[n - 1], out_err, out_ends, h)


@njit(cache=True)
def _sort(cand, err, ids, n):  # pragma: no cover - compiled
    """Insertion sort of cand[:n], carrying err and ids along (n <= _CAP: no allocation)."""
    for k in range(1, n):
        zk, ek, ik = cand[k], err[k], ids[k]
        j = k - 1
        while j >= 0 and cand[j] > zk:
            cand[j + 1], err[j + 1], ids[j + 1] = cand[j], err[j], ids[j]
            j -= 1
        cand[j + 1], err[j + 1], ids[j + 1] = zk, ek, ik


@njit(cache=True, parallel=True)
def _columns_kernel(base, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig,
                    zbox):  # pragma: no cover - compiled
    M = base.shape[0]
    chunks = min(M, 64)
    for ch in prange(chunks):
        _columns_range(base, ch * M // chunks, (ch + 1) * M // chunks, ax, z0, z1, g, passive, modes, out_len, out_err,
                       out_ends, out_sig, zbox)


@njit(cache=True)
def _columns_serial(base, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig,
                    zbox):  # pragma: no cover - compiled
    """`_columns_kernel` on one core (small batches: no parallel launch)."""
    _columns_range(base, 0, base.shape[0], ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig, zbox)


@njit(cache=True, inline="always")
def _columns_range(base, c0, c1, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, out_sig,
                   zbox):  # pragma: no cover - compiled
    """Columns c0..c1 - 1 of `_columns_kernel`."""
    o0, o1 = other_axes(ax)
    T = modes.shape[0] + 1
    p0 = np.zeros(3)
    polys = np.zeros((3, _NPOLY + 2, _DEG + 1))
    cand = np.empty(_CAP)
    err = np.empty(_CAP)
    ids = np.empty(_CAP, np.int64)
    work = np.zeros((_DEG + 1, _DEG + 1))
    crit = np.zeros((64, 2 * _DEG + 2))
    prev_in = np.zeros(T, np.bool_)
    pm = np.empty(8)
    pt = np.zeros(3)
    a = np.empty(8)
    b = np.empty(8)
    d = np.empty(8)
    tbuf = np.zeros((4, _DEG + 1))
    for c in range(c0, c1):
        p0[o0] = base[c, 0]
        p0[o1] = base[c, 1]
        p0[ax] = 0.0
        out_sig[c] = _one_column(p0, ax, z0, z1, g, passive, modes, out_len, out_err, out_ends, zbox, c, polys,
                                 cand, err, ids, work, crit, prev_in, pm, pt, a, b, d, tbuf)


class ExactColumns:
    """Exact columns of the Delta's per-mode and union margins (see the module docstring).

    Call it as `columns(base, axis, z0, z1)` with base (M, 2) the columns' other coordinates [m]:
    returns lengths (M, T) [m], their errors (M, T) [m], interval ends (M, T), signatures (M,)
    int64 and the inside extent along the axis of the last target (M, 2) (NaN where empty).
    """

    method = "real roots of polynomials of degree <= 6"
    """How the ends are found (for reports)."""

    def __init__(self, params: DeltaParams, modes: np.ndarray, passive: bool) -> None:
        self.passive = bool(passive)
        lo, hi = params.theta_limits
        # the scan kernel's geometry, then the trigonometry `_limb_polys` needs (indices 32-38)
        self.g = np.concatenate([kernel_geometry(params), [
            math.cos(lo), math.sin(lo), math.cos(hi), math.sin(hi), math.cos(params.cone),
            math.cos(params.elbow_socket), math.sin(params.elbow_socket) ** 2]])
        self.modes = np.ascontiguousarray(modes, dtype=np.int64)

    def __call__(self, base: np.ndarray, axis: int, z0: float, z1: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        base = np.ascontiguousarray(base, dtype=float)
        length, error, ends, sig, zbox = column_buffers(base.shape[0], len(self.modes) + 1)
        (_columns_kernel if len(base) >= PARALLEL_COLUMNS else _columns_serial)(
            base, int(axis), float(z0), float(z1), self.g, self.passive, self.modes, length, error, ends, sig, zbox)
        zbox[~np.isfinite(zbox)] = np.nan
        return length, error, ends, sig, zbox


def delta_margin(params: DeltaParams, cols: list[int], passive: bool) -> ThreeLimbMargin:
    """The Delta margin as `Delta.margin` returns it: each mode's slack (`scan.scan`), then their
    union, with `ExactColumns`."""
    return ThreeLimbMargin(params, cols, lambda points: scan(params, points, passive).margin,
                           ExactColumns(params, np.array(cols), passive))


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (_columns_kernel, _columns_serial)
