"""Small helpers shared by the URDF generators and readers: exact number text, joint/link/visual
elements, origins, axes and limits read back."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np


def axis_reference(ik: Any, params: Any, half_span: float, samples: int, mode: int) -> tuple[np.ndarray, str]:
    """A platform position on the base's z axis, within |z| <= half_span [m] on `samples` points,
    where working mode `mode` (an index of the 8 sign labels, '---' = 7) is assembled with every
    limit respected (mid-way along the valid stretch), else merely assembled: the reference
    configuration the generators write. `ik(params, points)` is the mechanism's vectorised IK."""
    z = np.linspace(-half_span, half_span, samples)
    pts = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=-1)
    res = ik(params, pts)
    for ok in (res.within_limits[:, mode], res.reachable[:, mode]):
        if ok.any():
            idx = np.flatnonzero(ok)
            return pts[idx[len(idx) // 2]], "---"
    from kinematics.errors import InvalidInputError

    raise InvalidInputError("design", "the platform cannot be assembled anywhere on the base's axis")


def fmt17(x: float) -> str:
    """A float with 17 significant digits (exact round trip through text)."""
    return format(float(x) + 0.0, ".17g")  # + 0.0: no "-0"


def vec(*xs: float) -> str:
    """Space-separated `fmt17` numbers."""
    return " ".join(fmt17(x) for x in xs)


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


def joint(name: str, kind: str, parent: str, child: str, xyz=(0, 0, 0), rpy=(0, 0, 0),
          axis: tuple[float, float, float] | None = None, limit: tuple[float, float] | None = None) -> str:
    """A `<joint>` element's text."""
    lines = [f'  <joint name="{name}" type="{kind}">', f'    <parent link="{parent}"/>',
             f'    <child link="{child}"/>', f'    <origin xyz="{vec(*xyz)}" rpy="{vec(*rpy)}"/>']
    if axis is not None:
        lines.append(f'    <axis xyz="{vec(*axis)}"/>')
    if limit is not None:
        lines.append(f'    <limit lower="{fmt17(limit[0])}" upper="{fmt17(limit[1])}" effort="1000" velocity="10"/>')
    lines.append("  </joint>")
    return "\n".join(lines)


def link(name: str, *visuals: str) -> str:
    """A `<link>` element's text with optional visuals."""
    if not visuals:
        return f'  <link name="{name}"/>'
    return "\n".join([f'  <link name="{name}">', *visuals, "  </link>"])


def visual(geometry: str, material: str, xyz=(0, 0, 0), rpy=(0, 0, 0)) -> str:
    """A `<visual>` element's text."""
    return (f'    <visual><origin xyz="{vec(*xyz)}" rpy="{vec(*rpy)}"/>'
            f"<geometry>{geometry}</geometry><material name=\"{material}\"/></visual>")


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
