"""The serial singular scan (`kinematics singularities ROBOT` on a serial arm: the cell engine,
`kinematics.analyses.serial_workspace`) at the CLI's defaults: the UR5 (a full-turn base: a
4-joint profile, 400 cells across) and the panda (a part-turn base: six joints in 3-D, 128
cells across), each within the CLI's budget of 2e6 configurations.

Run: python benchmarks/bench_serial_singular.py [--max-points N] [--resolution N] [--quick] [--json]
Per row (ROW_KEYS): wall seconds, configurations evaluated, possibly singular boxes, the boxes
the budget left unsplit and their largest image ball [m] against a finished box's (half a cell).
The kernels are compiled on a small run first; `machine` is `_timing.calibration()`.
Goal: the panda within a few minutes on 2 cores (it did not finish in 31 minutes before the
marking by rows and the budgeted level 0).
"""

from __future__ import annotations

import argparse
import time

from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.serial_workspace import serial_workspace
from kinematics.model.robot import load_robot

JSON_KEYS = ("rows", "max_points", "machine")
ROW_KEYS = ("robot", "mode", "resolution", "seconds", "points_evaluated", "singular_boxes", "unsplit_boxes",
            "unsplit_radius_m", "leaf_radius_m", "cell_m")
ROBOTS = ("ur5", "panda")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-points", type=float, default=2e6, help="budget of configurations (the CLI's default)")
    ap.add_argument("--resolution", type=int, default=None, help="cells across (default: the CLI's, 400 / 128)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parse(ap, {"max_points": 20_000, "resolution": 16})
    machine = calibration()
    serial_workspace(load_robot("ur5"), resolution=16, max_points=1000)  # compile the kernels
    rows = []
    for name in ROBOTS:
        robot = load_robot(name)
        t = time.perf_counter()
        w = serial_workspace(robot, resolution=args.resolution, max_points=int(args.max_points))
        rows.append({"robot": name, "mode": w.mode, "resolution": args.resolution, "seconds": time.perf_counter() - t,
                     "points_evaluated": w.points_evaluated, "singular_boxes": len(w.singular_radius),
                     "unsplit_boxes": w.unsplit, "unsplit_radius_m": w.unsplit_radius,
                     "leaf_radius_m": w.leaf_radius, "cell_m": w.grid.cell})
    out = {"rows": rows, "max_points": int(args.max_points), "machine": machine}
    if args.json:
        print(dump(out))
        return
    print(f"serial singular scan, budget {int(args.max_points):,} configurations")
    for r in rows:
        print(f"  {r['robot']:6s} ({r['mode']}): {r['seconds']:7.1f} s, {r['points_evaluated']:,} configurations, "
              f"{r['singular_boxes']:,} possibly singular boxes, {r['unsplit_boxes']:,} unsplit (ball up to "
              f"{r['unsplit_radius_m']:.3g} m against {r['leaf_radius_m']:.3g} m)")
    print(f"  {machine_line(machine)}")


if __name__ == "__main__":
    main()
