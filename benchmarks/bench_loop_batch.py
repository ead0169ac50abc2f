"""3-[P2(US)] inverse kinematics in every working mode: the generic batched closed-loop solver
(kinematics.generic.loop_batch) vs the closed forms (kinematics.mechanisms.p2us.closed_form, the fused scan kernel) vs
today's per-point Pinocchio solver (kinematics.generic.closedloop), measured side by side in one run.

Run: python benchmarks/bench_loop_batch.py [--points 20000] [--loop 4] [--quick] [--json]
The JSON holds JSON_KEYS; `machine` is `_timing.calibration()`.

The generic path runs with each of its two solvers (`LoopBatch(solver=...)`): block by block (the
default) and all unknowns of a branch at once. Scenarios (all 8 branches of every point, margins
included):
* cold: uniform random points in the bounding box, no cache (only the batch's own coarse-subset
  continuation);
* columns: the same number of points as columns along z over an x-y grid (what the column volume
  engine asks first), no cache;
* warm: the columns again, moved by 1 mm, with the first pass cached (root refinement, re-scans).
The per-point solver gets the closed-form actuator values of each mode and closes the loops from
the sidecar's reference (cold), as `ClosedLoop.solve` does for a new pose.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _timing import best_of, calibration, dump, machine_line, parse

from kinematics.errors import ConvergenceError
from kinematics.generic.closedloop import ClosedLoop
from kinematics.generic.loop_batch import SOLVERS, LoopBatch
from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.scan import bounding_box, scan
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

JSON_KEYS = ("points", "cores", "load_average", "build_s", "generic_cold_points_per_s", "generic_columns_points_per_s",
             "generic_warm_points_per_s", "generic_reachable_missed", "generic_reachable_points",
             "whole_cold_points_per_s", "whole_columns_points_per_s", "whole_warm_points_per_s",
             "whole_reachable_missed", "closed_form_numpy_points_per_s", "closed_form_scan_kernel_points_per_s",
             "per_point_solver_points_per_s", "per_point_solver_modes_solved", "per_point_solver_modes_tried",
             "machine")


def columns(lo: np.ndarray, hi: np.ndarray, n: int) -> np.ndarray:
    per = 50
    k = max(1, round(float(np.sqrt(n / per))))
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], k), np.linspace(lo[1], hi[1], k), indexing="ij")
    z = np.linspace(lo[2], hi[2], per)
    xy = np.c_[gx.ravel(), gy.ravel()]
    return np.concatenate([np.c_[np.repeat(c[None], per, 0), z] for c in xy])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20_000)
    ap.add_argument("--loop", type=int, default=4, help="task points for the per-point Pinocchio solver")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = parse(ap, {"points": 500, "loop": 1})
    machine = calibration()
    robot = load_robot("p2us")
    P = read_params(robot.urdf_path)
    lo, hi = bounding_box(P)
    rng = np.random.default_rng(0)
    pts = rng.uniform(lo, hi, (args.points, 3))
    cols = columns(lo, hi, args.points)

    t = time.perf_counter()
    lb = LoopBatch.from_robot(robot)
    t_build = time.perf_counter() - t
    reach = par.ik(P, cols, limits=False).reachable[:, 0]
    generic = {}
    for solver in SOLVERS:
        lb = LoopBatch.from_robot(robot, solver=solver)
        lb.ik(pts[:100], warm=False)  # compile / load the kernels

        def cold(lb: LoopBatch = lb) -> None:
            lb.ik(pts, warm=False)

        def col(lb: LoopBatch = lb) -> None:
            lb.ik(cols, warm=False)

        t_cold = best_of(3, cold)
        t_col = best_of(3, col)
        shifted = cols + 1e-3
        t_warm = np.inf
        for _ in range(3):  # each repeat from the same cache: the first pass only
            lb.forget()
            first = lb.ik(cols)
            t_warm = min(t_warm, best_of(1, lambda lb=lb, shifted=shifted: lb.ik(shifted)))
        generic[solver] = {"cold": args.points / t_cold, "columns": len(cols) / t_col, "warm": len(cols) / t_warm,
                           "missed": int(np.sum(reach & ~first.found.all(axis=1)))}

    t_np = best_of(3, lambda: par.ik(P, pts))
    scan(P, pts[:10])
    t_scan = best_of(3, lambda: scan(P, pts))

    loop = ClosedLoop(robot)
    ik = par.ik(P, pts[: 50 * args.loop], limits=False)
    sample = ik.q[ik.reachable[:, 0]][: args.loop]  # (k, 8, 3)
    t = time.perf_counter()
    solved = 0
    for modes in sample:
        for q in modes:
            try:
                loop.solve(q)
            except ConvergenceError:  # a failed continuation still costs its time
                continue
            solved += 1
    t_loop = (time.perf_counter() - t) / max(len(sample), 1)

    load = os.getloadavg()
    out = {
        "points": args.points,
        "cores": os.cpu_count(),
        "load_average": [round(x, 2) for x in load],
        "build_s": round(t_build, 3),
        "generic_cold_points_per_s": generic["blocks"]["cold"],
        "generic_columns_points_per_s": generic["blocks"]["columns"],
        "generic_warm_points_per_s": generic["blocks"]["warm"],
        "generic_reachable_missed": generic["blocks"]["missed"],
        "generic_reachable_points": int(reach.sum()),
        "whole_cold_points_per_s": generic["whole"]["cold"],
        "whole_columns_points_per_s": generic["whole"]["columns"],
        "whole_warm_points_per_s": generic["whole"]["warm"],
        "whole_reachable_missed": generic["whole"]["missed"],
        "closed_form_numpy_points_per_s": args.points / t_np,
        "closed_form_scan_kernel_points_per_s": args.points / t_scan,
        "per_point_solver_points_per_s": 1 / t_loop,
        "per_point_solver_modes_solved": solved,
        "per_point_solver_modes_tried": int(sample.shape[0] * sample.shape[1]),
        "machine": machine,
    }
    if args.json:
        print(dump(out))
        return
    print(f"3-[P2(US)], IK in all 8 working modes; {args.points:,} points; {out['cores']} cores; "
          f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    for solver, name in (("blocks", "generic, block by block"), ("whole", "generic, all unknowns at once")):
        r = generic[solver]
        print(f"  {name}:")
        print(f"    cold random points                  : {r['cold']:14,.0f} points/s")
        print(f"    columns                             : {r['columns']:14,.0f} points/s")
        print(f"    warm (cached)                       : {r['warm']:14,.0f} points/s")
        print(f"    reachable column points missing a branch: {r['missed']} of {int(reach.sum())}")
    print(f"  closed form, NumPy (parallel.ik)      : {out['closed_form_numpy_points_per_s']:14,.0f} points/s")
    print(f"  closed form, fused scan kernel        : {out['closed_form_scan_kernel_points_per_s']:14,.0f} points/s")
    print(f"  per-point Pinocchio solver (cold)     : {out['per_point_solver_points_per_s']:14,.2f} points/s "
          f"({solved}/{out['per_point_solver_modes_tried']} modes closed)")
    print(f"  ratio generic (columns) / per-point   : {out['generic_columns_points_per_s'] * t_loop:14,.0f} x")
    print(f"  ratio scan kernel / generic (columns) : {out['closed_form_scan_kernel_points_per_s'] / out['generic_columns_points_per_s']:14,.0f} x")
    print(f"  LoopBatch.from_robot (atlas search)   : {t_build:.2f} s")
    print(f"  {machine_line(machine)}")


if __name__ == "__main__":
    main()
