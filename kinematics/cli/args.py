"""The CLI's shared argument helpers: the parser class, the number and type parsers, the
arguments several commands take (ROBOT with --range, --q, the scan and serial-arm options), and
`command`, through which each command module's `register` adds its subparser. No heavy imports:
everything the parser imports must keep `kinematics --help` instant.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

EXIT_OK, EXIT_NO, EXIT_ERROR = 0, 1, 2
"""Exit status: success, a well-formed question whose answer is \"no\", bad input (argparse's usage
errors too); the others are in `kinematics.cli.app`."""

MAX_MAGNITUDE = 1e6
"""Largest magnitude of a coordinate on the command line [m, rad, deg, N]: a million metres is
beyond any robot, and squares of such values stay far from overflowing."""

CLOSED_POSE = (", default: the actuators of its default closed pose (the sidecar's reference, or a pose found from "
               "the neutral pose; the report says which)")
"""The closed-loop default of --q (fk, jacobian), for the help."""

ROBOT_HELP = ("built-in name (scara, p2us, p2us-results, delta), URDF path, or example-robot-data name "
              "(ur5, panda, ...)")


class Parser(argparse.ArgumentParser):
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


def _real(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def positive(text: str) -> float:
    import math

    v = _real(text)
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be positive and finite, got {text}")
    return v


def non_negative(text: str) -> float:
    """0 (however spelt: 0.00, -0, 0e0) or a positive finite number."""
    import math

    v = _real(text)
    if v == 0.0:
        return 0.0
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be 0 or positive and finite, got {text}")
    return v


def number(text: str) -> float:
    """A coordinate: finite, magnitude at most MAX_MAGNITUDE."""
    import math

    v = _real(text)
    if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
        raise argparse.ArgumentTypeError(f"must be finite and at most {MAX_MAGNITUDE:g} in magnitude, got {text}")
    return v


def angle_value(text: str) -> float:
    """A number, or a multiple or fraction of pi [rad]: `-pi`, `pi/2`, `0.5pi`, `2*pi`, `-3pi/4`
    (NaN when it is neither)."""
    import math
    import re

    try:
        return float(text)
    except ValueError:
        pass
    m = re.fullmatch(r"\s*([+-]?)\s*(\d*\.?\d*)\s*\*?\s*pi\s*(?:/\s*(\d+\.?\d*))?\s*", text)
    if m is None or m.group(2) == ".":
        return float("nan")
    factor = float(m.group(2)) if m.group(2) else 1.0
    divisor = float(m.group(3)) if m.group(3) else 1.0
    if divisor == 0.0:
        return float("nan")
    value = factor * math.pi / divisor
    return -value if m.group(1) == "-" else value


def joint_range(text: str) -> tuple[str, tuple[float, float]]:
    """`JOINT=LO:HI` -> (joint, (lo, hi)), both finite with lo < hi; LO and HI numbers or
    multiples of pi (`angle_value`: `--range mot1=-pi:pi`)."""
    name, sep, pair = text.partition("=")
    lo, colon, hi = pair.partition(":")
    a, b = angle_value(lo), angle_value(hi)
    if not (sep and colon and name) or not (abs(a) <= MAX_MAGNITUDE and abs(b) <= MAX_MAGNITUDE and a < b):
        raise argparse.ArgumentTypeError(f"expected JOINT=LO:HI with finite LO < HI, each at most {MAX_MAGNITUDE:g} in "
                                         f"magnitude, got {text!r} (LO, HI: numbers or multiples of pi such as -pi, "
                                         "pi/2)")
    return name, (a, b)


def integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


class Version(argparse.Action):
    """--version from the installed package's metadata (looked up only when asked)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        from importlib.metadata import version

        print(f"kinematics {version('kinematics')}")
        parser.exit(0)


Handler = Callable[[argparse.Namespace], int]
"""A command's handler: the parsed arguments -> the exit status."""
Command = Callable[[str, Handler, str], argparse.ArgumentParser]
"""`command(name, handler, help)`: adds a subparser with --json whose handler is `handler`."""


def subcommands(sub: Any) -> Command:
    """The `command` function adding subparsers to `sub` (from `add_subparsers`)."""

    def command(name: str, func: Handler, help_: str) -> argparse.ArgumentParser:
        p: argparse.ArgumentParser = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(func=func)
        p.add_argument("--json", action="store_true", help="print JSON instead of a readable report")
        return p

    return command


