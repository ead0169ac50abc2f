"""Mechanisms: one interface (`Mechanism`, in `base`) over every robot family, and the one
dispatcher (`mechanism_of`, in `dispatch`) that decides what a loaded robot is.

Families, one subpackage each: `scara` (planar 2R arm), `p2us` (3-[P2(US)]), `delta` (3-RUU
Delta) with closed forms; `serial` (any open chain) and `closed_loop` (any URDF + loop sidecar)
through the generic kinematics.
"""

from kinematics.mechanisms.base import (
    CAPABILITIES,
    SINGULAR_TOL,
    SINGULARITY_TYPES,
    UNION,
    Assemblies,
    BranchIK,
    MarginFn,
    Mechanism,
    SingularFields,
    Velocity,
    classify,
)
from kinematics.mechanisms.dispatch import families, mechanism_of

__all__ = [
    "CAPABILITIES",
    "SINGULARITY_TYPES",
    "SINGULAR_TOL",
    "UNION",
    "Assemblies",
    "BranchIK",
    "MarginFn",
    "Mechanism",
    "SingularFields",
    "Velocity",
    "classify",
    "families",
    "mechanism_of",
]
