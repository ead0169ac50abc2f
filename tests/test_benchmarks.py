"""Every benchmark script still runs: each at its `--quick` size with `--json`, against this tree's code.

A script declares the top-level JSON keys it promises in `JSON_KEYS` (and, if its JSON holds lists
of rows, each row's keys in `ROW_KEYS`); every number in the output must be finite (strict JSON),
every rate (`*_per_s`) positive, and `machine` must hold `_timing.calibration()`'s figures. A new
`benchmarks/*.py` is covered without being listed here (helpers start with `_`).
"""

from __future__ import annotations

import ast
import importlib.util
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# report.py is not a benchmark: it runs them all and writes docs/benchmarks.md
SCRIPTS = sorted(p for p in (ROOT / "benchmarks").glob("*.py") if not p.name.startswith("_") and p.name != "report.py")
CALIBRATION = ("cores", "load_avg_1min", "calib_numba_loop_s", "calib_matmul_s")

_spec = importlib.util.spec_from_file_location("benchmarks_report", ROOT / "benchmarks" / "report.py")
assert _spec and _spec.loader
report = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(report)


def declared(script: Path, name: str) -> tuple[str, ...] | None:
    """The literal tuple a script assigns to `name` at module level (None if it does not)."""
    for node in ast.parse(script.read_text()).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    return None


def _strict(token: str) -> float:
    raise ValueError(f"{token} is not JSON")


def numbers(value: object, path: str = "") -> list[tuple[str, float]]:
    """Every number in a JSON value with its path (booleans are not numbers)."""
    if isinstance(value, dict):
        return [n for k, v in value.items() for n in numbers(v, f"{path}.{k}")]
    if isinstance(value, list):
        return [n for i, v in enumerate(value) for n in numbers(v, f"{path}[{i}]")]
    if isinstance(value, int | float) and not isinstance(value, bool):
        return [(path, float(value))]
    return []


def test_every_benchmark_declares_its_json_keys():
    assert len(SCRIPTS) >= 10, [p.name for p in SCRIPTS]
    for script in SCRIPTS:
        keys = declared(script, "JSON_KEYS")
        assert keys and "machine" in keys, f"{script.name}: JSON_KEYS must list its keys, machine among them"
        text = script.read_text()
        assert "--quick" in text or "parse(ap" in text, f"{script.name}: no --quick size"


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_benchmark_runs_at_quick_size(script, tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    run = subprocess.run([sys.executable, str(script), "--quick", "--json"], cwd=tmp_path, env=env,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout, parse_constant=_strict)
    if out.get("skipped"):  # a benchmark whose inputs are not on this machine says why (e.g. bench_models)
        pytest.skip(f"{script.name}: {out['skipped']}")

    keys = declared(script, "JSON_KEYS") or ()
    assert sorted(set(keys) - set(out)) == [], f"{script.name}: promised keys missing"
    row_keys = declared(script, "ROW_KEYS")
    if row_keys is not None:
        rows = [r for v in out.values() if isinstance(v, list) for r in v if isinstance(r, dict)]
        assert rows, f"{script.name}: ROW_KEYS declared but no rows"
        for r in rows:
            assert sorted(set(row_keys) - set(r)) == [], f"{script.name}: row {r} lacks promised keys"

    found = numbers(out)
    assert found, "no figures"
    bad = [(p, x) for p, x in found if not math.isfinite(x)]
    assert bad == [], f"{script.name}: not finite"
    rates = [(p, x) for p, x in found if p.endswith("_per_s")]
    assert all(x > 0 for _, x in rates), rates

    machine = out["machine"]
    assert sorted(set(CALIBRATION) - set(machine)) == []
    assert machine["cores"] >= 1 and machine["load_avg_1min"] >= 0
    assert machine["calib_numba_loop_s"] > 0 and machine["calib_matmul_s"] > 0

    if script.stem.startswith("bench_"):  # docs/benchmarks.md's rows read this output
        rows = report.HEADLINES[script.stem](out)
        assert rows and all(figure and value and "nan" not in value for figure, value in rows), rows


def test_report_has_headlines_for_every_benchmark():
    """A new bench_*.py without a row in docs/benchmarks.md fails here, not at the coordinator's run."""
    names = sorted(p.stem for p in (ROOT / "benchmarks").glob("bench_*.py"))
    assert len(names) >= 10
    assert sorted(set(names) - set(report.HEADLINES)) == []
    assert sorted(set(report.HEADLINES) - set(names)) == []


def test_report_marks_a_failed_benchmark(tmp_path):
    script = tmp_path / "bench_broken.py"
    script.write_text("import sys\nprint('warming up', file=sys.stderr)\n"
                      "raise SystemExit('bench_broken: the engine changed under me')\n")
    out = report.run(script, quick=True)
    assert out == {"failed": "bench_broken: the engine changed under me"}
    page = report.table({"bench_broken": out}, quick=False, date="2026-01-01 00:00 UTC")
    assert "| `bench_broken` | failed | bench_broken: the engine changed under me |" in page


def value_numbers(page: str, figure: str) -> list[float]:
    """The numbers in the value cell of the table row whose figure starts with `figure`."""
    row = next(ln for ln in page.splitlines() if ln.startswith("| `") and ln.split("|")[2].strip().startswith(figure))
    return [float(x) for x in re.findall(r"\d+(?:\.\d+)?(?:e[+-]?\d+)?", row.split("|")[3])]


@pytest.mark.slow
def test_report_writes_the_page_from_the_benchmarks(tmp_path):
    """report.py --quick on two quick benchmarks: the page says it is a smoke run, names the machine,
    carries each benchmark's figures from its own JSON, and --from-json rewrites the same table."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    page, saved = tmp_path / "benchmarks.md", tmp_path / "json"
    only = ["bench_guidance_step", "bench_scara_manipulability"]
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "report.py"), "--quick", "--only", *only,
                          "--save", str(saved), "-o", str(page)], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    text = page.read_text()
    assert "Smoke run" in text and "not measurements" in text
    assert f"on {os.cpu_count()} cores" in text
    assert "python benchmarks/report.py" in text
    guidance = json.loads((saved / "bench_guidance_step.json").read_text())
    step = next(r for r in guidance["rows"] if r["call"] == "step_closed_form")
    # three significant digits: a printed figure is within 5e-3 (half a unit of the third digit) of the JSON's
    assert value_numbers(text, "guidance step, closed forms") == pytest.approx([step["p50_us"], step["p99_us"]],
                                                                                rel=5e-3)
    scara = json.loads((saved / "bench_scara_manipulability.json").read_text())
    assert value_numbers(text, "SCARA manipulability, closed form, ") == pytest.approx([scara["closed_form_per_s"]],
                                                                                      rel=5e-3)
    table = [ln for ln in text.splitlines() if ln.startswith("| `bench_")]
    assert {ln.split("|")[1].strip() for ln in table} == {f"`{n}`" for n in only}
    assert all(ln.rstrip(" |").split("|")[-1].strip() for ln in table), "a row without its load"

    again = tmp_path / "again.md"
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "report.py"), "--only", *only,
                          "--from-json", str(saved), "-o", str(again)], cwd=tmp_path, env=env,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    assert [ln for ln in again.read_text().splitlines() if ln.startswith("|")] == \
        [ln for ln in text.splitlines() if ln.startswith("|")]
    assert "Smoke run" in again.read_text()
