"""Compiled kernels of `kinematics.generic.capsules`: placements of the closed-form shapes over
the tree of their joints, and the closed-form pair distances (every pair per configuration, or one
chosen pair per configuration with its two shapes placed alone), each `parallel=True` (a small
batch runs it on one thread, `jit.on_cores`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def tree_kernel(q, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis
                 ):  # pragma: no cover - compiled
    """World placements of every joint of the tree (parents first), oM_j = oM_parent M_j X_j(q)
    with X_j a rotation by t about the axis a (Rodrigues, as Pinocchio; (cos t, sin t) from q for
    a continuous joint) or a translation t a; then each used geometry's centre oR_j p + op_j and
    axis oR_j a_local, in blocks of 64 configurations on every core."""
    J = parent.shape[0]
    for blk in prange((q.shape[0] + 63) // 64):
        R = np.empty((J, 3, 3))
        p = np.empty((J, 3))
        for n in range(blk * 64, min(q.shape[0], blk * 64 + 64)):
            tree_row(q, n, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis,
                      R, p)


@njit(cache=True, inline="always")
def tree_row(q, n, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, centre, out_axis, R, p
              ):  # pragma: no cover - compiled
    """`tree_kernel` at configuration n, with scratch R (J, 3, 3) and p (J, 3)."""
    for j in range(parent.shape[0]):
        joint_pose(q, n, j, parent[j], kind[j], axis, iq[j], rot, tra, R, p)
    for m in range(used.shape[0]):
        place(n, used[m], of_geometry[m], R, p, local_p, local_axis, centre, out_axis)


@njit(cache=True, inline="always")
def place(n, g, j, R, p, local_p, local_axis, centre, out_axis):  # pragma: no cover - compiled
    """Geometry g's world centre and axis at configuration n from its joint j's pose (-1: the world)."""
    for r in range(3):
        if j < 0:
            centre[n, g, r], out_axis[n, g, r] = local_p[g, r], local_axis[g, r]
        else:
            centre[n, g, r] = p[j, r] + R[j, r, 0] * local_p[g, 0] + R[j, r, 1] * local_p[g, 1] \
                + R[j, r, 2] * local_p[g, 2]
            out_axis[n, g, r] = R[j, r, 0] * local_axis[g, 0] + R[j, r, 1] * local_axis[g, 1] \
                + R[j, r, 2] * local_axis[g, 2]


@njit(cache=True, inline="always")
def joint_pose(q, n, j, u, kind, axis, iq, rot, tra, R, p):  # pragma: no cover - compiled
    """Joint j's world rotation R[j] and origin p[j] at configuration q[n], from its parent u's."""
    for r in range(3):
        if u < 0:
            for c in range(3):
                R[j, r, c] = rot[j, r, c]
            p[j, r] = tra[j, r]
        else:
            for c in range(3):
                R[j, r, c] = R[u, r, 0] * rot[j, 0, c] + R[u, r, 1] * rot[j, 1, c] + R[u, r, 2] * rot[j, 2, c]
            p[j, r] = p[u, r] + R[u, r, 0] * tra[j, 0] + R[u, r, 1] * tra[j, 1] + R[u, r, 2] * tra[j, 2]
    ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
    t = q[n, iq]
    if kind == 2:  # prismatic: p += t R a
        for r in range(3):
            p[j, r] += t * (R[j, r, 0] * ax + R[j, r, 1] * ay + R[j, r, 2] * az)
        return
    if kind == 1:  # continuous: (cos t, sin t) from q
        cs, sn = t, q[n, iq + 1]
    else:
        cs, sn = math.cos(t), math.sin(t)
    d = 1.0 - cs
    e00, e01, e02 = cs + d * ax * ax, d * ax * ay - sn * az, d * ax * az + sn * ay
    e10, e11, e12 = d * ay * ax + sn * az, cs + d * ay * ay, d * ay * az - sn * ax
    e20, e21, e22 = d * az * ax - sn * ay, d * az * ay + sn * ax, cs + d * az * az
    for r in range(3):
        a0, a1, a2 = R[j, r, 0], R[j, r, 1], R[j, r, 2]
        R[j, r, 0] = a0 * e00 + a1 * e10 + a2 * e20
        R[j, r, 1] = a0 * e01 + a1 * e11 + a2 * e21
        R[j, r, 2] = a0 * e02 + a1 * e12 + a2 * e22


@njit(cache=True, inline="always")
def segments(p1x, p1y, p1z, d1x, d1y, d1z, p2x, p2y, p2z, d2x, d2y, d2z):  # pragma: no cover - compiled
    """Distance [m] between segments p1 + s d1 and p2 + t d2, s, t in [0, 1] (Ericson 5.1.9,
    clamped; parallel and degenerate segments included)."""
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-300
    s = 0.0
    t = 0.0
    if a <= eps and e <= eps:
        pass
    elif a <= eps:
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            if denom > 0.0:
                s = min(max((b * f - c * e) / denom, 0.0), 1.0)
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    x = rx + d1x * s - d2x * t
    y = ry + d1y * s - d2y * t
    z = rz + d1z * s - d2z * t
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True, parallel=True)
def pairs_kernel(centre, axis, radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    for n in prange(centre.shape[0]):
        pairs_row(n, centre, axis, radius, half, pairs, kinds, out, ok)


@njit(cache=True, inline="always")
def pairs_row(n, centre, axis, radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """Every pair's closed form at configuration n."""
    for k in range(pairs.shape[0]):
        pair_value(n, k, centre, axis, radius, half, pairs, kinds, out, ok)


