"""Kinematics of any Pinocchio model: serial frame poses and Jacobians, compiled batched
kinematics, the closed-loop solvers, manipulability ellipsoids.

Modules: `batched`, `closedloop`, `loop_batch` (a package), `loop_singular`, `manipulability`, `serial`,
`singularity`. The names a user starts from are listed once, in `__init__.pyi` (which type
checkers read), and imported on first use; everything else is imported from its module.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
