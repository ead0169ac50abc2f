"""The `kinematics` command line. Private to the package: the library never imports it.

`main` (in `app`) parses the command line and hands each command to its handler; `run` is the
process's entry point around it. Each command is
registered in one place, its module's `register(command)`, which adds its subparser, arguments and
handler: `info`, `fk`, `ik`, `jacobian`, `manipulability`, `mobility`, `workspace`
(workspace-volume, singularities, sweep), `design` (usable-workspace, dexterity, synthesize,
workspace-mesh), `guidance` (guide), `views` (show), `urdf`; `app.build_parser` loops over them.
`args` holds the shared argument helpers (the parser class, number and type parsers, ROBOT with
--range, --q, the scan options). These modules import nothing heavy at module level; their
handlers import NumPy, Pinocchio etc. when the command runs, so `kinematics --help` stays instant.
`parallel` holds the closed-loop robots' handlers, `report` formats JSON and text reports.
"""

from __future__ import annotations

from kinematics.cli.app import main as main
from kinematics.cli.app import run as run

