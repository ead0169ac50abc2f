"""A fixed tool orientation for a serial arm's reachable set: a whole rotation (roll, pitch, yaw)
or one tool axis (the frame's z axis along a world direction, free to spin about it).

`ToolOrientation.parse("rpy R P Y")` reads the URDF convention R = Rz(Y) Ry(P) Rx(R) [rad]
(extrinsic x, y, z); `ToolOrientation.axis(d)` the tool's z axis along d (normalised).
What the search matches (`vectors`): the frame's z axis for a tool axis, its x and z axes for a
whole rotation (two orthonormal columns fix a rotation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.mechanisms.serial.joint_box import Setup
from kinematics.model.robot import Robot


@dataclass(frozen=True, eq=False)
class ToolOrientation:
    """A fixed tool orientation in the world.

    Attributes:
        kind: "rotation" (the frame's whole rotation is `matrix`) or "axis" (the frame's z axis is
            `matrix[:, 2]`; the other columns complete a right-handed basis and are not matched).
        matrix: (3, 3) rotation, world from tool.
        text: how it was given, for reports.
    """

    kind: Literal["rotation", "axis"]
    matrix: np.ndarray
    text: str

    @classmethod
    def rpy(cls, roll: float, pitch: float, yaw: float) -> ToolOrientation:
        """The rotation Rz(yaw) Ry(pitch) Rx(roll) [rad] (URDF's rpy)."""
        from scipy.spatial.transform import Rotation

        vals = [float(roll), float(pitch), float(yaw)]
        if not all(math.isfinite(v) for v in vals):
            raise InvalidInputError("orientation", f"roll, pitch, yaw must be finite radians, got {vals}")
        m = Rotation.from_euler("xyz", vals).as_matrix()
        return cls("rotation", m, f"rpy {vals[0]:g} {vals[1]:g} {vals[2]:g}")

    @classmethod
    def axis(cls, direction: Any) -> ToolOrientation:
        """The tool's z axis along `direction` (3,) (any non-zero length)."""
        d = np.asarray(direction, dtype=float).reshape(-1)
        norm = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
        if not (norm > 0 and math.isfinite(norm)):
            raise InvalidInputError("tool axis", f"needs three finite numbers, not all zero, got {d.tolist()}")
        z = d / norm
        e = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        x = e / np.linalg.norm(e)
        return cls("axis", np.column_stack([x, np.cross(z, x), z]), f"tool z axis {z.tolist()}")

    @classmethod
    def parse(cls, text: str) -> ToolOrientation:
        """ "rpy R P Y" [rad] or "axis X Y Z"."""
        words = text.replace(",", " ").split()
        if len(words) == 4 and words[0].lower() in ("rpy", "axis"):
            try:
                vals = [float(w) for w in words[1:]]
            except ValueError:
                vals = []
            if vals:
                return cls.rpy(*vals) if words[0].lower() == "rpy" else cls.axis(vals)
        raise InvalidInputError("orientation", f"expected 'rpy R P Y' (radians) or 'axis X Y Z', got {text!r}")

    def vectors(self, frame_rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(m, 3) tool vectors in the last chain joint's frame (`frame_rotation` @ e_i) and (m, 3)
        their world directions: e_z for an axis, e_x and e_z for a rotation."""
        cols = [2] if self.kind == "axis" else [0, 2]
        eye = np.eye(3)
        vec = np.stack([np.asarray(frame_rotation, dtype=float) @ eye[:, c] for c in cols])
        dirs = np.stack([self.matrix[:, c] for c in cols])
        return np.ascontiguousarray(vec), np.ascontiguousarray(dirs)

    def invariant_about(self, direction: np.ndarray) -> bool:
        """A turn about `direction` (3,) leaves the constraint unchanged: a tool axis parallel to it."""
        return self.kind == "axis" and float(np.linalg.norm(np.cross(self.matrix[:, 2], direction))) <= 1e-12

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: kind, the matched world directions, the text given."""
        out: dict[str, Any] = {"kind": self.kind, "text": self.text, "tool_z": self.matrix[:, 2].tolist()}
        if self.kind == "rotation":
            out["rotation"] = self.matrix.tolist()
        return out


def oriented_setup(robot: Robot, kin: Any, s: Setup, orientation: ToolOrientation, tol: float) -> Setup:
    """The setup with every chain joint searched (a joint that never moves the point still turns
    the tool) but those that only spin the tool about a held axis (`_spins_tool_axis`, within
    0.1 `tol` [m] of the search's residual), and the mode a fixed orientation allows: a solid of revolution only when the
    constraint is unchanged by the base's turn (a tool axis along the base axis)."""
    import dataclasses

    from kinematics.mechanisms.serial.joint_box import dof_of

    dofs = [dof_of(robot, int(v)) for v in kin.idx_v]
    robot.require_ranges([robot.dofs[i].name for i in dofs], "a workspace")
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)[dofs]
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)[dofs]
    kinds = [robot.dofs[i].kind for i in dofs]
    periodic = np.array([k == "continuous" or (k == "revolute" and h - l >= 2 * math.pi - 1e-9)
                         for k, l, h in zip(kinds, lo, hi, strict=True)])
    mode = s.mode
    if mode == "revolved" and not orientation.invariant_about(np.asarray(s.axis_direction)):
        mode = "spatial"
    first = 1 if mode == "revolved" else 0
    keep = np.ones(len(dofs), bool)
    keep[:first] = False
    if orientation.kind == "axis":
        keep &= ~_spins_tool_axis(robot, kin, 0.1 * tol / max(s.reach, 1e-3))
    active = np.array(dofs, dtype=int)[keep]
    return dataclasses.replace(s, mode=mode, active=active, lo=lo[keep], hi=hi[keep], periodic=periodic[keep],
                               fixed=tuple(robot.dofs[d].name for d, k in zip(dofs, keep, strict=True)
                                           if not k and d not in dofs[:first]))


