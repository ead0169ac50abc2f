"""The `kinematics` command line. `main(argv)` is the entry point; it returns the exit status.

Exit status: 0 success, 1 a well-formed question whose answer is "no" (an unreachable target),
2 bad input (one line on stderr, never a traceback). Heavy imports happen inside the commands so
that `kinematics --help` stays instant.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from .errors import KinematicsError

EXIT_OK, EXIT_NO, EXIT_ERROR = 0, 1, 2

ROBOT_HELP = "built-in name (scara, p2us), URDF path, or example-robot-data name (ur5, panda, ...)"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_ERROR, f"{self.prog}: error: {message}\n")


def _out(args: argparse.Namespace, payload: dict[str, Any], human: Callable[[], str]) -> None:
    from .report import dumps

    print(dumps(payload) if args.json else human())


# -- commands ------------------------------------------------------------------------------------
def _load(args: argparse.Namespace) -> Any:
    from .model import load_robot

    return load_robot(args.robot)


def _is_parallel(robot: Any) -> bool:
    return robot.loops is not None


def cmd_info(args: argparse.Namespace) -> int:
    """Joints, limits, frames, parameters and the two-parser check."""
    from .model import parser_agreement
    from .report import key_values, table
    from .serial import plane

    robot = _load(args)
    agree = parser_agreement(robot)
    params: dict[str, Any] = {}
    if _is_parallel(robot):
        params = _parallel_parameters(robot)
    else:
        from .errors import UnsupportedRobotError
        from .scara import ScaraParams

        try:
            sp = ScaraParams.from_robot(robot)
            params = {"l1": sp.l1, "l2": sp.l2}
        except UnsupportedRobotError:
            pass
    axes = plane(robot)
    payload = {
        "name": robot.name,
        "urdf": str(robot.urdf_path),
        "dof": robot.nv,
        "joints": [{"name": d.name, "type": d.kind, "lower": d.lower, "upper": d.upper} for d in robot.dofs],
        "tool_frame": robot.tool_frame,
        "frames": list(robot.frame_names),
        "planar": axes is not None,
        "plane_axes": None if axes is None else ["xyz"[i] for i in axes],
        "parameters": params,
        "parsers_agree": {
            "frames": agree.frames,
            "max_position_error": agree.max_position_error,
            "max_rotation_error": agree.max_rotation_error,
        },
        "loops": _loops_payload(robot),
    }

    def human() -> str:
        unit = {"prismatic": "m", "revolute": "rad", "continuous": "rad"}
        parts = [
            f"{robot.name}  ({robot.urdf_path})",
            f"{robot.nv} degrees of freedom, tool frame {robot.tool_frame!r}, "
            + ("planar in " + "-".join(payload["plane_axes"]) if axes else "spatial"),
            "",
            table(
                ["joint", "type", "lower", "upper", "unit"],
                [(d.name, d.kind, d.lower, d.upper, unit[d.kind]) for d in robot.dofs],
            ),
        ]
        if params:
            parts += ["", "parameters (read from the URDF):", key_values(params.items(), None)]
        if payload["loops"]:
            lp = payload["loops"]
            parts += ["", f"loop closures: {len(lp['constraints'])} point constraints; actuated: {', '.join(lp['actuated'])}"]
        parts += [
            "",
            f"frames ({len(robot.frame_names)}): {', '.join(robot.frame_names)}",
            "",
            f"Pinocchio vs yourdfpy: {agree.frames} link frames, max position error "
            f"{agree.max_position_error:.2e} m, max rotation error {agree.max_rotation_error:.2e} rad",
        ]
        return "\n".join(parts)

    _out(args, payload, human)
    return EXIT_OK


def _loops_payload(robot: Any) -> dict[str, Any] | None:
    if robot.loops is None:
        return None
    return robot.loops.as_dict()


def _parallel_parameters(robot: Any) -> dict[str, Any]:
    from .p2us_urdf import MECHANISM, read_params

    if robot.loops.mechanism != MECHANISM:
        return {}
    return read_params(robot.urdf_path, robot.name).as_dict()


def _values(args: argparse.Namespace, robot: Any) -> Any:
    if args.q is None:
        from .errors import InvalidInputError

        raise InvalidInputError("--q", f"{robot.name} needs joint values, one per degree of freedom")
    return robot.joint_values(args.q, degrees=args.degrees)


def cmd_fk(args: argparse.Namespace) -> int:
    """Forward kinematics: tool position (and rotation for spatial robots)."""
    robot = _load(args)
    if _is_parallel(robot):
        return _parallel_fk(args, robot)
    from .report import key_values, matrix
    from .serial import forward_kinematics, plane

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
    """Closed-form inverse kinematics: planar 2R arms and the 3-[P2(US)]."""
    robot = _load(args)
    if _is_parallel(robot):
        return _parallel_ik(args, robot)
    from .errors import InvalidInputError, UnsupportedRobotError
    from .report import table
    from .scara import ScaraParams, solve_ik

    try:
        params = ScaraParams.from_robot(robot)
    except UnsupportedRobotError as exc:
        raise UnsupportedRobotError(
            robot.name,
            "closed-form IK is available for planar 2R arms (scara) and 3-[P2(US)] robots (p2us); "
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
    from .report import matrix
    from .serial import task_jacobian, task_rows

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
    from .manipulability import ellipsoid

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
    from .manipulability import SINGULAR_RTOL
    from .report import key_values, matrix, table
    from .serial import frame_jacobian, plane, task_rows

    robot = _load(args)
    if _is_parallel(robot):
        from .errors import UnsupportedRobotError

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
    from .mobility_cli import run

    return run(args, _load(args), _out)


def cmd_urdf(args: argparse.Namespace) -> int:
    """Write the URDF and loop sidecar of a 3-[P2(US)] design."""
    from .parallel_cli import cmd_urdf as run

    return run(args)


def cmd_workspace_volume(args: argparse.Namespace) -> int:
    """Workspace volume (area) with bounds, per mode and union, and the singular points in it."""
    from .workspace_cli import workspace_volume

    return workspace_volume(args, _load(args), _out)


def cmd_singularities(args: argparse.Namespace) -> int:
    """Singular loci over a grid (p2us) or the joint grid (planar arm)."""
    from .workspace_cli import singularities

    return singularities(args, _load(args), _out)


def cmd_sweep(args: argparse.Namespace) -> int:
    """Design sweep of the 3-[P2(US)] on Dask."""
    from .workspace_cli import sweep

    return sweep(args, _load(args), _out)


def cmd_guide(args: argparse.Namespace) -> int:
    """Paper A's manual-guidance experiments, simulated."""
    from .guidance_cli import run

    return run(args, _out)


