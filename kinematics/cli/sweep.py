"""`kinematics sweep`: the 3-[P2(US)]'s design sweep on Dask, its arguments and handler."""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING

from kinematics.cli.args import Command, collision_args, integer, load, positive, robot_arg
from kinematics.cli.report import Out, emit, show_progress, table
from kinematics.errors import InvalidInputError
from kinematics.files import write_atomic

if TYPE_CHECKING:
    from kinematics.model.robot import Robot


def register(command: Command) -> None:
    p = command("sweep", cmd_sweep, "design sweep of the 3-[P2(US)] on Dask: volume, singularity-free "
                                     "fraction, conditioning")
    robot_arg(p)
    p.add_argument("--param", action="append", metavar="NAME=START:STOP:COUNT",
                   help="a swept parameter (repeatable): b, d, L, beta, theta_zero, rod_spacing, stroke_min, "
                        "stroke_max [m, rad]")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (default: an embedded "
                                                            "local cluster)")
    p.add_argument("--workers", type=integer, metavar="N",
                   help="worker processes of the local cluster, 1 to 4 per core (default: cores)")
    p.add_argument("--step", type=positive, default=0.02, metavar="M", help="grid step per design [m] (default 0.02)")
    p.add_argument("--rtol", type=positive, default=1e-2, metavar="R", help="volume tolerance (default 1e-2)")
    p.add_argument("--out", metavar="FILE.csv", help="write the table as CSV")
    collision_args(p, "; adds each design's collision-free volume (its URDF generated with the robot's "
                      "collision sizes)")


def cmd_sweep(args: argparse.Namespace) -> int:
    """Design sweep of the 3-[P2(US)] on Dask."""
    return sweep(args, load(args), emit)


def sweep(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses import sweep as sw
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    mech.require("sweep_parameters", "a design sweep (of the 3-[P2(US)]'s dimensions)")
    params = mech.sweep_parameters()
    if not args.param:
        raise InvalidInputError("--param", f"give at least one, e.g. b=0.25:0.40:16; sweepable: {', '.join(sw.SWEEPABLE)}")
    axes = [sw.Axis.parse(p) for p in args.param]
    collisions = None
    if args.collisions or args.obstacles:
        from kinematics.analyses.collisions import design_options

        collisions = design_options(robot, args.collisions, args.obstacles)
    t0 = time.perf_counter()
    rows = sw.run(axes, params, step=args.step, rtol=args.rtol, scheduler=args.scheduler,
                  workers=args.workers, progress=show_progress(args), collisions=collisions)
    seconds = time.perf_counter() - t0
    text = sw.to_csv(rows)
    if args.out:
        write_atomic(args.out, text, "--out")
    payload = {"designs": rows, "columns": list(sw.columns_of(rows)), "seconds": seconds,
               "scheduler": args.scheduler or "local"}

    def human() -> str:
        shown = [c for c in sw.columns_of(rows) if c in ("design", *[a.name for a in axes]) or c not in sw.SWEEPABLE]
        return "\n".join([
            f"{len(rows)} designs on {payload['scheduler']} in {seconds:.1f} s"
            + (f"; table written to {args.out}" if args.out else ""),
            "",
            table(shown, [[r[c] for c in shown] for r in rows]),
        ])

    out(args, payload, human)
    return 0