def robot_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("robot", metavar="ROBOT", help=ROBOT_HELP)
    p.add_argument("--range", action="append", type=joint_range, metavar="JOINT=LO:HI",
                   help="give or replace a joint's range [rad or m] (repeat per joint; LO and HI numbers "
                        "or multiples of pi: mot1=-pi:pi, q2=0:pi/2): for URDFs whose <limit> has no lower/upper")
    p.add_argument("--tool-frame", metavar="FRAME",
                   help="the frame analysed: an open chain's tool, a closed loop's end effector (default: the loop "
                        "sidecar's end_effector; a Gepetto model's 'effector' frame, else its first closure frame; "
                        "an open chain's last link)")


def q_args(p: argparse.ArgumentParser, required: bool = True, p2us: str = "one per actuated joint",
           loops: str | None = "") -> None:
    """--q and --degrees. `loops`: what follows "closed-loop robot, one per actuated joint" (None:
    the command takes serial robots only); `p2us`: what --q is for the p2us and the Delta."""
    closed = "" if loops is None else f"; closed-loop robot, one per actuated joint{loops}; p2us, delta: {p2us}"
    p.add_argument("--q", nargs="+", type=number, required=required, metavar="Q",
                   help=f"joint values [rad or m]: serial robot, one per degree of freedom{closed}")
    p.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")


def scan_args(p: argparse.ArgumentParser, step: float) -> None:
    p.add_argument("--step", type=positive, default=step, metavar="M",
                   help=f"grid step [m] (default {step:g}; the volume: the column spacing to start "
                        "from, and the sampling step along columns where no exact columns exist)")
    p.add_argument("--modes", nargs="+", metavar="MODE",
                   help="working modes such as --- +-+ (p2us, delta; default all 8); planar arm: "
                        "elbows up/down; other robots: their branch labels (a wrong one lists them)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuator strokes only")
    p.add_argument("--plot", metavar="FILE.png", help="write a figure")


SERIAL_BUDGET = 2_000_000
"""--max-points' default: configurations of a serial arm's cell engine."""


def serial_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--max-points", type=positive, default=None, metavar="N",
                   help="serial arms: budget of configurations (default 2e6: 15-25 s for the UR5 on 2 cores, "
                        "proved bounds about +/-50 %%; the bounds stay valid at any budget)")
    p.add_argument("--resolution", type=integer, metavar="N",
                   help="serial arms: cells across the reached extent (default 400 for a plane or a solid "
                        "of revolution's profile, 128 in space)")


def collision_args(p: argparse.ArgumentParser, what: str = "") -> None:
    p.add_argument("--collisions", action="store_true",
                   help="exclude configurations where two bodies collide (the URDF's collision shapes, less "
                        f"adjacent, touching-at-reference and sidecar-disabled pairs){what}")
    p.add_argument("--obstacles", metavar="FILE",
                   help="fixed bodies the robot must not touch: a URDF whose links' collision shapes are the "
                        "obstacles (fixed joints, root = the world frame) or a YAML list of shapes with a pose "
                        "(docs/collisions.md); alone, only robot-obstacle pairs are checked")


# -- what handlers read from the arguments -------------------------------------------------------
def refuse_serial_args(args: argparse.Namespace, why: str) -> None:
    """Refuse --max-points or --resolution (`serial_args`) where no serial arm's cell engine runs
    (`why` says what runs instead), rather than ignore them."""
    from kinematics.errors import InvalidInputError

    for flag, value in (("--max-points", args.max_points), ("--resolution", args.resolution)):
        if value is not None:
            raise InvalidInputError(flag, f"is for a serial arm's joint boxes (the cell engine); {why}")


def refuse_pose_args(args: argparse.Namespace, why: str) -> None:
    """Refuse --position or --mode (which pose the p2us and the Delta) where they pose nothing
    (`why` says what does), rather than ignore them."""
    from kinematics.errors import InvalidInputError

    for flag in ("position", "mode"):
        if getattr(args, flag) is not None:
            raise InvalidInputError(f"--{flag}", why)


