"""`kinematics ik`: closed-form inverse kinematics, every solution (planar 2R arms here; the
3-[P2(US)] and the Delta in `kinematics.cli.parallel`)."""

from __future__ import annotations

import argparse

from kinematics.cli.args import EXIT_NO, EXIT_OK, Command, is_parallel, load, number, robot_arg
from kinematics.cli.report import emit


def register(command: Command) -> None:
    p = command("ik", cmd_ik, "closed-form inverse kinematics (scara, p2us, delta): all solutions")
    robot_arg(p)
    p.add_argument("--position", nargs="+", type=number, required=True, metavar="X",
                   help="target position [m]: X Y for a planar arm, X Y Z for p2us and delta")


def cmd_ik(args: argparse.Namespace) -> int:
    """Closed-form inverse kinematics: planar 2R arms, the 3-[P2(US)] and the Delta."""
    robot = load(args)
    if is_parallel(robot):
        from kinematics.cli.parallel import ik as parallel_ik

        return parallel_ik(args, robot, emit)
    from kinematics.cli.report import table
    from kinematics.errors import InvalidInputError, UnsupportedRobotError
    from kinematics.mechanisms.scara.closed_form import ScaraParams, solve_ik

    try:
        params = ScaraParams.from_robot(robot)
    except UnsupportedRobotError as exc:
        raise UnsupportedRobotError(
            robot.name,
            "closed-form IK is available for planar 2R arms (scara), 3-[P2(US)] (p2us) and Delta robots (delta); "
            f"this one is not: {exc.problem}",
        ) from None
    if len(args.position) != 2:
        raise InvalidInputError("--position", f"{robot.name} is planar: give X Y, got {len(args.position)} values")
    answer = solve_ik(params, args.position)
    payload = {
        "position": list(args.position),
        "reachable": answer.reachable,
        "reason": answer.reason,
        "solutions": [
            {"q": s.q, "elbow": s.elbow, "within_limits": s.within_limits, "violations": list(s.violations)}
            for s in answer.solutions
        ],
    }

    def human() -> str:
        head = f"position {list(args.position)} m: " + ("reachable" if answer.reachable else "NOT reachable")
        parts = [head]
        if answer.solutions:
            parts.append(
                table(
                    ["elbow", "theta1 [rad]", "theta2 [rad]", "within limits"],
                    [(s.elbow, s.q[0], s.q[1], s.within_limits) for s in answer.solutions],
                    12,
                )
            )
        if answer.reason:
            parts.append(f"reason: {answer.reason}")
        return "\n".join(parts)

    emit(args, payload, human)
    return EXIT_OK if answer.reachable else EXIT_NO
