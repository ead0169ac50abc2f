"""A fixed tool orientation (`ToolOrientation`): the set a robot reaches with its tool (end effector)
held so. A serial arm's margin searches for it (`kinematics.mechanisms.serial.orientation`); a
closed loop with six actuators holds a whole rotation in its batched solver
(`kinematics.mechanisms.closed_loop`).

`ToolOrientation.parse("rpy R P Y")` reads the URDF convention R = Rz(Y) Ry(P) Rx(R) [rad]
(extrinsic x, y, z); `ToolOrientation.axis(d)` the tool's z axis along d (normalised);
`ToolOrientation.reference()` a closed loop's end effector at its reference rotation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from kinematics.errors import InvalidInputError


@dataclass(frozen=True, eq=False)
class ToolOrientation:
    """A fixed tool orientation in the world.

    Attributes:
        kind: "rotation" (the frame's whole rotation is `matrix`), "axis" (the frame's z axis is
            `matrix[:, 2]`; the other columns complete a right-handed basis and are not matched)
            or "reference" (a closed loop's: the whole rotation the end effector has at the loop
            sidecar's reference configuration, which the mechanism reads; `matrix` is NaN).
        matrix: (3, 3) rotation, world from tool.
        text: how it was given, for reports.
    """

    kind: Literal["rotation", "axis", "reference"]
    matrix: np.ndarray
    text: str

    def __post_init__(self) -> None:
        m = np.array(self.matrix, dtype=float)  # an own, read-only copy: the dataclass is frozen
        m.flags.writeable = False
        object.__setattr__(self, "matrix", m)

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
    def reference(cls) -> ToolOrientation:
        """A closed loop's end effector held at its rotation at the reference configuration."""
        return cls("reference", np.full((3, 3), np.nan), "reference")

    @classmethod
    def parse(cls, text: str) -> ToolOrientation:
        """ "rpy R P Y" [rad], "axis X Y Z" or "reference"."""
        words = text.replace(",", " ").split()
        if [w.lower() for w in words] == ["reference"]:
            return cls.reference()
        if len(words) == 4 and words[0].lower() in ("rpy", "axis"):
            try:
                vals = [float(w) for w in words[1:]]
            except ValueError:
                vals = []
            if vals:
                return cls.rpy(*vals) if words[0].lower() == "rpy" else cls.axis(vals)
        raise InvalidInputError("orientation", f"expected 'rpy R P Y' (radians), 'axis X Y Z' or 'reference', "
                                               f"got {text!r}")

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
        if self.kind == "reference":
            return {"kind": self.kind, "text": self.text}
        out: dict[str, Any] = {"kind": self.kind, "text": self.text, "tool_z": self.matrix[:, 2].tolist()}
        if self.kind == "rotation":
            out["rotation"] = self.matrix.tolist()
        return out


__all__ = ["ToolOrientation"]
