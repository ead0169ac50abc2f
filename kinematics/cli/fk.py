"""CLI handler of `kinematics fk ROBOT --q-file Q --out P` (called from `cli`): many
configurations through the compiled batched kinematics.

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

import numpy as np

from kinematics.cli.report import Out
from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.files import check_output, write_atomic
from kinematics.model.robot import Robot


def _check_out(path: str, q_file: str) -> None:
    """Refuse an output we could not write (the shared check), or the input file itself."""
    check_output(path, "--out", "poses")
    if os.path.exists(q_file) and os.path.exists(path) and os.path.samefile(path, q_file):
        raise InvalidInputError("--out", f"{path} is the --q-file itself")


def read_rows(path: str) -> np.ndarray:
    """A 2-D float array from .npy or CSV (comma-separated, an optional header line)."""
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
    from kinematics.generic.batched import compile_frame, configurations
    from kinematics.generic.serial import plane

    if args.q is not None:
        raise InvalidInputError("--q-file", "give either --q or --q-file, not both")
    if args.out is None:
        raise InvalidInputError("--out", "--q-file needs --out, the .csv or .npy file for the poses")
    if args.q_file is None:
        raise InvalidInputError("--q-file", "--out writes the poses of the --q-file rows; give --q-file")
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
