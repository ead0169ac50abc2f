"""Kinematics of any Pinocchio model: serial frame poses and Jacobians, compiled batched kinematics, the closed-loop solver, manipulability ellipsoids.

Modules: `batched`, `closedloop`, `loop_batch`, `loop_singular`, `manipulability`, `serial`, `singularity`. Public names are re-exported
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
    from kinematics.generic.loop_batch import (
        CACHE_POINTS,
        LIMITS,
        STALL,
        TOL,
        WARM_RADIUS_FACTOR,
        Block,
        BranchSolutions,
        LoopBatch,
        Singularities,
        loop_batch,
    )
    from kinematics.generic.loop_singular import LoopFields, loop_fields
    from kinematics.generic.manipulability import (
        SINGULAR_RTOL,
        Ellipses,
        Ellipsoid,
        ellipses_2x2,
        ellipsoid,
    )
    from kinematics.generic.serial import (
        DEFAULT_LENGTH,
        TASKS,
        Pose,
        common_axis,
        forward_kinematics,
        frame_jacobian,
        key_points,
        length_scale,
        plane,
        task_jacobian,
        task_rows,
    )
    from kinematics.generic.singularity import (
        SINGULAR_TOL,
        SINGULARITY_TYPES,
        classify,
    )

_LAZY = {
    "BLOCK": "batched",
    "BatchedKinematics": "batched",
    "BatchedPoses": "batched",
    "Block": "loop_batch",
    "LoopFields": "loop_singular",
    "loop_fields": "loop_singular",
    "BranchSolutions": "loop_batch",
    "CACHE_POINTS": "loop_batch",
    "ClosedLoop": "closedloop",
    "DEFAULT_LENGTH": "serial",
    "Ellipses": "manipulability",
    "Ellipsoid": "manipulability",
    "FREE_RTOL": "closedloop",
    "LIMITS": "loop_batch",
    "LoopBatch": "loop_batch",
    "LoopSolution": "closedloop",
    "MAX_DRIFT": "closedloop",
    "MAX_PASSIVE_STEP": "closedloop",
    "Pose": "serial",
    "RANK_RTOL": "closedloop",
    "SINGULARITY_TYPES": "singularity",
    "SINGULAR_RTOL": "manipulability",
    "SINGULAR_TOL": "singularity",
    "STALL": "loop_batch",
    "SUPPORTED": "batched",
    "Singularities": "loop_batch",
    "TASKS": "serial",
    "TOL": "loop_batch",
    "TOLERANCE": "closedloop",
    "WARM_RADIUS_FACTOR": "loop_batch",
    "batched_fk": "batched",
    "batched_jacobian": "batched",
    "classify": "singularity",
    "common_axis": "serial",
    "compile_frame": "batched",
    "configurations": "batched",
    "ellipses_2x2": "manipulability",
    "ellipsoid": "manipulability",
    "forward_kinematics": "serial",
    "frame_jacobian": "serial",
    "key_points": "serial",
    "length_scale": "serial",
    "loop_batch": "loop_batch",
    "plane": "serial",
    "task_jacobian": "serial",
    "task_rows": "serial",
}

__all__ = [
    "BLOCK",
    "CACHE_POINTS",
    "DEFAULT_LENGTH",
    "FREE_RTOL",
    "LIMITS",
    "MAX_DRIFT",
    "MAX_PASSIVE_STEP",
    "RANK_RTOL",
    "SINGULARITY_TYPES",
    "SINGULAR_RTOL",
    "SINGULAR_TOL",
    "STALL",
    "SUPPORTED",
    "TASKS",
    "TOL",
    "TOLERANCE",
    "WARM_RADIUS_FACTOR",
    "BatchedKinematics",
    "BatchedPoses",
    "Block",
    "BranchSolutions",
    "ClosedLoop",
    "Ellipses",
    "Ellipsoid",
    "LoopBatch",
    "LoopFields",
    "LoopSolution",
    "Pose",
    "Singularities",
    "batched_fk",
    "batched_jacobian",
    "classify",
    "common_axis",
    "compile_frame",
    "configurations",
    "ellipses_2x2",
    "ellipsoid",
    "forward_kinematics",
    "frame_jacobian",
    "key_points",
    "length_scale",
    "loop_batch",
    "loop_fields",
    "plane",
    "task_jacobian",
    "task_rows",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
