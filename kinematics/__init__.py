"""kinematics: kinematic analysis of a planar SCARA and the 3-[P2(US)] parallel robot, and of any
robot described the same way (URDF + loop-closure sidecar), built on Pinocchio.

Submodules (imported on demand, so `import kinematics` stays light):

* `kinematics.model.robot` - load robots (built-in names, URDF paths, example-robot-data names)
* `kinematics.generic.serial` - frame poses and world-aligned Jacobians through Pinocchio
* `kinematics.mechanisms.scara.closed_form` - closed forms of the planar 2R arm, vectorised
* `kinematics.generic.manipulability` - manipulability ellipsoids of any Jacobian
* `kinematics.errors` - the `KinematicsError` hierarchy
"""

from __future__ import annotations

import importlib
from typing import Any

from kinematics.errors import KinematicsError

__version__ = "0.1.0"
__all__ = ["KinematicsError", "__version__", "load_robot"]


def __getattr__(name: str) -> Any:
    if name == "load_robot":
        return importlib.import_module(".model", __name__).load_robot
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