@njit(cache=True, inline="always")
def pair_value(n, k, centre, axis, radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """Pair k's closed form at configuration n: out[n, k], ok[n, k] (`AnalyticDistances.closed_form`)."""
    i = pairs[k, 0]
    j = pairs[k, 1]
    kind = kinds[k]
    if kind == 2:
        out[n, k] = np.nan
        ok[n, k] = False
        return
    hi = half[i]
    ax, ay, az = axis[n, i, 0], axis[n, i, 1], axis[n, i, 2]
    p1x = centre[n, i, 0] - hi * ax
    p1y = centre[n, i, 1] - hi * ay
    p1z = centre[n, i, 2] - hi * az
    if kind == 0:
        hj = half[j]
        bx, by, bz = axis[n, j, 0], axis[n, j, 1], axis[n, j, 2]
        dist = segments(p1x, p1y, p1z, 2 * hi * ax, 2 * hi * ay, 2 * hi * az,
                         centre[n, j, 0] - hj * bx, centre[n, j, 1] - hj * by, centre[n, j, 2] - hj * bz,
                         2 * hj * bx, 2 * hj * by, 2 * hj * bz)
        out[n, k] = dist - radius[i] - radius[j]
        ok[n, k] = True
        return
    if kind == 3:  # capsule i against the half-space j: n.x <= n.c
        zu = axis[n, j, 0] * (p1x - centre[n, j, 0]) + axis[n, j, 1] * (p1y - centre[n, j, 1]) \
            + axis[n, j, 2] * (p1z - centre[n, j, 2])
        zv = zu + 2 * hi * (axis[n, j, 0] * ax + axis[n, j, 1] * ay + axis[n, j, 2] * az)
        out[n, k] = min(zu, zv) - radius[i]
        ok[n, k] = True
        return
    # capsule i against plate j (axis a, centre c): end heights z and axis distances rho
    cx, cy, cz = centre[n, j, 0], centre[n, j, 1], centre[n, j, 2]
    a0, a1, a2 = axis[n, j, 0], axis[n, j, 1], axis[n, j, 2]
    ux, uy, uz = p1x - cx, p1y - cy, p1z - cz
    vx, vy, vz = ux + 2 * hi * ax, uy + 2 * hi * ay, uz + 2 * hi * az
    zu = a0 * ux + a1 * uy + a2 * uz
    zv = a0 * vx + a1 * vy + a2 * vz
    wx, wy, wz = ux - zu * a0, uy - zu * a1, uz - zu * a2
    ru = math.sqrt(wx * wx + wy * wy + wz * wz)
    wx, wy, wz = vx - zv * a0, vy - zv * a1, vz - zv * a2
    rv = math.sqrt(wx * wx + wy * wy + wz * wz)
    r = radius[i]
    h = half[j]
    d = max(min(zu, zv) - r - h, -h - max(zu, zv) - r)
    ok[n, k] = max(ru, rv) + r <= radius[j] - max(0.0, -d)
    if ok[n, k] or d > 0.0:
        out[n, k] = d  # exact, or a lower bound: the disk is in the slab
        return
    # beside the disk: on the axis part within the band |z| <= h + r + m (m = h + r > 0) the
    # segment's distance to the axis, less R + r, bounds the gap; beyond the band the
    # height alone keeps the segment m + r away: min(m, that) when positive, else NaN
    m = h + r
    band = h + r + m
    s0, s1 = 0.0, 1.0
    if zv != zu:
        sa = (-band - zu) / (zv - zu)
        sb = (band - zu) / (zv - zu)
        s0 = max(0.0, min(sa, sb))
        s1 = min(1.0, max(sa, sb))
    gap = m
    if s0 <= s1:
        e0x, e0y, e0z = p1x + 2 * hi * ax * s0, p1y + 2 * hi * ay * s0, p1z + 2 * hi * az * s0
        rho = segments(e0x, e0y, e0z, 2 * hi * ax * (s1 - s0), 2 * hi * ay * (s1 - s0), 2 * hi * az * (s1 - s0),
                        cx - band * a0, cy - band * a1, cz - band * a2, 2 * band * a0, 2 * band * a1, 2 * band * a2)
        gap = min(m, rho - radius[j] - r)
    out[n, k] = gap if gap > 0.0 else np.nan


@njit(cache=True, inline="always")
def scratch(J, G, P):  # pragma: no cover - compiled
    """One configuration's work arrays for J tree joints, G shapes and P pairs: the joints'
    rotations (J, 3, 3) and origins (J, 3), the shapes' centres and axes (1, G, 3), the pairs'
    values (1, P) and flags (1, P)."""
    return (np.empty((max(J, 1), 3, 3)), np.empty((max(J, 1), 3)), np.zeros((1, G, 3)), np.zeros((1, G, 3)),
            np.empty((1, P)), np.empty((1, P), np.bool_))


@njit(cache=True, parallel=True)
def closed_form_kernel(q, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, radius, half,
                       pairs, kinds, out, ok):  # pragma: no cover - compiled
    """out (N, P), ok (N, P): every pair's closed form (`pair_value`) at each configuration, the
    tree posed (`tree_row`) into per-block scratch (no (N, G, 3) placements), in blocks of 64
    configurations on every core: `tree_kernel` then `pairs_kernel` in one pass."""
    N = q.shape[0]
    for blk in prange((N + 63) // 64):
        closed_form_block(q, blk * 64, min(N, blk * 64 + 64), parent, kind, axis, iq, rot, tra, of_geometry, used,
                          local_p, local_axis, radius, half, pairs, kinds, out, ok)


@njit(cache=True, inline="always")
def closed_form_block(q, n0, n1, parent, kind, axis, iq, rot, tra, of_geometry, used, local_p, local_axis, radius,
                      half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """`closed_form_kernel` for configurations n0..n1 - 1."""
    R, p, centre, gaxis, o, good = scratch(parent.shape[0], radius.shape[0], pairs.shape[0])
    for n in range(n0, n1):
        for j in range(parent.shape[0]):
            joint_pose(q, n, j, parent[j], kind[j], axis, iq[j], rot, tra, R, p)
        for m in range(used.shape[0]):
            place(0, used[m], of_geometry[m], R, p, local_p, local_axis, centre, gaxis)
        for k in range(pairs.shape[0]):
            pair_value(0, k, centre, gaxis, radius, half, pairs, kinds, o, good)
            out[n, k], ok[n, k] = o[0, k], good[0, k]


@njit(cache=True, parallel=True)
def pair_rows_kernel(q, pair, parent, kind, axis, iq, rot, tra, chain, chain_len, joint_of, local_p, local_axis,
                     radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """out[n], ok[n]: pair pair[n]'s closed form at configuration n (`pair_value`), the joints on
    the chains of its two shapes alone posed (chain[j, :chain_len[j]]: tree joint j's ancestors and
    itself, parents first; joint_of[g]: shape g's tree joint, -1 the world), in blocks of 64
    configurations on every core."""
    N = q.shape[0]
    for blk in prange((N + 63) // 64):
        pair_rows_block(q, pair, blk * 64, min(N, blk * 64 + 64), parent, kind, axis, iq, rot, tra, chain, chain_len,
                        joint_of, local_p, local_axis, radius, half, pairs, kinds, out, ok)


@njit(cache=True, inline="always")
def pair_at(q, n, k, parent, kind, axis, iq, rot, tra, chain, chain_len, joint_of, local_p, local_axis, radius, half,
            pairs, kinds, R, p, centre, gaxis, o, good):  # pragma: no cover - compiled
    """Pair k's closed form at configuration q[n] into o[0, k], good[0, k], the joints on the
    chains of its two shapes alone posed (scratch R, p, centre, gaxis as `scratch`'s)."""
    for s in range(2):
        g = pairs[k, s]
        j = joint_of[g]
        if j >= 0:
            for c in range(chain_len[j]):
                jj = chain[j, c]
                joint_pose(q, n, jj, parent[jj], kind[jj], axis, iq[jj], rot, tra, R, p)
        place(0, g, j, R, p, local_p, local_axis, centre, gaxis)
    pair_value(0, k, centre, gaxis, radius, half, pairs, kinds, o, good)


@njit(cache=True, inline="always")
def pair_rows_block(q, pair, n0, n1, parent, kind, axis, iq, rot, tra, chain, chain_len, joint_of, local_p, local_axis,
                    radius, half, pairs, kinds, out, ok):  # pragma: no cover - compiled
    """`pair_rows_kernel` for configurations n0..n1 - 1."""
    R, p, centre, gaxis, o, good = scratch(parent.shape[0], radius.shape[0], pairs.shape[0])
    for n in range(n0, n1):
        k = pair[n]
        pair_at(q, n, k, parent, kind, axis, iq, rot, tra, chain, chain_len, joint_of, local_p, local_axis, radius, half,
                pairs, kinds, R, p, centre, gaxis, o, good)
        out[n], ok[n] = o[0, k], good[0, k]


def kernels() -> tuple[Any, ...]:
    """The compiled kernels (for `kinematics.jit`)."""
    return (pairs_kernel, tree_kernel, closed_form_kernel, pair_rows_kernel)


__all__ = ["closed_form_kernel", "joint_pose", "pair_at", "pair_rows_kernel", "pair_value", "pairs_kernel",
           "place", "scratch", "segments", "tree_kernel"]
