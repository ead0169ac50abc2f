"""Grübler–Kutzbach count of the physical mechanism (composite joints merged, closures as joints)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from kinematics.generic.serial import common_axis
from kinematics.model.robot import Robot

_ORIGIN_TOL = 1e-12


@dataclass(frozen=True)
class PhysicalJoint:
    """A joint of the physical mechanism (composite joints merged; closures included)."""

    name: str
    type: str  # R, P, U, S, C, weld, or "<n>-DOF"
    freedoms: int
    members: tuple[str, ...]


@dataclass(frozen=True)
class GrublerCount:
    """M = lambda (links - joints - 1) + sum of joint freedoms."""

    links: int
    joints: int
    freedoms: int
    lam: int
    mobility: int
    planar: bool
    joint_list: tuple[PhysicalJoint, ...]

    def as_dict(self) -> dict[str, Any]:
        types: dict[str, int] = {}
        for j in self.joint_list:
            types[j.type] = types.get(j.type, 0) + 1
        return {"links": self.links, "joints": self.joints, "freedoms": self.freedoms, "lambda": self.lam,
                "mobility": self.mobility, "planar": self.planar, "joint_types": types}


def composite_type(kinds: list[str]) -> str:
    if len(kinds) == 1:
        return "P" if kinds[0] == "prismatic" else "R"
    if all(k == "revolute" for k in kinds) and len(kinds) in (2, 3):
        return "U" if len(kinds) == 2 else "S"
    if sorted(kinds) == ["prismatic", "revolute"]:
        return "C"
    return f"{len(kinds)}-DOF"


def grubler(robot: Robot, q: np.ndarray | None = None) -> GrublerCount:
    """Grübler–Kutzbach count of the physical mechanism (planar lambda = 3 when every revolute
    axis is parallel at q, else 6; a point closure then acts as a pin, a 6d closure as a weld)."""
    model = robot.model
    q = pin.neutral(model) if q is None else q
    kinds = {d.name: d.kind for d in robot.dofs}
    children: dict[int, list[int]] = {}
    for jid in range(1, model.njoints):
        children.setdefault(int(model.parents[jid]), []).append(jid)
    anchored = set()  # bodies that carry a closure or the end effector: never a joint cross
    frames = [robot.frame_id(c.frame1) for c in (robot.loops.closures if robot.loops else ())]
    frames += [robot.frame_id(c.frame2) for c in (robot.loops.closures if robot.loops else ())]
    frames.append(robot.frame_id(robot.loops.end_effector if robot.loops else robot.tool_frame))
    for f in frames:
        anchored.add(int(model.frames[f].parentJoint))

    def is_cross(body: int) -> bool:
        kids = children.get(body, [])
        return bool(body != 0 and body not in anchored and len(kids) == 1
                    and np.linalg.norm(model.jointPlacements[kids[0]].translation) <= _ORIGIN_TOL)

    # A weld (6d closure) keeps a planar mechanism planar: it removes the welded body's 3 planar
    # freedoms just as it removes 6 spatial ones, so lambda = 3 holds whatever the closure types.
    planar = common_axis(model, q) is not None
    joints: list[PhysicalJoint] = []
    bodies = {0}
    for jid in range(1, model.njoints):
        if is_cross(int(model.parents[jid])):
            continue  # inside a composite joint that starts higher up
        chain = [jid]
        while is_cross(chain[-1]):
            chain.append(children[chain[-1]][0])
        bodies.add(chain[-1])
        names = [model.names[j] for j in chain]
        joints.append(PhysicalJoint(names[0], composite_type([kinds[n] for n in names]),
                                    sum(model.joints[j].nv for j in chain), tuple(names)))
    for c in robot.loops.closures if robot.loops else ():
        if c.type == "point":
            joints.append(PhysicalJoint(c.name, "R" if planar else "S", 1 if planar else 3, (c.name,)))
        else:
            joints.append(PhysicalJoint(c.name, "weld", 0, (c.name,)))
    lam = 3 if planar else 6
    total = sum(j.freedoms for j in joints)
    links = len(bodies)
    return GrublerCount(links, len(joints), total, lam, lam * (links - len(joints) - 1) + total, planar, tuple(joints))

