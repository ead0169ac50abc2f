"""Paper A's manual-guidance controller (admittance, saturation, virtual impedance) and its
simulated experiments.

Modules: `controller`, `simulation`. The names a user starts from are listed once, in `__init__.pyi` (which type
checkers read), and imported on first use; everything else is imported from its module.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
