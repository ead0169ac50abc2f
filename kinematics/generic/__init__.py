"""Kinematics of any Pinocchio model: serial frame poses and Jacobians, compiled batched kinematics, the closed-loop solver, manipulability ellipsoids.

Modules: `batched`, `closedloop`, `manipulability`, `serial`. Public names are re-exported
here and imported on first use, so importing the package stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinematics.generic.batched import (
        BLOCK,
        SUPPORTED,
        BatchedKinematics,
        BatchedPoses,
        batched_fk,
        batched_jacobian,
        compile_frame,
        configurations,
    )
    from kinematics.generic.closedloop import (
        FREE_RTOL,
        MAX_DRIFT,
        MAX_PASSIVE_STEP,
        RANK_RTOL,
        TOLERANCE,
        ClosedLoop,
        LoopSolution,
    )
    from kinematics.generic.manipulability import (
        SINGULAR_RTOL,
        Ellipses,
        Ellipsoid,
        ellipses_2x2,
        ellipsoid,
    )
    from kinematics.generic.serial import (
        TASKS,
        Pose,
        common_axis,
        forward_kinematics,
        frame_jacobian,
        plane,
        task_jacobian,
        task_rows,
    )

_LAZY = {
    "BLOCK": "batched",
    "BatchedKinematics": "batched",
    "BatchedPoses": "batched",
    "ClosedLoop": "closedloop",
    "Ellipses": "manipulability",
    "Ellipsoid": "manipulability",
    "FREE_RTOL": "closedloop",
    "LoopSolution": "closedloop",
    "MAX_DRIFT": "closedloop",
    "MAX_PASSIVE_STEP": "closedloop",
    "Pose": "serial",
    "RANK_RTOL": "closedloop",
    "SINGULAR_RTOL": "manipulability",
    "SUPPORTED": "batched",
    "TASKS": "serial",
    "TOLERANCE": "closedloop",
    "batched_fk": "batched",
    "batched_jacobian": "batched",
    "common_axis": "serial",
    "compile_frame": "batched",
    "configurations": "batched",
    "ellipses_2x2": "manipulability",
    "ellipsoid": "manipulability",
    "forward_kinematics": "serial",
    "frame_jacobian": "serial",
    "plane": "serial",
    "task_jacobian": "serial",
    "task_rows": "serial",
}

__all__ = [
    "BLOCK",
    "FREE_RTOL",
    "MAX_DRIFT",
    "MAX_PASSIVE_STEP",
    "RANK_RTOL",
    "SINGULAR_RTOL",
    "SUPPORTED",
    "TASKS",
    "TOLERANCE",
    "BatchedKinematics",
    "BatchedPoses",
    "ClosedLoop",
    "Ellipses",
    "Ellipsoid",
    "LoopSolution",
    "Pose",
    "batched_fk",
    "batched_jacobian",
    "common_axis",
    "compile_frame",
    "configurations",
    "ellipses_2x2",
    "ellipsoid",
    "forward_kinematics",
    "frame_jacobian",
    "plane",
    "task_jacobian",
    "task_rows",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
