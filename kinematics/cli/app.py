"""The `kinematics` command line. `main(argv)` is the entry point; it returns the exit status.

Exit status: 0 success, 1 a well-formed question whose answer is "no" (an unreachable target),
2 bad input (one line on stderr, never a traceback), 130 interrupted (Ctrl-C), 141 stdout closed
by its reader (`| head`), quietly. Output files are checked before any work and written
atomically. Heavy imports happen inside the commands so that `kinematics --help` stays instant.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from kinematics.errors import KinematicsError

EXIT_OK, EXIT_NO, EXIT_ERROR, EXIT_INTERRUPTED, EXIT_PIPE = 0, 1, 2, 130, 141

MAX_MAGNITUDE = 1e6
"""Largest magnitude of a coordinate on the command line [m, rad, deg, N]: a million metres is
beyond any robot, and squares of such values stay far from overflowing."""

OUTPUTS = {"plot": ("--plot", "figure"), "output": ("-o/--output", "urdf"), "export": ("--export", "html"),
           "points": ("--points", "points"), "out": ("--out", "csv"), "csv": ("--csv", "csv")}
"""Output options (argparse dest -> option, kind of file), checked before a command runs."""
OUTPUTS_BY_COMMAND = {("fk", "out"): ("--out", "poses")}
"""Where one command's option writes another kind of file than OUTPUTS says."""

CLOSED_POSE = (", default: the actuators of its default closed pose (the sidecar's reference, or a pose found from "
               "the neutral pose; the report says which)")
"""The closed-loop default of --q (fk, jacobian), for the help."""

ROBOT_HELP = ("built-in name (scara, p2us, p2us-results, delta), URDF path, or example-robot-data name "
              "(ur5, panda, ...)")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and exit status 2, and numbers such as -1e-3
    and -inf taken as values, not options (as Python 3.12's argparse does), as are working-mode
    labels such as --- and -+-."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        import re

        super().__init__(*args, **kwargs)
        # working-mode labels such as --- and -+- are values too (no option is spelled that way)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$|^-inf(inity)?$|^-[+-]{2}$",
                                                   re.I)

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_ERROR, f"{self.prog}: error: {message}\n")


def _out(args: argparse.Namespace, payload: dict[str, Any], human: Callable[[], str]) -> None:
    from kinematics.cli.report import emit

    emit(args, payload, human)


# -- commands ------------------------------------------------------------------------------------
def _load(args: argparse.Namespace) -> Any:
    from kinematics.model.robot import load_robot

    return load_robot(args.robot, ranges=dict(getattr(args, "range", None) or ()))


def _is_parallel(robot: Any) -> bool:
    """A closed-loop mechanism, as the dispatcher (`mechanism_of`) decides."""
    from kinematics.mechanisms import mechanism_of

    return mechanism_of(robot).closed_loop


