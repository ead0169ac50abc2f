"""The joint box a serial workspace samples: the joints that move the point and their ranges, the
measurement's mode (planar, revolved, spatial), bounds on the position's derivatives over the
box, and where a box meets the limits."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.batched import PRISMATIC, BatchedKinematics, configurations
from kinematics.generic.serial import plane
from kinematics.model.robot import Robot

Mode = Literal["planar", "revolved", "spatial"]
"""How a serial workspace is measured: in the arm's plane, as a profile turned about the base axis, or in 3-D."""

_DEAD_TOL = 1e-12
"""A joint whose position-Jacobian column is below this [m/rad] at every probe never moves the point."""


@dataclass(frozen=True, eq=False)
class Setup:
    """The joint box sampled and what the measurement knows of it (`setup`): mode, task rows,
    the sampled joints and their ranges, the values of the others, derivative bounds, the
    Jacobian columns entering sigma_min and eps, the revolution axis or plane, the reach ball."""

    mode: Mode
    rows: tuple[int, ...]
    active: np.ndarray  # dof indices sampled
    lo: np.ndarray
    hi: np.ndarray
    periodic: np.ndarray
    base: np.ndarray  # (nv,) values of the joints not sampled
    L: np.ndarray
    M: float
    B: np.ndarray  # (k, k) bounds on |d^2 f / dq_i dq_j| over the sampled joints
    Bcol: np.ndarray  # (k,) bounds on |dJ / dq_i| (spectral <= Frobenius) over the sampled joints
    graves_cols: np.ndarray  # velocity columns entering sigma_min (active, + the base yaw when revolved)
    sample_cols: np.ndarray  # velocity columns of the sampled joints
    axes: tuple[int, ...]
    axis_origin: np.ndarray | None
    axis_direction: np.ndarray | None
    fixed: tuple[str, ...]
    reach_centre: np.ndarray  # in task coordinates: |y - reach_centre| <= reach over the joint box
    reach: float


def setup(robot: Robot, kin: BatchedKinematics, revolve: bool = True) -> Setup:
    """The joints that move `kin`'s frame (the others fixed), their ranges (a full turn for a
    periodic one), the derivative bounds, and the mode: planar when the arm moves in a plane,
    revolved when the first joint is a full-turn revolution (and `revolve`: False measures such
    an arm in 3-D, for a margin the base's turn changes, e.g. against obstacles), spatial otherwise."""
    nv = robot.nv
    chain_v = [int(v) for v in kin.idx_v]
    dof_idx = [dof_of(robot, v) for v in chain_v]
    # Joints that never move the point: a zero position column at every probe configuration.
    rng = np.random.default_rng(0)
    lo_all = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi_all = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    probe = rng.uniform(lo_all, hi_all, (64, nv))
    Jp = kin.jacobian(configurations(robot, probe))[:, :3, :]
    moving = np.abs(Jp).max(axis=(0, 1)) > _DEAD_TOL
    R = _distal_lengths(kin, robot)
    prismatic = kin.kind == PRISMATIC
    pl = plane(robot)
    base = np.clip(np.zeros(nv), lo_all, hi_all)
    fixed = tuple(robot.dofs[i].name for i, v in zip(dof_idx, chain_v, strict=True) if not moving[v])
    keep = [k for k, v in enumerate(chain_v) if moving[v]]
    if not keep:
        raise UnsupportedRobotError(robot.name, f"no joint moves frame {kin.frame!r}: its workspace is a point")
    # every joint that moves the point is an actuator: a workspace needs its range (a continuous
    # joint's is a full turn)
    robot.require_ranges([robot.dofs[dof_idx[k]].name for k in keep], "a workspace")
    lo = np.array([lo_all[dof_idx[k]] for k in keep])
    hi = np.array([hi_all[dof_idx[k]] for k in keep])
    kinds = [robot.dofs[dof_idx[k]].kind for k in keep]
    periodic = np.array([kd == "continuous" or (kd == "revolute" and h - l >= 2 * math.pi - 1e-9)
                         for kd, l, h in zip(kinds, lo, hi, strict=True)])
    hi = np.where(periodic, lo + 2 * math.pi, hi)  # f is 2 pi periodic in these: one turn suffices
    M = _hessian_bound(prismatic[keep], R[keep])
    Bfull = _hessian_matrix(prismatic[keep], R[keep])
    Bcol = np.sqrt((Bfull**2).sum(axis=0))
    L = np.where(prismatic[keep], 1.0, R[keep])
    active = np.array([dof_idx[k] for k in keep])
    first = robot.dofs[dof_idx[0]]
    reach = float(R[0] + (max(abs(first.lower), abs(first.upper)) if kin.kind[0] == PRISMATIC else 0.0))
    o1 = kin.translation[0].copy()  # the first joint's origin, fixed in the world
    cols = np.array([chain_v[k] for k in keep])
    if pl is not None:
        return Setup("planar", pl, active, lo, hi, periodic, base, L, M, Bfull, Bcol, cols, cols, pl, None, None, fixed,
                      o1[list(pl)], reach)
    if revolve and keep[0] == 0 and kin.kind[0] != PRISMATIC and periodic[0]:
        direction = kin.rotation[0] @ kin.axis[0]
        origin = kin.translation[0].copy()
        return Setup("revolved", (0, 1, 2), active[1:], lo[1:], hi[1:], periodic[1:], base, L[1:], M, Bfull[1:, 1:], Bcol[1:], cols,
                      cols[1:], (), origin, direction, fixed, np.zeros(2), reach)
    return Setup("spatial", (0, 1, 2), active, lo, hi, periodic, base, L, M, Bfull, Bcol, cols, cols, (), None, None, fixed, o1, reach)


