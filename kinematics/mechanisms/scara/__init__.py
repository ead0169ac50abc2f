"""The planar 2R arm (paper A's SCARA): closed forms.

Modules: `closed_form`, `mechanism`. Public names are re-exported
here and imported on first use, so importing the package stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinematics.mechanisms.scara.closed_form import (
        BOUNDARY_TOL,
        ELBOWS,
        IKAnswer,
        IKSolution,
        ScaraIK,
        ScaraParams,
        det_jacobian,
        ellipse_point,
        fk,
        ik,
        ik_elbow,
        jacobian,
        manipulability,
        solve_ik,
    )
    from kinematics.mechanisms.scara.mechanism import (
        ELBOW_LEGEND,
        Scara,
        scara_margin,
    )

_LAZY = {
    "BOUNDARY_TOL": "closed_form",
    "ELBOWS": "closed_form",
    "ELBOW_LEGEND": "mechanism",
    "IKAnswer": "closed_form",
    "IKSolution": "closed_form",
    "Scara": "mechanism",
    "ScaraIK": "closed_form",
    "ScaraParams": "closed_form",
    "det_jacobian": "closed_form",
    "ellipse_point": "closed_form",
    "fk": "closed_form",
    "ik": "closed_form",
    "ik_elbow": "closed_form",
    "jacobian": "closed_form",
    "manipulability": "closed_form",
    "scara_margin": "mechanism",
    "solve_ik": "closed_form",
}

__all__ = [
    "BOUNDARY_TOL",
    "ELBOWS",
    "ELBOW_LEGEND",
    "IKAnswer",
    "IKSolution",
    "Scara",
    "ScaraIK",
    "ScaraParams",
    "det_jacobian",
    "ellipse_point",
    "fk",
    "ik",
    "ik_elbow",
    "jacobian",
    "manipulability",
    "scara_margin",
    "solve_ik",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
