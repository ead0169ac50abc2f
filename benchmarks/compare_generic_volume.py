"""The 3-[P2(US)]'s workspace volume through the generic closed-loop path (the batched solver's
margin, `kinematics.generic.loop_batch`, no closed forms) against the closed-form engine, with the
same column engine and settings, per working mode and for the union, in one run.

The generic branches are matched to the closed-form modes by their actuator values at two
reachable points (a fixed bijection, as tests/test_loop_batch.py checks). Sampled columns are used
for both (the closed form's exact columns are switched off), so the two integrate the same kind
of estimate; the difference must lie within the sum of the two error estimates.

Two cheaper forms, for the strokes-only limits (whose 8 per-mode volumes at step 0.02 m and rtol
1e-2 ask for ~5e7 margin evaluations, a quarter of an hour or more through the generic path):
* --union-only: the union's volume alone (every branch is still solved at every point; only the
  engine's refinement is driven by the union: ~2e6 evaluations);
* --slice Y: per-mode and union areas of the plane y = Y [m] (a 2D column integration).

Timed: each path's column integration alone; the set-up (the atlas search, the branch matching, a
first margin call that compiles the kernels on the first run after a change) is reported apart as
setup_seconds.

Run: python benchmarks/compare_generic_volume.py [--step 0.02] [--rtol 1e-2] [--limits all]
[--union-only | --slice Y] [--quick] [--json]
(minutes to hours: the generic margin runs at ~5·10^4 points/s in the column engine's call pattern;
--quick: seconds, the plane y = 0 at a coarse step and tolerance). The JSON holds JSON_KEYS, `rows`
one per mode and the union (ROW_KEYS); `machine` is `_timing.calibration()`.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from _timing import calibration, dump, machine_line, parse

from kinematics.analyses.columns import column_volume
from kinematics.generic.loop_batch import LoopBatch
from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.mechanism import p2us_margin
from kinematics.mechanisms.p2us.scan import bounding_box
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

JSON_KEYS = ("step_m", "rtol", "limits", "slice_y_m", "union_only", "measure", "rows", "closed_form", "generic",
             "setup_seconds", "cores", "load_average_start", "load_average_end", "machine")
ROW_KEYS = ("mode", "closed_form_m3", "closed_error", "generic_m3", "generic_error", "difference", "within_estimates")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=0.02)
    ap.add_argument("--rtol", type=float, default=1e-2)
    ap.add_argument("--limits", default="all", choices=["all", "actuators"])
    ap.add_argument("--union-only", action="store_true", help="measure the union only")
    ap.add_argument("--slice", type=float, default=None, metavar="Y",
                    help="per-mode areas of the plane y = Y [m] instead of volumes")
    ap.add_argument("--json", action="store_true")
    a = parse(ap, {"step": 0.1, "rtol": 0.5, "slice": 0.0})
    machine = calibration()
    robot = load_robot("p2us")
    P = read_params(robot.urdf_path)
    lo, hi = bounding_box(P)
    load0 = os.getloadavg()
    if a.slice is not None:  # the plane y = Y: (x, z) -> (x, Y, z)
        y0 = a.slice
        lo, hi = lo[[0, 2]], hi[[0, 2]]
        lift = lambda q: np.c_[q[:, 0], np.full(len(q), y0), q[:, 1]]  # noqa: E731
    else:
        lift = lambda q: q  # noqa: E731
    pick = (lambda v: v[:, -1:]) if a.union_only else (lambda v: v)

    # set-up apart from the timed measurements: the atlas search, the branch matching, and a first
    # call of each margin (which compiles its kernels on the first run after a change: 50-100 s)
    t = time.perf_counter()
    closed_3d = p2us_margin(P, par.MODES, a.limits).sampled()
    lb = LoopBatch.from_robot(robot, seeds=256)
    pts = np.array([[0.0, 0.0, -0.45], [0.05, 0.03, -0.5]])
    ik = par.ik(P, pts, limits=False)
    gq = lb.ik(pts, warm=False).x[..., lb.actuated]  # (2, B, 3)
    d = np.abs(gq[:, :, None, :] - ik.q[:, None, :, :]).max(axis=-1)  # (2, B, 8)
    mapping = np.argmin(d, axis=2)
    if not np.array_equal(mapping[0], mapping[1]) or len(set(mapping[0])) != len(mapping[0]):
        raise SystemExit(f"generic branches do not map one-to-one onto the closed-form modes: {mapping}")
    closed_3d(pts)
    lb.margin(pts, a.limits)
    lb.forget()
    t_setup = time.perf_counter() - t

    t = time.perf_counter()
    ref = column_volume(lambda q: pick(closed_3d(lift(q))), lo, hi, step=a.step, rtol=a.rtol)
    t_closed = time.perf_counter() - t

    t = time.perf_counter()
    gen = column_volume(lambda q: pick(lb.margin(lift(q), a.limits)), lo, hi, step=a.step, rtol=a.rtol)
    t_generic = time.perf_counter() - t

    rows = []
    for b, m in ([] if a.union_only else enumerate(mapping[0])):
        rows.append({"mode": par.MODES[m], "closed_form_m3": float(ref.estimate[m]), "closed_error": float(ref.error[m]),
                     "generic_m3": float(gen.estimate[b]), "generic_error": float(gen.error[b])})
    rows.append({"mode": "union", "closed_form_m3": float(ref.estimate[-1]), "closed_error": float(ref.error[-1]),
                 "generic_m3": float(gen.estimate[-1]), "generic_error": float(gen.error[-1])})
    for r in rows:
        r["difference"] = r["generic_m3"] - r["closed_form_m3"]
        r["within_estimates"] = abs(r["difference"]) <= r["closed_error"] + r["generic_error"]
    out = {"step_m": a.step, "rtol": a.rtol, "limits": a.limits, "slice_y_m": a.slice, "union_only": a.union_only,
           "measure": "area_m2" if a.slice is not None else "volume_m3", "rows": rows,
           "closed_form": {"seconds": t_closed, "points": ref.points_evaluated, "converged": ref.converged},
           "generic": {"seconds": t_generic, "points": gen.points_evaluated, "converged": gen.converged,
                       "points_per_s": gen.points_evaluated / t_generic},
           "setup_seconds": t_setup,
           "cores": os.cpu_count(), "load_average_start": list(load0), "load_average_end": list(os.getloadavg()), "machine": machine}
    if a.json:
        print(dump(out))
        return
    unit = "m^2" if a.slice is not None else "m^3"
    print(f"{'mode':6s} {f'closed form [{unit}]':>20s} {f'generic [{unit}]':>20s} {'difference':>12s}  within")
    for r in rows:
        print(f"{r['mode']:6s} {r['closed_form_m3']:.6f} ± {r['closed_error']:.1e} {r['generic_m3']:.6f} ± "
              f"{r['generic_error']:.1e} {r['difference']:+.2e}  {r['within_estimates']}")
    print(json.dumps({k: v for k, v in out.items() if k not in ("rows", "machine")}, indent=1))
    print(machine_line(machine))


if __name__ == "__main__":
    main()
