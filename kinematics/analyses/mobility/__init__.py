"""Mobility of a mechanism three ways: Grübler–Kutzbach, screw theory, and the numeric rank of
the loop-constraint Jacobian. Works on any robot model plus its loop sidecar.

Conventions. A twist is T = (v_O; w) — the velocity of the body point at the world origin O and
the angular velocity — which is Pinocchio's WORLD-frame Jacobian column. A wrench is
W = (f; m_O), force and moment about O. They are reciprocal when W . T = f.v_O + m_O.w = 0 (the
plain dot product in this ordering), i.e. the wrench does no work on the twist.

Physical links and joints (for the counts) come from the URDF tree: a massless intermediate body
whose single child joint sits at the same origin is the cross of a composite joint, so revolute
chains through such bodies merge into U (2 R) and S (3 R) joints. Each loop closure is a joint:
`point` a spherical joint (3 freedoms; in a planar mechanism it acts as a pin, 1), `6d` a weld (0).
"""

from .graph import Edge, JointGraph, joint_graph, simple_paths
from .grubler import GrublerCount, PhysicalJoint, grubler
from .linalg import RANK_RTOL
from .numeric import (
    REGULAR_RTOL,
    REGULAR_SEED,
    NumericMobility,
    RegularConfiguration,
    numeric_mobility,
    regular_configuration,
)
from .report import MobilityReport, analyse
from .screws import (
    TRANSLATION_RTOL,
    Freedom,
    Limb,
    ScrewAnalysis,
    Wrench,
    classify_twists,
    classify_wrenches,
    screw_analysis,
)

__all__ = [
    "RANK_RTOL", "REGULAR_RTOL", "REGULAR_SEED", "TRANSLATION_RTOL", "Edge", "Freedom", "GrublerCount", "JointGraph",
    "Limb", "MobilityReport", "NumericMobility", "PhysicalJoint", "RegularConfiguration", "ScrewAnalysis", "Wrench",
    "analyse", "classify_twists", "classify_wrenches", "grubler", "joint_graph", "numeric_mobility",
    "regular_configuration", "screw_analysis", "simple_paths",
]
