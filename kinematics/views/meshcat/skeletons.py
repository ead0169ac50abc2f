"""The kinematic skeleton: what the kinematics knows of a robot at one configuration (joints,
links between their origins, loop-closure and end-effector frames), its objects' transforms, and
its drawing in a meshcat scene."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kinematics.views.meshcat.materials import hex_colour

SKELETON_SIZE = {
    "link": 0.005,  # rod radius
    "joint_length": 0.08,  # revolute cylinder, along the axis
    "joint_radius": 0.015,
    "arrow_length": 0.10,  # prismatic arrow's shaft
    "arrow_head": 0.04,
    "closure": 0.02,  # ball radius
    "end_effector": 0.03,
}
"""Skeleton sizes as fractions of the model's length scale L (`generic.serial.length_scale`, the
diagonal of the bounding box of its joints and frames): robot_delta (L = 0.11 m) gets 0.55 mm rods,
9 mm joint cylinders, 3.3 mm end-effector ball -- rods a few pixels wide, joints distinct where
they sit 0.01 m apart."""

SKELETON_STYLE: dict[str, tuple[tuple[float, float, float], str]] = {
    "ground": ((0.62, 0.62, 0.68), "ground link (world origin to the root joints)"),
    "link": ((0.25, 0.25, 0.30), "links"),
    "revolute": ((0.95, 0.55, 0.10), "revolute joints (along the axis)"),
    "prismatic": ((0.15, 0.45, 0.85), "prismatic joints (arrow along the axis)"),
    "closure": ((0.80, 0.10, 0.60), "loop-closure frames"),
    "end_effector": ((0.10, 0.65, 0.25), "end effector"),
}
"""Skeleton part -> (RGB, legend label)."""

_SEGMENT_MIN = 1e-9
"""A link segment shorter than this fraction of L is not drawn (a U or S joint's cross: its joint
origins coincide); a zero-length rod has no direction to draw."""


@dataclass(frozen=True, eq=False)
class SkeletonJoint:
    """A joint of the skeleton: name, "revolute" or "prismatic", world origin [m] and unit axis."""

    name: str
    kind: str
    origin: np.ndarray
    axis: np.ndarray


@dataclass(frozen=True, eq=False)
class Skeleton:
    """What the kinematics knows of a robot at one configuration, for drawing.

    Attributes:
        robot: the robot.
        joints: every joint, in model order.
        segments: (label "parent->child", start, end) [m]: from each body's joint origin to its
            child joints' origins and to its closure / end-effector frames (zero-length ones left out).
        closures: (closure name, frame1 position, frame2 position) [m].
        end_effector: the end-effector frame's position [m].
        length: the model's length scale L [m].
    """

    robot: Any
    joints: tuple[SkeletonJoint, ...]
    segments: tuple[tuple[str, np.ndarray, np.ndarray], ...]
    closures: tuple[tuple[str, np.ndarray, np.ndarray], ...]
    end_effector: np.ndarray
    length: float

    def joint(self, path: str) -> SkeletonJoint:
        """The joint drawn at node path `joints/<k>_<name>`."""
        return self.joints[int(path.split("/", 1)[1].split("_", 1)[0])]

    def points(self) -> np.ndarray:
        """Every point of the skeleton [m] (n, 3)."""
        pts = [j.origin for j in self.joints] + [p for _, a, b in self.segments for p in (a, b)]
        pts += [p for _, a, b in self.closures for p in (a, b)] + [self.end_effector]
        return np.array(pts, dtype=float).reshape(-1, 3)


def skeleton(robot: Any, q: np.ndarray) -> Skeleton:
    """The skeleton of `robot` at Pinocchio configuration q (see `Scene.add_skeleton`). A joint's
    axis is its motion's world direction: the angular part of its Jacobian column for a revolute
    joint, the linear part for a prismatic one."""
    import pinocchio as pin

    from kinematics.generic.serial import length_scale
    from kinematics.model.robot import matrix

    model = robot.model
    data = model.createData()
    q = np.asarray(q, dtype=float)
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    L = length_scale(robot, q)
    joints = []
    for jid in range(1, model.njoints):
        col = matrix(pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED), model.nv)[:, model.joints[jid].idx_v]
        revolute = bool(np.linalg.norm(col[3:]) > 0)
        axis = col[3:] if revolute else col[:3]
        joints.append(SkeletonJoint(model.names[jid], "revolute" if revolute else "prismatic",
                                    data.oMi[jid].translation.copy(), axis / np.linalg.norm(axis)))
    origin = [np.zeros(3)] + [j.origin for j in joints]  # body b's joint origin (0: the world's)
    frames = [(c.name, robot.frame_id(c.frame1), robot.frame_id(c.frame2)) for c in
              (robot.loops.closures if robot.loops is not None else ())]
    ee = robot.frame_id()
    ends: list[tuple[int, str, np.ndarray]] = [(int(model.parents[j]), model.names[j], origin[j])
                                               for j in range(1, model.njoints)]
    for fid in sorted({f for _, a, b in frames for f in (a, b)} | {ee}):
        ends.append((int(model.frames[fid].parentJoint), model.frames[fid].name, data.oMf[fid].translation.copy()))
    parent_name = ["world"] + list(model.names)[1:]
    segments = tuple((f"{parent_name[b]}->{label}", origin[b], end) for b, label, end in ends
                     if np.linalg.norm(end - origin[b]) > _SEGMENT_MIN * L)
    closures = tuple((n, data.oMf[a].translation.copy(), data.oMf[b].translation.copy()) for n, a, b in frames)
    return Skeleton(robot, tuple(joints), segments, closures, data.oMf[ee].translation.copy(), L)


def skeleton_transforms(sk: Skeleton) -> dict[str, np.ndarray]:
    """Node path (under `<robot>_skeleton/`) -> 4 x 4 world transform of every skeleton object.

    Joints: the joint's origin, local y (meshcat's cylinder axis) along the joint's axis. Links: a
    cylinder of height 1 scaled along y to the segment, centred on it, so that local (0, -1/2, 0)
    and (0, 1/2, 0) land on its ends. Balls: their frames' positions."""
    out: dict[str, np.ndarray] = {}
    for k, j in enumerate(sk.joints):
        out[f"joints/{k}_{_node_name(j.name)}"] = _along_y(j.axis, j.origin)
    for k, (label, a, b) in enumerate(sk.segments):
        out[f"links/{k}_{_node_name(label)}"] = _along_y(b - a, (a + b) / 2)
    for name, a, b in sk.closures:
        out[f"closures/{_node_name(name)}_1"] = _translation(*a)
        out[f"closures/{_node_name(name)}_2"] = _translation(*b)
    out["end_effector"] = _translation(*sk.end_effector)
    return out


