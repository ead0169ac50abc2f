"""kinematics: kinematic analysis of robots described by a URDF (plus a loop-closure sidecar for
closed chains), built on Pinocchio: the planar SCARA of paper A, the 3-[P2(US)] of paper B, the
Delta, and any serial or closed-loop robot.

Layers, each importing only those below it (enforced by import-linter, see pyproject.toml):

* `kinematics.model` - load robots (built-ins, URDF paths, example-robot-data names), loop sidecars
* `kinematics.generic` - kinematics of any Pinocchio model: poses, Jacobians, compiled batches,
  the closed-loop solver, manipulability ellipsoids
* `kinematics.mechanisms` - the `Mechanism` interface, the dispatcher `mechanism_of`, one
  subpackage per family (scara, p2us, delta, serial, closed_loop)
* `kinematics.analyses` - workspace volumes, singular loci, mobility, usable workspace, sweeps
* `kinematics.guidance` - paper A's manual-guidance controller and simulations
* `kinematics.views` - Meshcat scenes and figures
* `kinematics.cli` - the command line (private: the library never imports it)

Below them: `errors` (the `KinematicsError` hierarchy), `sizes`, `chunks`, `files`. The names
below are re-exported here and imported on first use, so `import kinematics` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from kinematics.errors import KinematicsError

if TYPE_CHECKING:
    from kinematics.analyses.columns import column_volume
    from kinematics.analyses.singularities import singular_loci
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms import Mechanism, mechanism_of
    from kinematics.model.robot import Robot, load_robot

__version__ = "0.1.0"

_LAZY = {
    "load_robot": "kinematics.model.robot",
    "Robot": "kinematics.model.robot",
    "Mechanism": "kinematics.mechanisms",
    "mechanism_of": "kinematics.mechanisms",
    "measure_workspace": "kinematics.analyses.workspace",
    "singular_loci": "kinematics.analyses.singularities",
    "column_volume": "kinematics.analyses.columns",
}

__all__ = [
    "KinematicsError",
    "Mechanism",
    "Robot",
    "__version__",
    "column_volume",
    "load_robot",
    "measure_workspace",
    "mechanism_of",
    "singular_loci",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
