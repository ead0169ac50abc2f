"""Meshcat scenes and matplotlib figures.

Modules: `meshcat`, `plots`. Public names are re-exported
here and imported on first use, so importing the package stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinematics.views.meshcat import (
        BACKGROUND,
        FOV_DEG,
        GRID_SQUARES,
        NEAR_SINGULAR,
        VIEW_CELLS,
        Scene,
        closed_loop_view,
        conditioning_view,
        default_pose,
        parallel_view,
        scara_view,
        serial_view,
        visual_model,
    )
    from kinematics.views.plots import (
        CONDITIONING_CMAP,
        INVERSE_KAPPA_CMAP,
        LIMITS_TEXT,
        RADIUS_CMAP,
        SCARA_SINGULAR_COLOUR,
        SINGULAR_STYLE,
        conditioning_map,
        guidance_run,
        guidance_title,
        headless,
        p2us_singular_loci,
        p2us_workspace,
        pareto_front,
        planar_workspace,
        save,
        scara_workspace,
        spatial_workspace,
        volume_convergence,
    )

_LAZY = {
    "BACKGROUND": "meshcat",
    "CONDITIONING_CMAP": "plots",
    "FOV_DEG": "meshcat",
    "GRID_SQUARES": "meshcat",
    "INVERSE_KAPPA_CMAP": "plots",
    "LIMITS_TEXT": "plots",
    "NEAR_SINGULAR": "meshcat",
    "RADIUS_CMAP": "plots",
    "SCARA_SINGULAR_COLOUR": "plots",
    "SINGULAR_STYLE": "plots",
    "Scene": "meshcat",
    "VIEW_CELLS": "meshcat",
    "closed_loop_view": "meshcat",
    "conditioning_map": "plots",
    "conditioning_view": "meshcat",
    "default_pose": "meshcat",
    "guidance_run": "plots",
    "guidance_title": "plots",
    "headless": "plots",
    "p2us_singular_loci": "plots",
    "p2us_workspace": "plots",
    "parallel_view": "meshcat",
    "pareto_front": "plots",
    "planar_workspace": "plots",
    "save": "plots",
    "scara_view": "meshcat",
    "scara_workspace": "plots",
    "serial_view": "meshcat",
    "spatial_workspace": "plots",
    "visual_model": "meshcat",
    "volume_convergence": "plots",
}

__all__ = [
    "BACKGROUND",
    "CONDITIONING_CMAP",
    "FOV_DEG",
    "GRID_SQUARES",
    "INVERSE_KAPPA_CMAP",
    "LIMITS_TEXT",
    "NEAR_SINGULAR",
    "RADIUS_CMAP",
    "SCARA_SINGULAR_COLOUR",
    "SINGULAR_STYLE",
    "VIEW_CELLS",
    "Scene",
    "closed_loop_view",
    "conditioning_map",
    "conditioning_view",
    "default_pose",
    "guidance_run",
    "guidance_title",
    "headless",
    "p2us_singular_loci",
    "p2us_workspace",
    "parallel_view",
    "pareto_front",
    "planar_workspace",
    "save",
    "scara_view",
    "scara_workspace",
    "serial_view",
    "spatial_workspace",
    "visual_model",
    "volume_convergence",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
