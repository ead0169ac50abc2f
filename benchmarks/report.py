"""Runs every benchmark and writes docs/benchmarks.md: one table of the headline figures, with the
machine (cores, CPU, load average, calibration) and the date at the top.

Run: python benchmarks/report.py [--quick] [--only NAME ...] [--save DIR] [--from-json DIR] [-o FILE]

Each `benchmarks/bench_*.py` runs in its own process, one after the other, as
`python benchmarks/NAME.py --json` (with `--quick`: at its smoke size, and the page says so in
its first lines: those figures only show that the scripts run). `--save DIR` keeps each
benchmark's JSON as DIR/NAME.json; `--from-json DIR` writes the page from such files without
running anything (DIR/_report.json records whether they were quick). A benchmark that fails is a row saying so (its last stderr line) and the exit
status is 1. HEADLINES says which figures of each benchmark's JSON make the table; a benchmark
without an entry fails the report (tests/test_benchmarks.py checks every script has one).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = ROOT / "docs" / "benchmarks.md"
Row = tuple[str, str]


def num(x: float, digits: int = 3) -> str:
    """`digits` significant digits, large and small numbers as 1.23e6 (no "+", no leading zeros)."""
    text = f"{x:.{digits}g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


def rate(x: float, unit: str = "points/s") -> str:
    return f"{num(x)} {unit}"


def sec(x: float) -> str:
    return f"{num(x)} s"


def _batched_fk(o: dict[str, Any]) -> list[Row]:
    return [(f"{o['robot']} tool poses, compiled, {o['threads']} threads", rate(o["compiled_fk_per_s"], "configurations/s")),
            (f"{o['robot']} tool poses, compiled, 1 thread (per wall / CPU second)",
             (f"{rate(o['compiled_fk_1thread_per_s'], 'configurations/s')} / "
             f"{rate(o['compiled_fk_1thread_cpu_time_per_s'], 'configurations/s')}")),
            (f"{o['robot']} tool Jacobians, compiled", rate(o["compiled_jacobian_per_s"], "configurations/s")),
            (f"{o['robot']} tool poses, Pinocchio loop", (f"{rate(o['pinocchio_loop_fk_per_s'], 'configurations/s')} "
             f"(compiled: {num(o['ratio'], 2)} x; largest difference {num(o['max_abs_difference'], 1)})"))]


def _scara(o: dict[str, Any]) -> list[Row]:
    return [(f"SCARA manipulability, closed form, {o['threads']} threads", rate(o["closed_form_per_s"], "configurations/s")),
            ("SCARA manipulability, closed form, 1 thread", rate(o["closed_form_1thread_per_s"], "configurations/s")),
            ("SCARA manipulability, Pinocchio loop", (f"{rate(o['pinocchio_loop_per_s'], 'configurations/s')} "
             f"(closed form: {num(o['ratio'], 2)} x)"))]


def _p2us_kinematics(o: dict[str, Any]) -> list[Row]:
    return [("3-[P2(US)] IK, 8 modes + limits, closed form", rate(o["closed_form_ik_points_per_s"])),
            ("3-[P2(US)] FK, both assembly modes, closed form", rate(o["closed_form_fk_points_per_s"])),
            ("3-[P2(US)] Pinocchio closed-loop solve, per point (cold / warm)",
             f"{rate(o['closed_loop_solve_cold_points_per_s'])} / {rate(o['closed_loop_solve_warm_points_per_s'])}")]


def _p2us_scan(o: dict[str, Any]) -> list[Row]:
    c, cells = o["columns"], o["cells"]
    return [(f"3-[P2(US)] fused scan, chunked grid, {o['threads']} threads", rate(o["full_scan_points_per_s"])),
            ("3-[P2(US)] scan kernel, 1 thread", rate(o["kernel_1_thread_per_s"])),
            ("3-[P2(US)] per-point Pinocchio evaluation", (f"{rate(o['pinocchio_per_point_points_per_s'])} "
             f"(fused scan: {num(o['ratio_full_scan_to_pinocchio'], 2)} x)")),
            (f"3-[P2(US)] volume, columns, rtol {c['rtol']:g}", (f"{num(c['volume_m3'], 6)} m^3 +/- {num(c['error_estimate'], 1)} "
             f"in {sec(c['seconds'])} (true error {num(c['true_rel_error'], 1)} relative)")),
            (f"3-[P2(US)] volume, adaptive cells, rtol {cells['rtol']:g}", (f"{sec(cells['seconds'])} "
             f"(true error {num(cells['true_rel_error'], 1)} relative)"))]


def _volume(o: dict[str, Any]) -> list[Row]:
    limits = {"all": "every limit", "actuators": "strokes only"}
    return [(f"3-[P2(US)] volume, {limits.get(r['limits'], r['limits'])}, {r['target']}, {r['method']}",
             f"{sec(r['seconds'])} (true error {num(r['true_rel'], 1)} relative)")
            for r in o["rows"] if r["target"] == "union"]


def _delta(o: dict[str, Any]) -> list[Row]:
    rows = [(f"Delta scan kernel, {o['threads']} threads / 1 thread",
             f"{rate(o['kernel_all_threads_per_s'])} / {rate(o['kernel_1_thread_per_s'])}"),
            ("Delta margins, NumPy closed forms", rate(o["numpy_closed_forms_per_s"]))]
    if o.get("volume_m3") is not None:
        rows.append(("Delta volume (`workspace-volume delta`)", (f"{num(o['volume_m3'], 5)} m^3 +/- {num(o['error_estimate'], 1)} "
                     f"in {sec(o['volume_seconds'])}")))
    return rows


def _guidance(o: dict[str, Any]) -> list[Row]:
    names = {"step_closed_form": "guidance step, closed forms", "step_generic_pinocchio": "guidance step, generic Pinocchio"}
    return [(f"{names[r['call']]} (p50 / p99)", f"{num(r['p50_us'])} / {num(r['p99_us'])} us")
            for r in o["rows"] if r["call"] in names]


def _loop_batch(o: dict[str, Any]) -> list[Row]:
    return [("3-[P2(US)] generic batched loop solver, 8 branches (cold / columns / warm)",
             " / ".join(rate(o[f"generic_{k}_points_per_s"]) for k in ("cold", "columns", "warm"))),
            ("3-[P2(US)] per-point Pinocchio solver, 8 modes", rate(o["per_point_solver_points_per_s"])),
            ("3-[P2(US)] closed forms, scan kernel", rate(o["closed_form_scan_kernel_points_per_s"]))]


def _serial_workspace(o: dict[str, Any]) -> list[Row]:
    unit = {"m2": "m^2", "m3": "m^3"}
    return [(f"serial workspace, {r['robot']} (rtol {r['rtol']:g})",
             (f"{num(r['volume'], 6)} {unit.get(r['unit'], r['unit'])} +/- {num(r['error_estimate'], 1)}"
              + ("" if r["true_error"] is None else f" (true error {num(r['true_error'], 1)})")
              + f" in {sec(r['seconds'])}" + ("" if r["converged"] else ", not converged")))
            for r in o["results"]]


def _serial_singular(o: dict[str, Any]) -> list[Row]:
    return [(f"`singularities {r['robot']}` scan ({r['mode']}, budget {o['max_points']:,})",
             (f"{sec(r['seconds'])}, {r['singular_boxes']:,} possibly singular boxes, {r['unsplit_boxes']:,} left "
              f"unsplit (ball up to {num(r['unsplit_radius_m'], 2)} m)")) for r in o["rows"]]


def _models(o: dict[str, Any]) -> list[Row]:
    if o.get("skipped"):
        return [("Gepetto models, every command", f"skipped: {o['skipped']}")]
    ok = sum(r["status"] == "ok" for r in o["rows"])
    total = sum(r["seconds"] for r in o["rows"])
    return [("Gepetto models, every command ([models](models.md))", f"{ok} of {len(o['rows'])} ok, {sec(total)} in all")]


def _collisions(o: dict[str, Any]) -> list[Row]:
    return [(f"{r['robot']} volume with collisions ({len(r['modes'])} modes, rtol {r['rtol']:g})",
             (f"{num(r['collision_volume'], 5)} m^3 (kinematic {num(r['kinematic_volume'], 5)}) in "
              f"{sec(r['collision_seconds'])}, {num(r['time_ratio'], 2)} x the kinematic run")) for r in o["rows"]]


def _serial_collisions(o: dict[str, Any]) -> list[Row]:
    return [((f"{r['robot']} volume with self-collisions (rtol {r['rtol']:g}, step {r['step']:g} m, turn "
              f"{r['turn']}: {r['route']}, search {r['search']['mode']}; wall / CPU)"),
             (f"{num(r['collision_volume'], 4)} +/- {num(r['collision_error'], 2)} m^3 (kinematic "
              f"{num(r['kinematic_volume'], 4)}) in {sec(r['collision_seconds'])} / {sec(r['collision_cpu_seconds'])} "
              f"CPU, {num(r['time_ratio'], 2)} x the kinematic run")) for r in o["rows"]]


def _cli(o: dict[str, Any]) -> list[Row]:
    return [(f"`{r['command']}` (best of {o['repeats']}, wall / volume)",
             "failed" if r["wall_s"] is None else
             f"{sec(r['wall_s'])} / {sec(r['volume_s'])}: {num(r['volume'], 6)} +/- {num(r['error_estimate'], 1)}")
            for r in o["rows"]]


HEADLINES: dict[str, Callable[[dict[str, Any]], list[Row]]] = {
    "bench_cli": _cli,
    "bench_collisions": _collisions,
    "bench_serial_collisions": _serial_collisions,
    "bench_batched_fk": _batched_fk,
    "bench_scara_manipulability": _scara,
    "bench_p2us_kinematics": _p2us_kinematics,
    "bench_p2us_scan": _p2us_scan,
    "bench_volume": _volume,
    "bench_delta_scan": _delta,
    "bench_loop_batch": _loop_batch,
    "bench_guidance_step": _guidance,
    "bench_serial_workspace": _serial_workspace,
    "bench_serial_singular": _serial_singular,
    "bench_models": _models,
}


def scripts() -> list[Path]:
    return sorted((ROOT / "benchmarks").glob("bench_*.py"))


def run(script: Path, quick: bool) -> dict[str, Any]:
    """One benchmark's JSON, or {"failed": its last stderr line}."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    argv = [sys.executable, str(script), "--json", *(["--quick"] if quick else [])]
    with tempfile.TemporaryDirectory() as tmp:
        done = subprocess.run(argv, cwd=tmp, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines() or [f"exit status {done.returncode}"]
        return {"failed": lines[-1]}
    try:
        out: dict[str, Any] = json.loads(done.stdout)
    except json.JSONDecodeError as e:
        return {"failed": f"output is not JSON ({e})"}
    return out


def table(results: dict[str, dict[str, Any]], quick: bool, date: str) -> str:
    """docs/benchmarks.md from each benchmark's JSON (keyed by script name)."""
    machines = [o["machine"] for o in results.values() if "machine" in o]
    lines = ["# Benchmarks", ""]
    if quick:
        lines += [("**Smoke run at the benchmarks' `--quick` sizes: these figures only show that every script runs; "
                  "they are not measurements. Regenerate at full size (below) for the current figures.**"), ""]
    if machines:
        loads = [m["load_avg_1min"] for m in machines]
        loop = statistics.median(m["calib_numba_loop_s"] for m in machines)
        matmul = statistics.median(m["calib_matmul_s"] for m in machines)
        lines += [(f"Measured {date} on {machines[0]['cores']} cores ({machines[0].get('cpu') or 'CPU unknown'}); "
                  f"load average (1 min) {min(loads):.2f} to {max(loads):.2f} at the benchmarks' starts; calibration "
                  f"(median over the benchmarks, see `benchmarks/_timing.py`): compiled loop {loop * 1e3:.1f} ms, "
                  f"500 x 500 matmul {matmul * 1e3:.2f} ms."), ""]
    lines += [("Regenerate: `python benchmarks/report.py` (every `benchmarks/bench_*.py` with `--json`, one after "
              "the other, on an otherwise idle machine). Each script's own "
              "`--help` says what it measures; its `--json` output has every figure."), "",
              "| benchmark | figure | value | load |", "|---|---|---|---|"]
    for name, out in results.items():
        load = f"{out['machine']['load_avg_1min']:.2f}" if "machine" in out else ""
        if "failed" in out:
            rows: list[Row] = [("failed", str(out["failed"]).replace("|", "\\|"))]
        else:
            rows = HEADLINES[name](out)
        for figure, value in rows:
            lines.append(f"| `{name}` | {figure} | {value} | {load} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="each benchmark at its smoke size (the page says so)")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="these benchmarks only (e.g. bench_volume)")
    ap.add_argument("--save", type=Path, metavar="DIR", help="keep each benchmark's JSON as DIR/NAME.json")
    ap.add_argument("--from-json", type=Path, metavar="DIR", help="write the page from DIR/NAME.json, run nothing")
    ap.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT, help="the page (default docs/benchmarks.md)")
    args = ap.parse_args()

    names = [p.stem for p in scripts() if not args.only or p.stem in args.only]
    missing = [n for n in names if n not in HEADLINES]
    if missing:
        print(f"report.py: no HEADLINES entry for {', '.join(missing)}", file=sys.stderr)
        return 2
    results: dict[str, dict[str, Any]] = {}
    quick = args.quick
    if args.from_json and (args.from_json / "_report.json").exists():
        quick = quick or json.loads((args.from_json / "_report.json").read_text())["quick"]
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
        (args.save / "_report.json").write_text(json.dumps({"quick": args.quick}))
    for name in names:
        if args.from_json:
            results[name] = json.loads((args.from_json / f"{name}.json").read_text())
            continue
        print(f"{name} ...", file=sys.stderr, flush=True)
        results[name] = run(ROOT / "benchmarks" / f"{name}.py", args.quick)
        if args.save:
            (args.save / f"{name}.json").write_text(json.dumps(results[name], indent=2))
    when = datetime.datetime.now(datetime.timezone.utc)
    if args.from_json:  # when the saved runs ended, not when the page was rewritten
        newest = max((args.from_json / f"{n}.json").stat().st_mtime for n in names)
        when = datetime.datetime.fromtimestamp(newest, datetime.timezone.utc)
    date = when.strftime("%Y-%m-%d %H:%M UTC")
    text = table(results, quick, date)
    tmp = args.out.with_name(f".{args.out.name}.tmp")
    tmp.write_text(text)
    tmp.replace(args.out)  # atomic: a reader never sees half a page
    print(f"wrote {args.out}", file=sys.stderr)
    return 1 if any("failed" in o for o in results.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
