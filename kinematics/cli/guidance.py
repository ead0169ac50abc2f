"""`kinematics guide`: paper A's guidance experiments, simulated, as a report, JSON, CSV or plot."""

from __future__ import annotations

import argparse

from kinematics.cli.args import Command, number, positive
from kinematics.cli.report import Out, emit, fmt, key_values
from kinematics.errors import UnsupportedRobotError
from kinematics.files import write_atomic


def register(command: Command) -> None:
    p = command("guide", cmd_guide, "simulate paper A's manual-guidance experiments (admittance + virtual impedance)")
    p.add_argument("--experiment", type=int, required=True, choices=[1, 2, 3],
                   help="1: hard short push (saturation); 2: push to (0.7, 0), operator stops; 3: keeps pushing")
    p.add_argument("--robot", default="scara", metavar="ROBOT", help="a planar 2R arm (default scara)")
    p.add_argument("--no-virtual-impedance", action="store_true", help="the baseline: plain admittance control")
    p.add_argument("--force", type=number, metavar="N", help="operator push [N] (default 30 for 1, 6 for 2 and 3)")
    p.add_argument("--mass", type=positive, metavar="KG", help="admittance mass per axis [kg] (default 5)")
    p.add_argument("--damping", type=positive, metavar="NS/M", help="admittance damping [N s/m] (default 40)")
    p.add_argument("--v-max", type=positive, metavar="M/S", help="velocity saturation [m/s] (default 0.25)")
    p.add_argument("--saturation", choices=["norm", "axis"], help="saturate the speed (default) or each axis")
    p.add_argument("--threshold", type=positive, metavar="M", help="radius threshold [m] (default 0.1)")
    p.add_argument("--k-max", type=positive, metavar="N/M", help="eq. 16 step height (default 250)")
    p.add_argument("--gain", type=positive, metavar="1/M", help="eq. 16 arctan slope (default 1e4)")
    p.add_argument("--dt", type=positive, metavar="S", help="control period [s] (default 0.001)")
    p.add_argument("--plot", metavar="FILE.png", help="write the time histories (paper A's Figs. 14-30)")
    p.add_argument("--csv", metavar="FILE", help="write every step: force, position, velocities, radii, K_v, joints")


def cmd_guide(args: argparse.Namespace) -> int:
    """Paper A's manual-guidance experiments, simulated."""
    return run(args, emit)


def run(args: argparse.Namespace, out: Out) -> int:
    from kinematics.guidance.controller import GuidanceParams
    from kinematics.guidance.simulation import EXPERIMENTS, run_experiment
    from kinematics.mechanisms.scara.closed_form import ScaraParams
    from kinematics.model.robot import load_robot

    robot = load_robot(args.robot)
    if robot.loops is not None:
        raise UnsupportedRobotError(robot.name, "the guidance experiments need a planar 2R arm")
    sp = ScaraParams.from_robot(robot)
    overrides = {k: getattr(args, k) for k in ("mass", "damping", "v_max", "threshold", "k_max", "gain", "dt",
                                               "saturation") if getattr(args, k) is not None}
    params = GuidanceParams(virtual_impedance=not args.no_virtual_impedance, **overrides)
    res = run_experiment(args.experiment, sp, params, args.force)
    ex = EXPERIMENTS[args.experiment]
    summary = res.summary()
    if args.csv:
        write_atomic(args.csv, res.to_csv(), "--csv")
    if args.plot:
        from kinematics.views import plots

        plots.headless()
        plots.save(plots.guidance_run(res, plots.guidance_title(ex, res)), args.plot)
    payload = {"experiment": ex.number, "title": ex.title, "robot": robot.name, "start": list(ex.start),
               "params": {k: getattr(params, k) for k in params.__dataclass_fields__}, **summary}

    def human() -> str:
        s = summary
        return "\n".join([
            f"experiment {ex.number} on {robot.name}: {ex.title}",
            f"virtual impedance {'on' if params.virtual_impedance else 'OFF (baseline)'}; start {list(ex.start)} m",
            "",
            key_values([
                ("max speed [m/s]", f"{fmt(s['max_speed'])} (limit {params.v_max:g})"),
                ("saturated [s]", f"{fmt(s['saturated_seconds'])} {s['saturated_intervals']}"),
                ("smallest radius [m]", f"{fmt(s['min_radius'])} (threshold {params.threshold:g})"),
                ("final position [m]", [round(v, 5) for v in s["final_position"]]),
                ("min |theta2| [rad]", fmt(s["min_abs_theta2"])),
                ("peak joint speed [rad/s]", fmt(s["peak_joint_speed"])),
                ("max K_v [N/m]", fmt(s["max_k_v"])),
                ("reached the singularity", s["reached_singularity"]),
            ], digits=None),
        ])

    out(args, payload, human)
    return 0