def cmd_info(args: argparse.Namespace) -> int:
    """Joints, limits, frames, parameters and the two-parser check."""
    import numpy as np

    from kinematics.cli.report import key_values, table
    from kinematics.generic.serial import plane
    from kinematics.model.robot import parser_agreement

    robot = _load(args)
    agree = parser_agreement(robot)
    params: dict[str, Any] = {}
    sources: dict[str, str] = {}
    if _is_parallel(robot):
        params = _parallel_parameters(robot)
        if params:
            from kinematics.mechanisms.p2us.paper_b import parameter_sources

            sources = parameter_sources(robot.name, robot.urdf_path)
    else:
        from kinematics.errors import UnsupportedRobotError
        from kinematics.mechanisms.scara.closed_form import ScaraParams

        try:
            sp = ScaraParams.from_robot(robot)
            params = {"l1": sp.l1, "l2": sp.l2}
        except UnsupportedRobotError:
            pass
    axes = plane(robot)
    mob = _loop_mobility(robot) if robot.loops is not None else None
    mobility = robot.nv if mob is None else mob["mobility"]
    payload = {
        "name": robot.name,
        "urdf": str(robot.urdf_path),
        "dof": robot.nv,
        "joint_coordinates": robot.nv,
        "mobility": mobility,
        "grubler_mobility": None if mob is None else mob["grubler"],
        "mobility_pose": None if mob is None else mob["pose"],
        "mobility_note": None if mob is None else mob["note"],
        "joints": [{"name": d.name, "type": d.kind, "lower": d.lower, "upper": d.upper, "range_given": d.range_given}
                   for d in robot.dofs],
        "tool_frame": robot.tool_frame,
        "frames": list(robot.frame_names),
        "planar": axes is not None,
        "plane_axes": None if axes is None else ["xyz"[i] for i in axes],
        "parameters": params,
        "parameter_sources": sources,
        "parsers_agree": {
            "frames": agree.frames,
            "max_position_error": agree.max_position_error,
            "max_rotation_error": agree.max_rotation_error,
        },
        "loops": _loops_payload(robot),
    }

    def human() -> str:
        unit = {"prismatic": "m", "revolute": "rad", "continuous": "rad"}
        if mob is None:
            head = f"{robot.nv} degrees of freedom"
        elif mobility is None:
            head = f"{robot.nv} joint coordinates, Grübler-Kutzbach count {mob['grubler']} (numeric mobility unknown)"
        else:
            head = f"{robot.nv} joint coordinates, mobility {mobility}"
        parts = [
            f"{robot.name}  ({robot.urdf_path})",
            head + f", tool frame {robot.tool_frame!r}, " + ("planar in " + "-".join(payload["plane_axes"]) if axes
                                                             else "spatial"),
            "",
            table(
                ["joint", "type", "lower", "upper", "unit"],
                [(d.name, d.kind, *(v if np.isfinite(v) or d.kind == "continuous" else "none given"
                                     for v in (d.lower, d.upper)), unit[d.kind]) for d in robot.dofs],
            ),
        ]
        if mob is not None:
            parts += ["", (f"mobility {mobility} = nv - rank of the loop-constraint Jacobian at {mob['pose']}; "
                           f"Grübler-Kutzbach count {mob['grubler']}" if mobility is not None
                           else f"mobility: {mob['note']}")]
        if robot.unranged:
            parts += ["", (f"{len(robot.unranged)} joint(s) without a range in the URDF (<limit> without lower/upper): "
                           "unbounded; a command that needs the range of one asks for it (--range JOINT=LO:HI)")]
        if params and sources:
            parts += ["", "parameters (read from the URDF and its sidecar; source of each number):",
                      table(["parameter", "value", "source"], [(k, v, sources.get(k, "")) for k, v in params.items()])]
        elif params:
            parts += ["", "parameters (read from the URDF):", key_values(params.items(), None)]
        if payload["loops"]:
            lp = payload["loops"]
            kinds = [c["type"] for c in lp["constraints"]]
            counts = ", ".join(f"{kinds.count(k)} {k}" for k in dict.fromkeys(kinds))
            parts += ["", f"loop closures ({lp['sidecar']}): {counts or 'none'}; actuated: {', '.join(lp['actuated'])}"]
        parts += [
            "",
            f"frames ({len(robot.frame_names)}): {', '.join(robot.frame_names)}",
            "",
            (f"Pinocchio vs yourdfpy: {agree.frames} link frames, max position error "
             f"{agree.max_position_error:.2e} m, max rotation error {agree.max_rotation_error:.2e} rad"),
        ]
        return "\n".join(parts)

    _out(args, payload, human)
    return EXIT_OK


def _loop_mobility(robot: Any) -> dict[str, Any]:
    """A closed-loop robot's mobility for `info`: the numeric one (nv - rank of the loop-constraint
    Jacobian) at the default closed pose, beside the Grübler-Kutzbach count; the count alone, with
    a note, when no closed pose is found."""
    from kinematics.analyses.mobility import grubler, numeric_mobility
    from kinematics.errors import ConvergenceError
    from kinematics.generic.closedloop import ClosedLoop

    count = grubler(robot).mobility
    try:
        a = ClosedLoop(robot).assembly
    except ConvergenceError as exc:
        return {"mobility": None, "grubler": count, "pose": None,
                "note": (f"no closed pose found ({exc}), so no numeric mobility; the Grübler-Kutzbach count "
                         f"{count} alone assumes independent loop constraints (an over-constrained model's "
                         "are not, and the count can then be wrong, even negative)")}
    return {"mobility": numeric_mobility(robot, a.q).mobility, "grubler": count, "pose": a.description, "note": None}


def _loops_payload(robot: Any) -> dict[str, Any] | None:
    if robot.loops is None:
        return None
    return robot.loops.as_dict()


def _parallel_parameters(robot: Any) -> dict[str, Any]:
    from kinematics.cli.parallel import family_of

    found = family_of(robot)
    return {} if found is None else found[1].as_dict()


def _values(args: argparse.Namespace, robot: Any) -> Any:
    if args.q is None:
        from kinematics.errors import InvalidInputError

        raise InvalidInputError("--q", f"{robot.name} needs joint values, one per degree of freedom ({robot.nv})")
    return robot.joint_values(args.q, degrees=args.degrees)


