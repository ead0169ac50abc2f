"""`kinematics fk`: forward kinematics at one configuration (closed loops in
`kinematics.cli.parallel`), and `fk ROBOT --q-file Q --out P`: many configurations through the
compiled batched kinematics.

--q-file rows hold one value per degree of freedom, in model order ([rad] or [m]; with --degrees
the angles are in degrees); a continuous joint takes its angle, not Pinocchio's (cos, sin) pair.
--out rows: x y z and the rotation matrix row-major (9 entries) for spatial robots; the two plane
coordinates for planar arms (as `fk --q`).
"""

from __future__ import annotations

import argparse
import io
import os
import warnings
from typing import TYPE_CHECKING, Any

from kinematics.cli.args import CLOSED_POSE, EXIT_OK, Command, is_parallel, load, q_args, robot_arg, values
from kinematics.cli.report import Out, emit, with_plane
from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.files import check_output, write_atomic

if TYPE_CHECKING:
    import numpy as np

    from kinematics.model.robot import Robot


def register(command: Command) -> None:
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


def cmd_fk(args: argparse.Namespace) -> int:
    """Forward kinematics: tool position (and rotation for spatial robots)."""
    robot = load(args)
    out = with_plane(robot, emit)
    if args.q_file is not None or args.out is not None:
        return fk_file(args, robot, out)
    if is_parallel(robot):
        from kinematics.cli.parallel import fk as parallel_fk

        return parallel_fk(args, robot, out)
    from kinematics.cli.report import key_values, matrix
    from kinematics.generic.serial import forward_kinematics, plane

    v = values(args, robot)
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

    out(args, payload, human)
    return EXIT_OK


def _check_out(path: str, q_file: str) -> None:
    """Refuse an output we could not write (the shared check), or the input file itself."""
    check_output(path, "--out", "poses")
    if os.path.exists(q_file) and os.path.exists(path) and os.path.samefile(path, q_file):
        raise InvalidInputError("--out", f"{path} is the --q-file itself")


def read_rows(path: str) -> np.ndarray:
    """A 2-D float array from .npy or CSV (comma-separated, an optional header line)."""
    import numpy as np

    if not os.path.isfile(path):
        raise InvalidInputError("--q-file", f"{path}: no such file")
    try:
        if path.lower().endswith(".npy"):
            a = np.load(path, allow_pickle=False)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # an empty file: refused below, in one line
                try:
                    a = np.loadtxt(path, delimiter=",", ndmin=2)
                except ValueError:
                    a = np.loadtxt(path, delimiter=",", ndmin=2, skiprows=1)  # a header line
    except (ValueError, OSError) as exc:
        raise InvalidInputError("--q-file", f"{path}: cannot read numbers ({exc})") from None
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0 or not np.issubdtype(a.dtype, np.number):
        raise InvalidInputError("--q-file", f"{path}: expected a non-empty table of numbers, got shape {a.shape}")
    return a.astype(float, copy=False)


def fk_file(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    """Evaluate every row of --q-file, write --out."""
    import numpy as np

    from kinematics.generic.batched import compile_frame, configurations
    from kinematics.generic.serial import plane

    # the missing --q-file first: --q with --out is a missing file, not a clash with one
    if args.q_file is None:
        raise InvalidInputError("--q-file", "--out writes the poses of the --q-file rows; give --q-file")
    if args.q is not None:
        raise InvalidInputError("--q-file", "give either --q or --q-file, not both")
    if args.out is None:
        raise InvalidInputError("--out", "--q-file needs --out, the .csv or .npy file for the poses")
    _check_out(args.out, args.q_file)
    if robot.loops is not None:
        raise UnsupportedRobotError(robot.name, "--q-file evaluates serial robots; this one has loop closures")
    kin = compile_frame(robot, args.frame)
    values = read_rows(args.q_file)
    try:
        q = configurations(robot, values, degrees=args.degrees)
    except InvalidInputError as exc:
        raise InvalidInputError("--q-file", f"{args.q_file}: {exc.problem}") from None
    rows = kin.fk(q).rows
    axes = plane(robot)
    if axes is not None:
        table, columns = rows[:, list(axes)], ["xyz"[i] for i in axes]
    else:
        table, columns = rows, ["x", "y", "z", *(f"r{i}{j}" for i in range(3) for j in range(3))]
    if args.out.lower().endswith(".npy"):
        buf = io.BytesIO()
        np.save(buf, table)
        write_atomic(args.out, buf.getvalue(), "--out")
    else:
        text = io.StringIO()
        np.savetxt(text, table, delimiter=",", header=",".join(columns), comments="", fmt="%.17g")
        write_atomic(args.out, text.getvalue(), "--out")
    payload = {"frame": kin.frame, "configurations": len(table), "columns": columns, "out": args.out}

    def human() -> str:
        return (
            f"{len(table):,} configurations of {robot.name}: frame {kin.frame!r} written to {args.out} "
            f"(columns {' '.join(columns)}; metres)"
        )

    out(args, payload, human)
    return 0
