"""Collision-aware workspace volume against the kinematic one, in one run: p2us-results and delta.

For each robot: `workspace-volume` as the CLI measures it (`measure_workspace`, with its check
run) and with `--collisions` (`analyses.collision_volume.measure_collision_workspace`: the pre-scan for
binding pairs, then the collision-free exact columns of p2us and delta, elsewhere sampled columns,
with the kinematic union and each binding pair's removal as extra targets, with the check run), at
the same step and rtol; wall and CPU seconds, the time ratio (goal <= 5 x), the volume the
collisions remove and the pairs that bind most.

Run: python benchmarks/bench_collisions.py [--rtol 1e-3] [--step 0.01] [--modes ---] [--watch 8] [--quick] [--json]
The JSON holds JSON_KEYS: `rows`, one per robot with ROW_KEYS, and `machine`.
"""

from __future__ import annotations

import argparse
import time

from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.collision_volume import measure_collision_workspace
from kinematics.analyses.workspace import measure_workspace
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

JSON_KEYS = ("rows", "machine")
ROW_KEYS = ("robot", "modes", "rtol", "step", "kinematic_volume", "kinematic_error", "kinematic_seconds",
            "collision_volume", "collision_error", "collision_seconds", "time_ratio", "kinematic_cpu_seconds",
            "collision_cpu_seconds", "removed", "binding_pairs",
            "converged", "points_evaluated")


def measure(robot_name: str, rtol: float, step: float, modes: list[str] | None, watch: int, max_points: int | None
            ) -> dict:
    robot = load_robot(robot_name)
    mech = mechanism_of(robot)
    branches = mech.check_branches(modes or None)
    measure_collision_workspace(mech, robot, step=0.2, rtol=0.2, branches=branches[:1], check=False, watch=0,
                                max_points=10_000)  # compile
    t, c = time.perf_counter(), time.process_time()
    kin = measure_workspace(mech, step=step, rtol=rtol, branches=branches, check=True)
    kin_s, kin_c = time.perf_counter() - t, time.process_time() - c
    t, c = time.perf_counter(), time.process_time()
    cw = measure_collision_workspace(mech, robot, step=step, rtol=rtol, branches=branches, watch=watch,
                                     max_points=max_points)
    col_s, col_c = time.perf_counter() - t, time.process_time() - c
    return {"robot": robot_name, "modes": list(branches), "rtol": rtol, "step": step,
            "kinematic_volume": kin.total, "kinematic_error": kin.error, "kinematic_seconds": kin_s,
            "collision_volume": cw.workspace.total, "collision_error": cw.workspace.error, "collision_seconds": col_s,
            "time_ratio": col_s / kin_s, "kinematic_cpu_seconds": kin_c, "collision_cpu_seconds": col_c,
            "removed": cw.removed,
            "binding_pairs": [{"links": list(p.links), "removed": p.removed} for p in cw.pairs[:4]],
            "converged": bool(cw.workspace.result.converged), "points_evaluated": cw.workspace.result.points_evaluated}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtol", type=float, default=1e-3)
    ap.add_argument("--step", type=float, default=0.01, help="column step [m] (the CLI default)")
    ap.add_argument("--modes", nargs="+", default=None, help="working modes (default: all)")
    ap.add_argument("--robots", nargs="+", default=["p2us-results", "delta"])
    ap.add_argument("--watch", type=int, default=8, help="binding pairs measured alone (default 8)")
    ap.add_argument("--max-points", type=int, default=None, help="evaluation budget of the collision run")
    ap.add_argument("--json", action="store_true")
    args = parse(ap, {"rtol": 0.2, "step": 0.1, "modes": ["---"], "watch": 0, "max_points": 200_000})
    machine = calibration()
    rows = [measure(r, args.rtol, args.step, args.modes, args.watch, args.max_points) for r in args.robots]
    out = {"rows": rows, "machine": machine}
    if args.json:
        print(dump(out))
        return
    print(machine_line(machine))
    for r in rows:
        pairs = ", ".join(f"{a}-{b} {p['removed']:.3g}" for p in r["binding_pairs"] for a, b in [p["links"]])
        print(f"{r['robot']} ({', '.join(r['modes'])}), rtol {r['rtol']:g}, step {r['step']:g} m: kinematic "
              f"{r['kinematic_volume']:.6g} m^3 in {r['kinematic_seconds']:.2f} s ({r['kinematic_cpu_seconds']:.2f} s CPU); "
              f"collision-free {r['collision_volume']:.6g} +/- {r['collision_error']:.2g} m^3 in "
              f"{r['collision_seconds']:.2f} s ({r['collision_cpu_seconds']:.2f} s CPU) "
              f"({r['time_ratio']:.1f} x); removed {r['removed']:.4g} m^3; binding: {pairs or 'none'}")


if __name__ == "__main__":
    main()