def cmd_fk(args: argparse.Namespace) -> int:
    """Forward kinematics: tool position (and rotation for spatial robots)."""
    robot = _load(args)
    if args.q_file is not None or args.out is not None:
        from kinematics.cli.fk import fk_file

        return fk_file(args, robot, _out)
    if _is_parallel(robot):
        return _parallel_fk(args, robot)
    from kinematics.cli.report import key_values, matrix
    from kinematics.generic.serial import forward_kinematics, plane

    v = _values(args, robot)
    pose = forward_kinematics(robot, robot.configuration(v), args.frame)
    axes = plane(robot)
    frame = args.frame or robot.tool_frame
    if axes is not None:
        payload: dict[str, Any] = {"frame": frame, "q": v, "position": pose.position[list(axes)]}
    else:
        payload = {"frame": frame, "q": v, "position": pose.position, "rotation": pose.rotation}

    def human() -> str:
        lines = [key_values([("frame", frame), ("q", v), ("position [m]", payload["position"])], 12)]
        if "rotation" in payload:
            lines += ["rotation:", matrix(pose.rotation, 9)]
        return "\n".join(lines)

    _out(args, payload, human)
    return EXIT_OK


def cmd_ik(args: argparse.Namespace) -> int:
    """Closed-form inverse kinematics: planar 2R arms, the 3-[P2(US)] and the Delta."""
    robot = _load(args)
    if _is_parallel(robot):
        return _parallel_ik(args, robot)
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

    _out(args, payload, human)
    return EXIT_OK if answer.reachable else EXIT_NO


def cmd_jacobian(args: argparse.Namespace) -> int:
    """World-aligned task Jacobian."""
    robot = _load(args)
    if _is_parallel(robot):
        return _parallel_jacobian(args, robot)
    from kinematics.cli.report import matrix
    from kinematics.generic.serial import task_jacobian, task_rows

    v = _values(args, robot)
    task = args.task
    J = task_jacobian(robot, robot.configuration(v), args.frame, task)
    names = [("x", "y", "z", "wx", "wy", "wz")[i] for i in task_rows(robot, task)]
    payload = {"frame": args.frame or robot.tool_frame, "q": v, "rows": names, "jacobian": J}

    def human() -> str:
        return f"Jacobian of {payload['frame']!r}, rows {', '.join(names)} (world axes):\n" + matrix(J, 9)

    _out(args, payload, human)
    return EXIT_OK


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

    robot = _load(args)
    if _is_parallel(robot):
        from kinematics.errors import UnsupportedRobotError

        raise UnsupportedRobotError(robot.name, "manipulability needs a serial robot; use `jacobian` for p2us")
    v = _values(args, robot)
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

    _out(args, payload, human)
    return EXIT_OK


def cmd_mobility(args: argparse.Namespace) -> int:
    """Grübler–Kutzbach, screw-theory and numeric mobility at a configuration."""
    from kinematics.cli.mobility import run

    return run(args, _load(args), _out)


def cmd_urdf(args: argparse.Namespace) -> int:
    """Write the URDF and loop sidecar of a 3-[P2(US)] design."""
    from kinematics.cli.parallel import cmd_urdf as run

    return run(args)


def cmd_workspace_volume(args: argparse.Namespace) -> int:
    """Workspace volume (area) with bounds, per mode and union, and the singular points in it."""
    from kinematics.cli.workspace import workspace_volume

    return workspace_volume(args, _load(args), _out)


def cmd_singularities(args: argparse.Namespace) -> int:
    """Singular loci over a grid (p2us) or the joint grid (planar arm)."""
    from kinematics.cli.workspace import singularities

    return singularities(args, _load(args), _out)


def cmd_sweep(args: argparse.Namespace) -> int:
    """Design sweep of the 3-[P2(US)] on Dask."""
    from kinematics.cli.workspace import sweep

    return sweep(args, _load(args), _out)


def cmd_usable_workspace(args: argparse.Namespace) -> int:
    """Largest cube, cylinder or sphere in the well-conditioned workspace."""
    from kinematics.cli.design import usable_workspace

    return usable_workspace(args, _load(args), _out)


def cmd_dexterity(args: argparse.Namespace) -> int:
    """Global conditioning index and mean Yoshikawa index with error bars; conditioning maps."""
    from kinematics.cli.design import dexterity

    return dexterity(args, _load(args), _out)


def cmd_synthesize(args: argparse.Namespace) -> int:
    """Multi-objective dimensional synthesis (NSGA-II) on Dask."""
    from kinematics.cli.design import synthesize

    return synthesize(args, _load(args), _out)


