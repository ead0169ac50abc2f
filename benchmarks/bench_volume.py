"""Workspace volume of the 3-[P2(US)], three methods side by side in one run:

1. the column engine (`kinematics.analyses.columns.column_volume`): exact columns, adaptive quadrature;
2. today's adaptive cells (`kinematics.analyses.cells.adaptive_volume`), rtol 1e-3 from 1 cm;
3. plain counting of cell centres at 2.5 mm.

Each for the every-limit union, the strokes-only union and per working mode (strokes only), with
time (warm), margin evaluations and the true error against a reference: the column engine at a
tighter rtol with its columns along another axis (an independent sampling of every root).
The machine's cores and load (`uptime`) are printed beside the figures.

Run: python benchmarks/bench_volume.py [--rtol 1e-5] [--ref-rtol 2e-6] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np

from kinematics.analyses.cells import adaptive_volume
from kinematics.analyses.columns import column_volume
from kinematics.analyses.workspace import p2us_margin
from kinematics.mechanisms.p2us.scan import bounding_box
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot


def counting(margin, lo, hi, step: float) -> tuple[np.ndarray, int]:
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
    count = 0
    for zk in axes[2]:
        plane = np.stack([X.ravel(), Y.ravel(), np.full(X.size, zk)], axis=1)
        count = count + (margin(plane) >= 0).sum(axis=0)
    return count * step**3, math.prod(len(a) for a in axes)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtol", type=float, default=1e-5)
    ap.add_argument("--ref-rtol", type=float, default=2e-6)
    ap.add_argument("--step", type=float, default=0.005, help="column engine's column step [m]")
    ap.add_argument("--limits", nargs="+", default=["all", "actuators"], choices=["all", "actuators"])
    ap.add_argument("--ref", nargs="+", default=[], metavar="LIMITS=V",
                    help="pinned union reference volumes [m^3] instead of computing them, e.g. all=0.0295811")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    P = read_params(load_robot("p2us").urdf_path)
    lo, hi = bounding_box(P)
    rows = []
    load0 = os.getloadavg()
    pinned = {k: float(v) for k, v in (r.split("=") for r in args.ref)}
    for limits in args.limits:
        margin = p2us_margin(P, limits=limits)
        column_volume(margin, lo, hi, step=0.05, rtol=1e-2)  # warm-up (compile / load the kernels)
        ref = None if limits in pinned else column_volume(margin, lo, hi, step=args.step, rtol=args.ref_rtol, axis=2)
        t = time.perf_counter()
        new = column_volume(margin, lo, hi, step=args.step, rtol=args.rtol)
        t_new = time.perf_counter() - t
        t = time.perf_counter()
        old = adaptive_volume(margin, lo, hi, 0.01, 1e-3, progress=False)
        t_old = time.perf_counter() - t
        t = time.perf_counter()
        cnt, n_cnt = counting(margin, lo, hi, 0.0025)
        t_cnt = time.perf_counter() - t
        targets = ["union"] if limits == "all" else [*__import__("kinematics.mechanisms.p2us.closed_form").parallel.MODES, "union"]
        for name in targets:
            k = -1 if name == "union" else targets.index(name)
            if ref is None and name != "union":
                continue
            V = pinned[limits] if ref is None else ref.estimate[k]
            ref_rel = math.nan if ref is None else ref.error[k] / V
            for method, est, err, sec, pts in (
                ("columns", new.estimate[k], new.error[k], t_new, new.points_evaluated),
                ("cells", old.estimate[k], old.error[k], t_old, old.points_evaluated),
                ("counting", cnt[k], math.nan, t_cnt, n_cnt),
            ):
                rows.append(dict(limits=limits, target=name, method=method, volume=float(est),
                                 true_rel=float(abs(est - V) / V), reported_rel=float(err / V), seconds=sec,
                                 points=int(pts), reference=float(V), reference_rel_err=float(ref_rel)))
    machine = {"cores": os.cpu_count(), "load_before": load0, "load_after": os.getloadavg()}
    if args.json:
        print(json.dumps({"rows": rows, "machine": machine}, indent=2))
        return
    print(f"machine: {machine['cores']} cores, load average {load0[0]:.2f} before, "
          f"{machine['load_after'][0]:.2f} after (the mode rows share the union's run)")
    print(f"{'limits':9} {'target':6} {'method':9} {'volume [m^3]':>13} {'true err':>9} {'reported':>9} "
          f"{'time [s]':>8} {'points':>12}")
    for r in rows:
        print(f"{r['limits']:9} {r['target']:6} {r['method']:9} {r['volume']:13.9f} {r['true_rel']:9.1e} "
              f"{r['reported_rel']:9.1e} {r['seconds']:8.2f} {r['points']:12,}")


if __name__ == "__main__":
    main()