def cmd_show(args: argparse.Namespace) -> int:
    """Meshcat view of a robot with overlays."""
    from .viz_cli import run

    return run(args, _load(args), _out)


# Parallel-robot handlers live with the parallel module's CLI helpers.
def _parallel_fk(args: argparse.Namespace, robot: Any) -> int:
    from .parallel_cli import fk

    return fk(args, robot, _out)


def _parallel_ik(args: argparse.Namespace, robot: Any) -> int:
    from .parallel_cli import ik

    return ik(args, robot, _out)


def _parallel_jacobian(args: argparse.Namespace, robot: Any) -> int:
    from .parallel_cli import jacobian

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


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (exposed for the CLI-reference check in the tests)."""
    parser = _Parser(
        prog="kinematics",
        description="Kinematic analysis of serial and parallel robots described by URDF (built on Pinocchio).",
        epilog="Units are SI (m, rad, s, N). Exit status: 0 ok, 1 unreachable target, 2 bad input.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser, required=True)

    def command(name: str, func: Callable[[argparse.Namespace], int], help_: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(func=func)
        p.add_argument("--json", action="store_true", help="print JSON instead of a readable report")
        return p

    def robot_arg(p: argparse.ArgumentParser) -> None:
        p.add_argument("robot", metavar="ROBOT", help=ROBOT_HELP)

    def q_args(p: argparse.ArgumentParser, required: bool = True) -> None:
        p.add_argument("--q", nargs="+", type=float, required=required, metavar="Q",
                       help="joint values, one per degree of freedom [rad or m]; for a closed-loop "
                            "robot, one per actuated joint")
        p.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")

    p = command("info", cmd_info, "joints, limits, frames and parameters of a robot")
    robot_arg(p)

    p = command("fk", cmd_fk, "forward kinematics: tool position (and rotation)")
    robot_arg(p)
    q_args(p)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")

    p = command("ik", cmd_ik, "closed-form inverse kinematics (scara, p2us): all solutions")
    robot_arg(p)
    p.add_argument("--position", nargs="+", type=float, required=True, metavar="X",
                   help="target position [m]: X Y for a planar arm, X Y Z for p2us")

    p = command("jacobian", cmd_jacobian, "world-aligned Jacobian at a configuration (p2us: at a position)")
    robot_arg(p)
    q_args(p, required=False)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")
    p.add_argument("--task", default="auto", choices=["auto", "planar", "translation", "rotation", "full"],
                   help="task-space rows (default auto: x-y for planar arms, x-y-z otherwise)")
    p.add_argument("--position", nargs=3, type=float, metavar=("X", "Y", "Z"), help="p2us: platform position [m]")
    p.add_argument("--mode", help="p2us: working mode label such as +++ (default: every mode)")

    p = command("manipulability", cmd_manipulability, "manipulability ellipsoid at a configuration")
    robot_arg(p)
    q_args(p)
    p.add_argument("--frame", help="frame name (default: the robot's tool frame)")

    p = command("mobility", cmd_mobility, "mobility three ways: Grübler-Kutzbach, screw theory, constraint rank")
    robot_arg(p)
    q_args(p, required=False)
    p.add_argument("--position", nargs=3, type=float, metavar=("X", "Y", "Z"),
                   help="p2us: platform position [m] (default: the sidecar's reference configuration)")
    p.add_argument("--mode", help="p2us: working mode for --position (default ---)")

    def scan_args(p: argparse.ArgumentParser, step: float) -> None:
        p.add_argument("--step", type=_positive, default=step, metavar="M",
                       help=f"grid step [m] (default {step:g}; the volume: sampling step along each column)")
        p.add_argument("--modes", nargs="+", metavar="MODE",
                       help="p2us working modes such as --- +-+ (default all 8); planar arm: elbows up/down")
        p.add_argument("--limits", default="all", choices=["all", "actuators"],
                       help="all limits (default), or the actuator strokes only")
        p.add_argument("--plot", metavar="FILE.png", help="write a figure")

    p = command("workspace-volume", cmd_workspace_volume,
                "workspace volume (p2us) or area (planar arm) with its error estimate, per mode, with singular points")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--rtol", type=_non_negative, default=1e-3, metavar="R",
                   help="relative tolerance on the volume's error estimate; the quadrature refines until it "
                        "is met (default 1e-3; 0: 1e-2)")
    p.add_argument("--points", metavar="FILE", help="write the grid points inside the workspace (.npy or CSV)")

    p = command("singularities", cmd_singularities,
                "type I/II/III singular loci over a grid (p2us); theta2 = 0 boundary (planar arm)")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--paper-scan", action="store_true", help="p2us: also paper B's 8x8x8 actuator scan")
    p.add_argument("--angle-step-deg", type=_positive, default=1.0, metavar="DEG",
                   help="planar arm: joint-grid step in degrees (default 1)")

    p = command("sweep", cmd_sweep, "design sweep of the 3-[P2(US)] on Dask: volume, singularity-free "
                                     "fraction, conditioning")
    robot_arg(p)
    p.add_argument("--param", action="append", metavar="NAME=START:STOP:COUNT",
                   help="a swept parameter (repeatable): b, d, L, beta, theta_zero, rod_spacing, stroke_min, "
                        "stroke_max [m, rad]")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (default: an embedded "
                                                            "local cluster)")
    p.add_argument("--workers", type=int, metavar="N", help="worker processes of the local cluster (default: cores)")
    p.add_argument("--step", type=_positive, default=0.02, metavar="M", help="grid step per design [m] (default 0.02)")
    p.add_argument("--rtol", type=_positive, default=1e-2, metavar="R", help="volume tolerance (default 1e-2)")
    p.add_argument("--out", metavar="FILE.csv", help="write the table as CSV")

    p = command("guide", cmd_guide, "simulate paper A's manual-guidance experiments (admittance + virtual impedance)")
    p.add_argument("--experiment", type=int, required=True, choices=[1, 2, 3],
                   help="1: hard short push (saturation); 2: push to (0.7, 0), operator stops; 3: keeps pushing")
    p.add_argument("--robot", default="scara", metavar="ROBOT", help="a planar 2R arm (default scara)")
    p.add_argument("--no-virtual-impedance", action="store_true", help="the baseline: plain admittance control")
    p.add_argument("--force", type=float, metavar="N", help="operator push [N] (default 30 for 1, 6 for 2 and 3)")
    p.add_argument("--mass", type=float, metavar="KG", help="admittance mass per axis [kg] (default 5)")
    p.add_argument("--damping", type=float, metavar="NS/M", help="admittance damping [N s/m] (default 40)")
    p.add_argument("--v-max", type=float, metavar="M/S", help="velocity saturation [m/s] (default 0.25)")
    p.add_argument("--saturation", choices=["norm", "axis"], help="saturate the speed (default) or each axis")
    p.add_argument("--threshold", type=float, metavar="M", help="radius threshold [m] (default 0.1)")
    p.add_argument("--k-max", type=float, metavar="N/M", help="eq. 16 step height (default 250)")
    p.add_argument("--gain", type=float, metavar="1/M", help="eq. 16 arctan slope (default 1e4)")
    p.add_argument("--dt", type=float, metavar="S", help="control period [s] (default 0.001)")
    p.add_argument("--plot", metavar="FILE.png", help="write the time histories (paper A's Figs. 14-30)")
    p.add_argument("--csv", metavar="FILE", help="write every step: force, position, velocities, radii, K_v, joints")

    p = command("show", cmd_show, "Meshcat view with overlays: prints the viewer URL and serves until "
                                   "interrupted, or writes a static HTML scene with --export")
    robot_arg(p)
    p.add_argument("--q", nargs="+", type=float, metavar="Q",
                   help="joint values [rad or m]; p2us: the 3 actuator values (closed-loop solved)")
    p.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")
    p.add_argument("--position", nargs=3, type=float, metavar=("X", "Y", "Z"),
                   help="p2us: platform position [m] (default: the sidecar's reference pose)")
    p.add_argument("--mode", help="p2us: working mode for --position (default ---)")
    p.add_argument("--ellipsoid", action="store_true", help="the manipulability ellipse/ellipsoid at the tool")
    p.add_argument("--workspace", action="store_true",
                   help="the workspace as points coloured by smallest radius (arm) or min(iota_I, iota_II) (p2us)")
    p.add_argument("--singularities", action="store_true", help="the singular points")
    p.add_argument("--guide", type=int, choices=[1, 2, 3], help="planar arm: animate guidance experiment N")
    p.add_argument("--limits", default="all", choices=["all", "actuators"], help="p2us: limits for --workspace")
    p.add_argument("--step", type=_positive, default=0.02, metavar="M", help="p2us: grid step [m] (default 0.02)")
    p.add_argument("--export", metavar="FILE.html", help="write a self-contained HTML scene and exit")
    p.add_argument("--serve-seconds", type=float, metavar="S", help=argparse.SUPPRESS)

    p = command("urdf", cmd_urdf, "write the URDF + loop sidecar of a 3-[P2(US)] design (paper B's by default)")
    p.add_argument("robot", metavar="ROBOT", choices=["p2us"], help="the mechanism: p2us")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="URDF to write; the sidecar goes beside it as NAME.loops.yaml")
    p.add_argument("--b", type=float, metavar="M", help="base radius [m] (default 0.325)")
    p.add_argument("--d", type=float, metavar="M", help="platform radius [m] (default 0.028)")
    p.add_argument("--L", type=float, metavar="M", help="rod length [m] (default 0.34)")
    p.add_argument("--beta", type=float, metavar="A", help="rail angle below horizontal [rad] (default 40 deg)")
    p.add_argument("--alpha", type=float, nargs=3, metavar="A", help="limb angles [rad] (default 0, 120, 240 deg)")
    p.add_argument("--stroke", type=float, nargs=2, metavar=("MIN", "MAX"), help="actuator range [m] (default 0.1 0.6)")
    p.add_argument("--theta", type=float, nargs=2, metavar=("MIN", "MAX"),
                   help="universal joint theta range [rad] (default -10 100 deg)")
    p.add_argument("--phi", type=float, nargs=2, metavar=("MIN", "MAX"),
                   help="universal joint phi range [rad] (default -70 70 deg)")
    p.add_argument("--theta-zero", type=float, metavar="A",
                   help="rod elevation below the inward horizontal at theta = 0 [rad] (default 0)")
    p.add_argument("--rod-spacing", type=float, metavar="M", help="parallelogram rod spacing [m] (default 0.05)")
    p.add_argument("--degrees", action="store_true", help="angles (beta, alpha, theta, phi, theta-zero) in degrees")
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 1 unreachable, 2 bad input)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except KinematicsError as exc:
        print(f"kinematics {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"kinematics {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    if sys.argv[1:] == ["--reference"]:
        sys.stdout.write(reference_markdown())
        sys.exit(0)
    sys.exit(main())
