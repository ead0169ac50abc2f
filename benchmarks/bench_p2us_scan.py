"""The 3-[P2(US)] workspace scan and volume, measured side by side in one run:

1. the fused scan (IK in all 8 modes + every limit + both singularity measures) in points/s, on
   one thread and on every core, against a per-point Pinocchio closed-loop evaluation of the same
   points (closed-loop solve of each mode's actuator values + the constrained Jacobian);
2. the workspace volume (every limit) to 0.1 % (estimated error): the default engine (column
   integration, `kinematics.analyses.columns`), the adaptive cells (boundary refinement,
   `kinematics.analyses.cells`, engine="cells": its guaranteed-looking bounds and finest step), against
   uniform grids: the cells' estimator on their finest step everywhere, and plain point counting.
   The reference is the column engine at --ref-rtol.

Run: python benchmarks/bench_p2us_scan.py [--points 20000000] [--loop 60] [--quick] [--json]
The JSON holds JSON_KEYS (`counting` one entry per --counting-step); `machine` is
`_timing.calibration()`.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numba
import numpy as np
from _timing import best_of, calibration, dump, machine_line, parse

from kinematics.analyses.cells import adaptive_volume
from kinematics.analyses.workspace import measure_workspace
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.p2us import scan as S
from kinematics.mechanisms.p2us.closed_form import ik
from kinematics.mechanisms.p2us.mechanism import P2US, p2us_margin
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

CHUNK = 1 << 18
JSON_KEYS = ("grid_points", "full_scan_points_per_s", "full_scan_seconds", "kernel_1_thread_per_s",
             "kernel_all_threads_per_s", "threads", "pinocchio_per_point_points_per_s", "pinocchio_modes_tried", "ratio_full_scan_to_pinocchio",
             "reference", "columns", "cells", "uniform_cells_estimator", "counting", "machine")


def full_scan(P, lo, hi, n: int) -> tuple[float, int]:
    """Scan n grid points in chunks (buffers reused), reducing to per-mode inside counts and the
    smallest measures, as a workspace/singularity scan does. Returns (seconds, points inside)."""
    g = S.kernel_geometry(P)
    side = round(n ** (1 / 3))
    axes = [np.linspace(lo[k], hi[k], side) for k in range(3)]
    total = side**3
    margin, det, disc = np.empty((CHUNK, 8)), np.empty((CHUNK, 8)), np.empty((CHUNK, 3))
    x, y, z = np.empty(CHUNK), np.empty(CHUNK), np.empty(CHUNK)
    inside = 0
    t = time.perf_counter()
    for start in range(0, total, CHUNK):
        m = min(CHUNK, total - start)
        i, j, k = np.unravel_index(np.arange(start, start + m), (side, side, side))
        x[:m], y[:m], z[:m] = axes[0][i], axes[1][j], axes[2][k]
        S._kernel(x[:m], y[:m], z[:m], g, True, margin[:m], det[:m], disc[:m])
        inside += int((margin[:m] >= 0).any(axis=1).sum())
    return time.perf_counter() - t, inside


def kernel_only(P, pts, threads: int) -> float:
    numba.set_num_threads(threads)
    g = S.kernel_geometry(P)
    n = len(pts)
    out = (np.empty((n, 8)), np.empty((n, 8)), np.empty((n, 3)))
    x, y, z = (np.ascontiguousarray(pts[:, k]) for k in range(3))
    S._kernel(x, y, z, g, True, *out)
    best = best_of(3, lambda: S._kernel(x, y, z, g, True, *out))
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return n / best


def pinocchio_per_point(robot, P, pts) -> tuple[float, int]:
    """Seconds per point: every reachable mode solved on the closed-loop model + its Jacobian; and
    the number of modes tried."""
    loop = ClosedLoop(robot)
    sol = ik(P, pts)
    tried = 0
    t = time.perf_counter()
    for k in range(len(pts)):
        for m in range(8):
            if sol.reachable[k, m] and np.all(np.isfinite(sol.q[k, m])):
                tried += 1
                try:
                    s = loop.solve(sol.q[k, m])
                    loop.constrained_jacobian(s.q)
                except Exception:  # noqa: BLE001, S110 - an unassemblable mode still cost the attempt
                    pass
    return (time.perf_counter() - t) / len(pts), tried


def volume_figures(ws, V: float, seconds: float | None = None) -> dict[str, Any]:
    r = ws.result
    return {"volume_m3": ws.total, "error_estimate": ws.error, "true_rel_error": abs(ws.total - V) / V,
            "points": r.points_evaluated, "seconds": ws.seconds if seconds is None else seconds,
            "converged": bool(r.converged)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20_000_000, help="grid points of the chunked full scan")
    ap.add_argument("--kernel-points", type=int, default=4_000_000, help="random points for the kernel-only rates")
    ap.add_argument("--loop", type=int, default=60, help="points for the per-point Pinocchio evaluation")
    ap.add_argument("--step", type=float, default=0.01, help="the volumes' step [m] (columns and cells)")
    ap.add_argument("--rtol", type=float, default=1e-3, help="the volumes' relative tolerance")
    ap.add_argument("--ref-rtol", type=float, default=2e-5, help="the reference volume's relative tolerance")
    ap.add_argument("--counting-steps", type=float, nargs="+", default=[0.0025, 0.00125],
                    help="grid steps [m] for plain counting")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parse(ap, {"points": 20_000, "kernel_points": 20_000, "loop": 10, "step": 0.05, "rtol": 1e-2,
                      "ref_rtol": 1e-3, "counting_steps": [0.02]})
    machine = calibration()
    robot = load_robot("p2us")
    P = read_params(robot.urdf_path)
    lo, hi = S.bounding_box(P)
    rng = np.random.default_rng(0)
    pts = lo + (hi - lo) * rng.random((args.kernel_points, 3))
    cores = numba.config.NUMBA_NUM_THREADS

    full_scan(P, lo, hi, 10_000)  # compile / load the cache
    t_full, _ = full_scan(P, lo, hi, args.points)
    grid = round(args.points ** (1 / 3)) ** 3
    rate_full = grid / t_full
    rate_1 = kernel_only(P, pts, 1)
    rate_n = kernel_only(P, pts, cores)
    t_pin, tried = pinocchio_per_point(robot, P, pts[: args.loop])
    out: dict[str, Any] = {
        "grid_points": grid, "full_scan_points_per_s": rate_full, "full_scan_seconds": t_full,
        "kernel_1_thread_per_s": rate_1, "kernel_all_threads_per_s": rate_n, "threads": cores,
        "pinocchio_per_point_points_per_s": 1 / t_pin, "pinocchio_modes_tried": tried, "ratio_full_scan_to_pinocchio": rate_full * t_pin,
    }

    # -- volume ------------------------------------------------------------------------------
    for engine in ("columns", "cells"):  # warm-up (compile / load the kernels)
        measure_workspace(P2US(P), step=0.05, rtol=None, progress=False, engine=engine)
    ref = measure_workspace(P2US(P), step=args.step, rtol=args.ref_rtol, progress=False, max_points=400_000_000)
    V = ref.total
    out["reference"] = {"engine": "columns", "rtol": args.ref_rtol, **volume_figures(ref, V)}
    cols = measure_workspace(P2US(P), step=args.step, rtol=args.rtol, progress=False)
    out["columns"] = {"rtol": args.rtol, "step_m": args.step, "columns": cols.result.columns, **volume_figures(cols, V)}
    ws = measure_workspace(P2US(P), step=args.step, rtol=args.rtol, progress=False, engine="cells")
    r = ws.result
    out["cells"] = {"rtol": args.rtol, "step_m": args.step, "bounds_m3": [float(r.lower[-1]), float(r.upper[-1])],
                    "finest_step_m": r.finest_step, **volume_figures(ws, V)}
    margin = p2us_margin(P)
    h = r.finest_step
    t = time.perf_counter()
    uni = adaptive_volume(margin, lo, hi, h, None, progress=False, max_points=400_000_000)
    t_uni = time.perf_counter() - t
    u = float(uni.estimate[-1])
    out["uniform_cells_estimator"] = {"step_m": h, "volume_m3": u, "true_rel_error": abs(u - V) / V,
                                      "points": uni.points_evaluated, "seconds": t_uni}
    out["counting"] = []
    for step in args.counting_steps:
        axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
        n = math.prod(len(a) for a in axes)
        t = time.perf_counter()
        count = 0
        for zk in axes[2]:
            X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
            plane = np.stack([X.ravel(), Y.ravel(), np.full(X.size, zk)], axis=1)
            count += int((margin(plane)[:, -1] >= 0).sum())
        est = count * step**3
        out["counting"].append({"step_m": step, "volume_m3": est, "true_rel_error": abs(est - V) / V, "points": n,
                                "seconds": time.perf_counter() - t})
    out["machine"] = machine
    if args.json:
        print(dump(out))
        return

    print(f"3-[P2(US)] scan: IK x 8 modes + strokes + theta/phi limits + iota_I/iota_II ({cores} cores)")
    print(f"  full grid scan, chunked ({grid:,} pts)  : {rate_full:14,.0f} points/s  ({t_full:.2f} s)")
    print(f"  kernel, 1 thread                          : {rate_1:14,.0f} points/s")
    print(f"  kernel, {cores} threads                         : {rate_n:14,.0f} points/s")
    print(f"  Pinocchio closed loop, per point (8 modes): {1 / t_pin:14,.1f} points/s  ({t_pin * 1e3:.2f} ms each; "
          f"{tried} reachable modes in {args.loop} points)")
    print(f"  ratio full scan / Pinocchio               : {rate_full * t_pin:14,.0f} x")
    print()
    c, a = out["columns"], out["cells"]
    print(f"workspace volume (all limits), reference {V:.7f} m^3 (columns, rtol {args.ref_rtol:g}, "
          f"{ref.result.points_evaluated:,} points)")
    print(f"  columns, rtol {args.rtol:g} : {c['volume_m3']:.7f} m^3, error {c['true_rel_error']:.1e} (estimated "
          f"{c['error_estimate'] / c['volume_m3']:.1e}), {c['points']:,} points, {c['seconds']:.2f} s")
    print(f"  cells, rtol {args.rtol:g}   : {a['volume_m3']:.7f} m^3, error {a['true_rel_error']:.1e} (estimated "
          f"{a['error_estimate'] / a['volume_m3']:.1e}), bounds [{a['bounds_m3'][0]:.5f}, {a['bounds_m3'][1]:.5f}], "
          f"{a['points']:,} points, {a['seconds']:.2f} s")
    print(f"  uniform, the cells' estimator at {h:g} m : {u:.7f} m^3, error {abs(u - V) / V:.1e}, "
          f"{uni.points_evaluated:,} points, {t_uni:.2f} s ({t_uni / a['seconds']:.1f} x the cells' time)")
    for row in out["counting"]:
        print(f"  uniform, counting cell centres at {row['step_m']:g} m : {row['volume_m3']:.7f} m^3, error "
              f"{row['true_rel_error']:.1e}, {row['points']:,} points, {row['seconds']:.2f} s")
    print(f"  {machine_line(machine)}")


if __name__ == "__main__":
    main()
