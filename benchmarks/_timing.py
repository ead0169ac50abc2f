"""Helpers shared by the benchmark scripts (run as `python benchmarks/NAME.py`): best-of timing and
the machine's calibration.

Every benchmark records `calibration()` under the JSON key `machine` (and prints `machine_line`):
the cores, the load average when it started, and the time of two fixed workloads that do not
depend on this project, so figures measured on different machines (or on one machine under
different loads) can be scaled by them:

* calib_numba_loop_s: a compiled (Numba) loop of CALIB_LOOP steps of the logistic map, each step
  depending on the last (one core, no vectorisation);
* calib_matmul_s: a CALIB_MATMUL x CALIB_MATMUL float64 matrix product through NumPy's BLAS (as
  many threads as BLAS uses; a busy core delays single products several-fold, hence more repeats).

Each is the best of its repeats (CALIB_LOOP_REPEATS, CALIB_MATMUL_REPEATS); the whole calibration costs ~0.4 s once the loop is
compiled (Numba caches it beside this file), most of it Numba's first call in the process.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

CALIB_LOOP = 10_000_000
CALIB_MATMUL = 500
CALIB_LOOP_REPEATS = 3
CALIB_MATMUL_REPEATS = 7


def best_of(repeats: int, fn: Callable[[], object]) -> float:
    """Smallest wall time of `repeats` calls of fn [s] (the least disturbed run)."""
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


@numba.njit(cache=True)
def _logistic(n: int) -> float:  # pragma: no cover - compiled
    x = 0.5
    for _ in range(n):
        x = 3.9 * x * (1.0 - x)
    return x


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def calibration() -> dict[str, Any]:
    """The machine and the time of the fixed workloads (see the module docstring)."""
    load = os.getloadavg()
    _logistic(10)  # compile (or load from the cache) outside the timing
    x = 0.0

    def loop() -> None:
        nonlocal x
        x = _logistic(CALIB_LOOP)

    a = np.random.default_rng(0).random((CALIB_MATMUL, CALIB_MATMUL))
    out = {
        "cores": os.cpu_count(),
        "cpu": _cpu_model(),
        "load_avg_1min": load[0],
        "load_average": list(load),
        "calib_numba_loop_s": best_of(CALIB_LOOP_REPEATS, loop),
        "calib_matmul_s": best_of(CALIB_MATMUL_REPEATS, lambda: a @ a),
    }
    if not 0.0 < x < 1.0:  # the loop's result is used, so the compiler cannot drop it
        raise RuntimeError(f"logistic map left (0, 1): {x}")
    return out


def machine_line(m: dict[str, Any]) -> str:
    """One line for the text reports."""
    return (f"machine: {m['cores']} cores ({m['cpu'] or 'cpu unknown'}), load average {m['load_avg_1min']:.2f} at "
            f"start; calibration: compiled loop {m['calib_numba_loop_s'] * 1e3:.1f} ms, "
            f"{CALIB_MATMUL}x{CALIB_MATMUL} matmul {m['calib_matmul_s'] * 1e3:.2f} ms")


def parse(ap: argparse.ArgumentParser, quick: dict[str, Any]) -> argparse.Namespace:
    """ap's arguments, with `--quick`: the sizes in `quick` replace the defaults (options given on
    the command line still win), for a smoke run of a few seconds whose figures mean little."""
    sizes = ", ".join(f"--{k.replace('_', '-')} {v}" for k, v in quick.items() if v is not None and v is not False)
    ap.add_argument("--quick", action="store_true", help=f"tiny sizes for a smoke run ({sizes or 'see the code'})")
    args = ap.parse_args()
    if args.quick:
        ap.set_defaults(**quick)
        args = ap.parse_args()
    return args


def dump(out: dict[str, Any]) -> str:
    """Strict JSON (NaN or inf raise: a figure that is not a number is written as null)."""
    return json.dumps(out, indent=2, allow_nan=False)
