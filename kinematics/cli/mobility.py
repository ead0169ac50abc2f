"""`kinematics mobility`: the three mobility analyses at one configuration, as a report."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from kinematics.cli.args import Command, load, mode_of, number, q_args, refuse_pose_args, robot_arg
from kinematics.cli.report import emit, fmt, key_values, table, with_plane
from kinematics.errors import InvalidInputError

if TYPE_CHECKING:
    import numpy as np

    from kinematics.model.robot import Robot


def register(command: Command) -> None:
    p = command("mobility", cmd_mobility, "mobility three ways: Grübler-Kutzbach, screw theory, constraint rank")
    robot_arg(p)
    q_args(p, required=False, p2us="the 3 actuator values (closed-loop solved)")
    p.add_argument("--position", nargs=3, type=number, metavar=("X", "Y", "Z"),
                   help="p2us, delta: platform position [m] (default: the sidecar's reference configuration)")
    p.add_argument("--mode", help="p2us, delta: working mode for --position (default ---)")


def cmd_mobility(args: argparse.Namespace) -> int:
    """Grübler–Kutzbach, screw-theory and numeric mobility at a configuration."""
    robot = load(args)
    return run(args, robot, with_plane(robot, emit))


def configuration(args: argparse.Namespace, robot: Robot) -> tuple[np.ndarray, str]:
    """The configuration to analyse and a description of where it came from.

    Loop robots: --position (the mechanism family's closed forms), --q (actuated values, closed-loop solve)
    or the sidecar's reference (closed first where it is open, `kinematics.generic.assembly`); serial robots: --q (every joint) or a seeded random regular
    configuration within the ranges (`mobility.regular_configuration`).
    """
    import numpy as np

    if robot.loops is None:
        if robot.nv == 0:  # its tool Jacobian is 6 x 0: no rank, no regular pose, no twist to count
            from kinematics.errors import UnsupportedRobotError

            raise UnsupportedRobotError(robot.name, "has no degree of freedom (every joint is fixed): nothing moves")
        refuse_pose_args(args, f"{robot.name} is serial: give its joint values with --q")
        if args.q is None:
            from kinematics.analyses.mobility import REGULAR_SEED, regular_configuration

            reg = regular_configuration(robot)
            return reg.q, (f"a regular configuration (random within the joint ranges, seed {REGULAR_SEED}): "
                           f"q = {np.round(reg.values, 6).tolist()}")
        return robot.configuration(args.q, degrees=args.degrees), f"q = {list(args.q)}"
    from kinematics.generic.closedloop import ClosedLoop

    loop = ClosedLoop(robot)
    if args.position is not None and args.q is not None:
        raise InvalidInputError("--position/--q", "give one of them, not both")
    if args.position is not None:
        from kinematics.cli.parallel import position_arg, require_closed_forms

        mech = require_closed_forms(robot)
        p = position_arg(args)
        values = mech.joint_values(p, mode_of(args, "---"))
        q = robot.configuration([values[n] for n in robot.joint_names])
        return q, f"platform at {p.tolist()} m, mode {mode_of(args, '---')}"
    if args.q is not None:
        from kinematics.cli.parallel import actuated_arg
        from kinematics.mechanisms import mechanism_of

        actuators = actuated_arg(args, robot)  # --degrees applied: the values analysed are these
        sol = loop.solve(actuators, fallback=True)
        held = " (closed with the actuators held: possibly another assembly mode)" if sol.held else ""
        return sol.q, f"actuators at {np.round(actuators, 9).tolist()} {mechanism_of(robot).actuator_unit}{held}"
    return loop.assembly.q, loop.assembly.description


def _unreachable(args: argparse.Namespace, robot: Robot) -> dict[str, Any] | None:
    """For a mechanism with closed forms given --position or --q: None if the platform can be
    there, else the answer."""
    if (args.position is None) == (args.q is None):
        return None
    from kinematics.cli.parallel import actuated_arg, closed_forms, position_arg

    mech = closed_forms(robot)
    if mech is None:
        return None
    if args.q is not None:
        q = actuated_arg(args, robot)
        fk = mech.pose_fk(q)
        if fk.exists:
            return None
        return {"robot": robot.name, "q": q.tolist(), "reachable": False, "reason": fk.reason}
    mech.check_branches([mode_of(args, "---")])  # a bad mode is bad input even where nothing reaches
    p = position_arg(args)
    ik = mech.pose_ik(p)
    if all(lb["reachable"] for lb in ik.limbs):
        return None
    return {"robot": robot.name, "position": p.tolist(), "reachable": False, "reason": ik.reason}


def _freedom(f: Any) -> str:
    """'translation [axis]' or 'rotation [axis] through [point] m, pitch h m/rad'."""
    if f.type == "translation":
        return f"translation {fmt(f.axis, 3)}"
    return f"rotation {fmt(f.axis, 3)} through {fmt(f.point, 4)} m, pitch {f.pitch:.3g} m/rad"


def run(args: argparse.Namespace, robot: Robot, out: Any) -> int:
    from kinematics.analyses.mobility import analyse

    answer = _unreachable(args, robot)
    if answer is not None:
        from kinematics.mechanisms import mechanism_of

        unit = mechanism_of(robot).actuator_unit
        where = f"platform at {answer['position']} m" if "position" in answer else f"actuators at {answer['q']} {unit}"
        out(args, answer, lambda: f"{where} is NOT reachable: {answer['reason']}")
        return 1
    q, where = configuration(args, robot)
    rep = analyse(robot, q)
    payload = {"robot": robot.name, "configuration": where, **rep.as_dict()}

    def human() -> str:
        g, n, s = rep.grubler, rep.numeric, rep.screw
        kinds = ", ".join(f"{v} {k}" for k, v in g.as_dict()["joint_types"].items())
        parts = [
            f"{robot.name} at {where}",
            "",
            f"Grübler-Kutzbach ({'planar' if g.planar else 'spatial'}, lambda = {g.lam}):",
            f"  {g.links} links, {g.joints} joints ({kinds}), {g.freedoms} joint freedoms",
            f"  M = {g.lam} ({g.links} - {g.joints} - 1) + {g.freedoms} = {g.mobility}",
            "",
            "numeric (loop-constraint Jacobian K):",
            key_values([("nv", n.nv), ("constraint rows", n.constraints), ("rank K", n.rank),
                        ("mobility nv - rank", n.mobility), ("platform freedoms", n.platform_freedoms),
                        ("redundant freedoms" if n.serial else "idle freedoms", n.redundant if n.serial else n.idle),
                        ("platform, actuators locked", n.locked_platform_freedoms),
                        ("rank tolerance (relative)", n.tolerance), ("smallest kept sigma", n.smallest_kept),
                        ("largest dropped sigma", n.largest_dropped)]),
            "",
            (f"screw theory: {s.translations} translation(s), {s.rotations} rotation(s); "
             f"{s.constraint_rank} independent constraint wrench(es)"),
            table(["limb", "sub-chains", "twist rank", "constraint wrenches"],
                  [(lb.name, lb.paths, lb.twist_rank,
                    "; ".join(f"{w.type} {fmt(w.axis, 3)}" for w in lb.wrenches) or "-") for lb in s.limbs]),
            "platform freedoms: " + ("; ".join(map(_freedom, s.freedoms)) or "none"),
            (f"end-effector point: {s.point_translations} translation(s)"
             + (f" {'; '.join(fmt(a, 3) for a in s.point_axes)}" if s.point_axes else "")),
        ]
        if rep.notes:
            parts += ["", "notes:"] + [f"  - {note}" for note in rep.notes]
        return "\n".join(parts)

    out(args, payload, human)
    return 0
