"""Every command on every Gepetto model folder, as a user runs them: status, time and figures.

Run: python benchmarks/bench_models.py [--models DIR] [--only NAME ...] [--timeout S] [--jobs N]
                                        [--rtol R] [--quick] [--json | --markdown] [--from-json FILE]

Each (model, command) is one subprocess, `python -m kinematics COMMAND MODEL ... --json`, against
this tree's code, with a time limit (the whole process group is killed at the limit). Commands:
`info`, `fk`, `jacobian`, `mobility` (no --q: each closed loop at its default closed pose),
`workspace-volume --rtol 1e-2` (`--rtol`: another; the command's default is 1e-3) with `--range JOINT=-pi:pi` for every actuator (an open tree: every
joint the URDF gives no range), and `show --export` to a temporary HTML file. `--quick` is a smoke
run: info, fk and mobility only on QUICK_MODELS (those of them in the folder, else its first three),
30 s limit, two at a time.

A row per (model, command), ROW_KEYS: `status` from the exit code (0 ok, 1 unreachable, 2 error,
the time limit: timeout; a traceback or any other code: crash), `seconds` (wall time of the
subprocess, interpreter start included), `value` / `error_estimate` (the area [m^2] or volume
[m^3] of `workspace-volume`, else null), `figure` (a short reading of the command's JSON: the
mobility, the end-effector position, the Jacobian's shape and rank, the file size), and `error`
(stderr's first line, for anything but ok). The JSON holds JSON_KEYS; `machine` is
`_timing.calibration()` at the start, plus the load average at the end. `--markdown` prints the
table of docs/models.md (from this run, or from a saved `--json` output with --from-json).

Without the models folder (default ../shared/models/gepetto beside the repository) the run is skipped: a reason on
stderr and, with --json, `skipped` set and no rows.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from _timing import calibration, dump, machine_line, parse

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
MODELS = Path(__file__).resolve().parents[2] / "shared" / "models" / "gepetto"
COMMANDS = ("info", "fk", "jacobian", "mobility", "workspace-volume", "show")
QUICK_COMMANDS = ("info", "fk", "mobility")
QUICK_MODELS = ("5bar_linkage", "robot_delta", "cassie_like")
"""`--quick`'s models: a planar five-bar, a planar Delta, a leg with more motors than position coordinates."""
RTOL = 1e-2
JSON_KEYS = ("machine", "models_dir", "commands", "timeout_s", "jobs", "quick", "rtol", "skipped", "rows")
ROW_KEYS = ("model", "command", "status", "seconds", "value", "error_estimate", "figure", "error")
STATUS = {0: "ok", 1: "unreachable", 2: "error"}


def model_folders(root: Path) -> list[str]:
    """Every folder under root that holds a URDF, as a path relative to root (sorted)."""
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_dir() and any(p.glob("*.urdf")))


def unbounded_actuators(folder: Path) -> list[str]:
    """The joints a workspace is given -pi:pi for: every actuator of a closed loop, every joint the
    URDF gives no range of an open tree; none when the model does not load (the command says why)."""
    from kinematics.errors import KinematicsError
    from kinematics.model.robot import load_robot

    try:
        robot = load_robot(folder)
    except KinematicsError:
        return []
    return list(robot.loops.actuated) if robot.loops is not None else list(robot.unranged)


def argv_of(command: str, folder: Path, tmp: Path, rtol: float = RTOL) -> list[str]:
    """The command line after `python -m kinematics`."""
    argv = [command, str(folder), "--json"]
    if command == "workspace-volume":
        argv += ["--rtol", repr(rtol)]
        for joint in unbounded_actuators(folder):
            argv += ["--range", f"{joint}={-math.pi!r}:{math.pi!r}"]
    elif command == "show":
        argv += ["--export", str(tmp / f"{str(folder).replace('/', '_')}.html")]
    return argv


def _run(argv: list[str], timeout: float) -> tuple[int | None, str, str, float]:
    """(exit code or None at the time limit, stdout, stderr, seconds): the whole process group is
    killed at the limit (nothing is left running)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    t = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "kinematics", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        code: int | None = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        code = None
    return code, out, err, time.perf_counter() - t


def _number(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) else None


def figure(command: str, data: dict[str, Any], export: Path | None) -> str | None:
    """A short reading of a command's JSON for the table."""
    if command == "info":
        g = data.get("grubler_mobility")
        if data.get("mobility") is None:
            return None if g is None else f"Grübler {g} (no closed pose)"
        return f"mobility {data['mobility']}" + ("" if g is None else f" (Grübler {g})")
    if command == "fk":
        pos = data.get("position")
        if pos is None and data.get("solutions"):
            pos = data["solutions"][0]["position"]
        return None if pos is None else "(" + ", ".join(f"{x:.3f}" for x in pos) + ") m"
    if command == "jacobian":
        import numpy as np

        J = np.array(data.get("jacobian") or data.get("J") or [], dtype=float)
        if J.ndim != 2:
            return None
        return f"{J.shape[0]}x{J.shape[1]}, rank {int(np.linalg.matrix_rank(J))}"
    if command == "mobility":
        n = data.get("numeric", {})
        return None if "mobility" not in n else f"{n['mobility']} ({n.get('platform_freedoms')} at the end effector)"
    if command == "show" and export is not None and export.exists():
        return f"{export.stat().st_size / 1e6:.1f} MB"
    return None