def load(args: argparse.Namespace) -> Any:
    """The robot of ROBOT, --range and --tool-frame. --range is refused for a mechanism whose limits
    are design parameters (the p2us, the Delta): its closed forms would answer as if it were not
    given; --tool-frame (by the dispatcher) for a frame other than such a mechanism's platform."""
    from kinematics.model.robot import load_robot

    ranges = dict(getattr(args, "range", None) or ())
    tool = getattr(args, "tool_frame", None)
    robot = load_robot(args.robot, ranges=ranges, tool_frame=tool)
    if tool:  # a closed-form family refuses a frame other than its platform's at once
        from kinematics.mechanisms import mechanism_of

        mechanism_of(robot)
    if ranges:
        from kinematics.errors import InvalidInputError
        from kinematics.mechanisms import mechanism_of

        mech = mechanism_of(robot)
        if mech.limits_in_design:
            raise InvalidInputError("--range", f"{robot.name}'s limits are design parameters read from its URDF, "
                                    "which a joint range does not change; write a design with other limits "
                                    f"(`kinematics urdf {mech.family} --help`)")
    return robot


def is_parallel(robot: Any) -> bool:
    """A closed-loop mechanism, as the dispatcher (`mechanism_of`) decides."""
    from kinematics.mechanisms import mechanism_of

    return mechanism_of(robot).closed_loop


def values(args: argparse.Namespace, robot: Any) -> Any:
    """The joint values of --q (and --degrees): required here."""
    if args.q is None:
        from kinematics.errors import InvalidInputError

        raise InvalidInputError("--q", f"{robot.name} needs joint values, one per degree of freedom ({robot.nv})")
    return robot.joint_values(args.q, degrees=args.degrees)


def mode_of(args: argparse.Namespace, default: str) -> str:
    """--mode, or `default` when it is not given. An empty --mode '' is given: a label to check
    (and refuse, listing the valid ones), not the default."""
    return default if args.mode is None else args.mode


def collision_checks(args: argparse.Namespace, robot: Any) -> Any:
    """The `CollisionModel` of --collisions and --obstacles, or None when neither is given."""
    if not (getattr(args, "collisions", False) or getattr(args, "obstacles", None)):
        return None
    from kinematics.analyses.collisions import collision_model_of, collision_refusal
    from kinematics.errors import InvalidInputError
    from kinematics.generic.obstacles import load_obstacles
    from kinematics.mechanisms import mechanism_of

    refused = collision_refusal(mechanism_of(robot))  # before any solver is compiled or grid scanned
    if refused is not None:
        raise InvalidInputError(*refused)
    obstacles = load_obstacles(args.obstacles) if args.obstacles else None
    return collision_model_of(robot, obstacles, self_collisions=args.collisions)


def orientation_args(p: argparse.ArgumentParser, what: str, closed_loops: bool = False) -> None:
    """--orientation / --tool-axis: `what` is measured with the tool held so (open chains; with
    `closed_loops`, closed loops with six actuators too, which hold a whole rotation)."""
    orient = p.add_mutually_exclusive_group()
    loops = (", and closed loops with six actuators (their end effector; 'reference': the rotation it has at the "
             "loop sidecar's reference configuration)") if closed_loops else ""
    orient.add_argument("--orientation", metavar="'rpy R P Y' | reference" if closed_loops else "'rpy R P Y'",
                        help=f"{what} with the tool frame at this fixed rotation (roll, pitch, yaw [rad], URDF "
                             f"convention), within the joint limits: open chains{loops} (--json key orientation: "
                             "kind, text, tool_z, rotation)")
    orient.add_argument("--tool-axis", nargs=3, type=number, metavar=("X", "Y", "Z"),
                        help="open chains: the same with only the tool frame's z axis fixed along (X, Y, Z), "
                             "e.g. 0 0 -1 for a tool pointing down")


def orientation_of(args: argparse.Namespace) -> Any:
    """The fixed tool orientation of --orientation / --tool-axis (a `ToolOrientation`), or None."""
    if not (getattr(args, "orientation", None) or getattr(args, "tool_axis", None)):
        return None
    from kinematics.mechanisms.orientation import ToolOrientation

    if getattr(args, "orientation", None):
        return ToolOrientation.parse(args.orientation)
    return ToolOrientation.axis(args.tool_axis)
