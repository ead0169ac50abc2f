"""Paper A's manual-guidance controller (admittance, saturation, virtual impedance) and its simulated experiments.

Modules: `controller`, `simulation`. Public names are re-exported
here and imported on first use, so importing the package stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinematics.guidance.controller import (
        Controller,
        GuidanceParams,
        Kinematics,
        ScaraKinematics,
        SerialKinematics,
        Step,
        virtual_gain,
    )
    from kinematics.guidance.simulation import (
        EXPERIMENTS,
        SINGULAR_RADIUS,
        Experiment,
        Profile,
        ReactiveOperator,
        Run,
        StubbornOperator,
        run_experiment,
        simulate,
    )

_LAZY = {
    "Controller": "controller",
    "EXPERIMENTS": "simulation",
    "Experiment": "simulation",
    "GuidanceParams": "controller",
    "Kinematics": "controller",
    "Profile": "simulation",
    "ReactiveOperator": "simulation",
    "Run": "simulation",
    "SINGULAR_RADIUS": "simulation",
    "ScaraKinematics": "controller",
    "SerialKinematics": "controller",
    "Step": "controller",
    "StubbornOperator": "simulation",
    "run_experiment": "simulation",
    "simulate": "simulation",
    "virtual_gain": "controller",
}

__all__ = [
    "EXPERIMENTS",
    "SINGULAR_RADIUS",
    "Controller",
    "Experiment",
    "GuidanceParams",
    "Kinematics",
    "Profile",
    "ReactiveOperator",
    "Run",
    "ScaraKinematics",
    "SerialKinematics",
    "Step",
    "StubbornOperator",
    "run_experiment",
    "simulate",
    "virtual_gain",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
