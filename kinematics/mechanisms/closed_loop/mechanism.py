"""A URDF + loop sidecar with no closed forms as a `Mechanism`.

Forward kinematics goes through the generic Pinocchio closed-loop solver
(`kinematics.generic.closedloop.ClosedLoop`: Newton with continuation from the sidecar's
reference configuration), one actuator vector at a time, so only the assembly reached from the
reference is reported. Workspace margins, all-branch inverse kinematics and singular fields need
a batched solver; until the mechanism has one it says so (`MissingCapabilityError`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.mechanisms.base import Assemblies, Mechanism
from kinematics.model.robot import Robot


class GenericClosedLoop(Mechanism):
    """Any closed-loop robot (URDF tree + loop sidecar)."""

    family = "closed-loop"
    closed_loop = True
    description = "closed-loop model (generic Pinocchio solver)"
    actuator_unit = "rad or m"
    assembly_modes = ("reached from the reference",)

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.name = robot.name

    def parameters(self) -> dict[str, Any]:
        loops = self.robot.loops
        return {"closures": len(loops.closures) if loops else 0,
                "actuated": list(loops.actuated) if loops else [], "end_effector": self.robot.tool_frame}

    def fk(self, q: np.ndarray) -> Assemblies:
        from kinematics.errors import KinematicsError
        from kinematics.generic.closedloop import ClosedLoop

        loop = ClosedLoop(self.robot)
        q = np.atleast_2d(np.asarray(q, dtype=float))
        p = np.full((len(q), 1, 3), np.nan)
        for k, row in enumerate(q):
            try:
                sol = loop.solve(row)
            except KinematicsError:
                continue
            p[k, 0] = sol.pose.translation
        return Assemblies(p, np.isfinite(p).all(axis=-1), self.assembly_modes)
