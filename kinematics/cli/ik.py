"""`kinematics ik`: closed-form inverse kinematics, every solution (`Mechanism.pose_ik`: planar 2R
arms, the 3-[P2(US)] and the Delta; the report is `kinematics.cli.parallel.ik`)."""

from __future__ import annotations

import argparse

from kinematics.cli.args import Command, load, number, robot_arg
from kinematics.cli.report import emit


def register(command: Command) -> None:
    p = command("ik", cmd_ik, "closed-form inverse kinematics (scara, p2us, delta): all solutions")
    robot_arg(p)
    p.add_argument("--position", nargs="+", type=number, required=True, metavar="X",
                   help="target position [m]: X Y for a planar arm, X Y Z for p2us and delta")


def cmd_ik(args: argparse.Namespace) -> int:
    """Closed-form inverse kinematics: planar 2R arms, the 3-[P2(US)] and the Delta."""
    from kinematics.cli.parallel import ik

    return ik(args, load(args), emit)
