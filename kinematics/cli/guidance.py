"""`kinematics guide`: paper A's guidance experiments, simulated, as a report, JSON, CSV or plot."""

from __future__ import annotations

import argparse

from kinematics.cli.report import Out, fmt, key_values
from kinematics.errors import UnsupportedRobotError
from kinematics.files import write_atomic


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
