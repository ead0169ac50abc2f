"""kinematics.jit.call: processes that call an uncached kernel together compile it once."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

fcntl = pytest.importorskip("fcntl")

ROOT = Path(__file__).resolve().parents[1]
KERNEL = "from numba import njit\n\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n"
CALLER = """
import sys
import kernelmod
from kinematics import jit
print("ready", flush=True)
value = jit.call(kernelmod.twice, 21)
print(value, sum(kernelmod.twice.stats.cache_hits.values()), sum(kernelmod.twice.stats.cache_misses.values()))
"""


def _caller(tmp_path: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    env.pop("NUMBA_CACHE_DIR", None)  # the kernel's cache sits in tmp_path/__pycache__
    return subprocess.Popen([sys.executable, "-c", CALLER], cwd=tmp_path, env=env, stdout=subprocess.PIPE, text=True)


def test_a_second_process_loads_what_the_first_compiles(tmp_path):
    """While this process holds the kernel's lock and compiles it, a caller that reached
    `jit.call` first waits, then loads the kernel from the cache (a hit, no miss). Without the
    lock the caller compiles `twice` for itself in a fraction of the wait (a miss; checked by
    disabling the lock)."""
    (tmp_path / "kernelmod.py").write_text(KERNEL)
    (tmp_path / "__pycache__").mkdir()
    lock = open(tmp_path / "__pycache__" / "kernelmod.twice.lock", "a")  # the name jit.call locks
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        proc = _caller(tmp_path)
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        time.sleep(2.0)  # the caller compiles `twice` in ~0.1 s when nothing holds it back
        assert proc.poll() is None, "the caller did not wait for the lock"
        sys.path.insert(0, str(tmp_path))
        try:
            import kernelmod

            assert kernelmod.twice(1) == 2  # compiles here and writes the cache
        finally:
            sys.path.remove(str(tmp_path))
            sys.modules.pop("kernelmod", None)
        fcntl.flock(lock, fcntl.LOCK_UN)
        out, _ = proc.communicate(timeout=120)
    finally:
        lock.close()
    value, hits, misses = out.split()
    assert value == "42"
    assert (int(hits), int(misses)) == (1, 0)
