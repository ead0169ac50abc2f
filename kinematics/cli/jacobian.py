"""`kinematics jacobian`: the world-aligned task Jacobian at a configuration (serial robots here;
closed loops in `kinematics.cli.parallel`)."""

from __future__ import annotations

import argparse

from kinematics.cli.args import (
    CLOSED_POSE,
    EXIT_OK,
    Command,
    is_parallel,
    load,
    number,
    q_args,
    refuse_pose_args,
    robot_arg,
    values,
)
from kinematics.cli.report import emit, with_plane


def register(command: Command) -> None:
    p = command("jacobian", cmd_jacobian, "world-aligned Jacobian at a configuration (p2us, delta: at a position)")
    robot_arg(p)
    q_args(p, required=False, p2us="not used, give --position", loops=CLOSED_POSE)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")
    p.add_argument("--task", default="auto", choices=["auto", "planar", "translation", "rotation", "full"],
                   help="task-space rows (default auto: x-y for planar arms, x-y-z for other serial robots, all "
                        "six for closed loops other than p2us and delta; p2us, delta: their platform's x-y-z, auto "
                        "or translation only)")
    p.add_argument("--position", nargs=3, type=number, metavar=("X", "Y", "Z"), help="p2us, delta: platform position [m]")
    p.add_argument("--mode", help="p2us, delta: working mode label such as +++ (default: the first mode within the "
                                  "limits, else the first that assembles)")


def cmd_jacobian(args: argparse.Namespace) -> int:
    """World-aligned task Jacobian."""
    robot = load(args)
    out = with_plane(robot, emit)
    if is_parallel(robot):
        from kinematics.cli.parallel import jacobian as parallel_jacobian

        return parallel_jacobian(args, robot, out)
    from kinematics.cli.report import matrix
    from kinematics.generic.serial import task_jacobian, task_rows

    refuse_pose_args(args, f"{robot.name} is serial: its Jacobian is at its joint values (--q)")
    v = values(args, robot)
    task = args.task
    J = task_jacobian(robot, robot.configuration(v), args.frame, task)
    names = [("x", "y", "z", "wx", "wy", "wz")[i] for i in task_rows(robot, task)]
    payload = {"frame": args.frame or robot.tool_frame, "q": v, "rows": names, "jacobian": J}

    def human() -> str:
        return f"Jacobian of {payload['frame']!r}, rows {', '.join(names)} (world axes):\n" + matrix(J, 9)

    out(args, payload, human)
    return EXIT_OK