# -- bounds on the derivatives -------------------------------------------------------------------
def _distal_lengths(kin: BatchedKinematics, robot: Robot) -> np.ndarray:
    """R_k >= |p - p_k| over the joint box, p the frame point, p_k chain joint k's origin:
    the lengths of the fixed offsets after joint k plus the travel of the prismatic joints after it."""
    n = len(kin.kind)
    seg = np.linalg.norm(kin.translation, axis=1)
    travel = np.zeros(n)
    for k in range(n):
        if kin.kind[k] == PRISMATIC:
            d = robot.dofs[dof_of(robot, int(kin.idx_v[k]))]
            travel[k] = max(abs(d.lower), abs(d.upper))
    tail = float(np.linalg.norm(kin.frame_translation))
    R = np.empty(n)
    for k in range(n):
        R[k] = tail + seg[k + 1 :].sum() + travel[k + 1 :].sum()
    return R


def dof_of(robot: Robot, idx_v: int) -> int:
    for i, d in enumerate(robot.dofs):
        if d.idx_v == idx_v:
            return i
    raise InvalidInputError("joint", f"no degree of freedom at velocity index {idx_v}")  # pragma: no cover


def _hessian_bound(prismatic: np.ndarray, R: np.ndarray) -> float:
    return float(np.linalg.norm(_hessian_matrix(prismatic, R), 2)) if len(R) else 0.0


def _hessian_matrix(prismatic: np.ndarray, R: np.ndarray) -> np.ndarray:
    """M >= |d^2 f (u, v)| / (|u| |v|) over the box for the chain joints given (root first).

    For revolute i <= j: d^2 p / dq_i dq_j = w_i x (w_j x (p - p_j)), norm <= R_j; a revolute
    before a prismatic gives w_i x w_j (<= 1), a prismatic before anything 0 (taken as 1 when
    mixed, to be safe), two prismatics 0. M is the spectral norm of that nonnegative matrix."""
    n = len(R)
    B = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            a, b = min(i, j), max(i, j)
            if not prismatic[a] and not prismatic[b]:
                B[i, j] = R[b]
            elif prismatic[a] != prismatic[b]:
                B[i, j] = 1.0
    return B


def room(centre: np.ndarray, s: Setup) -> np.ndarray:
    """Radius of the largest joint-space ball around each centre inside the limits (periodic
    joints have none; in revolved mode the base joint is periodic)."""
    if not (~s.periodic).any():
        return np.full(len(centre), np.inf)
    c = centre[:, ~s.periodic]
    return np.minimum(c - s.lo[~s.periodic], s.hi[~s.periodic] - c).min(axis=1)


def on_face(centre: np.ndarray, half: np.ndarray, s: Setup) -> np.ndarray:
    """Boxes whose closure meets a face of a (non-periodic) joint limit."""
    np_ = ~s.periodic
    if not np_.any():
        return np.zeros(len(centre), bool)
    tol = 1e-9 * (s.hi - s.lo)[np_]
    c, d = centre[:, np_], half[:, np_]
    return ((c - d <= s.lo[np_] + tol) | (c + d >= s.hi[np_] - tol)).any(axis=1)


