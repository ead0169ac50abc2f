"""3-[P2(US)] kinematics: vectorised closed-form IK (8 modes + limits) and FK against the
per-point Pinocchio closed-loop solve, measured side by side in one run.

Run: python benchmarks/bench_p2us_kinematics.py [--points 1000000] [--loop 200] [--quick] [--json]
The JSON holds JSON_KEYS; `machine` is `_timing.calibration()`.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _timing import best_of, calibration, dump, machine_line, parse

from kinematics.chunks import default_workers, map_chunks
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

JSON_KEYS = ("points", "threads", "closed_form_ik_points_per_s", "closed_form_fk_points_per_s",
             "closed_loop_solve_cold_points_per_s", "closed_loop_solve_warm_points_per_s", "ratio_fk_to_cold_solve",
             "ratio_fk_to_warm_solve", "max_position_difference_m", "poses_compared", "machine")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--loop", type=int, default=200, help="points for the per-point Pinocchio solve")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parse(ap, {"points": 20_000, "loop": 5})
    machine = calibration()
    robot = load_robot("p2us")
    P = read_params(robot.urdf_path)
    rng = np.random.default_rng(0)
    pts = rng.uniform([-0.4, -0.4, -0.7], [0.4, 0.4, -0.1], (args.points, 3))
    q = rng.uniform(0.1, 0.6, (args.points, 3))
    within = np.empty((args.points, 8), dtype=bool)
    fk_p = np.empty((args.points, 2, 3))

    def ik_all(s: slice) -> None:
        within[s] = par.ik(P, pts[s]).within_limits

    def fk_all(s: slice) -> None:
        fk_p[s] = par.fk(P, q[s]).p

    workers = default_workers()
    t_ik = best_of(3, lambda: map_chunks(ik_all, args.points, workers=workers, progress=False))
    t_fk = best_of(3, lambda: map_chunks(fk_all, args.points, workers=workers, progress=False))

    loop = ClosedLoop(robot)
    res = par.ik(P, pts[: 50 * args.loop])
    ok = res.within_limits[:, -1]
    sample_q, sample_p = res.q[ok, -1][: args.loop], pts[: 50 * args.loop][ok][: args.loop]
    t = time.perf_counter()
    err = max(np.linalg.norm(loop.solve(qi).pose.translation - pi) for qi, pi in zip(sample_q, sample_p, strict=True))
    t_cold = (time.perf_counter() - t) / len(sample_q)
    sol = loop.solve(sample_q[0])
    warm = sample_q[:50]
    t = time.perf_counter()
    for qi in warm:
        loop.solve(qi + 1e-3, q0=sol.q)
    t_warm = (time.perf_counter() - t) / len(warm)

    rate_ik, rate_fk = args.points / t_ik, args.points / t_fk
    out = {"points": args.points, "threads": workers, "closed_form_ik_points_per_s": rate_ik,
           "closed_form_fk_points_per_s": rate_fk, "closed_loop_solve_cold_points_per_s": 1 / t_cold,
           "closed_loop_solve_warm_points_per_s": 1 / t_warm, "ratio_fk_to_cold_solve": rate_fk * t_cold,
           "ratio_fk_to_warm_solve": rate_fk * t_warm, "max_position_difference_m": float(err),
           "poses_compared": len(sample_q), "machine": machine}
    if args.json:
        print(dump(out))
        return
    print(f"3-[P2(US)] kinematics, {args.points:,} points, {workers} threads")
    print(f"  closed-form IK, 8 modes + all limits : {rate_ik:14,.0f} points/s")
    print(f"  closed-form FK, both assembly modes  : {rate_fk:14,.0f} points/s")
    print(f"  Pinocchio closed-loop solve (cold)   : {1 / t_cold:14,.0f} points/s  ({t_cold * 1e3:.2f} ms each)")
    print(f"  Pinocchio closed-loop solve (warm)   : {1 / t_warm:14,.0f} points/s  ({t_warm * 1e3:.2f} ms each)")
    print(f"  ratio FK / closed-loop solve (cold)  : {rate_fk * t_cold:14,.0f} x")
    print(f"  ratio FK / closed-loop solve (warm)  : {rate_fk * t_warm:14,.0f} x")
    print(f"  closed loop vs closed form, max |dp| : {err:.2e} m over {len(sample_q)} poses")
    print(f"  {machine_line(machine)}")


if __name__ == "__main__":
    main()
