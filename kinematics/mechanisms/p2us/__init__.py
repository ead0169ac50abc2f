"""The 3-[P2(US)] translational parallel robot (paper B): closed forms, the compiled scan kernel,
the exact columns, the URDF generator, paper B's numbers and scan.

Modules: `closed_form`, `columns_reference`, `exact`, `mechanism`, `paper_b`, `paper_scan`, `scan`, `urdf`. The names a user starts from are listed once, in `__init__.pyi` (which type
checkers read), and imported on first use; everything else is imported from its module.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
