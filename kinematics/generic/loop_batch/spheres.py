"""Spherical joints behind 6D closures, solved in closed form (`SphereCut`, the block solver's
reduced blocks).

A 6D closure welds frame f_s, carried by the last link of a concurrent revolute triple (j1, j2, j3:
an Euler-angle spherical joint, `LoopStructure.concurrent_groups`) with nothing else on that link,
to a frame f_o of another chain. Its six equations then split: the triple's centre c (the origin
of j1, j2 and j3) must sit where the weld puts j3's frame,

    c = p(oM_o . fM_o . fM_s^-1)          (3 equations: a point closure),

and the triple's angles follow from the two links' orientations in closed form: with R_p the world
rotation of j1's parent link, jR_i the fixed rotations of the joints' placements and a_i their
axes, R_p jR_1 Rot(a_1, x_1) jR_2 Rot(a_2, x_2) jR_3 Rot(a_3, x_3) = oR_o fR_o fR_s^T. Moving the
fixed rotations to the right (jR Rot(a, x) = Rot(jR a, x) jR), Rot(u_1, x_1) Rot(v_2, x_2)
Rot(v_3, x_3) = Q with u_1 = a_1, v_2 = jR_2 a_2, v_3 = jR_2 jR_3 a_3 mutually perpendicular and
Q = (R_p jR_1)^T oR_o fR_o fR_s^T (jR_2 jR_3)^T; in the basis E = [u_1, v_2, h v_3] (h = det of
the three axes, so that det E = 1) M = E^T Q E = Rx(x_1) Ry(x_2) Rz(h x_3), whence
x_2 = atan2(M_02, hypot(M_12, M_22)) (cos x_2 >= 0: `LoopStructure.canonical`'s representation),
x_1 = atan2(-M_12, M_22), x_3 = h atan2(-M_01, M_00).

The block solver then solves the block with the point closure in place of the 6D one (Gepetto's
`5bar_linkage_iso6d`: 5 unknowns and 5 rows instead of 8 and 8) and writes the triple's angles
after each solve (`BlockSolver`). Its branch labels stay those of the full block: at a root, the
full block's determinant is the reduced one's times a positive factor (the orientation rows'
rate matrix) times det[w_1 w_2 w_3] = +-cos x_2, the sign fixed by the model, which
`LoopStructure.label_of` already divides out; the constant sign is read at the atlas poses.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from kinematics.generic.loop_batch.compiled import REVOLUTE


class SphereCut(NamedTuple):
    """A 6D closure whose one side ends in a spherical triple (module docstring).

    Attributes:
        closure: the closure's index (sidecar order).
        joints: the triple's degree-of-freedom indices (j1, j2, j3).
        centre: the point closure's frame on j1's parent link: (parent joint, R, t), the triple's
            centre (j1's placement).
        other: its frame on the other side: (parent joint of f_o, fR_o fR_s^T, the origin of j3's
            frame at closure in f_o's parent joint frame).
        basis: E (3 x 3, columns u_1, v_2, h v_3, in j1's frame); hand: h.
        tail: jR_2 jR_3.
        head: jR_1.
    """

    closure: int
    joints: tuple[int, int, int]
    centre: tuple[int, np.ndarray, np.ndarray]
    other: tuple[int, np.ndarray, np.ndarray]
    basis: np.ndarray
    hand: float
    tail: np.ndarray
    head: np.ndarray


def sphere_cuts(g: tuple[Any, ...], groups: tuple[tuple[int, ...], ...]) -> dict[int, SphereCut]:
    """The 6D closures of model tuple g (`LoopModel._g`) that end in one of the concurrent triples
    `groups` on one side, by closure index: the triple's last link carries that closure frame and
    no other frame and no joint, and the closure's other frame does not hang below the triple."""
    parent, _, axis, jR, jt, fparent, fR, ft, anc, ctype, cf1, cf2 = (g[i] for i in range(12))
    triples = {grp[2]: grp for grp in groups if len(grp) == 3}
    used = list(cf1) + list(cf2) + [g[12]]
    cuts: dict[int, SphereCut] = {}
    for c, kind in enumerate(ctype):
        if kind != 1:
            continue
        for fs, fo in ((int(cf1[c]), int(cf2[c])), (int(cf2[c]), int(cf1[c]))):
            j3 = int(fparent[fs])
            grp = triples.get(j3)
            if grp is None or np.any(parent == j3) or anc[fo, grp[0]]:
                continue
            if sum(1 for f in used if int(fparent[f]) == j3) != 1 or sum(1 for f in used if f == fs) != 1:
                continue
            j1, j2, _ = grp
            u1 = axis[j1]
            v2 = jR[j2] @ axis[j2]
            tail = jR[j2] @ jR[j3]
            v3 = tail @ axis[j3]
            hand = float(np.sign(np.linalg.det(np.stack([u1, v2, v3], axis=1))))
            R_o = fR[fo] @ fR[fs].T
            cuts[c] = SphereCut(c, (int(j1), int(j2), int(j3)), (int(parent[j1]), jR[j1].copy(), jt[j1].copy()),
                                (int(fparent[fo]), R_o, ft[fo] - R_o @ ft[fs]), np.stack([u1, v2, hand * v3], axis=1),
                                hand, tail, jR[j1].copy())
            break
    return cuts


@njit(cache=True, inline="always")
def _link_rotation(x, r, parent_chain, nchain, turns, axis, jR, R, tmp):  # pragma: no cover - compiled
    """R (3 x 3) = the world rotation of the link at the end of parent_chain[:nchain] (joints from
    the root down; none: the base) at joint values x[r]: R_j = R_parent jR_j Rot(axis_j, x_j) (turns[j]:
    a revolute; else jR_j only)."""
    for a in range(3):
        for b in range(3):
            R[a, b] = 1.0 if a == b else 0.0
    for q in range(nchain):
        j = parent_chain[q]
        for a in range(3):
            for b in range(3):
                tmp[a, b] = R[a, 0] * jR[j, 0, b] + R[a, 1] * jR[j, 1, b] + R[a, 2] * jR[j, 2, b]
        if turns[j]:
            ax, ay, az = axis[j, 0], axis[j, 1], axis[j, 2]
            c, s = math.cos(x[r, j]), math.sin(x[r, j])
            d = 1.0 - c
            e00, e01, e02 = c + d * ax * ax, d * ax * ay - s * az, d * ax * az + s * ay
            e10, e11, e12 = d * ay * ax + s * az, c + d * ay * ay, d * ay * az - s * ax
            e20, e21, e22 = d * az * ax - s * ay, d * az * ay + s * ax, c + d * az * az
            for a in range(3):
                t0, t1, t2 = tmp[a, 0], tmp[a, 1], tmp[a, 2]
                R[a, 0] = t0 * e00 + t1 * e10 + t2 * e20
                R[a, 1] = t0 * e01 + t1 * e11 + t2 * e21
                R[a, 2] = t0 * e02 + t1 * e12 + t2 * e22
        else:
            for a in range(3):
                for b in range(3):
                    R[a, b] = tmp[a, b]


@njit(cache=True)
def angles_kernel(x, turns, axis, jR, chain_p, np_, chain_o, no, left, right, basis, hand, out):  # pragma: no cover - compiled
    """`sphere_angles` per row of x: Q = (R_p left)^T R_o right, M = E^T Q E, the angles into out."""
    Rp = np.empty((3, 3))
    Ro = np.empty((3, 3))
    tmp = np.empty((3, 3))
    Q = np.empty((3, 3))
    M = np.empty((3, 3))
    for r in range(x.shape[0]):
        _link_rotation(x, r, chain_p, np_, turns, axis, jR, Rp, tmp)
        _link_rotation(x, r, chain_o, no, turns, axis, jR, Ro, tmp)
        for a in range(3):  # tmp = (R_p left)^T, Q = tmp R_o right
            for b in range(3):
                tmp[a, b] = Rp[b, 0] * left[0, a] + Rp[b, 1] * left[1, a] + Rp[b, 2] * left[2, a]
        for a in range(3):
            for b in range(3):
                M[a, b] = tmp[a, 0] * Ro[0, b] + tmp[a, 1] * Ro[1, b] + tmp[a, 2] * Ro[2, b]
        for a in range(3):
            for b in range(3):
                Q[a, b] = M[a, 0] * right[0, b] + M[a, 1] * right[1, b] + M[a, 2] * right[2, b]
        for a in range(3):  # M = E^T Q E
            for b in range(3):
                tmp[a, b] = Q[a, 0] * basis[0, b] + Q[a, 1] * basis[1, b] + Q[a, 2] * basis[2, b]
        for a in range(3):
            for b in range(3):
                M[a, b] = basis[0, a] * tmp[0, b] + basis[1, a] * tmp[1, b] + basis[2, a] * tmp[2, b]
        out[r, 0] = math.atan2(-M[1, 2], M[2, 2])
        out[r, 1] = math.atan2(M[0, 2], math.hypot(M[1, 2], M[2, 2]))
        out[r, 2] = hand * math.atan2(-M[0, 1], M[0, 0])


def _chain(parent: np.ndarray, j: int) -> np.ndarray:
    """Joint j's ancestors and j, from the root down (empty for the base, -1)."""
    out = []
    while j >= 0:
        out.append(j)
        j = int(parent[j])
    return np.array(out[::-1], dtype=np.int64)


def sphere_angles(g: tuple[Any, ...], cut: SphereCut, x: np.ndarray) -> np.ndarray:
    """(R, 3) the triple's angles [rad] (module docstring; cos x_2 >= 0, each in (-pi, pi]) that
    close the 6D closure at joint values x (R, n) of every joint above the triple and of the other
    chain (the triple's own entries are not read)."""
    parent, kind, axis, jR = g[0], g[1], g[2], g[3]
    cp, co = _chain(parent, cut.centre[0]), _chain(parent, cut.other[0])
    x = np.ascontiguousarray(x, dtype=float)
    out = np.empty((len(x), 3))
    if len(x):
        angles_kernel(x, np.asarray(kind) == REVOLUTE, np.ascontiguousarray(axis, dtype=float),
                      np.ascontiguousarray(jR, dtype=float), cp, len(cp), co, len(co), np.ascontiguousarray(cut.head),
                      np.ascontiguousarray(cut.other[1] @ cut.tail.T), np.ascontiguousarray(cut.basis), float(cut.hand), out)
    return out


def wrap(x: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Angles [rad] to within pi of their centres (`LoopStructure.canonical`, the spherical joints' angles)."""
    return (x - centre + math.pi) % (2 * math.pi) + centre - math.pi
