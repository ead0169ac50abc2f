"""`kinematics manipulability`: the manipulability ellipsoid of a serial robot at a configuration."""

from __future__ import annotations

import argparse
from typing import Any

from kinematics.cli.args import EXIT_OK, Command, is_parallel, load, q_args, robot_arg, values
from kinematics.cli.report import emit


def register(command: Command) -> None:
    p = command("manipulability", cmd_manipulability, "manipulability ellipsoid at a configuration")
    robot_arg(p)
    q_args(p, loops=None)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")


def _ellipsoid_payload(J: Any) -> dict[str, Any]:
    from kinematics.generic.manipulability import ellipsoid

    e = ellipsoid(J)
    return {
        "jacobian": J,
        "radii": e.radii,
        "directions": e.directions,
        "yoshikawa": e.yoshikawa,
        "condition_number": e.condition_number,
        "singular": e.singular,
    }


def cmd_manipulability(args: argparse.Namespace) -> int:
    """Manipulability ellipsoid: radii, directions, Yoshikawa index, conditioning, singularity."""
    from kinematics.cli.report import key_values, matrix, table
    from kinematics.generic.manipulability import SINGULAR_RTOL
    from kinematics.generic.serial import frame_jacobian, plane, task_rows

    robot = load(args)
    if is_parallel(robot):
        from kinematics.errors import UnsupportedRobotError

        raise UnsupportedRobotError(robot.name, "manipulability needs a serial robot; a closed loop's Jacobian is "
                                                "`jacobian` (p2us, delta: at --position X Y Z; others: at --q)")
    v = values(args, robot)
    J6 = frame_jacobian(robot, robot.configuration(v), args.frame)
    planar = plane(robot) is not None
    rows = task_rows(robot, "planar" if planar else "translation")
    payload = {"frame": args.frame or robot.tool_frame, "q": v, **_ellipsoid_payload(J6[list(rows)])}
    if not planar:
        payload["rotational"] = _ellipsoid_payload(J6[3:])

    def block(title: str, p: dict[str, Any], unit: str) -> str:
        return "\n".join(
            [
                title,
                "Jacobian:",
                matrix(p["jacobian"], 9),
                table([f"radius [{unit}]", "direction"], list(zip(p["radii"], p["directions"], strict=True)), 9),
                key_values(
                    [
                        ("Yoshikawa w", p["yoshikawa"]),
                        ("condition number", p["condition_number"]),
                        ("singular", f"{p['singular']} (r_min <= {SINGULAR_RTOL:g} r_max)"),
                    ],
                    9,
                ),
            ]
        )

    def human() -> str:
        axes = "".join("xyz"[i] for i in rows)
        out = [block(f"{robot.name} at q = {v.tolist()}, frame {payload['frame']!r}, task {axes}", payload, "m")]
        if not planar:
            out.append(block("rotational ellipsoid", payload["rotational"], "rad"))
        return "\n\n".join(out)

    emit(args, payload, human)
    return EXIT_OK