def draw_skeleton(root: Any, sk: Skeleton) -> None:
    """Set the objects and transforms of skeleton `sk` under meshcat node `root` (see
    `Scene.add_skeleton`): rods for the links, cylinders or arrows for the joints, balls for the
    closure and end-effector frames, sized by the model's length scale."""
    import meshcat.geometry as mg

    L = sk.length
    material = {key: mg.MeshLambertMaterial(color=hex_colour(rgb)) for key, (rgb, _) in SKELETON_STYLE.items()}
    for path, matrix in skeleton_transforms(sk).items():
        kind = path.split("/", 1)[0]
        node = root[path]
        if kind == "links":
            ground = path.split("_", 1)[1].startswith("world->")
            node.set_object(mg.Cylinder(1.0, SKELETON_SIZE["link"] * L), material["ground" if ground else "link"])
        elif kind == "joints" and sk.joint(path).kind == "revolute":
            node.set_object(mg.Cylinder(SKELETON_SIZE["joint_length"] * L, SKELETON_SIZE["joint_radius"] * L),
                            material["revolute"])
        elif kind == "joints":  # an arrow along +axis: shaft and head, in the joint's node
            shaft, head = SKELETON_SIZE["arrow_length"] * L, SKELETON_SIZE["arrow_head"] * L
            node["shaft"].set_object(mg.Cylinder(shaft, SKELETON_SIZE["joint_radius"] * L / 2), material["prismatic"])
            node["shaft"].set_transform(_translation(0.0, shaft / 2, 0.0))
            node["head"].set_object(mg.Cylinder(head, radiusTop=0.0, radiusBottom=SKELETON_SIZE["joint_radius"] * L),
                                    material["prismatic"])
            node["head"].set_transform(_translation(0.0, shaft + head / 2, 0.0))
        elif kind == "closures":
            node.set_object(mg.Sphere(SKELETON_SIZE["closure"] * L), material["closure"])
        else:
            node.set_object(mg.Sphere(SKELETON_SIZE["end_effector"] * L), material["end_effector"])
        node.set_transform(matrix)


def _node_name(name: str) -> str:
    return name.replace("/", "_")


def _translation(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _along_y(d: np.ndarray, at: np.ndarray) -> np.ndarray:
    """A transform taking local y to the vector d (its length a scale along y) and the local x, z
    to unit vectors normal to it (right-handed), with its origin at `at`."""
    y = np.asarray(d, dtype=float)
    u = y / np.linalg.norm(y)
    e = np.eye(3)[int(np.argmin(np.abs(u)))]  # the world axis least along d
    x = np.cross(u, e)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, np.cross(x, u), at
    return T

