"""The Delta's workspace margins, measured side by side in one run: the compiled scan kernel
(`kinematics.mechanisms.delta.scan`, all 8 working modes + singular fields) on one thread and on
every core, against the NumPy closed forms it replaced (`mechanism.limb_margins` + `closed_form.limb_ik`),
and the default `workspace-volume delta` computation (every limit, rtol 1e-3, with the half-step check).

Run: python benchmarks/bench_delta_scan.py [--points 2000000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numba
import numpy as np
from _timing import best_of

from kinematics.analyses.workspace import measure_workspace
from kinematics.mechanisms.delta import closed_form as cf
from kinematics.mechanisms.delta.mechanism import Delta, limb_margins
from kinematics.mechanisms.delta.scan import scan

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
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    params = cf.DeltaParams()
    mech = Delta(params)
    lo, hi = mech.bounding_box("all")
    pts = lo + (hi - lo) * np.random.default_rng(0).random((a.points, 3))
    scan(params, pts[:1000])  # compile (or load) outside the timing
    cores = numba.config.NUMBA_NUM_THREADS
    out: dict[str, object] = {"points": a.points}
    for threads in (1, cores):
        numba.set_num_threads(threads)
        out[f"kernel_{threads}_threads_per_s"] = a.points / best_of(3, lambda: scan(params, pts))
    numba.set_num_threads(cores)
    few = pts[: max(1, a.points // 10)]
    out["numpy_closed_forms_per_s"] = len(few) / best_of(2, lambda: numpy_path(params, few))
    out["ratio"] = out[f"kernel_{cores}_threads_per_s"] / out["numpy_closed_forms_per_s"]  # type: ignore[operator]
    if not a.no_volume:
        t = time.perf_counter()
        ws = measure_workspace(mech, step=0.005, rtol=1e-3, limits="all", check=True)
        r = ws.result
        out.update(volume_m3=float(r.estimate[-1]), error_estimate=float(r.error[-1]), converged=r.converged,
                   volume_points=r.points_evaluated, volume_seconds=time.perf_counter() - t)
    out.update(cores=os.cpu_count(), threads=cores, load_average=list(os.getloadavg()))
    if a.json:
        print(json.dumps(out, indent=2))
    else:
        for k, v in out.items():
            print(f"{k:32s} {v:,.4g}" if isinstance(v, float) else f"{k:32s} {v}")


if __name__ == "__main__":
    main()
