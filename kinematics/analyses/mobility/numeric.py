"""Numeric mobility (the rank of the loop-constraint Jacobian) and a regular configuration of a
serial arm to analyse it at."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.model.robot import Robot, matrix

from .linalg import RANK_RTOL, null, rank_of

REGULAR_RTOL = 1e-3
"""A serial configuration is *regular* when its tool Jacobian has the arm's generic rank r and
sigma_r / sigma_1 > REGULAR_RTOL (well away from a singularity, not merely off it)."""

REGULAR_SEED = 0
"""Seed of the random configurations `regular_configuration` draws."""


class RegularConfiguration(NamedTuple):
    """A serial arm's analysis configuration and what was checked about it.

    Attributes:
        q: Pinocchio configuration.
        values: one value per degree of freedom [rad or m].
        generic_rank: the largest rank of the tool's 6 x nv Jacobian over the samples.
        conditioning: sigma_r / sigma_1 of the tool Jacobian at q (r = generic_rank).
    """

    q: np.ndarray
    values: np.ndarray
    generic_rank: int
    conditioning: float


def _tool_jacobian(robot: Robot, q: np.ndarray) -> np.ndarray:
    model = robot.model
    return matrix(pin.computeFrameJacobian(model, model.createData(), q, robot.frame_id(), pin.LOCAL_WORLD_ALIGNED),
                  model.nv)


def _samples(robot: Robot, n: int, seed: int) -> np.ndarray:
    """n seeded random joint-value vectors within the limits (continuous joints: [-pi, pi))."""
    lo, hi = robot.lower.copy(), robot.upper.copy()
    free = ~(np.isfinite(lo) & np.isfinite(hi))
    lo[free], hi[free] = -np.pi, np.pi
    return np.random.default_rng(seed).uniform(lo, hi, (n, robot.nv))


@functools.lru_cache(maxsize=32)
def regular_configuration(robot: Robot, seed: int = REGULAR_SEED, tries: int = 64) -> RegularConfiguration:
    """A seeded random configuration within the joint limits where the serial arm is regular.

    The generic rank is the largest rank of the tool Jacobian over `tries` random samples (a
    singular pose has measure zero, so one regular sample suffices); the first sample with that
    rank and conditioning above REGULAR_RTOL is returned, else the best conditioned one. The
    middle of the joint ranges is a poor default: for UR5 it is q = 0, a singular pose.
    """
    samples = _samples(robot, tries, seed)
    svals = [np.linalg.svd(_tool_jacobian(robot, robot.configuration(v)), compute_uv=False) for v in samples]
    generic = max(rank_of(s) for s in svals)
    cond = np.array([s[generic - 1] / s[0] if generic and rank_of(s) == generic else 0.0 for s in svals])
    k = int(np.argmax(cond > REGULAR_RTOL)) if np.any(cond > REGULAR_RTOL) else int(np.argmax(cond))
    return RegularConfiguration(robot.configuration(samples[k]), samples[k], generic, float(cond[k]))


@dataclass(frozen=True)
class NumericMobility:
    """nv - rank(K) from the loop-constraint Jacobian K, with the evidence for the rank."""

    nv: int
    constraints: int
    rank: int
    tolerance: float
    smallest_kept: float
    largest_dropped: float
    platform_freedoms: int
    locked_platform_freedoms: int
    serial: bool = False
    locked_position_freedoms: int = 0
    """Of the locked platform freedoms, those that move the end effector's origin (the others only
    turn the frame about it)."""

    @property
    def mobility(self) -> int:
        return self.nv - self.rank

    @property
    def idle(self) -> int:
        """Loop freedoms that move joints but not the platform (e.g. a rod spinning between S
        joints); 0 for a serial arm, whose surplus freedoms are `redundant`."""
        return 0 if self.serial else self.mobility - self.platform_freedoms

    @property
    def redundant(self) -> int:
        """A serial arm's joint freedoms beyond the tool's (self-motion; more at a singular pose)."""
        return self.mobility - self.platform_freedoms if self.serial else 0

    @property
    def gap(self) -> float:
        """smallest kept / largest dropped singular value (inf when nothing was dropped)."""
        return self.smallest_kept / self.largest_dropped if self.largest_dropped > 0 else float("inf")

    def as_dict(self) -> dict[str, Any]:
        return {"mobility": self.mobility, "nv": self.nv, "constraints": self.constraints, "rank": self.rank,
                "tolerance": self.tolerance, "smallest_kept": self.smallest_kept,
                "largest_dropped": self.largest_dropped, "gap": self.gap,
                "platform_freedoms": self.platform_freedoms, "idle": self.idle, "redundant": self.redundant,
                "locked_platform_freedoms": self.locked_platform_freedoms,
                "locked_position_freedoms": self.locked_position_freedoms}


def numeric_mobility(robot: Robot, q: np.ndarray, rtol: float = RANK_RTOL) -> NumericMobility:
    """Rank of the loop-constraint Jacobian at q, the platform's share of the null space, and the
    platform's freedom with the actuators locked (0 away from singularities)."""
    model = robot.model
    if robot.loops is not None:
        from kinematics.generic.closedloop import ClosedLoop

        cl = ClosedLoop(robot)
        _, K = cl.residual(q)
        actuated = cl.actuated_v
        ee = cl.ee
    else:
        K = np.zeros((0, model.nv))
        actuated = np.arange(model.nv)
        ee = robot.frame_id()
    s = np.linalg.svd(K, compute_uv=False) if K.size else np.zeros(0)
    rank = rank_of(s, rtol)
    smallest = float(s[rank - 1]) if rank else 0.0
    dropped = float(s[rank]) if rank < s.size else 0.0
    N = null(K, rtol)
    J = matrix(pin.computeFrameJacobian(model, model.createData(), q, ee, pin.LOCAL_WORLD_ALIGNED), model.nv)
    scale = max(float(np.abs(J).max()), 1e-300)
    platform = rank_of(np.linalg.svd(J @ N, compute_uv=False), rtol) if N.size else 0
    lock = np.zeros((len(actuated), model.nv))
    lock[np.arange(len(actuated)), actuated] = 1.0
    KL = np.vstack([K / (s[0] if s.size and s[0] > 0 else 1.0), lock])
    NL = null(KL, rtol)
    locked = locked_position = 0
    if NL.size:
        sl = np.linalg.svd(J @ NL, compute_uv=False)
        locked = int(np.sum(sl > rtol * scale))
        locked_position = int(np.sum(np.linalg.svd(J[:3] @ NL, compute_uv=False) > rtol * scale))
    return NumericMobility(model.nv, K.shape[0], rank, rtol, smallest, dropped, platform, locked, robot.loops is None,
                           locked_position)

