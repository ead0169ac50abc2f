"""Any open chain as a `Mechanism`: forward kinematics and Jacobians of its tool frame's position
from the compiled batched kinematics (`kinematics.generic.batched`).

A serial arm has no closed-form inverse kinematics here, hence no margin: its workspace is
measured in joint space (`kinematics.analyses.serial_workspace`, proved bounds), which is what
the analyses use for this family. Singularity measure: iota_I = sigma_min / sigma_max of the
position Jacobian restricted to the task (the arm's plane for planar arms), 0 where it loses
rank (the inverse map is undefined: type I in Gosselin-Angeles' terms); iota_II = 1 (a serial arm
has no passive joints to release the tool).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.mechanisms.base import Assemblies, Mechanism, Velocity
from kinematics.model.robot import Robot


class SerialArm(Mechanism):
    """An open chain loaded from a URDF; q are Pinocchio configurations (nq values per row)."""

    family = "serial"
    description = "open chain (compiled batched kinematics; workspace in joint space)"
    actuator_unit = "rad or m"
    assembly_modes = ("tool",)

    def __init__(self, robot: Robot) -> None:
        from kinematics.generic.serial import plane

        self.robot = robot
        self.name = robot.name
        self.plane = plane(robot)
        if self.plane is not None:
            self.task_dim = 2
            self.task_axes = tuple("xyz"[k] for k in self.plane)

    def parameters(self) -> dict[str, Any]:
        r = self.robot
        return {"frame": r.tool_frame, "joints": [d.name for d in r.dofs], "lower": r.lower.tolist(),
                "upper": r.upper.tolist()}

    def _rows(self) -> list[int]:
        return list(self.plane) if self.plane is not None else [0, 1, 2]

    def fk(self, q: np.ndarray) -> Assemblies:
        from kinematics.generic.batched import batched_fk

        p = batched_fk(self.robot, np.atleast_2d(np.asarray(q, dtype=float))).position[:, self._rows()]
        return Assemblies(p[:, None, :], np.ones((len(p), 1), dtype=bool), ("tool",))

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        from kinematics.generic.batched import batched_jacobian

        J = batched_jacobian(self.robot, np.atleast_2d(np.asarray(q, dtype=float)))[:, self._rows()]
        sv = np.linalg.svd(J, compute_uv=False)
        with np.errstate(invalid="ignore", divide="ignore"):
            iota = np.where(sv[:, 0] > 0, sv[:, -1] / sv[:, 0], 0.0)
        return Velocity(J, np.linalg.pinv(J), iota, np.ones_like(iota))
