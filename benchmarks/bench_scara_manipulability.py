"""Manipulability over a grid of SCARA configurations: vectorised closed form vs a Pinocchio loop.

Run: python benchmarks/bench_scara_manipulability.py [--side 2000] [--loop 20000] [--quick] [--json]
Prints both throughputs (configurations/s), measured in this one run, and their ratio. The JSON
holds JSON_KEYS; `machine` is `_timing.calibration()`.
Goal (issue 2): >= 1e7 configurations/s for the vectorised closed form.
"""

from __future__ import annotations

import argparse

import numpy as np
import pinocchio as pin
from _timing import best_of, calibration, dump, machine_line, parse

from kinematics.chunks import default_workers, map_chunks
from kinematics.generic.manipulability import ellipsoid
from kinematics.mechanisms.scara import closed_form as sc
from kinematics.model.robot import load_robot

JSON_KEYS = ("configurations", "closed_form_1thread_per_s", "closed_form_per_s", "threads", "pinocchio_loop_per_s",
             "pinocchio_loop_configurations", "ratio", "max_r_min_difference_m", "goal_met", "machine")
GOAL = 1e7


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=2000, help="grid side: side x side configurations")
    ap.add_argument("--loop", type=int, default=20000, help="configurations for the Pinocchio loop")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parse(ap, {"side": 100, "loop": 500})
    machine = calibration()

    robot = load_robot("scara")
    p = sc.ScaraParams.from_robot(robot)
    t1, t2 = np.meshgrid(np.linspace(p.lower[0], p.upper[0], args.side),
                         np.linspace(p.lower[1], p.upper[1], args.side), indexing="ij")
    q = np.stack([t1.ravel(), t2.ravel()], axis=-1)
    n = len(q)
    r_min = np.empty(n)

    def vectorised(workers: int) -> None:
        def kernel(s: slice) -> None:
            r_min[s] = sc.manipulability(p, q[s]).radii[:, 0]

        map_chunks(kernel, n, workers=workers, progress=False)

    one = best_of(3, lambda: vectorised(1))
    many = best_of(3, lambda: vectorised(default_workers()))

    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id()
    sub = q[:: max(1, n // args.loop)][: args.loop]
    loop_r = np.empty(len(sub))

    def pinocchio_loop() -> None:
        for i, qi in enumerate(sub):
            J = pin.computeFrameJacobian(model, data, qi, fid, pin.LOCAL_WORLD_ALIGNED)[:2]
            loop_r[i] = ellipsoid(J).radii[0]

    loop = best_of(1, pinocchio_loop)
    # Same numbers both ways (the benchmark compares equal work).
    vectorised(default_workers())
    agree = np.abs(loop_r - r_min[:: max(1, n // args.loop)][: args.loop]).max()

    rate_one, rate_many, rate_loop = n / one, n / many, len(sub) / loop
    out = {"configurations": n, "closed_form_1thread_per_s": rate_one, "closed_form_per_s": rate_many,
           "threads": default_workers(), "pinocchio_loop_per_s": rate_loop, "pinocchio_loop_configurations": len(sub),
           "ratio": rate_many / rate_loop, "max_r_min_difference_m": float(agree), "goal_met": bool(rate_many >= GOAL),
           "machine": machine}
    if args.json:
        print(dump(out))
        return
    print(f"SCARA manipulability, {n:,} configurations ({args.side} x {args.side} grid over the joint limits)")
    print(f"  vectorised closed form, 1 thread   : {rate_one:14,.0f} configurations/s")
    print(f"  vectorised closed form, {default_workers()} threads  : {rate_many:14,.0f} configurations/s")
    print(f"  Pinocchio Jacobian + SVD, per point: {rate_loop:14,.0f} configurations/s ({len(sub):,} points)")
    print(f"  ratio vectorised / Pinocchio loop  : {rate_many / rate_loop:14,.0f} x")
    print(f"  max |r_min difference|             : {agree:.2e} m")
    print(f"  goal >= {GOAL:.0e}/s: {'met' if out['goal_met'] else 'NOT met'}")
    print(f"  {machine_line(machine)}")


if __name__ == "__main__":
    main()
