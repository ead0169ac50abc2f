"""Planar or spatial, decided once: the plane a robot's end effector moves in, loops closed.

A tree is planar when every revolute axis is parallel to one world axis (and every prismatic one
perpendicular to it: `kinematics.generic.serial.common_axis`). A closed loop can be planar without
its tree being so: Gepetto's `5bar_linkage_iso3d` adds a revolute at right angles to the five-bar's
axes, which the closure locks at 0 or pi; its tip then moves in one of two parallel planes. So
for a robot with loops the test is on the motions the loops allow: at closed poses (the default
closed pose and a few with the actuators moved), every velocity that keeps the loops closed (the
null space of the loop Jacobian K) gives the end effector a twist [v; w]; the motion is planar with
unit normal n when v . n = 0 and w x n = 0 for all of them, with the same n at every pose.

What it cannot see: a motion that leaves the plane only away from the poses checked (the poses
are the default closed pose and `poses` nearby ones; a mechanism planar there is planar on the
connected set of closed poses only if its structure keeps it so, as the five-bars' does).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.model.robot import Robot, matrix

if TYPE_CHECKING:
    from kinematics.generic.closedloop import ClosedLoop

PLANE_TOL = 1e-9
"""Relative size [-] of an out-of-plane velocity (or an off-normal angular velocity) below which the
motion counts as planar (the loop Jacobian's null space is computed to ~1e-12)."""


class MotionPlane(NamedTuple):
    """The plane of the end effector's motion.

    Attributes:
        axes: the two world axes (i, j) that span it.
        normal: index k of the world axis normal to it.
        offset: the end effector's coordinate along axis k [m] at the default closed pose (for a
            tree: at the neutral pose); other assembly modes can have other offsets (parallel planes).
        closed: decided on the loops' motion (True) or on the tree's joint axes alone (False).
    """

    axes: tuple[int, int]
    normal: int
    offset: float
    closed: bool

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: {"axes": ["x", "z"], "normal": "y", "offset_m": ..., "decided_on": "closed motion" | "joint axes"}."""
        return {"axes": ["xyz"[a] for a in self.axes], "normal": "xyz"[self.normal], "offset_m": self.offset,
                "decided_on": "closed motion" if self.closed else "joint axes"}


@functools.lru_cache(maxsize=64)
def motion_plane(robot: Robot, frame: str | None = None, poses: int = 4, rng: int = 0) -> MotionPlane | None:
    """The world-axis plane the end effector (or `frame`) moves in, or None if its motion is spatial
    (cached per robot and arguments: every command asks the same question).

    Trees: `common_axis` of the joint axes. Robots with loops: the tree's answer when its axes are
    planar; else the closed motions at the default closed pose and `poses` others with the
    actuators moved by up to 0.2 (rad or m) each (module docstring). A plane not spanned by two
    world axes is reported as spatial (None), as for trees.
    """
    from kinematics.generic.serial import common_axis

    fid = robot.frame_id(frame)
    normal = common_axis(robot.model)
    if normal is not None or robot.loops is None:
        return _world_plane(robot, normal, pin.neutral(robot.model), fid, closed=False)
    from kinematics.errors import KinematicsError
    from kinematics.generic.closedloop import ClosedLoop

    loop = ClosedLoop(robot)
    try:
        q0 = loop.reference
    except KinematicsError:
        return None  # no closed pose: nothing to decide on
    qs = [q0]
    gen = np.random.default_rng(rng)
    a0 = robot.values_from_configuration(q0)[loop.actuated_dofs]
    for _ in range(poses):
        try:
            qs.append(loop.solve(a0 + gen.uniform(-0.2, 0.2, len(a0)), q0=q0).q)
        except KinematicsError:
            continue
    n = None
    for q in qs:
        n_q = _closed_normal(loop, q, fid)
        if n_q is None or (n is not None and np.linalg.norm(np.cross(n, n_q)) > 1e3 * PLANE_TOL):
            return None
        n = n_q
    return _world_plane(robot, n, q0, fid, closed=True)


def _closed_normal(loop: ClosedLoop, q: np.ndarray, fid: int) -> np.ndarray | None:
    """The unit normal of the plane the frame's closed motions at q lie in, or None (spatial)."""
    from kinematics.generic.closedloop import RANK_RTOL
    _, K = loop.residual(q)
    _, s, Vt = np.linalg.svd(K)
    rank = int(np.sum(s > RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0
    N = Vt[rank:].T
    model, data = loop.model, loop.data
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    T = matrix(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED), model.nv) @ N
    v, w = T[:3], T[3:]
    scale = max(float(np.linalg.norm(T)), 1e-300)
    uw, sw, _ = np.linalg.svd(w)
    uv, sv, _ = np.linalg.svd(v)
    if sw[0] > PLANE_TOL * scale:  # it turns: about one axis only, which its velocities are normal to
        n = uw[:, 0]
        if sw[1] > PLANE_TOL * scale:
            return None
    elif sv[1] > PLANE_TOL * scale:  # it only translates: in a plane if its velocities span two axes
        n = uv[:, 2]
    else:
        return None  # one translation or none: no plane is defined by the motion
    if float(np.linalg.norm(n @ v)) > PLANE_TOL * scale:
        return None
    return n


def _world_plane(robot: Robot, n: np.ndarray | None, q: np.ndarray, fid: int, closed: bool) -> MotionPlane | None:
    if n is None:
        return None
    k = int(np.argmax(np.abs(n)))
    if abs(abs(float(n[k])) - 1.0) > 1e3 * PLANE_TOL:
        return None  # planar, but not in a plane spanned by world axes
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    i, j = (a for a in range(3) if a != k)
    return MotionPlane((i, j), k, float(data.oMf[fid].translation[k]), closed)
