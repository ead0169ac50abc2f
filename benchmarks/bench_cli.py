"""Wall time of whole `kinematics workspace-volume` commands (issue 31's table), each run as a
subprocess, so the figure includes the process start, the imports, Numba's kernel cache loading,
the singular-locus scan and the reports, beside the volume's own share (`volume_seconds` of the
command's JSON) and the process's CPU seconds (user + system, every thread: less sensitive to
other load than the wall time).

Rows (ROWS; `--rows` picks some):
* p2us: `kinematics workspace-volume p2us` (every limit; goal <= 1.5 s wall);
* p2us-actuators: the same with `--limits actuators` (goal <= 2 s);
* delta: `kinematics workspace-volume delta` (goal <= 2 s);
* delta-actuators: `... delta --limits actuators --rtol 1e-3` (goal <= 5 s);
* fivebar: the Gepetto five-bar through the generic closed-loop path, actuator ranges +/-pi,
  rtol 1e-3 (goal <= 10 s; minutes today). Skipped (its row says why) when the model is absent.

Each row is the best of `--repeats` runs (default 3; the first run after a change also compiles
the kernels: run once before timing). Keys per row: ROW_KEYS (`volume` in m^3, or m^2 for a
planar task space). `--quick`: p2us and delta at a coarse step and tolerance, one run each, for
tests/test_benchmarks.py (the figures mean little).

Run: python benchmarks/bench_cli.py [--rows p2us delta ...] [--repeats 3] [--fivebar DIR] [--quick] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from typing import Any

from _timing import calibration, dump, machine_line, parse

JSON_KEYS = ("rows", "repeats", "machine")
ROW_KEYS = ("row", "command", "wall_s", "cpu_s", "volume_s", "volume", "error_estimate")
FIVEBAR = "/work/shared/models/gepetto/5bar_linkage"
PI = "3.141592653589793"
ROWS: dict[str, list[str]] = {
    "p2us": ["p2us"],
    "p2us-actuators": ["p2us", "--limits", "actuators"],
    "delta": ["delta"],
    "delta-actuators": ["delta", "--limits", "actuators", "--rtol", "1e-3"],
    "fivebar": ["{fivebar}", "--range", f"mot1=-{PI}:{PI}", "--range", f"mot2=-{PI}:{PI}", "--rtol", "1e-3"],
}
QUICK_ARGS = ["--step", "0.05", "--rtol", "0.05"]


def run_row(name: str, args: list[str], repeats: int) -> dict[str, Any]:
    """Best of `repeats` runs of `kinematics workspace-volume ARGS --json` (a row of the table)."""
    argv = [sys.executable, "-m", "kinematics", "workspace-volume", *args, "--json"]
    best: dict[str, Any] | None = None
    for _ in range(repeats):
        t = time.perf_counter()
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        run = subprocess.run(argv, check=False, capture_output=True, text=True,
                             env={**os.environ, "TQDM_DISABLE": "1"})
        wall = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if run.returncode != 0:
            raise SystemExit(f"{' '.join(argv)} failed ({run.returncode}): {run.stderr[-2000:]}")
        out = json.loads(run.stdout)
        if best is None or wall < best["wall_s"]:
            best = {"row": name, "command": "kinematics workspace-volume " + " ".join(args), "wall_s": wall, "cpu_s": cpu,
                    "volume_s": out["volume_seconds"], "volume": out.get("volume_m3", out.get("area_m2")),
                    "error_estimate": out["error_estimate"], "converged": out["converged"]}
    assert best is not None
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", nargs="+", choices=list(ROWS), default=list(ROWS))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--fivebar", default=FIVEBAR, help="the Gepetto 5bar_linkage directory")
    ap.add_argument("--json", action="store_true")
    a = parse(ap, {"rows": ["p2us", "delta"], "repeats": 1})
    machine = calibration()
    rows = []
    for name in a.rows:
        args = [x.format(fivebar=a.fivebar) for x in ROWS[name]] + (QUICK_ARGS if a.quick else [])
        if name == "fivebar" and not os.path.isdir(a.fivebar):
            rows.append({"row": name, "command": "kinematics workspace-volume " + " ".join(args), "wall_s": None,
                         "cpu_s": None,
                         "volume_s": None, "volume": None, "error_estimate": None,
                         "skipped": f"no model at {a.fivebar}"})
            continue
        rows.append(run_row(name, args, a.repeats))
    out = {"rows": rows, "repeats": a.repeats, "machine": machine}
    if a.json:
        print(dump(out))
        return
    for r in rows:
        if r.get("skipped"):
            print(f"{r['row']:16s} skipped: {r['skipped']}")
        else:
            print(f"{r['row']:16s} {r['wall_s']:7.2f} s wall, {r['cpu_s']:.2f} s CPU (volume {r['volume_s']:.2f} s)  "
                  f"{r['volume']:.6g} +/- {r['error_estimate']:.2g}  [{r['command']}]")
    print(machine_line(machine))


if __name__ == "__main__":
    main()
