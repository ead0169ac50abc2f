"""Serial-arm workspaces through the one volume engine: each row of issue 29's table in one run.

Run: python benchmarks/bench_serial_workspace.py [--row NAME]... [--quick] [--json]
Rows (ROWS): the SCARA as a generic open chain (exact area 0.9729265761857 m^2), the revolved 3R
test arm (exact volume by Pappus, tests/test_serial_workspace.py), the UR5 at the CLI's default
rtol 1e-3 and at 1e-4 (its error against the 1e-4 run is reported as `true_error`, the 1e-4 run's
own estimate beside it), the panda and the kinova (example-robot-data) at the CLI's defaults (step
1 cm, rtol 1e-3), the z1 and the so100 (example-robot-data: base revolutes turning part of a
turn, `kinematics.mechanisms.serial.turn`) at the defaults (their circles' integral stops on its
search budget, `kinematics.analyses.columns.turned.SEARCHES`, reported as `search_budget`, and
says `converged: false` there), the wedge arm (tests/models/arm3r_wedge.urdf: a base range of
1.2 rad, measured in 3-D; exact volume derived in tests/test_serial_workspace.py) at the defaults,
whose first run stops on the 3-D search budget (`kinematics.mechanisms.serial.reach.SEARCHES`,
reported as `search_budget`; no check run then), and the SCARA's closed-form margin at
rtol 1e-5. With `--monte-carlo N` a partial turn's row also gets an independent count of N points
(`monte_carlo`: each point turned back by 121 base angles and searched with the base held at 0;
another seed; no profile, no circles) as `monte_carlo` [volume, standard error]. Every run is
`measure_workspace(..., check=True)` (the half-step run, with twice the search's seeds, compared
with the first). The kernels are compiled on a small run first. The machine
(cores, uptime load, `_timing.calibration()`) is recorded beside the figures: the CPU is shared.
JSON: `results` (one row per robot: ROW_KEYS) and `machine`.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import time
from pathlib import Path
from typing import Any

from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.columns.turned import SEARCHES
from kinematics.analyses.workspace import measure_workspace
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.serial.mechanism import SerialArm
from kinematics.mechanisms.serial.reach import SEARCHES as SEARCHES_3D
from kinematics.model.robot import load_robot

HERE = Path(__file__).resolve().parent
ARM3R = HERE.parent / "tests" / "models" / "arm3r_revolved.urdf"
WEDGE = HERE.parent / "tests" / "models" / "arm3r_wedge.urdf"
JSON_KEYS = ("results", "machine")
ROW_KEYS = ("robot", "volume", "unit", "error_estimate", "true_error", "converged", "rtol", "step_m",
            "points_evaluated", "seconds")
SCARA_AREA = 0.9729265761857  # m^2: tests/test_workspace.py::scara_area_closed_form


def arm3r_exact() -> float:
    """The revolved 3R arm's volume [m^3] (tests/test_serial_workspace.py::revolved_volume_closed_form)."""
    l2, l3, a1, a2, b1, b2 = 0.4, 0.25, -0.5, 0.8, 0.3, 1.5

    def g(a: float) -> float:
        return (b2 * math.cos(a) / 2 - math.sin(a + 2 * b2) / 4) - (b1 * math.cos(a) / 2 - math.sin(a + 2 * b1) / 4)

    return 2 * math.pi * l2 * l3 * (l2 * (math.sin(a2) - math.sin(a1)) * (math.cos(b1) - math.cos(b2))
                                    + l3 * (g(a2) - g(a1)))


def wedge_exact() -> float:
    """The wedge arm's volume [m^3] (tests/test_serial_workspace.py: two spherical-shell wedges of
    width 1.2 rad, (4 D / 3)(r(0.5)^3 - r(2.0)^3))."""
    def r(e: float) -> float:
        return math.sqrt(0.4**2 + 0.25**2 + 2 * 0.4 * 0.25 * math.cos(e))

    return 4 * 1.2 / 3 * (r(0.5) ** 3 - r(2.0) ** 3)


# name -> (robot, serial path, step [m], rtol, goal on the relative error)
ROWS: dict[str, tuple[str, bool, float, float, float]] = {
    "scara-serial": ("scara", True, 0.005, 1e-6, 1e-6),
    "arm3r": (str(ARM3R), True, 0.005, 1e-5, 1e-5),
    "ur5": ("ur5", True, 0.01, 1e-3, 1e-3),
    "ur5-1e-4": ("ur5", True, 0.005, 1e-4, 1e-4),
    "panda": ("panda", True, 0.01, 1e-3, 1e-3),
    "kinova": ("kinova", True, 0.01, 1e-3, 1e-3),
    "z1": ("z1", True, 0.01, 1e-3, 1e-3),
    "so100": ("so100", True, 0.01, 1e-3, 1e-3),
    "wedge": (str(WEDGE), True, 0.01, 1e-3, 1e-3),
    "scara-closed-form": ("scara", False, 0.01, 1e-5, 1e-5),
}
QUICK = {"scara-serial": (0.05, 1e-2), "arm3r": (0.05, 1e-2)}