def measure(command: str, argv: list[str], model: str, timeout: float) -> dict[str, Any]:
    code, out, err, seconds = _run(argv, timeout)
    if code is None:
        status = "timeout"
    elif "Traceback (most recent call last)" in err or code not in STATUS:
        status = "crash"
    else:
        status = STATUS[code]
    data: dict[str, Any] = {}
    if status in ("ok", "unreachable"):
        try:
            data = json.loads(out)
        except json.JSONDecodeError:
            status = "crash"
    value = error_estimate = None
    if command == "workspace-volume" and status == "ok":
        value = _number(data.get("volume_m3", data.get("area_m2")))
        error_estimate = _number(data.get("error_estimate"))
    if value is not None:
        unit = "m^3" if "volume_m3" in data else "m^2"
        fig: str | None = f"{value:.4g} ± {error_estimate or 0:.2g} {unit}"
    else:
        export = Path(argv[argv.index("--export") + 1]) if "--export" in argv else None
        fig = figure(command, data, export) if data else None
    lines = [ln for ln in err.splitlines() if ln.strip()]
    first = (lines[-1] if status == "crash" and lines else lines[0] if lines else None)
    if status == "timeout":
        first = f"no answer within {timeout:g} s"
    return {"model": model, "command": command, "status": status, "seconds": seconds, "value": value,
            "error_estimate": error_estimate, "figure": fig, "error": None if status == "ok" else first}


def markdown(result: dict[str, Any]) -> str:
    """The table of docs/models.md: a row per model, a column per command; each cell the status,
    the figure and the seconds."""
    rows = result["rows"]
    commands = [c for c in result["commands"] if any(r["command"] == c for r in rows)]
    models = list(dict.fromkeys(r["model"] for r in rows))
    cell = {(r["model"], r["command"]): r for r in rows}
    out = ["| model | " + " | ".join(f"`{c}`" for c in commands) + " |", "|---" * (len(commands) + 1) + "|"]
    for m in models:
        cells = []
        for c in commands:
            r = cell.get((m, c))
            if r is None:
                cells.append("")
                continue
            fig = f" {r['figure']}" if r["status"] == "ok" and r["figure"] else ""
            cells.append(f"{r['status']}{fig}, {r['seconds']:.1f} s".replace("|", "\\|"))
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    m = result["machine"]
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    out += ["", ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + f" of {len(rows)} runs; "
            f"workspace-volume at rtol {result.get('rtol', RTOL):g}; time limit "
            f"{result['timeout_s']:g} s per run, {result['jobs']} at a time; " + machine_line(m)
            + (f"; load average at the end {m['load_average_end'][0]:.2f}" if "load_average_end" in m else "")]
    return "\n".join(out)


def text(result: dict[str, Any]) -> str:
    lines = []
    for r in result["rows"]:
        what = r["figure"] if r["status"] == "ok" else r["error"]
        lines.append(f"{r['model']:>22} {r['command']:<17} {r['status']:<11} {r['seconds']:7.2f} s  {what or ''}")
    lines.append(f"  {machine_line(result['machine'])}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=Path, default=MODELS, help=f"the model folders' root (default {MODELS})")
    ap.add_argument("--only", nargs="+", metavar="MODEL", help="these model folders only (relative names)")
    ap.add_argument("--commands", nargs="+", choices=COMMANDS, default=list(COMMANDS), help="commands to run")
    ap.add_argument("--timeout", type=float, default=120.0, help="time limit per command [s] (default 120)")
    ap.add_argument("--jobs", type=int, default=1, help="commands run at a time (default 1: undisturbed timings)")
    ap.add_argument("--rtol", type=float, default=RTOL, help=f"workspace-volume's --rtol (default {RTOL:g})")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    ap.add_argument("--markdown", action="store_true", help="print docs/models.md's table")
    ap.add_argument("--from-json", type=Path, metavar="FILE", help="with --markdown: the table of a saved --json run")
    args = parse(ap, {"commands": list(QUICK_COMMANDS), "timeout": 30.0, "jobs": 2})
    if args.from_json is not None:
        print(markdown(json.loads(args.from_json.read_text())))
        return
    machine = calibration()
    result: dict[str, Any] = {"machine": machine, "models_dir": str(args.models), "commands": list(args.commands),
                              "timeout_s": args.timeout, "jobs": args.jobs, "quick": bool(args.quick), "rtol": args.rtol,
                              "skipped": None, "rows": []}
    if not args.models.is_dir():
        result["skipped"] = f"no model folders at {args.models} (give --models DIR)"
        print(f"bench_models: skipped: {result['skipped']}", file=sys.stderr)
        if args.json:
            print(dump(result))
        return
    models = model_folders(args.models)
    if args.only:
        unknown = sorted(set(args.only) - set(models))
        if unknown:
            ap.error(f"no such model folder(s) under {args.models}: {', '.join(unknown)}")
        models = [m for m in models if m in set(args.only)]
    elif args.quick:  # the smoke run: three models (tests/test_models_commands.py runs its commands on every one)
        models = [m for m in models if m in QUICK_MODELS] or models[:len(QUICK_MODELS)]
    with tempfile.TemporaryDirectory(prefix="bench_models_") as tmp:
        jobs = [(c, argv_of(c, args.models / m, Path(tmp), args.rtol), m) for m in models for c in args.commands]
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            result["rows"] = list(pool.map(lambda j: measure(*j, args.timeout), jobs))
    machine["load_average_end"] = list(os.getloadavg())
    if args.json:
        print(dump(result))
    elif args.markdown:
        print(markdown(result))
    else:
        print(text(result))


if __name__ == "__main__":
    main()
