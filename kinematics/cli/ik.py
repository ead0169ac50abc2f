"""`kinematics ik`: inverse kinematics, every solution in closed form (`Mechanism.pose_ik`: planar
2R arms, the 3-[P2(US)] and the Delta), and every working mode the batched solver finds for any
other closed loop (`Mechanism.ik`); the report is `kinematics.cli.parallel.ik`."""

from __future__ import annotations

import argparse

from kinematics.cli.args import Command, load, number, orientation_args, robot_arg
from kinematics.cli.report import emit


def register(command: Command) -> None:
    p = command("ik", cmd_ik, "inverse kinematics: every solution in closed form (scara, p2us, delta), every "
                              "working mode the batched solver finds (other closed loops)")
    robot_arg(p)
    p.add_argument("--position", nargs="+", type=number, required=True, metavar="X",
                   help="target position [m]: X Y for a planar arm, X Y Z for p2us and delta, a closed loop's "
                        "task coordinates (the report names them; e.g. Y Z for a five-bar in the y-z plane)")
    orientation_args(p, "the working modes", closed_loops=True)


def cmd_ik(args: argparse.Namespace) -> int:
    """Inverse kinematics: closed forms (planar 2R arms, the 3-[P2(US)], the Delta), else a closed
    loop's batched solver."""
    from kinematics.cli.parallel import ik

    return ik(args, load(args), emit)
