"""Serial kinematics through Pinocchio: frame poses and world-aligned frame Jacobians.

The task space depends on the robot: a planar arm (every joint axis parallel to one world axis)
moves its tool in the plane of the other two axes, so its task rows are those two translational
rows (x-y for the SCARA); a spatial arm has three translational rows and, separately, three
rotational rows.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.errors import InvalidInputError, UnknownNameError
from kinematics.model.robot import Robot, matrix

Task = Literal["auto", "planar", "translation", "rotation", "full"]
TASKS: tuple[str, ...] = ("auto", "planar", "translation", "rotation", "full")

_PARALLEL_TOL = 1e-12


class Pose(NamedTuple):
    """Frame placement in the world: position [m] (3,) and rotation matrix (3, 3)."""

    position: np.ndarray
    rotation: np.ndarray


def common_axis(model: pin.Model, q: np.ndarray | None = None) -> np.ndarray | None:
    """Unit axis to which every revolute joint is parallel (and every prismatic one
    perpendicular) at configuration q (default neutral), or None: the mechanism is planar
    iff such an axis exists."""
    data = model.createData()
    pin.computeJointJacobians(model, data, pin.neutral(model) if q is None else q)
    axes, slides = [], []
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        J = matrix(pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED), model.nv)
        for col in J[:, joint.idx_v : joint.idx_v + joint.nv].T:  # this joint's own motion
            lin, ang = col[:3], col[3:]
            if np.linalg.norm(ang) < _PARALLEL_TOL:
                slides.append(lin / np.linalg.norm(lin))
            else:
                axes.append(ang / np.linalg.norm(ang))
    if not axes:
        return None
    normal = axes[0]
    if any(np.linalg.norm(np.cross(a, normal)) > _PARALLEL_TOL for a in axes):
        return None
    if any(abs(d @ normal) > _PARALLEL_TOL for d in slides):
        return None
    return normal


def plane(robot: Robot) -> tuple[int, int] | None:
    """World axes (i, j) spanning the plane the tool moves in, else None: the axes of
    `kinematics.generic.motion_plane.motion_plane` (one decision for every command: a tree is
    planar when every revolute axis is parallel to one world axis and every prismatic one
    perpendicular to it; a robot with loops when its closed motion is)."""
    from kinematics.generic.motion_plane import motion_plane

    found = motion_plane(robot)
    return None if found is None else found.axes


def task_rows(robot: Robot, task: Task = "auto") -> tuple[int, ...]:
    """Rows of the 6-row (linear; angular) world-aligned Jacobian that make up `task`."""
    if task not in TASKS:
        raise UnknownNameError(task, TASKS)
    if task == "auto":
        task = "planar" if plane(robot) is not None else "translation"
    if task == "planar":
        rows = plane(robot)
        if rows is None:
            raise InvalidInputError("task", f"{robot.name} is not a planar arm; use auto, translation, rotation or full")
        return rows
    return {"translation": (0, 1, 2), "rotation": (3, 4, 5), "full": (0, 1, 2, 3, 4, 5)}[task]


def forward_kinematics(robot: Robot, q: np.ndarray, frame: str | None = None) -> Pose:
    """World placement of `frame` (default: the tool) at Pinocchio configuration `q` (nq,)
    (InvalidInputError unless nq finite values: `Robot.check_configuration`)."""
    fid = robot.frame_id(frame)
    data = robot.data
    pin.framesForwardKinematics(robot.model, data, robot.check_configuration(q))
    M = data.oMf[fid]
    return Pose(M.translation.copy(), M.rotation.copy())


def frame_jacobian(robot: Robot, q: np.ndarray, frame: str | None = None) -> np.ndarray:
    """6 x nv Jacobian of `frame`, LOCAL_WORLD_ALIGNED: [v; w] = J q_dot, v the frame origin's
    velocity [m/s] and w the angular velocity [rad/s], both in world axes, at Pinocchio
    configuration `q` (nq,) (checked as in `forward_kinematics`)."""
    fid = robot.frame_id(frame)
    q = robot.check_configuration(q)
    return matrix(pin.computeFrameJacobian(robot.model, robot.data, q, fid, pin.LOCAL_WORLD_ALIGNED), robot.nv).copy()


def task_jacobian(robot: Robot, q: np.ndarray, frame: str | None = None, task: Task = "auto") -> np.ndarray:
    """The rows of `frame_jacobian` that make up `task` (see `task_rows`)."""
    return frame_jacobian(robot, q, frame)[list(task_rows(robot, task))]


DEFAULT_LENGTH = 1.0
"""`length_scale` of a model whose key points all coincide (e.g. one revolute with its tool at
the joint origin) [m]: any positive length serves, there being no size to compare with."""


def key_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """World positions [m] (n, 3) at configuration q of every joint origin, then every loop-closure
    frame (both of each pair) and the tool (end-effector) frame."""
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    frames = [robot.frame_id(n) for c in (robot.loops.closures if robot.loops else ()) for n in (c.frame1, c.frame2)]
    frames.append(robot.frame_id())
    points = [data.oMi[j].translation for j in range(1, model.njoints)] + [data.oMf[f].translation for f in frames]
    return np.array(points, dtype=float).reshape(-1, 3)


def length_scale(robot: Robot, q: np.ndarray) -> float:
    """The model's size at configuration q [m]: the diagonal of the axis-aligned bounding box of
    its `key_points` (DEFAULT_LENGTH if that is 0). Origin-independent, so tolerances relative to
    it do not change when a robot is placed elsewhere in the world."""
    p = key_points(robot, q)
    size = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
    return size if size > 0 else DEFAULT_LENGTH
