"""The Delta's workspace margins, measured side by side in one run: the compiled scan kernel
(`kinematics.mechanisms.delta.scan`, all 8 working modes + singular fields) on one thread and on
every core, against the NumPy closed forms it replaced (`mechanism.limb_margins` + `closed_form.limb_ik`),
and the default `workspace-volume delta` computation (every limit, rtol 1e-3, with the half-step check).

Run: python benchmarks/bench_delta_scan.py [--points 2000000] [--no-volume] [--quick] [--json]
The JSON holds JSON_KEYS (the volume's only without --no-volume); `machine` is `_timing.calibration()`.
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
from _timing import best_of, calibration, dump, machine_line, parse

from kinematics.analyses.workspace import measure_workspace
from kinematics.mechanisms.delta import closed_form as cf
from kinematics.mechanisms.delta.mechanism import Delta, limb_margins
from kinematics.mechanisms.delta.scan import scan

JSON_KEYS = ("points", "kernel_1_thread_per_s", "kernel_all_threads_per_s", "numpy_closed_forms_per_s", "ratio",
             "volume_m3", "error_estimate", "converged", "volume_points", "volume_seconds", "cores", "threads",
             "load_average", "machine")
ROOTS = np.array([[0 if c == "+" else 1 for c in m] for m in cf.MODES])


def numpy_path(params: cf.DeltaParams, pts: np.ndarray) -> None:
    """What `Delta.margin` and `singular_fields` computed before the kernel."""
    lm = limb_margins(params, pts, "all")
    lm[:, np.arange(3), ROOTS].min(axis=-1)
    limbs = cf.limb_ik(params, pts)
    n = limbs.n[:, np.arange(3), ROOTS]
    np.linalg.det(np.where(np.isfinite(n), n, 0.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2_000_000)
    ap.add_argument("--no-volume", action="store_true", help="skip the workspace-volume run")
    ap.add_argument("--step", type=float, default=0.005, help="the volume's column step [m]")
    ap.add_argument("--rtol", type=float, default=1e-3, help="the volume's relative tolerance")
    ap.add_argument("--json", action="store_true")
    a = parse(ap, {"points": 20_000, "step": 0.1, "rtol": 0.5})
    machine = calibration()
    params = cf.DeltaParams()
    mech = Delta(params)
    lo, hi = mech.bounding_box("all")
    pts = lo + (hi - lo) * np.random.default_rng(0).random((a.points, 3))
    scan(params, pts[:1000])  # compile (or load) outside the timing
    cores = numba.config.NUMBA_NUM_THREADS
    out: dict[str, object] = {"points": a.points}
    for threads, key in ((1, "kernel_1_thread_per_s"), (cores, "kernel_all_threads_per_s")):
        numba.set_num_threads(threads)
        out[key] = a.points / best_of(3, lambda: scan(params, pts))
    numba.set_num_threads(cores)
    few = pts[: max(1, a.points // 10)]
    out["numpy_closed_forms_per_s"] = len(few) / best_of(2, lambda: numpy_path(params, few))
    out["ratio"] = out["kernel_all_threads_per_s"] / out["numpy_closed_forms_per_s"]  # type: ignore[operator]
    if not a.no_volume:
        t = time.perf_counter()
        ws = measure_workspace(mech, step=a.step, rtol=a.rtol, limits="all", check=True)
        r = ws.result
        out.update(volume_m3=float(r.estimate[-1]), error_estimate=float(r.error[-1]), converged=r.converged,
                   volume_points=r.points_evaluated, volume_seconds=time.perf_counter() - t)
    out.update(cores=os.cpu_count(), threads=cores, load_average=list(os.getloadavg()), machine=machine)
    if a.json:
        print(dump(out))
    else:
        for k, v in out.items():
            if k != "machine":
                print(f"{k:32s} {v:,.4g}" if isinstance(v, float) else f"{k:32s} {v}")
        print(machine_line(machine))


if __name__ == "__main__":
    main()