def reduced(robot: Robot, kin: Any, orientation: ToolOrientation, tol: float, reach: float) -> ToolOrientation:
    """A whole rotation is its tool z axis alone when a full-turn joint only spins the tool about
    that axis (`_spins_tool_axis`; the UR5's wrist 3): any spin about z is then reachable without
    moving the point or the axis, so the two sets are equal (exact). Otherwise `orientation`."""
    if orientation.kind != "rotation":
        return orientation
    from kinematics.mechanisms.serial.joint_box import dof_of

    spins = _spins_tool_axis(robot, kin, 0.1 * tol / max(reach, 1e-3))
    dofs = [robot.dofs[dof_of(robot, int(v))] for v in kin.idx_v]
    full = np.array([d.kind == "continuous" or (d.kind == "revolute" and d.upper - d.lower >= 2 * math.pi - 1e-9)
                     for d in dofs])
    if not (spins & full).any():
        return orientation
    return ToolOrientation("axis", orientation.matrix, f"{orientation.text} (as its z axis: a full-turn joint spins the "
                                                       "tool about it)")


def _spins_tool_axis(robot: Robot, kin: Any, angle: float) -> np.ndarray:
    """(n,) per chain joint: it only spins the tool about the tool's z axis: it never moves the
    point and its axis is within `angle` [rad] of the tool's z axis at 64 probe configurations (the
    UR5's wrist 3: 5e-12 rad, its URDF's rounded pi / 2), so neither the point nor a held z axis
    depends on it beyond the search's tolerance: it drops out of a tool axis's search, held at a
    value in its range."""
    from kinematics.generic.batched import configurations

    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    poses, J = kin.fk_jacobian(configurations(robot, rng.uniform(lo, hi, (64, robot.nv))))
    cols = [int(v) for v in kin.idx_v]
    lin, ang = J[:, :3, cols], J[:, 3:, cols]  # (64, 3, n)
    z = poses.rotation[:, :, 2]  # the tool's z axis in the world (64, 3)
    along = np.linalg.norm(np.cross(np.moveaxis(ang, 1, 2), z[:, None, :]), axis=2)  # (64, n)
    return np.asarray((np.abs(lin).max(axis=(0, 1)) <= 1e-12) & (along.max(axis=0) <= angle)
                      & (np.linalg.norm(ang, axis=1).min(axis=0) > 0.5))
