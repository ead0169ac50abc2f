"""Analyses over any mechanism (a `kinematics.mechanisms.Mechanism`, never a family's parameters):
workspace volumes (exact columns, cells), serial workspaces, singular loci, mobility, usable
workspace, boundary meshes, dexterity, dimensional synthesis, design sweeps.

Modules: `boundary_mesh`, `cells`, `columns`, `dexterity`, `mobility`, `serial_workspace`,
`singularities`, `sweep`, `synthesis`, `usable`, `workspace`. The names a user needs are listed
once, in `__init__.pyi` (which type checkers read), and imported on first use, so importing the
package stays light; everything else is imported from its module.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
