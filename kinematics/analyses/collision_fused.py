"""Compiled evaluations of the collision-free exact columns (`kinematics.analyses.collision_columns`)
for the 3-[P2(US)], each a single pass from column points to distances on every core, the tree
posed at each point by `p2us.configurations.configurations_kernel`:

* `distances`: every pair's signed distance at many points, as `AnalyticDistances.distances(
  signs=True)` at their configurations (+inf where a point has none), without the batched path's
  configuration array and its passes over it;
* `pair_roots`: each bracket's Illinois steps in one compiled loop on one pair's closed form, its
  two shapes' chains alone posed (as `AnalyticDistances.pair_distances(signs=True)`), without the
  batched path's configuration pass, distance pass and dozen numpy passes per step.

Both do the batched path's operations in the same order (the same values to the last bit). A point
or bracket where a pair has no closed form (a rod beside a plate: coal's) is flagged, and the
batched path evaluates it instead."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from kinematics.generic.capsule_kernels import joint_pose, pair_at, pair_value, place, scratch
from kinematics.generic.capsules import PARALLEL_MIN, PLATE
from kinematics.jit import on_cores
from kinematics.mechanisms.p2us.configurations import configurations_kernel


@njit(cache=True, parallel=True)
def pair_roots_kernel(bx, by, others, ax, za, zb, fa, fb, pair, root_tol, steps, e, w, t, geometry, roots, code,
                      limb, parent, kind, axis, iq, rot, tra, chain, chain_len, joint_of, local_p, local_axis, radius,
                      half, pairs, kinds, lo, hi, ylo, evaluations, failed):  # pragma: no cover - compiled
    """Bracket r (z in (za[r], zb[r]) [m] along axis ax of the column at (bx[r], by[r]) on the
    axes others, values fa[r], fb[r] of opposite signs of pair pair[r]'s distance) narrowed to
    root_tol by at most `steps` Illinois steps (false position clipped root_tol / 4 inside the
    bracket, bisection from the 8th step on; +inf where the point has no configuration): the
    final bracket lo[r], hi[r], the value ylo[r] at lo, the evaluations made; failed[r] where
    the pair needs coal at some step (the outputs are then not final)."""
    R = za.shape[0]
    for blk in prange((R + 63) // 64):
        Rm, pj, centre, gaxis, o, good = scratch(parent.shape[0], radius.shape[0], pairs.shape[0])
        pt = np.empty((1, 3))
        q = np.empty((1, code.shape[0]))
        for r in range(blk * 64, min(R, blk * 64 + 64)):
            a, c, ya, yc = za[r], zb[r], fa[r], fb[r]
            k = pair[r]
            side = 0
            n = 0
            failed[r] = False
            for step in range(steps):
                if not c - a > root_tol:
                    break
                if step < 8:
                    x = max(a - ya * (c - a) / (yc - ya), a + 0.25 * root_tol)
                    x = min(x, c - 0.25 * root_tol)
                else:
                    x = 0.5 * (a + c)
                pt[0, others[0]], pt[0, others[1]], pt[0, ax] = bx[r], by[r], x
                configurations_kernel(pt, e, w, t, geometry, roots, code, limb, q)
                n += 1
                y = math.inf
                if np.isfinite(q[0]).all():
                    pair_at(q, 0, k, parent, kind, axis, iq, rot, tra, chain, chain_len, joint_of, local_p, local_axis,
                            radius, half, pairs, kinds, Rm, pj, centre, gaxis, o, good)
                    y = o[0, k]
                    if not (good[0, k] or (kinds[k] == PLATE and y > 0.0)):
                        failed[r] = True
                        break
                below = (y >= 0.0) == (ya >= 0.0)  # the root is above x
                # Illinois: halve the value kept at the end that stays twice in a row
                if below and side == 1:
                    yc *= 0.5
                if not below and side == -1:
                    ya *= 0.5
                if below:
                    a, ya = x, y
                else:
                    c, yc = x, y
                side = 1 if below else -1
            lo[r], hi[r], ylo[r], evaluations[r] = a, c, ya, n


@njit(cache=True, parallel=True)
def distances_kernel(bx, by, z, others, ax, e, w, t, geometry, roots, code, limb, parent, kind, axis, iq, rot, tra,
                     of_geometry, used, local_p, local_axis, radius, half, pairs, kinds, out, need
                     ):  # pragma: no cover - compiled
    """out (N, P): every pair's closed form at the point z[n] along axis ax of the column at
    (bx[n], by[n]) on the axes others (a PLATE pair's positive lower bound kept; +inf in every
    pair where the point has no configuration); need[n] where some pair has no closed form there
    (coal's: the row is then not final), in blocks of 64 points on every core."""
    N = z.shape[0]
    for blk in prange((N + 63) // 64):
        Rm, pj, centre, gaxis, o, good = scratch(parent.shape[0], radius.shape[0], pairs.shape[0])
        pt = np.empty((1, 3))
        q = np.empty((1, code.shape[0]))
        for n in range(blk * 64, min(N, blk * 64 + 64)):
            pt[0, others[0]], pt[0, others[1]], pt[0, ax] = bx[n], by[n], z[n]
            configurations_kernel(pt, e, w, t, geometry, roots, code, limb, q)
            need[n] = False
            if not np.isfinite(q[0]).all():
                for k in range(pairs.shape[0]):
                    out[n, k] = math.inf
                continue
            for j in range(parent.shape[0]):
                joint_pose(q, 0, j, parent[j], kind[j], axis, iq[j], rot, tra, Rm, pj)
            for m in range(used.shape[0]):
                place(0, used[m], of_geometry[m], Rm, pj, local_p, local_axis, centre, gaxis)
            for k in range(pairs.shape[0]):
                pair_value(0, k, centre, gaxis, radius, half, pairs, kinds, o, good)
                out[n, k] = o[0, k]
                if not (good[0, k] or (kinds[k] == PLATE and o[0, k] > 0.0)):
                    need[n] = True


def distances(kernel_data: tuple[np.ndarray, ...], dist: Any, base: np.ndarray, ax: int, z: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """`distances_kernel` at the points z (N,) [m] along axis ax of the columns at base (N, 2)
    (`kernel_data`: `p2us.configurations.kernel_data` of the branch; `dist`: the
    `AnalyticDistances`): (N, P) distances and the rows the batched path must evaluate instead."""
    N = len(z)
    out = np.empty((N, len(dist.kinds)))
    need = np.zeros(N, np.bool_)
    others = np.array([k for k in range(3) if k != ax], np.int64)
    base = np.ascontiguousarray(base, dtype=float)
    on_cores(distances_kernel, N, PARALLEL_MIN, np.ascontiguousarray(base[:, 0]), np.ascontiguousarray(base[:, 1]),
                     np.ascontiguousarray(z, dtype=float), others, ax, *kernel_data, *dist.closed_form_data(), out, need)
    return out, need


def pair_roots(kernel_data: tuple[np.ndarray, ...], distances: Any, base: np.ndarray, ax: int, za: np.ndarray,
               zb: np.ndarray, fa: np.ndarray, fb: np.ndarray, pair: np.ndarray, root_tol: float, steps: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`pair_roots_kernel` on the brackets of pair pair[r]'s distance along the columns at base
    (R, 2) (`kernel_data`: `p2us.configurations.kernel_data` of the branch; `distances`: the
    `AnalyticDistances`): lo, hi, ylo (R,), the evaluations made (R,), and where the batched
    path must refine instead (R,) bool."""
    R = len(za)
    lo, hi, ylo = np.empty(R), np.empty(R), np.empty(R)
    evaluations = np.zeros(R, np.int64)
    failed = np.zeros(R, np.bool_)
    others = np.array([k for k in range(3) if k != ax], np.int64)
    base = np.ascontiguousarray(base, dtype=float)
    on_cores(pair_roots_kernel, R, PARALLEL_MIN, np.ascontiguousarray(base[:, 0]), np.ascontiguousarray(base[:, 1]), others, ax,
                      np.ascontiguousarray(za, dtype=float), np.ascontiguousarray(zb, dtype=float),
                      np.ascontiguousarray(fa, dtype=float), np.ascontiguousarray(fb, dtype=float),
                      np.ascontiguousarray(pair, dtype=np.int64), float(root_tol), int(steps), *kernel_data,
                      *distances.pair_kernel_data(), lo, hi, ylo, evaluations, failed)
    return lo, hi, ylo, evaluations, failed


def illinois(evaluate: Any, za: np.ndarray, zb: np.ndarray, fa: np.ndarray, fb: np.ndarray, root_tol: float,
             steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Brackets (za, zb) of roots (values fa, fb of opposite signs; `evaluate(rows, z)` the
    values at z of brackets `rows`) narrowed to `root_tol` by at most `steps` steps (Illinois
    false position, bisection from the 8th step on), batched over the live brackets: the final
    brackets and their values."""
    za, zb, fa, fb = za.copy(), zb.copy(), fa.copy(), fb.copy()
    side = np.zeros(len(za), np.int64)
    rows = np.arange(len(za))
    for step in range(steps):
        live = rows[zb[rows] - za[rows] > root_tol]
        if not len(live):
            break
        rows = live
        a, c, ya, yc = za[rows], zb[rows], fa[rows], fb[rows]
        tol = 0.25 * root_tol
        x = np.clip(a - ya * (c - a) / (yc - ya), a + tol, c - tol) if step < 8 else 0.5 * (a + c)
        y = evaluate(rows, x)
        below = (y >= 0) == (ya >= 0)  # the root is above x
        # Illinois: halve the value kept at the end that stays twice in a row
        fb[rows[below & (side[rows] == 1)]] *= 0.5
        fa[rows[~below & (side[rows] == -1)]] *= 0.5
        za[rows[below]], fa[rows[below]] = x[below], y[below]
        zb[rows[~below]], fb[rows[~below]] = x[~below], y[~below]
        side[rows] = np.where(below, 1, -1)
    return za, zb, fa, fb


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (distances_kernel, pair_roots_kernel)


__all__ = ["distances", "distances_kernel", "illinois", "pair_roots", "pair_roots_kernel"]
