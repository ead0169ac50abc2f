"""Workspace volume of the 3-[P2(US)], three methods side by side in one run:

1. the column engine (`kinematics.analyses.columns.column_volume`): exact columns (`mechanisms.p2us.exact`), breaks
   located, Gauss rules; timed as the CLI runs it (with the half-step check) and without it;
2. the adaptive cells (`kinematics.analyses.cells.adaptive_volume`), rtol 1e-3 from 1 cm;
3. plain counting of cell centres at 2.5 mm.

Each for the every-limit union, the strokes-only union and, strokes only, every working mode,
with wall and CPU time (warm), columns or margin evaluations, and the true error against a
reference: by default the pinned ones of tests/test_volume_engine.py (the engine along two other
column axes at rtol 1e-7 / 1e-6), or --ref-rtol R to recompute them here along x.
The machine's cores, load and calibration (`_timing.calibration()`) are printed beside the figures.

Run: python benchmarks/bench_volume.py [--rtol 1e-5] [--limits all actuators] [--quick] [--json]
The JSON holds JSON_KEYS: `rows`, one per (limits, target, method) with ROW_KEYS (reported_rel is
null for counting, which has no error estimate), and `machine`.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.cells import adaptive_volume
from kinematics.analyses.columns import column_volume
from kinematics.mechanisms.p2us.closed_form import MODES
from kinematics.mechanisms.p2us.mechanism import p2us_margin
from kinematics.mechanisms.p2us.scan import bounding_box
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

# the references of tests/test_volume_engine.py and docs/workspace.md: the engine with its columns
# along x (and z, every limit) at rtol 1e-7 (every limit: only mode --- is non-empty) and 1e-6
# (strokes only, per mode and the union)
PINNED = {
    "all": {"union": 0.02958608225, "---": 0.02958608225},
    "actuators": {"+++": 0.030264736346, "++-": 0.027716780559, "+-+": 0.027716780565, "+--": 0.031950943877, "-++": 0.027716795211, "-+-": 0.031950947397, "--+": 0.031950947403, "---": 0.048409850004, "union": 0.155350869736},
}
JSON_KEYS = ("rows", "machine")
ROW_KEYS = ("limits", "target", "method", "volume", "true_rel", "reported_rel", "seconds", "cpu_seconds", "work",
            "reference")


def counting(margin, lo, hi, step: float) -> tuple[np.ndarray, int]:
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
    count = 0
    for zk in axes[2]:
        plane = np.stack([X.ravel(), Y.ravel(), np.full(X.size, zk)], axis=1)
        count = count + (margin(plane) >= 0).sum(axis=0)
    return count * step**3, math.prod(len(a) for a in axes)


def timed(fn):
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t, time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtol", type=float, default=1e-5)
    ap.add_argument("--step", type=float, default=0.01, help="column engine's node spacing [m] (the CLI default)")
    ap.add_argument("--limits", nargs="+", default=["all", "actuators"], choices=["all", "actuators"])
    ap.add_argument("--ref-rtol", type=float, default=0.0,
                    help="recompute the references here (columns along x) at this rtol instead of the pinned ones")
    ap.add_argument("--no-baselines", action="store_true", help="skip the cells and counting rows")
    ap.add_argument("--cells-step", type=float, default=0.01, help="the adaptive cells' starting step [m]")
    ap.add_argument("--cells-rtol", type=float, default=1e-3, help="the adaptive cells' relative tolerance")
    ap.add_argument("--counting-step", type=float, default=0.0025, help="the counting grid's step [m]")
    ap.add_argument("--json", action="store_true")
    args = parse(ap, {"rtol": 1e-2, "step": 0.05, "cells_step": 0.05, "cells_rtol": 1e-2, "counting_step": 0.02})
    machine = calibration()
    P = read_params(load_robot("p2us").urdf_path)
    lo, hi = bounding_box(P)
    rows = []
    load0 = os.getloadavg()
    for limits in args.limits:
        margin = p2us_margin(P, limits=limits)
        targets = ["---", "union"] if limits == "all" else [*MODES, "union"]
        col = {"---": MODES.index("---")} if limits == "all" else {m: k for k, m in enumerate(MODES)}
        col["union"] = -1
        column_volume(margin, lo, hi, step=0.05, rtol=1e-2)  # warm-up (compile / load the kernels)
        if args.ref_rtol or limits not in PINNED:
            ref = column_volume(margin, lo, hi, step=args.step / 2, rtol=args.ref_rtol or 1e-7, axis=0)
            refs = {t: float(ref.estimate[col[t]]) for t in targets}
        else:
            refs = PINNED[limits]
        runs = []
        new, w, c = timed(lambda m=margin: column_volume(m, lo, hi, step=args.step, rtol=args.rtol))
        runs.append(("columns", new.estimate, new.error, w, c, new.columns))
        chk, w, c = timed(lambda m=margin: column_volume(m, lo, hi, step=args.step, rtol=args.rtol, check=True))
        runs.append(("columns+check", chk.estimate, chk.error, w, c, chk.columns))
        if not args.no_baselines:
            old, w, c = timed(lambda m=margin: adaptive_volume(m, lo, hi, args.cells_step, args.cells_rtol,
                                                               progress=False))
            runs.append(("cells", old.estimate, old.error, w, c, old.points_evaluated))
            (cnt, n_cnt), w, c = timed(lambda m=margin: counting(m, lo, hi, args.counting_step))
            runs.append(("counting", cnt, np.full(len(cnt), math.nan), w, c, n_cnt))
        for name in targets:
            if name not in refs:
                continue
            V = refs[name]
            k = col[name]
            for method, est, err, wall, cpu, work in runs:
                # full-mode outputs have 9 columns (8 modes + union); "all" margins too
                reported = float(err[k] / V)
                rows.append(dict(limits=limits, target=name, method=method, volume=float(est[k]),
                                 true_rel=float(abs(est[k] - V) / V),
                                 reported_rel=reported if math.isfinite(reported) else None, seconds=wall,
                                 cpu_seconds=cpu, work=int(work), reference=V))
    machine.update(load_before=load0, load_after=os.getloadavg())
    if args.json:
        print(dump({"rows": rows, "machine": machine}))
        return
    print(machine_line(machine))
    print(f"load average {load0[0]:.2f} before, {machine['load_after'][0]:.2f} after (the mode rows share their "
          "union's run; work: columns for the column engine, margin evaluations otherwise)")
    print(f"{'limits':9} {'target':6} {'method':14} {'volume [m^3]':>14} {'true err':>9} {'reported':>9} "
          f"{'wall [s]':>8} {'cpu [s]':>8} {'work':>12}")
    for r in rows:
        reported = "" if r["reported_rel"] is None else f"{r['reported_rel']:9.1e}"
        print(f"{r['limits']:9} {r['target']:6} {r['method']:14} {r['volume']:14.10f} {r['true_rel']:9.1e} "
              f"{reported:>9} {r['seconds']:8.2f} {r['cpu_seconds']:8.2f} {r['work']:12,}")


if __name__ == "__main__":
    main()