def cmd_workspace_mesh(args: argparse.Namespace) -> int:
    """A working mode's workspace boundary as a watertight mesh."""
    from kinematics.cli.design import workspace_mesh

    return workspace_mesh(args, _load(args), _out)


def cmd_guide(args: argparse.Namespace) -> int:
    """Paper A's manual-guidance experiments, simulated."""
    from kinematics.cli.guidance import run

    return run(args, _out)


def cmd_show(args: argparse.Namespace) -> int:
    """Meshcat view of a robot with overlays."""
    from kinematics.cli.views import run

    return run(args, _load(args), _out)


# Parallel-robot handlers live with the parallel module's CLI helpers.
def _parallel_fk(args: argparse.Namespace, robot: Any) -> int:
    from kinematics.cli.parallel import fk

    return fk(args, robot, _out)


def _parallel_ik(args: argparse.Namespace, robot: Any) -> int:
    from kinematics.cli.parallel import ik

    return ik(args, robot, _out)


def _parallel_jacobian(args: argparse.Namespace, robot: Any) -> int:
    from kinematics.cli.parallel import jacobian

    return jacobian(args, robot, _out)


# -- parser ---------------------------------------------------------------------------------------
def _positive(text: str) -> float:
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be positive and finite, got {text}")
    return v


def _non_negative(text: str) -> float:
    return 0.0 if text.strip() in ("0", "0.0") else _positive(text)


def _number(text: str) -> float:
    """A coordinate: finite, magnitude at most MAX_MAGNITUDE."""
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
        raise argparse.ArgumentTypeError(f"must be finite and at most {MAX_MAGNITUDE:g} in magnitude, got {text}")
    return v


def _joint_range(text: str) -> tuple[str, tuple[float, float]]:
    """`JOINT=LO:HI` -> (joint, (lo, hi)), both finite with lo < hi."""
    name, sep, pair = text.partition("=")
    lo, colon, hi = pair.partition(":")
    try:
        a, b = float(lo), float(hi)
    except ValueError:
        a = b = float("nan")
    if not (sep and colon and name) or not (abs(a) <= MAX_MAGNITUDE and abs(b) <= MAX_MAGNITUDE and a < b):
        raise argparse.ArgumentTypeError(f"expected JOINT=LO:HI with finite LO < HI, got {text!r}")
    return name, (a, b)


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


