"""Reading a three-limb design back from its URDF: the joints the generator writes, found by
name, checked for type and layout, and the per-limb values required to agree."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from kinematics.errors import UnsupportedRobotError
from kinematics.mechanisms.three_limb.urdf import LIMBS, SPHERICAL
from kinematics.model.urdf_xml import origin_of


class LayoutReader:
    """The joints of a three-limb URDF, read with the errors a reader owes its caller.

    Attributes:
        who: the robot's name in messages.
        joints: joint name -> `<joint>` element.
    """

    def __init__(self, urdf_path: str | os.PathLike[str], robot: str | None, mechanism: str, layout: str) -> None:
        """`mechanism` names the family in messages, `layout` lists the joints it expects."""
        from kinematics.model.robot import check_urdf_file

        root = check_urdf_file(urdf_path)
        self.who = robot or Path(urdf_path).stem
        self.mechanism, self.layout = mechanism, layout
        self.joints = {j.get("name"): j for j in root.findall("joint")}

    def fail(self, reason: str) -> UnsupportedRobotError:
        """The error for a URDF that does not have the layout."""
        return UnsupportedRobotError(self.who, reason)

    def need(self, name: str, kind: str) -> ET.Element:
        """Joint `name` of type `kind`; UnsupportedRobotError naming it when missing or of another type."""
        j = self.joints.get(name)
        if j is None:
            raise self.fail(f"not a {self.mechanism}: missing joint {name!r} (expected joints {self.layout})")
        if j.get("type") != kind:
            raise self.fail(f"not a {self.mechanism}: joint {name!r} is {j.get('type')}, expected {kind}")
        return j

    def placed(self, name: str, kind: str) -> tuple[ET.Element, tuple[float, ...], tuple[float, ...]]:
        """Joint `name` of type `kind` (`need`) with its origin's xyz [m] and rpy [rad]."""
        j = self.need(name, kind)
        return (j, *origin_of(j))

    def limb_angles(self) -> list[float]:
        """alpha_i [rad] of the three limbs from `limb_i_joint`, each a pure rotation about z."""
        out = []
        for i in LIMBS:
            _, xyz, rpy = self.placed(f"limb_{i}_joint", "fixed")
            if xyz != (0, 0, 0) or rpy[:2] != (0, 0):
                raise self.fail(f"joint 'limb_{i}_joint' must be a pure rotation about z")
            out.append(rpy[2])
        return out

    def same(self, what: str, values: list) -> Any:
        """The one value every limb/rod has; UnsupportedRobotError when they differ."""
        if any(v != values[0] for v in values[1:]):
            raise self.fail(f"the closed forms need identical limbs/rods, but {what} differs: {values}")
        return values[0]

    def tip_length(self, i: int, k: int, what: str) -> float:
        """Rod (i, k)'s length [m] from `tip_i_k_joint` at (`what`, 0, 0)."""
        xyz, rpy = origin_of(self.need(f"tip_{i}_{k}_joint", "fixed"))
        if xyz[1:] != (0, 0) or rpy != (0, 0, 0):
            raise self.fail(f"joint 'tip_{i}_{k}_joint' must be ({what}, 0, 0)")
        return xyz[0]

    def check_platform(self, alpha: list[float]) -> None:
        """The spherical joint's three revolutes, and `pmount_i_joint` turning by alpha_i about z."""
        for i in LIMBS:
            _, rpy = origin_of(self.need(f"pmount_{i}_joint", "fixed"))
            if rpy != (0, 0, alpha[i - 1]):
                raise self.fail(f"joint 'pmount_{i}_joint' must turn by alpha_{i} about z like 'limb_{i}_joint'")
        for name in SPHERICAL:
            self.need(name, "revolute")
