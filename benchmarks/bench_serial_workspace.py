"""Guaranteed workspace bounds of serial arms: time, configurations, measure and error estimate.

Run: python benchmarks/bench_serial_workspace.py [--robot ur5] [--resolution 400] [--max-points 1e7] [--quick] [--json]
One warm run per robot (the kernels are compiled first on a small run). Default robots: the
SCARA (area, exact 0.97292658 m^2), the 3R solid-of-revolution test arm (exact 0.331334 m^3) and
the UR5 (no exact answer); the true error is printed where it is known. The machine (cores,
uptime load, `_timing.calibration()`) is recorded beside the figures: the CPU is shared. The JSON
holds JSON_KEYS: `results`, one row (ROW_KEYS) per robot, and `machine`.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
from pathlib import Path

from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.serial_workspace import serial_workspace
from kinematics.model.robot import load_robot

HERE = Path(__file__).resolve().parent
ARM3R = HERE.parent / "tests" / "models" / "arm3r_revolved.urdf"
JSON_KEYS = ("results", "machine")
ROW_KEYS = ("robot", "mode", "measure", "unit", "bounds", "error_estimate", "true_error", "points_evaluated",
            "seconds", "cell_m")


def _arm3r_exact() -> float:
    # tests/test_serial_workspace.py::revolved_volume_closed_form for the model's numbers.
    l2, l3, a1, a2, b1, b2 = 0.4, 0.25, -0.5, 0.8, 0.3, 1.5

    def g(a: float) -> float:
        return (b2 * math.cos(a) / 2 - math.sin(a + 2 * b2) / 4) - (b1 * math.cos(a) / 2 - math.sin(a + 2 * b1) / 4)

    return 2 * math.pi * l2 * l3 * (l2 * (math.sin(a2) - math.sin(a1)) * (math.cos(b1) - math.cos(b2))
                                    + l3 * (g(a2) - g(a1)))


CASES = {
    "scara": (None, 0.97292658),
    str(ARM3R): ("tip", None),
    "ur5": (None, None),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", action="append", help="robot(s) to measure (default: scara, the 3R arm, ur5)")
    ap.add_argument("--resolution", type=int, default=None, help="cells across (default: the library's)")
    ap.add_argument("--max-points", type=float, default=1e7, help="configuration budget per robot")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parse(ap, {"resolution": 16, "max_points": 1e5})
    machine = calibration()

    names = args.robot or list(CASES)
    serial_workspace(load_robot("scara"), resolution=16)  # compile the kernels before timing
    rows = []
    for name in names:
        frame, exact = CASES.get(name, (None, None))
        if name == str(ARM3R):
            exact = _arm3r_exact()
        robot = load_robot(name)
        w = serial_workspace(robot, frame, resolution=args.resolution, max_points=int(args.max_points))
        d = w.as_dict()
        row = {
            "robot": robot.name,
            "mode": w.mode,
            "measure": w.measure,
            "unit": "m2" if w.planar else "m3",
            "bounds": [w.lower, w.upper],
            "error_estimate": w.error_estimate,
            "true_error": abs(w.measure - exact) if exact is not None else None,
            "points_evaluated": w.points_evaluated,
            "seconds": w.seconds,
            "cell_m": d["cell_m"],
        }
        rows.append(row)
    uptime = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    machine.update(load_average_end=list(os.getloadavg()), uptime=uptime)
    if args.json:
        print(dump({"results": rows, "machine": machine}))
        return
    for r in rows:
        true = "" if r["true_error"] is None else f", true error {r['true_error']:.3g}"
        print(f"{r['robot']:>16} ({r['mode']}): {r['measure']:.6g} {r['unit']} +/- {r['error_estimate']:.3g}"
              f" (bounds {r['bounds'][0]:.6g} .. {r['bounds'][1]:.6g}{true}); "
              f"{r['points_evaluated']} configurations, {r['seconds']:.1f} s, cell {r['cell_m'] * 1e3:.2f} mm")
    print(f"  {machine_line(machine)}")
    print(f"  at the end: {uptime}")


if __name__ == "__main__":
    main()
