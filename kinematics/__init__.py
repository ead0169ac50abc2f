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

Below them: `errors` (the `KinematicsError` hierarchy), `sizes`, `chunks`, `files`. The few names
a user starts from are listed once, in `__init__.pyi` (which type checkers read), and imported on
first use (`lazy_loader`), so `import kinematics` stays light; each package lists its own the same
way, and everything else is imported from its module.
"""

import lazy_loader as _lazy

__version__ = "0.1.0"

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