def monte_carlo(robot_name: str, n: int, seed: int = 7, angles: int = 121) -> tuple[float, float]:
    """The volume [m^3] and its standard error by n points uniform in the cylinder about the base
    axis around the reach ball, each turned back by `angles` base angles evenly over the base's
    range and searched with the base held at 0 (a point is in W iff some turn of it is in W0; every
    hit is a reached configuration), with seed `seed`: no profile, no circles. (The world search,
    the base bounded by its limits, misses ~2-6 % of the z1's and the so100's volume.)"""
    import numpy as np

    from kinematics.mechanisms.serial.reach import Reach

    reach = Reach(load_robot(robot_name), seed=seed)
    assert reach.turn is not None
    R, c = reach.setup.reach, reach.reach_centre
    rng = np.random.default_rng(seed)
    r, phi, z = R * np.sqrt(rng.random(n)), rng.uniform(-np.pi, np.pi, n), rng.uniform(-R, R, n)
    finite = np.isfinite(reach.lo_base0) & np.isfinite(reach.hi_base0)
    mid = np.tile(np.where(finite, 0.5 * (np.where(finite, reach.lo_base0, 0) + np.where(finite, reach.hi_base0, 0)), 0.0),
                  (n, 1))
    hit = np.zeros(n, bool)
    for t in np.linspace(reach.turn[0], reach.turn[1], angles):
        p0 = c + np.column_stack([r * np.cos(phi - t), r * np.sin(phi - t), z]) @ reach.basis
        hit |= reach.distance(p0, (reach.lo_base0, reach.hi_base0), first_seed=mid)[0] >= 0
    box = math.pi * R * R * 2 * R
    f = float(hit.mean())
    return box * f, box * math.sqrt(f * (1 - f) / n)


def run_row(name: str, quick: bool) -> dict[str, Any]:
    robot_name, serial, step, rtol, goal = ROWS[name]
    if quick:
        step, rtol = QUICK[name]
    robot = load_robot(robot_name)
    mech = SerialArm(robot) if serial else mechanism_of(robot)
    t0 = time.perf_counter()
    ws = measure_workspace(mech, step=step, rtol=rtol, check=True)
    seconds = time.perf_counter() - t0
    exact = {"scara-serial": SCARA_AREA, "scara-closed-form": SCARA_AREA, "arm3r": arm3r_exact(),
             "wedge": wedge_exact()}.get(name)
    r = ws.result
    reach = getattr(mech, "reach", None)  # a partial turn's circles, or the 3-D path, stop on a search budget
    budget = None if reach is None else (SEARCHES if reach.turn is not None else
                                         SEARCHES_3D if reach.setup.mode == "spatial" else None)
    return {
        "robot": name, "volume": ws.total, "unit": "m2" if ws.planar else "m3", "error_estimate": ws.error,
        "true_error": None if exact is None else abs(ws.total - exact),
        "converged": bool(r.target_converged[-1]) and r.converged, "rtol": rtol, "goal_relative": goal,
        "step_m": step, "points_evaluated": r.points_evaluated, "seconds": seconds,
        **({"search_budget": budget} if budget is not None else {}),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--row", action="append", choices=list(ROWS), help="rows to run (default: all)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--monte-carlo", type=int, default=0, metavar="N",
                    help="also count N points turned back over the base's range for the partial turns' rows (z1, so100)")
    args = parse(ap, {})
    machine = calibration()
    names = args.row or (list(QUICK) if args.quick else list(ROWS))
    if args.quick:
        names = [n for n in names if n in QUICK]
    arm = SerialArm(load_robot(str(ARM3R)))  # compile the search kernels before timing
    arm.margin()(arm.bounding_box()[0][None])
    rows = [run_row(n, args.quick) for n in names]
    for r in rows:
        if args.monte_carlo and r["robot"] in ("z1", "so100"):
            t0 = time.perf_counter()
            r["monte_carlo"] = list(monte_carlo(ROWS[r["robot"]][0], args.monte_carlo))
            r["monte_carlo_seconds"] = time.perf_counter() - t0
    by = {r["robot"]: r for r in rows}
    if "ur5" in by and "ur5-1e-4" in by:  # the default run against the tighter one
        by["ur5"]["true_error"] = abs(by["ur5"]["volume"] - by["ur5-1e-4"]["volume"])
        by["ur5"]["true_error_reference"] = "the ur5-1e-4 row (its own error estimate beside it)"
    uptime = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    machine.update(load_average_end=list(os.getloadavg()), uptime=uptime)
    if args.json:
        print(dump({"results": rows, "machine": machine}))
        return
    for r in rows:
        true = "" if r["true_error"] is None else f", true error {r['true_error'] / r['volume']:.2g} relative"
        if "monte_carlo" in r:
            true += f", Monte Carlo {r['monte_carlo'][0]:.6g} +/- {r['monte_carlo'][1]:.2g}"
        print(f"{r['robot']:>18}: {r['volume']:.10g} {r['unit']} +/- {r['error_estimate']:.3g} "
              f"({r['error_estimate'] / r['volume']:.2g} relative{true}; goal {r['goal_relative']:g}; "
              f"{'converged' if r['converged'] else 'NOT converged'}); {r['points_evaluated']:,} points, "
              f"{r['seconds']:.1f} s")
    print(f"  {machine_line(machine)}")
    print(f"  at the end: {uptime}")


if __name__ == "__main__":
    main()
