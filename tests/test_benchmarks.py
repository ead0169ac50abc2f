"""Every benchmark script still runs: each at its `--quick` size with `--json`, against this tree's code.

A script declares the top-level JSON keys it promises in `JSON_KEYS` (and, if its JSON holds lists
of rows, each row's keys in `ROW_KEYS`); every number in the output must be finite (strict JSON),
every rate (`*_per_s`) positive, and `machine` must hold `_timing.calibration()`'s figures. A new
`benchmarks/*.py` is covered without being listed here (helpers start with `_`).
"""

from __future__ import annotations

import ast
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# report.py is not a benchmark: it runs them all and writes docs/benchmarks.md
SCRIPTS = sorted(p for p in (ROOT / "benchmarks").glob("*.py") if not p.name.startswith("_") and p.name != "report.py")
CALIBRATION = ("cores", "load_avg_1min", "calib_numba_loop_s", "calib_matmul_s")


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
