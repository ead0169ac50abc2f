"""The `kinematics` command line. Private to the package: the library never imports it.

`main` (in `app`) parses the command line and hands each command to its handler module
(`parallel`, `workspace`, `mobility`, `views`, `guidance`, `design`, `fk`), imported only when
that command runs, so `kinematics --help` stays instant. `report` formats JSON and text reports.
"""

from __future__ import annotations

from kinematics.cli.app import main

__all__ = ["main"]
