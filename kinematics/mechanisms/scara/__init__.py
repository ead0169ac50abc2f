"""The planar 2R arm (paper A's SCARA): closed forms and joint-space references.

Modules: `closed_form`, `joint_space`, `mechanism`. The names a user starts from are listed once, in `__init__.pyi` (which type
checkers read), and imported on first use; everything else is imported from its module.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
