"""Collision-aware workspace volume of a serial arm against its kinematic volume: ur5 (meshes,
self-collisions through coal).

Per robot: the kinematic `workspace-volume` (`measure_workspace`: the reach search on the
revolved profile where the base turns fully) and `--collisions`
(`analyses.collision_volume.measure_collision_workspace` -> `analyses.serial_collisions`: pairs with
the base link change with the base's turn; `--turns auto` brackets them on the profile by the
base link's turn envelope, `--turns spatial` searches in 3-D; the same run measures the kinematic
union), at the same step and rtol; wall and CPU seconds, the time ratio, the volume the
collisions remove, the bracket and the pairs that bind most, one row per robot, turn and number
of coal worker processes (`--workers`, `kinematics.generic.coal_pool.WORKERS`: 1 evaluates coal
inline; the CPU seconds are this process's, the workers' not counted).

Run: python benchmarks/bench_serial_collisions.py [--robots ur5] [--turns auto spatial] [--workers 1 2] [--rtol 0.1]
     [--step 0.1] [--no-check] [--quick] [--json]
The JSON holds JSON_KEYS: `rows`, one per robot with ROW_KEYS, and `machine`.
"""

from __future__ import annotations

import argparse
import time

from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.collision_volume import measure_collision_workspace
from kinematics.analyses.workspace import measure_workspace
from kinematics.generic import coal_pool
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

JSON_KEYS = ("rows", "machine")
ROW_KEYS = ("robot", "turn", "workers", "route", "bracket", "rtol", "step", "check", "kinematic_volume", "kinematic_error", "kinematic_seconds",
            "kinematic_cpu_seconds", "same_run_kinematic_volume", "same_run_kinematic_error", "collision_volume",
            "collision_error", "collision_seconds", "collision_cpu_seconds", "time_ratio", "removed", "search",
            "binding_pairs", "converged", "points_evaluated")


def measure(robot_name: str, turn: str, workers: int | None, rtol: float, step: float, check: bool,
            max_points: int | None) -> dict:
    coal_pool.WORKERS = workers
    robot = load_robot(robot_name)
    mech = mechanism_of(robot)
    t, c = time.perf_counter(), time.process_time()
    kin = measure_workspace(mech, step=step, rtol=rtol, check=check)
    kin_s, kin_c = time.perf_counter() - t, time.process_time() - c
    t, c = time.perf_counter(), time.process_time()
    cw = measure_collision_workspace(mech, robot, step=step, rtol=rtol, check=check, max_points=max_points,
                                     turn=turn)  # type: ignore[arg-type]
    col_s, col_c = time.perf_counter() - t, time.process_time() - c
    bounds = cw.collision.get("turn", {})
    return {"robot": robot_name, "turn": turn, "workers": coal_pool.workers(), "route": bounds.get("route"),
            "bracket": {k: bounds[k] for k in ("lower", "lower_error_estimate", "upper", "upper_error_estimate",
                                               "half_width") if k in bounds} or None,
            "rtol": rtol, "step": step, "check": check,
            "kinematic_volume": kin.total, "kinematic_error": kin.error, "kinematic_seconds": kin_s,
            "kinematic_cpu_seconds": kin_c, "same_run_kinematic_volume": cw.kinematic,
            "same_run_kinematic_error": cw.kinematic_error, "collision_volume": cw.workspace.total,
            "collision_error": cw.workspace.error, "collision_seconds": col_s, "collision_cpu_seconds": col_c,
            "time_ratio": col_s / kin_s, "removed": cw.removed, "search": cw.collision.get("search"),
            "binding_pairs": [{"links": list(p.links), "removed": p.removed} for p in cw.pairs[:4]],
            "converged": bool(cw.workspace.result.converged), "points_evaluated": cw.workspace.result.points_evaluated}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=["ur5"])
    ap.add_argument("--turns", nargs="+", default=["auto"], choices=["auto", "envelope", "spatial"],
                    help="how pairs the base's turn changes are measured (`serial_collisions.Turn`)")
    ap.add_argument("--workers", nargs="+", type=int, default=[None],
                    help="coal worker processes per row (default: one per CPU; 1: inline)")
    ap.add_argument("--rtol", type=float, default=0.1)
    ap.add_argument("--step", type=float, default=0.1, help="column step [m]")
    ap.add_argument("--no-check", dest="check", action="store_false", help="no check run (half the step, "
                    "twice the search's samples and restarts)")
    ap.add_argument("--max-points", type=int, default=None, help="evaluation budget of the collision run")
    ap.add_argument("--json", action="store_true")
    args = parse(ap, {"rtol": 0.3, "step": 0.3, "check": False, "max_points": 8_000})
    machine = calibration()
    rows = [measure(r, turn, w, args.rtol, args.step, args.check, args.max_points) for r in args.robots
            for turn in args.turns for w in args.workers]
    out = {"rows": rows, "machine": machine}
    if args.json:
        print(dump(out))
        return
    print(machine_line(machine))
    for r in rows:
        pairs = ", ".join(f"{a}-{b} {p['removed']:.3g}" for p in r["binding_pairs"] for a, b in [p["links"]])
        b = r["bracket"]
        bracket = (f"; bracket {b['lower']:.6g} +/- {b['lower_error_estimate']:.2g} to {b['upper']:.6g} +/- "
                   f"{b['upper_error_estimate']:.2g}" if b else "")
        print(f"{r['robot']}, turn {r['turn']} (route {r['route']}), {r['workers']} coal process(es), rtol {r['rtol']:g}, step {r['step']:g} m, "
              f"check {r['check']}: kinematic "
              f"{r['kinematic_volume']:.5g} +/- {r['kinematic_error']:.2g} m^3 in {r['kinematic_seconds']:.2f} s "
              f"({r['kinematic_cpu_seconds']:.2f} s CPU); collision-free {r['collision_volume']:.5g} +/- "
              f"{r['collision_error']:.2g} m^3 (same run's kinematic {r['same_run_kinematic_volume']:.5g} +/- "
              f"{r['same_run_kinematic_error']:.2g}, search {r['search']['mode']}) in {r['collision_seconds']:.1f} s "
              f"({r['collision_cpu_seconds']:.1f} s CPU) ({r['time_ratio']:.0f} x); converged {r['converged']}; "
              f"{r['points_evaluated']} points; binding: {pairs or 'none'}{bracket}")


if __name__ == "__main__":
    main()