class _Version(argparse.Action):
    """--version from the installed package's metadata (looked up only when asked)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        from importlib.metadata import version

        print(f"kinematics {version('kinematics')}")
        parser.exit(0)


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (exposed for the CLI-reference check in the tests)."""
    parser = _Parser(
        prog="kinematics",
        description="Kinematic analysis of serial and parallel robots described by URDF (built on Pinocchio).",
        epilog="Units are SI (m, rad, s, N). Exit status: 0 ok, 1 unreachable target, 2 bad input, "
               "130 interrupted, 141 output pipe closed.",
    )
    parser.add_argument("--version", action=_Version, help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def command(name: str, func: Callable[[argparse.Namespace], int], help_: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(func=func)
        p.add_argument("--json", action="store_true", help="print JSON instead of a readable report")
        return p

    def robot_arg(p: argparse.ArgumentParser) -> None:
        p.add_argument("robot", metavar="ROBOT", help=ROBOT_HELP)
        p.add_argument("--range", action="append", type=_joint_range, metavar="JOINT=LO:HI",
                       help="give or replace a joint's range [rad or m] (repeat per joint): for URDFs whose "
                            "<limit> has no lower/upper")

    def q_args(p: argparse.ArgumentParser, required: bool = True, p2us: str = "one per actuated joint",
               loops: str = "") -> None:
        p.add_argument("--q", nargs="+", type=_number, required=required, metavar="Q",
                       help="joint values [rad or m]: serial robot, one per degree of freedom; closed-loop "
                            f"robot, one per actuated joint{loops}; p2us: {p2us}")
        p.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")

    p = command("info", cmd_info, "joints, limits, frames and parameters of a robot")
    robot_arg(p)

    p = command("fk", cmd_fk, "forward kinematics: tool position (and rotation)")
    robot_arg(p)
    q_args(p, required=False, loops=CLOSED_POSE)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")
    p.add_argument("--q-file", metavar="Q.csv|Q.npy",
                   help="serial robots: many configurations (compiled, every core), one per row, one value "
                        "per degree of freedom [rad or m] (a continuous joint: its angle); CSV may have a "
                        "header line")
    p.add_argument("--out", metavar="P.csv|P.npy",
                   help="with --q-file: one row per configuration: x y z [m] then the rotation matrix "
                        "row-major (9 entries) for spatial robots; the plane coordinates for planar arms")

    p = command("ik", cmd_ik, "closed-form inverse kinematics (scara, p2us, delta): all solutions")
    robot_arg(p)
    p.add_argument("--position", nargs="+", type=_number, required=True, metavar="X",
                   help="target position [m]: X Y for a planar arm, X Y Z for p2us and delta")

    p = command("jacobian", cmd_jacobian, "world-aligned Jacobian at a configuration (p2us, delta: at a position)")
    robot_arg(p)
    q_args(p, required=False, p2us="not used, give --position", loops=CLOSED_POSE)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")
    p.add_argument("--task", default="auto", choices=["auto", "planar", "translation", "rotation", "full"],
                   help="task-space rows (default auto: x-y for planar arms, x-y-z for other serial robots, all "
                        "six for closed loops other than p2us and delta)")
    p.add_argument("--position", nargs=3, type=_number, metavar=("X", "Y", "Z"), help="p2us, delta: platform position [m]")
    p.add_argument("--mode", help="p2us, delta: working mode label such as +++ (default: the first mode within the "
                                  "limits, else the first that assembles)")

    p = command("manipulability", cmd_manipulability, "manipulability ellipsoid at a configuration")
    robot_arg(p)
    q_args(p)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")

    p = command("mobility", cmd_mobility, "mobility three ways: Grübler-Kutzbach, screw theory, constraint rank")
    robot_arg(p)
    q_args(p, required=False, p2us="the 3 actuator values (closed-loop solved)")
    p.add_argument("--position", nargs=3, type=_number, metavar=("X", "Y", "Z"),
                   help="p2us, delta: platform position [m] (default: the sidecar's reference configuration)")
    p.add_argument("--mode", help="p2us, delta: working mode for --position (default ---)")

    def scan_args(p: argparse.ArgumentParser, step: float) -> None:
        p.add_argument("--step", type=_positive, default=step, metavar="M",
                       help=f"grid step [m] (default {step:g}; the volume: the column spacing to start "
                            "from, and the sampling step along columns where no exact columns exist)")
        p.add_argument("--modes", nargs="+", metavar="MODE",
                       help="working modes such as --- +-+ (p2us, delta; default all 8); planar arm: "
                            "elbows up/down; other robots: their branch labels (a wrong one lists them)")
        p.add_argument("--limits", default="all", choices=["all", "actuators"],
                       help="all limits (default), or the actuator strokes only")
        p.add_argument("--plot", metavar="FILE.png", help="write a figure")

    def serial_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("--max-points", type=_positive, default=2_000_000, metavar="N",
                       help="serial arms: budget of configurations (default 2e6: 15-25 s for the UR5 on 2 cores, "
                            "proved bounds about +/-50 %%; the bounds stay valid at any budget)")
        p.add_argument("--resolution", type=_integer, metavar="N",
                       help="serial arms: cells across the reached extent (default 400 for a plane or a solid "
                            "of revolution's profile, 128 in space)")

    p = command("workspace-volume", cmd_workspace_volume,
                "workspace volume (p2us, delta, closed loops, serial arms) or area (planar arms and loops) with its "
                "error estimate, per mode, with singular points")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--rtol", type=_non_negative, default=1e-3, metavar="R",
                   help="relative tolerance on the volume's error estimate; the quadrature refines until it "
                        "is met (default 1e-3; 0: 1e-2)")
    p.add_argument("--points", metavar="FILE", help="write the grid points inside the workspace (.npy or CSV)")
    serial_args(p)

    p = command("singularities", cmd_singularities,
                "type I/II/III singular loci over a grid (p2us, delta, any closed loop); theta2 = 0 boundary "
                "(planar arm); possibly singular joint boxes (serial arms)")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--paper-scan", action="store_true", help="p2us: also paper B's 8x8x8 actuator scan")
    p.add_argument("--angle-step-deg", type=_positive, default=1.0, metavar="DEG",
                   help="planar arm: joint-grid step in degrees (default 1)")
    serial_args(p)

    p = command("sweep", cmd_sweep, "design sweep of the 3-[P2(US)] on Dask: volume, singularity-free "
                                     "fraction, conditioning")
    robot_arg(p)
    p.add_argument("--param", action="append", metavar="NAME=START:STOP:COUNT",
                   help="a swept parameter (repeatable): b, d, L, beta, theta_zero, rod_spacing, stroke_min, "
                        "stroke_max [m, rad]")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (default: an embedded "
                                                            "local cluster)")
    p.add_argument("--workers", type=_integer, metavar="N",
                   help="worker processes of the local cluster, 1 to 4 per core (default: cores)")
    p.add_argument("--step", type=_positive, default=0.02, metavar="M", help="grid step per design [m] (default 0.02)")
    p.add_argument("--rtol", type=_positive, default=1e-2, metavar="R", help="volume tolerance (default 1e-2)")
    p.add_argument("--out", metavar="FILE.csv", help="write the table as CSV")

    p = command("usable-workspace", cmd_usable_workspace, "p2us, delta (any spatial mechanism with closed forms): "
                "the largest axis-aligned cube, vertical cylinder or sphere where every point is reachable, "
                "non-singular and has kappa <= K")
    robot_arg(p)
    p.add_argument("--shape", required=True, choices=["cube", "cylinder", "sphere"], help="the shape")
    p.add_argument("--kappa-max", type=_positive, default=10.0, metavar="K",
                   help="largest condition number sigma_max/sigma_min of the forward Jacobian J (default 10)")
    p.add_argument("--mode", help="working mode such as --- (default), or union")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuators' only")
    p.add_argument("--step", type=_positive, default=0.02, metavar="M", help="coarse grid step [m] (default 0.02)")

    p = command("dexterity", cmd_dexterity, "global conditioning index (mean 1/kappa) and mean Yoshikawa index "
                "with 95 %% error bars (randomised quasi-Monte Carlo), per mode and for their union; conditioning "
                "maps")
    robot_arg(p)
    p.add_argument("--mode", help="one working mode / elbow such as --- or up (default: every one, and the union)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuators' only")
    p.add_argument("--samples", type=_integer, default=16384, metavar="N",
                   help="points per replicate, rounded up to a power of two (default 16384)")
    p.add_argument("--replicates", type=_integer, default=8, metavar="R",
                   help="independently scrambled Sobol' sets, >= 2 (default 8)")
    p.add_argument("--seed", type=_integer, default=0, metavar="S", help="random seed of the scrambling (default 0)")
    p.add_argument("--step", type=_positive, metavar="M",
                   help="grid step of the maps (--plot, --export) [m] (default: the bounding box's longest side / 50)")
    p.add_argument("--plot", metavar="FILE.png", help="write a conditioning map (slices of 1/kappa)")
    p.add_argument("--export", metavar="FILE.html", help="write a Meshcat scene: points coloured by 1/kappa")

    p = command("synthesize", cmd_synthesize, "p2us, delta: multi-objective dimensional synthesis (NSGA-II) on "
                "Dask: maximise the usable cube and the GCI, minimise the footprint; the Pareto front")
    robot_arg(p)
    p.add_argument("--param", action="append", metavar="NAME=LOWER:UPPER",
                   help="a design variable and its bounds (repeatable) [m, rad]: p2us b, d, L, beta, theta_zero, "
                        "rod_spacing, stroke_min, stroke_max; delta R, r, la, lb, cone, theta_min, theta_max, "
                        "elbow_socket, platform_socket")
    p.add_argument("--population", type=_integer, default=16, metavar="N", help="designs per generation (default 16)")
    p.add_argument("--generations", type=_integer, default=8, metavar="G", help="generations (default 8)")
    p.add_argument("--seed", type=_integer, default=0, metavar="S", help="random seed (default 0): same seed, same front")
    p.add_argument("--mode", help="working mode of the cube and the GCI: --- (default) or union")
    p.add_argument("--kappa-max", type=_positive, default=10.0, metavar="K",
                   help="largest condition number in the usable cube (default 10)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuators' only")
    p.add_argument("--cube-cells", type=_integer, default=40, metavar="N",
                   help="coarse grid of the cube search: steps along the design's bounding box (default 40)")
    p.add_argument("--gci-samples", type=_integer, default=4096, metavar="N",
                   help="GCI points per replicate (4 replicates; default 4096)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (default: an embedded "
                                                            "local cluster)")
    p.add_argument("--workers", type=_integer, metavar="N",
                   help="worker processes of the local cluster, 1 to 4 per core (default: cores)")
    p.add_argument("--out", metavar="FILE.csv", help="write the Pareto front as CSV")
    p.add_argument("--plot", metavar="FILE.png", help="write the Pareto front's figure")

    p = command("workspace-mesh", cmd_workspace_mesh, "p2us: a working mode's workspace boundary as a "
                "watertight triangle mesh (STL, PLY or glTF binary)")
    robot_arg(p)
    p.add_argument("--mode", help="working mode such as --- (default), or union")
    p.add_argument("-o", required=True, metavar="FILE.stl|.ply|.glb", help="the mesh file")
    p.add_argument("--step", type=_positive, default=0.01, metavar="M", help="grid step [m] (default 0.01)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuator strokes only")

    p = command("guide", cmd_guide, "simulate paper A's manual-guidance experiments (admittance + virtual impedance)")
    p.add_argument("--experiment", type=int, required=True, choices=[1, 2, 3],
                   help="1: hard short push (saturation); 2: push to (0.7, 0), operator stops; 3: keeps pushing")
    p.add_argument("--robot", default="scara", metavar="ROBOT", help="a planar 2R arm (default scara)")
    p.add_argument("--no-virtual-impedance", action="store_true", help="the baseline: plain admittance control")
    p.add_argument("--force", type=_number, metavar="N", help="operator push [N] (default 30 for 1, 6 for 2 and 3)")
    p.add_argument("--mass", type=_positive, metavar="KG", help="admittance mass per axis [kg] (default 5)")
    p.add_argument("--damping", type=_positive, metavar="NS/M", help="admittance damping [N s/m] (default 40)")
    p.add_argument("--v-max", type=_positive, metavar="M/S", help="velocity saturation [m/s] (default 0.25)")
    p.add_argument("--saturation", choices=["norm", "axis"], help="saturate the speed (default) or each axis")
    p.add_argument("--threshold", type=_positive, metavar="M", help="radius threshold [m] (default 0.1)")
    p.add_argument("--k-max", type=_positive, metavar="N/M", help="eq. 16 step height (default 250)")
    p.add_argument("--gain", type=_positive, metavar="1/M", help="eq. 16 arctan slope (default 1e4)")
    p.add_argument("--dt", type=_positive, metavar="S", help="control period [s] (default 0.001)")
    p.add_argument("--plot", metavar="FILE.png", help="write the time histories (paper A's Figs. 14-30)")
    p.add_argument("--csv", metavar="FILE", help="write every step: force, position, velocities, radii, K_v, joints")

    p = command("show", cmd_show, "Meshcat view with overlays: prints the viewer URL and serves until "
                                   "interrupted, or writes a static HTML scene with --export")
    robot_arg(p)
    p.add_argument("--q", nargs="+", type=_number, metavar="Q",
                   help="joint values [rad or m]; closed loops: the actuator values (closed-loop solved)")
    p.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")
    p.add_argument("--position", nargs=3, type=_number, metavar=("X", "Y", "Z"),
                   help="p2us, delta: platform position [m] (default: the sidecar's reference pose)")
    p.add_argument("--mode", help="p2us, delta: working mode for --position (default ---)")
    p.add_argument("--ellipsoid", action="store_true", help="the manipulability ellipse/ellipsoid at the tool")
    p.add_argument("--workspace", action="store_true",
                   help="the workspace as points coloured by smallest radius (arms) or min(iota_I, iota_II) "
                        "(closed loops: p2us, delta, any URDF + sidecar)")
    p.add_argument("--singularities", action="store_true", help="the singular points")
    p.add_argument("--guide", type=int, choices=[1, 2, 3], help="planar arm: animate guidance experiment N")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="closed loops: limits for --workspace")
    p.add_argument("--step", type=_positive, default=None, metavar="M",
                   help="closed loops: grid step [m] (default 0.02; 0.05 for a generic closed loop, whose solver is "
                        "slower)")
    serial_args(p)
    p.add_argument("--skeleton", action="store_true",
                   help="also draw the kinematic skeleton: joints along their axes, links joint to joint, loop-closure "
                        "frames, the end effector (drawn anyway for a robot whose mesh files are missing)")
    p.add_argument("--mesh", metavar="FILE", help="also draw a triangle mesh (.stl, .ply, .glb), e.g. a workspace "
                                                  "boundary from `workspace-mesh`")
    p.add_argument("--export", metavar="FILE.html", help="write a self-contained HTML scene and exit")
    p.add_argument("--serve-seconds", type=_non_negative, metavar="S", help=argparse.SUPPRESS)

    p = command("urdf", cmd_urdf, "write the URDF + loop sidecar of a 3-[P2(US)] (paper B's by default) or "
                                   "Delta design")
    p.add_argument("robot", metavar="ROBOT", choices=["p2us", "delta"], help="the mechanism: p2us or delta")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="URDF to write; the sidecar goes beside it as NAME.loops.yaml")
    p.add_argument("--design", choices=["table2", "results"], default="table2",
                   help="p2us: the preset the flags below change: table2 (paper B's Table 2, built-in p2us; "
                        "default) or results (the geometry behind its computed results, built-in p2us-results)")
    p.add_argument("--b", type=_number, metavar="M", help="base radius [m] (default p2us 0.325, delta 0.2)")
    p.add_argument("--d", type=_number, metavar="M", help="platform radius [m] (default p2us 0.028, delta 0.05)")
    p.add_argument("--L", type=_number, metavar="M", help="p2us: rod length [m] (default 0.34)")
    p.add_argument("--beta", type=_number, metavar="A", help="p2us: rail angle below horizontal [rad] (default 40 deg)")
    p.add_argument("--alpha", type=_number, nargs=3, metavar="A", help="limb angles [rad] (default 0, 120, 240 deg)")
    p.add_argument("--stroke", type=_number, nargs=2, metavar=("MIN", "MAX"),
                   help="p2us: actuator range [m] (default 0.1 0.6)")
    p.add_argument("--theta", type=_number, nargs=2, metavar=("MIN", "MAX"),
                   help="p2us: universal joint theta range [rad] (default -10 100 deg); delta: actuator range "
                        "below the horizontal [rad] (default -40 90 deg)")
    p.add_argument("--phi", type=_number, nargs=2, metavar=("MIN", "MAX"),
                   help="p2us: universal joint phi range [rad] (default -70 70 deg)")
    p.add_argument("--theta-zero", type=_number, metavar="A",
                   help="p2us: rod elevation below the inward horizontal at theta = 0 [rad] (default 0)")
    p.add_argument("--rod-spacing", type=_number, metavar="M",
                   help="parallelogram rod spacing [m] (default p2us 0.05, delta 0.08)")
    p.add_argument("--upper-arm", type=_number, metavar="M", help="delta: upper-arm length [m] (default 0.3)")
    p.add_argument("--forearm", type=_number, metavar="M", help="delta: forearm (rod) length [m] (default 0.8)")
    p.add_argument("--cone", type=_number, metavar="A", help="delta: ball-joint cone half-angle [rad] (default 45 deg)")
    p.add_argument("--elbow-socket", type=_number, metavar="A",
                   help="delta: elbow socket axis below the upper arm [rad] (default 90 deg)")
    p.add_argument("--platform-socket", type=_number, metavar="A",
                   help="delta: platform socket axis tilt outward from vertical [rad] (default 20 deg)")
    p.add_argument("--degrees", action="store_true", help="angle flags in degrees")
    return parser


