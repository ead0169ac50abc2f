"""Small helpers shared by the URDF generators and readers: exact number text, an ElementTree
builder of links, joints and visuals, origins, axes and limits read back."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np


def num(x: float) -> str:
    """A float as the shortest text that reads back as the same float (Python's repr), whole
    numbers without ".0"."""
    text = repr(float(x) + 0.0)  # + 0.0: no "-0.0"
    return text[:-2] if text.endswith(".0") else text


def vec(*xs: float) -> str:
    """Space-separated `num` numbers."""
    return " ".join(num(x) for x in xs)


def rpy_of(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(y) Ry(p) Rx(r)) of a rotation matrix."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    roll = math.atan2(R[2, 1], R[2, 2])
    yaw = math.atan2(R[1, 0], R[0, 0])
    return roll, pitch, yaw


def rot_y(a: float) -> np.ndarray:
    """Rotation by `a` [rad] about y."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation by `a` [rad] about z."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def visual(shape: str, material: str, xyz=(0, 0, 0), rpy=(0, 0, 0),
           **size: float | tuple[float, ...]) -> ET.Element:
    """A `<visual>` element: geometry `shape` ("box", "cylinder", "sphere") with its size
    attributes (`size=(x, y, z)` for a box, `radius`, `length`) [m], placed at xyz/rpy."""
    v = ET.Element("visual")
    ET.SubElement(v, "origin", xyz=vec(*xyz), rpy=vec(*rpy))
    attrs = {k: vec(*x) if isinstance(x, tuple) else num(x) for k, x in size.items()}
    ET.SubElement(ET.SubElement(v, "geometry"), shape, attrs)
    ET.SubElement(v, "material", name=material)
    return v


def collision(shape: str, xyz=(0, 0, 0), rpy=(0, 0, 0), **size: float | tuple[float, ...]) -> ET.Element:
    """A `<collision>` element: geometry `shape` ("box", "cylinder", "sphere") with its size
    attributes [m], placed at xyz/rpy."""
    c = ET.Element("collision")
    ET.SubElement(c, "origin", xyz=vec(*xyz), rpy=vec(*rpy))
    attrs = {k: vec(*x) if isinstance(x, tuple) else num(x) for k, x in size.items()}
    ET.SubElement(ET.SubElement(c, "geometry"), shape, attrs)
    return c


def capsule(start: np.ndarray | tuple[float, ...], end: np.ndarray | tuple[float, ...],
            radius: float) -> tuple[ET.Element, ...]:
    """A capsule (the points within `radius` [m] of the segment start-end, in the link's frame)
    as URDF can say it: a `<collision>` cylinder between the two ends and a sphere at each
    (URDF has no `<capsule>`). `kinematics.generic.collision` merges the three back into one
    capsule."""
    a, b = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    u = b - a
    length = float(np.linalg.norm(u))
    u = u / length
    # a rotation taking z to u: yaw about z, then pitch about y
    rpy = (0.0, math.acos(max(-1.0, min(1.0, float(u[2])))), math.atan2(float(u[1]), float(u[0])))
    if abs(u[2]) == 1.0:
        rpy = (0.0, 0.0 if u[2] > 0 else math.pi, 0.0)
    mid = tuple(float(x) for x in 0.5 * (a + b))
    return (collision("cylinder", mid, rpy, radius=radius, length=length),
            collision("sphere", tuple(float(x) for x in a), radius=radius),
            collision("sphere", tuple(float(x) for x in b), radius=radius))


class UrdfBuilder:
    """A URDF document built element by element (`xml.etree.ElementTree`); `text` gives it
    indented, every number written so that it reads back as the same float (`num`)."""

    def __init__(self, name: str, materials: dict[str, str]) -> None:
        """A `<robot name=...>` with its materials (name -> "r g b a")."""
        self.root = ET.Element("robot", name=name)
        for material, rgba in materials.items():
            ET.SubElement(ET.SubElement(self.root, "material", name=material), "color", rgba=rgba)

    def link(self, name: str, *elements: ET.Element) -> None:
        """Append a `<link>` with optional visuals and collisions."""
        ET.SubElement(self.root, "link", name=name).extend(elements)

    def joint(self, name: str, kind: str, parent: str, child: str, xyz=(0, 0, 0), rpy=(0, 0, 0),
              axis: tuple[float, float, float] | None = None, limit: tuple[float, float] | None = None) -> None:
        """Append a `<joint>`: origin xyz [m] / rpy [rad], axis, limit (lower, upper) [m or rad]."""
        j = ET.SubElement(self.root, "joint", name=name, type=kind)
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=child)
        ET.SubElement(j, "origin", xyz=vec(*xyz), rpy=vec(*rpy))
        if axis is not None:
            ET.SubElement(j, "axis", xyz=vec(*axis))
        if limit is not None:
            ET.SubElement(j, "limit", lower=num(limit[0]), upper=num(limit[1]), effort="1000", velocity="10")

    def text(self, comment: str) -> str:
        """The document: XML declaration, `comment` (lines, indented by two), then the robot."""
        if "--" in comment:
            from kinematics.errors import InvalidInputError

            raise InvalidInputError("comment", "an XML comment cannot contain '--'")
        ET.indent(self.root, "  ")
        body = "\n".join("  " + line if line else "" for line in comment.splitlines())
        head = ET.tostring(ET.Comment("\n" + body + "\n"), encoding="unicode")
        return '<?xml version="1.0"?>\n' + head + "\n" + ET.tostring(self.root, encoding="unicode") + "\n"


def origin_of(element: ET.Element) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(xyz, rpy) of a joint's `<origin>` (zeros when absent)."""
    o = element.find("origin")
    xyz = tuple(float(x) for x in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split())
    rpy = tuple(float(x) for x in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split())
    return xyz, rpy


def axis_of(element: ET.Element) -> tuple[float, ...]:
    """A joint's `<axis>` (URDF default x)."""
    a = element.find("axis")
    return tuple(float(x) for x in (a.get("xyz", "1 0 0") if a is not None else "1 0 0").split())


def limit_of(element: ET.Element) -> tuple[float, float]:
    """A joint's (lower, upper) limit; (-inf, inf) when it has none."""
    lim = element.find("limit")
    if lim is None:
        return (-math.inf, math.inf)
    return float(lim.get("lower", "0")), float(lim.get("upper", "0"))
