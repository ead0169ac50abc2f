"""Mechanisms: one interface (`Mechanism`, in `base`) over every robot family, and the one
dispatcher (`mechanism_of`, in `dispatch`) that decides what a loaded robot is.

Families, one subpackage each: `scara` (planar 2R arm), `p2us` (3-[P2(US)]), `delta` (3-RUU
Delta) with closed forms; `serial` (any open chain) and `closed_loop` (any URDF + loop sidecar)
through the generic kinematics. The public names are listed once, in `__init__.pyi`, and imported
on first use.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
