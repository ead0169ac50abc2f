"""Clavel's 3-RUU Delta robot: closed forms, the compiled scan kernel and the URDF generator.

Modules: `closed_form`, `mechanism`, `scan`, `urdf`. Public names are re-exported
here and imported on first use, so importing the package stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinematics.mechanisms.delta.closed_form import (
        MECHANISM,
        DeltaParams,
        IKResult,
        Jacobians,
        LimbSolutions,
        cone_angles,
        elbows,
        fk,
        fk_reason,
        ik,
        in_plane,
        jacobian_inverse,
        jacobians,
        limb_ik,
        limb_limits,
        limb_reasons,
        passive_angles,
        rod_vectors,
        sphere_centres,
        violations,
    )
    from kinematics.mechanisms.delta.mechanism import (
        LIMITS,
        MODE_LEGEND,
        Delta,
        limb_margins,
    )
    from kinematics.mechanisms.delta.scan import DeltaScan
    from kinematics.mechanisms.delta.urdf import (
        LIMBS,
        RODS,
        SPHERICAL,
        joint_values_at,
        read_params,
        reference_configuration,
        reference_pose,
        rod_offset,
        sidecar_text,
        urdf_text,
        write,
    )

_LAZY = {
    "Delta": "mechanism",
    "DeltaParams": "closed_form",
    "DeltaScan": "scan",
    "IKResult": "closed_form",
    "Jacobians": "closed_form",
    "LIMBS": "urdf",
    "LIMITS": "mechanism",
    "LimbSolutions": "closed_form",
    "MECHANISM": "closed_form",
    "MODE_LEGEND": "mechanism",
    "RODS": "urdf",
    "SPHERICAL": "urdf",
    "cone_angles": "closed_form",
    "elbows": "closed_form",
    "fk": "closed_form",
    "fk_reason": "closed_form",
    "ik": "closed_form",
    "in_plane": "closed_form",
    "jacobian_inverse": "closed_form",
    "jacobians": "closed_form",
    "joint_values_at": "urdf",
    "limb_ik": "closed_form",
    "limb_limits": "closed_form",
    "limb_margins": "mechanism",
    "limb_reasons": "closed_form",
    "passive_angles": "closed_form",
    "read_params": "urdf",
    "reference_configuration": "urdf",
    "reference_pose": "urdf",
    "rod_offset": "urdf",
    "rod_vectors": "closed_form",
    "sidecar_text": "urdf",
    "sphere_centres": "closed_form",
    "urdf_text": "urdf",
    "violations": "closed_form",
    "write": "urdf",
}

__all__ = [
    "LIMBS",
    "LIMITS",
    "MECHANISM",
    "MODE_LEGEND",
    "RODS",
    "SPHERICAL",
    "Delta",
    "DeltaParams",
    "DeltaScan",
    "IKResult",
    "Jacobians",
    "LimbSolutions",
    "cone_angles",
    "elbows",
    "fk",
    "fk_reason",
    "ik",
    "in_plane",
    "jacobian_inverse",
    "jacobians",
    "joint_values_at",
    "limb_ik",
    "limb_limits",
    "limb_margins",
    "limb_reasons",
    "passive_angles",
    "read_params",
    "reference_configuration",
    "reference_pose",
    "rod_offset",
    "rod_vectors",
    "sidecar_text",
    "sphere_centres",
    "urdf_text",
    "violations",
    "write",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
