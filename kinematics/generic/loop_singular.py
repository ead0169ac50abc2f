"""Signed singularity fields of any closed loop from the batched solver, for singular-locus scans
(`kinematics.analyses.singularities.singular_loci`): a sign change between grid neighbours marks
a type I locus of one labelling block (limb) or a type II locus of one branch.

**Type I, per labelling block k** (the square block of the loop equations that holds actuator k's
working-mode sign, `LoopBatch.label_blocks`). With the end effector at the target:

* where some branch assembles: s_k = the largest, over the branches found, of
  |det(B_k D_k^-1)| (B_k the block's Jacobian at that branch's solution, D_k its column norms: a
  scale-free number in [0, 1] that vanishes where the block's two roots merge, its type I locus);
* elsewhere, the blocks are solved one at a time in their triangular order (each block's unknowns
  from its own equations, the earlier blocks' held, by the same Levenberg-Marquardt kernel, from
  the branch search's last start): s_k = |det| as above where block k closes (its residual within
  the solver's TOL), else minus its least-squares residual [m] (< 0: the limb cannot reach).
  In a URDF tree the platform hangs on one limb and the other limbs' closures are measured from
  it; for a translational mechanism with a 3D task the platform's pose is the target's, so those
  closure blocks are solved with the platform placed there (`LoopBatch.newton(pinned=True)`),
  whether or not the carrying limb reaches. Where an earlier block that block k still depends on
  does not close (a mechanism whose end-effector orientation is not held, or a closure to an
  intermediate link), s_k is NaN (undefined); a scan skips edges with a NaN end.

A representation singularity of a universal or spherical joint (its middle angle at +-90 deg)
also zeroes det(B_k) (by a factor cos b), but |det| does not change sign there, so no locus is
reported: only a block with no roots at all makes s_k negative.

**Type II, per branch b**: det of J^-1 D^-1 (J^-1 the inverse Jacobian, actuator rates per task
velocity, `LoopBatch.jacobians`; D its row norms): vanishes where a task velocity needs no actuator
rate (locked actuators do not hold the end effector) and changes sign there; NaN where the branch
is absent. It also changes sign through infinity at type I, but there the branch ends, so a scan
never sees both ends of that edge in the branch. Mechanisms whose actuator count differs from the
task dimension have no square J^-1: the field is NaN (no type II locus is reported).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

__all__ = ["LoopFields", "loop_fields"]


class LoopFields(NamedTuple):
    """Per task point (see the module docstring).

    Attributes:
        margin: (N, B) each branch's joint-limit margin [m] (minus its residual where absent).
        limb: (N, L) type I field per labelling block (>= 0 where the block closes; NaN undefined).
        det: (N, B) type II field per branch, in [-1, 1] (NaN where the branch is absent).
    """

    margin: np.ndarray
    limb: np.ndarray
    det: np.ndarray


def _block_measure(J: np.ndarray, blk: Any) -> np.ndarray:
    """|det(B_k D_k^-1)| of labelling block `blk` in Jacobians J (R, m, n): scale-free, in [0, 1]."""
    return np.abs(_normalised_det(J[:, list(blk.rows)][:, :, list(blk.cols)], axis=-2))


def _normalised_det(M: np.ndarray, axis: int) -> np.ndarray:
    """det of M with its columns (axis -2) or rows (axis -1) scaled to unit norm."""
    norms = np.linalg.norm(M, axis=axis, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.det(M / np.where(norms > 0, norms, 1.0))


def loop_fields(batch: Any, points: np.ndarray, limits: str = "all") -> LoopFields:
    """The signed fields of `batch` (a `kinematics.generic.loop_batch.LoopBatch`) at task points
    (N, d) [m], joint limits `limits` for the margins.

    Raises:
        UnsupportedRobotError: the batch holds its end effector at a rotation (`require_unheld`).
    """
    from kinematics.generic.loop_batch import TOL

    batch.require_unheld("singular fields")
    p = np.atleast_2d(np.asarray(points, dtype=float))
    sol = batch.ik(p, every_block=True)  # each block's own end outside (the whole-system solver has them anyway)
    N, B = sol.found.shape
    x = np.nan_to_num(sol.x)
    margin = np.where(sol.found, batch.limit_margin(x.reshape(-1, batch.n), limits).reshape(N, B), sol.margin)
    blocks = batch.label_blocks
    L = len(blocks)
    limb = np.full((N, L), np.nan)
    # inside: the best |det| of each labelling block over the branches found
    k_i, b_i = np.nonzero(sol.found)
    if len(k_i):
        _, J, _ = batch.evaluate(p[k_i], sol.x[k_i, b_i])
        for k, blk in enumerate(blocks):
            s = _block_measure(J, blk)
            best = np.full(N, -np.inf)
            np.maximum.at(best, k_i, s)
            limb[:, k] = np.where(np.isfinite(best), best, limb[:, k])
    # outside every branch: block by block from where the search ended
    out = np.flatnonzero(~sol.found.any(axis=1))
    if len(out):
        ends = sol.end[out]
        start = ends[np.arange(len(out)), np.argmin(np.where(np.isfinite(ends[..., 0]), sol.residual[out], np.inf),
                                                            axis=1)]
        xs = np.where(np.isfinite(start), start, batch.atlas[0])
        closed: dict[int, np.ndarray] = {}  # block index -> (R,) closes
        # the Jacobian's pattern at the atlas: the row count and which blocks feed which
        _, J0, _ = batch.evaluate(np.zeros((1, batch.task_dim)), batch.atlas[:1])
        m = J0.shape[1]
        used = {pinned: (np.abs(J0[0]) > 0.0) & batch.row_dependencies(pinned) for pinned in (False, True)
                if batch.can_pin or not pinned}
        label_index = {blk: k for k, blk in enumerate(blocks)}
        task = set(batch.task_rows)
        for j, blk in enumerate(batch.blocks):
            if not blk.cols:
                continue
            rows = np.zeros(m, dtype=bool)
            rows[list(blk.rows)] = True
            free = np.zeros(batch.n, dtype=bool)
            free[list(blk.cols)] = True
            # a closure block of a translational mechanism meets the platform where the target
            # puts it, even where the chain that carries it in the tree cannot reach that far
            pinned = batch.can_pin and not task & set(blk.rows)
            y, res, _ = batch.newton(p[out], xs, iters=30, free=free, rows=rows, pinned=pinned)
            xs = batch.canonical(y)
            ok = res <= TOL
            upstream = np.ones(len(out), dtype=bool)
            for i in _depends_on(batch.blocks, j, used[pinned]):
                upstream &= closed[i]
            closed[j] = ok & upstream
            lk = label_index.get(blk)
            if lk is None:
                continue
            _, J, _ = batch.evaluate(p[out], xs)
            limb[out, lk] = np.where(upstream, np.where(ok, _block_measure(J, blk), -res), np.nan)
    det = np.full((N, B), np.nan)
    if batch.actuated.size == batch.task_dim and len(k_i):
        _, inverse = batch.jacobians(p[k_i], sol.x[k_i, b_i][:, None, :])
        det[k_i, b_i] = _normalised_det(inverse[:, 0], axis=-1)
    return LoopFields(margin, limb, det)


def _depends_on(blocks: Any, j: int, pattern: np.ndarray) -> list[int]:
    """Earlier blocks whose unknowns enter block j's equations (pattern (m, n): the Jacobian's
    non-zero entries at one configuration that the rows' frames can depend on)."""
    used = set(np.flatnonzero(np.any(pattern[list(blocks[j].rows)], axis=0)).tolist())
    return [i for i in range(j) if blocks[i].cols and set(blocks[i].cols) & used]
