"""The 3-[P2(US)] workspace scan and volume, measured side by side in one run:

1. the fused scan (IK in all 8 modes + every limit + both singularity measures) in points/s, on
   one thread and on every core, against a per-point Pinocchio closed-loop evaluation of the same
   points (closed-loop solve of each mode's actuator values + the constrained Jacobian);
2. the workspace volume to 0.1 % (estimated error) by boundary refinement, against uniform grids:
   the same interpolating estimator on the finest step everywhere, and plain point counting.

Run: python benchmarks/bench_p2us_scan.py [--points 20000000] [--loop 100]
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np
from _timing import best_of

from kinematics.analyses.cells import adaptive_volume
from kinematics.analyses.workspace import p2us_margin, p2us_workspace
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.p2us import scan as S
from kinematics.mechanisms.p2us.closed_form import ik
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

CHUNK = 1 << 18


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


def pinocchio_per_point(robot, P, pts) -> float:
    """Seconds per point: every reachable mode solved on the closed-loop model + its Jacobian."""
    loop = ClosedLoop(robot)
    sol = ik(P, pts)
    t = time.perf_counter()
    for k in range(len(pts)):
        for m in range(8):
            if sol.reachable[k, m] and np.all(np.isfinite(sol.q[k, m])):
                try:
                    s = loop.solve(sol.q[k, m])
                    loop.constrained_jacobian(s.q)
                except Exception:  # noqa: BLE001, S110 - an unassemblable mode still cost the attempt
                    pass
    return (time.perf_counter() - t) / len(pts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20_000_000)
    ap.add_argument("--loop", type=int, default=60, help="points for the per-point Pinocchio evaluation")
    args = ap.parse_args()
    robot = load_robot("p2us")
    P = read_params(robot.urdf_path)
    lo, hi = S.bounding_box(P)
    rng = np.random.default_rng(0)
    pts = lo + (hi - lo) * rng.random((4_000_000, 3))
    cores = numba.config.NUMBA_NUM_THREADS

    full_scan(P, lo, hi, 10_000)  # compile / load the cache
    t_full, _ = full_scan(P, lo, hi, args.points)
    rate_full = (round(args.points ** (1 / 3)) ** 3) / t_full
    rate_1 = kernel_only(P, pts, 1)
    rate_n = kernel_only(P, pts, cores)
    t_pin = pinocchio_per_point(robot, P, pts[: args.loop])

    print(f"3-[P2(US)] scan: IK x 8 modes + strokes + theta/phi limits + iota_I/iota_II ({cores} cores)")
    print(f"  full grid scan, chunked ({args.points:,} pts)  : {rate_full:14,.0f} points/s  ({t_full:.2f} s)")
    print(f"  kernel, 1 thread                          : {rate_1:14,.0f} points/s")
    print(f"  kernel, {cores} threads                         : {rate_n:14,.0f} points/s")
    print(f"  Pinocchio closed loop, per point (8 modes): {1 / t_pin:14,.1f} points/s  ({t_pin * 1e3:.2f} ms each)")
    print(f"  ratio full scan / Pinocchio               : {rate_full * t_pin:14,.0f} x")

    # -- volume ------------------------------------------------------------------------------
    p2us_workspace(P, step=0.05, rtol=None, progress=False)  # warm-up
    t = time.perf_counter()
    ws = p2us_workspace(P, step=0.01, rtol=1e-3, progress=False)
    t_adapt = time.perf_counter() - t
    ref = p2us_workspace(P, step=0.01, rtol=2e-5, progress=False, max_points=400_000_000)
    V = ref.total
    r = ws.result
    print()
    print(f"workspace volume (all limits), reference {V:.7f} m^3 (rtol 2e-5, {ref.result.points_evaluated:,} points)")
    print(f"  adaptive, rtol 1e-3 : {ws.total:.7f} m^3, error {abs(ws.total - V) / V:.1e} (estimated "
          f"{r.error[-1] / ws.total:.1e}), bounds [{r.lower[-1]:.5f}, {r.upper[-1]:.5f}], "
          f"{r.points_evaluated:,} points, {t_adapt:.2f} s")
    margin = p2us_margin(P)
    h = r.finest_step
    t = time.perf_counter()
    uni = adaptive_volume(margin, lo, hi, h, None, progress=False, max_points=400_000_000)
    t_uni = time.perf_counter() - t
    print(f"  uniform, same estimator at {h:g} m : {uni.estimate[-1]:.7f} m^3, error "
          f"{abs(uni.estimate[-1] - V) / V:.1e}, {uni.points_evaluated:,} points, {t_uni:.2f} s "
          f"({t_uni / t_adapt:.1f} x the adaptive time)")
    for step in (0.0025, 0.00125):
        axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
        n = math.prod(len(a) for a in axes)
        t = time.perf_counter()
        count = 0
        for zk in axes[2]:
            X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
            plane = np.stack([X.ravel(), Y.ravel(), np.full(X.size, zk)], axis=1)
            count += int((margin(plane)[:, -1] >= 0).sum())
        t_c = time.perf_counter() - t
        est = count * step**3
        print(f"  uniform, counting cell centres at {step:g} m : {est:.7f} m^3, error {abs(est - V) / V:.1e}, "
              f"{n:,} points, {t_c:.2f} s")


if __name__ == "__main__":
    main()
