"""Boxes of joint space: the first partition, the evaluation of FK and the Jacobian at the boxes'
centres, and their splitting."""

from __future__ import annotations

from itertools import product

import numpy as np

from kinematics.analyses.serial_workspace.kernels import jacobian_stats
from kinematics.chunks import slices
from kinematics.errors import UnsupportedRobotError
from kinematics.generic.batched import BatchedKinematics, configurations
from kinematics.mechanisms.serial.joint_box import Setup
from kinematics.model.robot import Robot

LEAF = 0.5
"""A box is a leaf once its image ball's radius eps is at most LEAF x the cell side."""

SPLIT = 0.5
"""A box is halved along every joint contributing at least SPLIT x the largest share of eps."""


LEVEL_ZERO_SHARE = 16
"""Level 0 takes at most 1/LEVEL_ZERO_SHARE of the budget, leaving the rest to the refinement."""


def level_zero(s: Setup, budget: int) -> tuple[np.ndarray, np.ndarray]:
    """Level 0: boxes whose images span about a quarter of the reach along each joint (centres
    and half-widths), coarsened to at most budget / LEVEL_ZERO_SHARE boxes (at least one) when
    that is more: the boxes' image spans along the joints are then kept equal, only larger."""
    span = s.hi - s.lo
    image = s.L * span  # a box's image along joint i spans about image_i / count_i
    per = np.maximum(2, np.ceil(image / (s.reach / 4))).astype(int)
    cap = max(1, budget // LEVEL_ZERO_SHARE)
    if np.prod(per.astype(float)) > cap:
        # the smallest common image span t whose counts ceil(image / t) fit the cap (bisection
        # on t; at t = max(image) every count is 1)
        lo_t, hi_t = s.reach / 4, float(max(image.max(), s.reach / 4))
        for _ in range(60):
            t = 0.5 * (lo_t + hi_t)
            if np.prod(np.maximum(1, np.ceil(image / t))) > cap:
                lo_t = t
            else:
                hi_t = t
        per = np.maximum(1, np.ceil(image / hi_t)).astype(int)
    axes_1d = [s.lo[i] + (np.arange(per[i]) + 0.5) * span[i] / per[i] for i in range(len(per))]
    centre = np.array(list(product(*axes_1d)), dtype=float).reshape(-1, len(per))
    half = np.repeat((span / per / 2)[None, :], len(centre), axis=0)
    return centre, half


def evaluate(robot: Robot, kin: BatchedKinematics, s: Setup, centre: np.ndarray,
             half: np.ndarray) -> tuple[np.ndarray, ...]:
    """Task point y, sigma_min, sigma_max, Yoshikawa index, image-ball radius eps and the
    sampled joints' column norms at the box centres, in chunks (memory stays bounded)."""
    rows = list(s.rows)
    N = len(centre)
    y = np.empty((N, 2 if s.mode != "spatial" else 3))
    stats = [np.empty(N) for _ in range(4)]
    norms = np.empty((N, len(s.sample_cols)))
    for sl in slices(N, 1 << 18):
        values = np.repeat(s.base[None, :], sl.stop - sl.start, axis=0)
        values[:, s.active] = centre[sl]
        poses, J = kin.fk_jacobian(configurations(robot, values))
        p = poses.position
        Jt = J[:, rows, :]
        if s.mode == "planar":
            y[sl] = p[:, rows]
        elif s.mode == "revolved":
            if s.axis_origin is None or s.axis_direction is None:
                raise UnsupportedRobotError("revolved workspace", "the revolution axis was not found")
            rel = p - s.axis_origin
            z = rel @ s.axis_direction
            y[sl, 0] = np.linalg.norm(rel - z[:, None] * s.axis_direction, axis=1)
            y[sl, 1] = z
        else:
            y[sl] = p
        Ja = np.ascontiguousarray(Jt[:, :, s.sample_cols])
        jacobian_stats(np.ascontiguousarray(Jt[:, :, s.graves_cols]), Ja, np.ascontiguousarray(half[sl]), s.B,
                       *(a[sl] for a in stats))
        norms[sl] = np.linalg.norm(Ja, axis=1)
    return (y, *stats, norms)


def split_mask(half: np.ndarray, norms: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The joints to halve: those contributing at least SPLIT x the largest share of eps."""
    contrib = norms * half + 0.5 * half * (half @ B)
    return contrib >= SPLIT * contrib.max(axis=1, keepdims=True)


def split(centre: np.ndarray, half: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Halve each box along the joints its mask row selects."""
    n = centre.shape[1]
    codes = mask @ (1 << np.arange(n))
    out_c, out_h = [], []
    for code in np.unique(codes):
        sel = codes == code
        dims = [i for i in range(n) if code >> i & 1]
        c0, h0 = centre[sel], half[sel].copy()
        h0[:, dims] /= 2
        for signs in product((-1.0, 1.0), repeat=len(dims)):
            c = c0.copy()
            c[:, dims] += np.array(signs) * h0[:, dims]
            out_c.append(c)
            out_h.append(h0)
    return np.concatenate(out_c), np.concatenate(out_h)