def reference_markdown() -> str:
    """The CLI reference (docs/cli.md): every command's --help, at a fixed width of 100 columns."""
    import os

    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        parser = build_parser()
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parts = [
            "# CLI reference",
            "",
            "Generated from the parser by `python -m kinematics.cli --reference > docs/cli.md`; a test",
            "fails if this page and `kinematics COMMAND --help` disagree.",
            "",
            "```text",
            parser.format_help().rstrip(),
            "```",
        ]
        for name, p in sub.choices.items():
            parts += ["", f"## `kinematics {name}`", "", "```text", p.format_help().rstrip(), "```"]
        return "\n".join(parts) + "\n"
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved


def _check_outputs(args: argparse.Namespace) -> None:
    from kinematics.files import check_output

    for dest, default in OUTPUTS.items():
        path = getattr(args, dest, None)
        if path is not None:
            option, kind = OUTPUTS_BY_COMMAND.get((args.command, dest), default)
            check_output(path, option, kind)


def _run(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a one-line usage error already printed
        return exc.code if isinstance(exc.code, int) else EXIT_ERROR
    if args.command is None:
        parser.print_help()
        return EXIT_OK
    import warnings

    try:
        with warnings.catch_warnings():
            # an overflow or invalid operation the inputs provoked is bad input, not a result
            warnings.simplefilter("error", RuntimeWarning)
            _check_outputs(args)
            return int(args.func(args))
    except KinematicsError as exc:
        print(f"kinematics {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except RuntimeWarning as exc:
        print(f"kinematics {args.command}: error: the inputs are out of a computable range ({exc})", file=sys.stderr)
        return EXIT_ERROR


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 1 unreachable, 2 bad input, 130 interrupted,
    141 stdout closed early)."""
    import os

    try:
        code = _run(argv)
        sys.stdout.flush()
        return code
    except KeyboardInterrupt:
        print("kinematics: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as exc:
        import errno

        if not isinstance(exc, BrokenPipeError) and exc.errno != errno.ENOSPC and exc.errno != errno.EIO:
            raise
        # stdout is gone (reader closed the pipe) or full: send what is left to /dev/null so the
        # interpreter's final flush is quiet too
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):  # pragma: no cover - stdout without a descriptor
            pass
        if isinstance(exc, BrokenPipeError):
            return EXIT_PIPE
        print(f"kinematics: error: cannot write the report to stdout: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_ERROR

