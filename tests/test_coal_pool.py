"""Coal on every core (kinematics.generic.coal_pool): CollisionModel.distances through forked
worker processes gives the inline values to the last bit, whatever the batching; a pool ends with
its model; with one worker there is none."""

from __future__ import annotations

import gc
import multiprocessing
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from kinematics.generic import coal_pool
from kinematics.generic.collision import ROWS, CollisionModel

fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="pools fork their workers")


def _configurations(robot, count, rng):
    lo = np.maximum(robot.model.lowerPositionLimit, -np.pi)
    hi = np.minimum(robot.model.upperPositionLimit, np.pi)
    return rng.uniform(lo, hi, (count, robot.model.nq))


@pytest.fixture()
def pooled(monkeypatch):
    """Pools start at a model's first batch of two chunks or more, with two workers (even on one CPU)."""
    monkeypatch.setattr(coal_pool, "START_AFTER", 0.0)
    monkeypatch.setattr(coal_pool, "WORKERS", 2)


def _children() -> set[int]:
    return {p.pid for p in multiprocessing.active_children()}


def test_values_do_not_depend_on_earlier_calls(ur5, rng):
    """A configuration's distances are the same whatever the model evaluated before (coal's GJK
    warm starts are not carried from one chunk to the next): the ur5's 20 mesh pairs at 3 chunks
    of random configurations, evaluated in one batch, then the chunks alone in reverse order on
    the same model, then the middle chunk on a new model: equal to the last bit (with warm starts
    carried over, ~30 % of the entries differed, by up to 2e-12 m)."""
    cm = CollisionModel.from_robot(ur5)
    q = _configurations(ur5, 3 * ROWS, rng)
    whole = cm.distances(q)
    alone = np.concatenate([cm.distances(q[k * ROWS:(k + 1) * ROWS]) for k in (2, 1, 0)][::-1])
    assert np.array_equal(whole, alone)
    assert np.array_equal(CollisionModel.from_robot(ur5).distances(q[ROWS:2 * ROWS]), whole[ROWS:2 * ROWS])


@fork
def test_pool_gives_the_inline_values(ur5, rng, pooled):
    """The ur5's distances by two forked workers equal the inline ones to the last bit: every
    entry, chosen entries (`where`, NaN elsewhere), one pair (`only`), the signs-only clamp
    (`near`), over a batch that is not a whole number of chunks."""
    q = _configurations(ur5, 5 * ROWS + 17, rng)
    before = _children()
    coal_pool.WORKERS = 1  # the inline reference (monkeypatch restores WORKERS)
    inline = CollisionModel.from_robot(ur5)
    where = rng.random((len(q), len(inline.pairs))) < 0.3
    expected = [inline.distances(q), inline.distances(q, where=where, near=True),
                inline.distances(q, only=np.array([3]))]
    assert _children() == before
    coal_pool.WORKERS = 2
    cm = CollisionModel.from_robot(ur5)
    got = [cm.distances(q), cm.distances(q, where=where, near=True), cm.distances(q, only=np.array([3]))]
    assert len(_children() - before) == 2
    for a, b in zip(expected, got, strict=True):
        assert np.array_equal(a, b, equal_nan=True)


@fork
def test_a_pool_is_shut_down_when_its_model_is_collected(ur5, rng, pooled):
    """The workers exit with their model: the executor is shut down, its workers joined and its
    manager thread's wake-up pipe closed by the time the model is collected. Left to the manager thread (asynchronous), a shutdown
    still under way at the interpreter's exit raced concurrent.futures' exit hook writing to that
    pipe: `singularities ur5 --collisions --max-points 20000` ended with "Exception ignored ...
    OSError: [Errno 9] Bad file descriptor" on stderr in 3 runs of 6 (CPython 3.11); none in 3 since."""
    from concurrent.futures import process

    before = _children()
    cm = CollisionModel.from_robot(ur5)
    cm.distances(_configurations(ur5, 2 * ROWS, rng))
    started = _children() - before
    assert len(started) == 2
    del cm
    gc.collect()
    assert not started & _children()  # no waiting: joined already
    assert all(wakeup._closed for wakeup in process._threads_wakeups.values())


def test_one_worker_means_no_pool(ur5, rng, pooled, monkeypatch):
    """WORKERS = 1: every batch inline, no process started."""
    monkeypatch.setattr(coal_pool, "WORKERS", 1)
    before = _children()
    CollisionModel.from_robot(ur5).distances(_configurations(ur5, 3 * ROWS, rng))
    assert coal_pool.workers() == 1
    assert _children() == before


def test_failed_penetration_depths_are_retried(rng):
    """Coal's EPA returns -DBL_MAX now and then for overlapping cylinders (the z1's links: 24 of
    145,000 entries at these 5,000 random configurations before the retry): every distance is
    now finite and above EPA_FAILED, and on the pairs of primitives (the meshes' signs come from
    their own test) its sign is coal's collision test's (an independent GJK boolean) wherever the
    shapes are more than 1e-9 m from contact (GJK/EPA tolerances 1e-10, retries at 1e-6: a value
    within 1e-9 of zero may fall either side of the test). The test runs from a fresh coal state
    per configuration: reusing one, coal's collision test missed 13 overlaps of link02_1 and
    link04_0 (up to 5.5 cm deep, confirmed by sampling) after ~4,700 configurations."""
    import pinocchio as pin

    from kinematics.generic.collision import EPA_FAILED
    from kinematics.model.robot import load_robot

    z1 = load_robot("z1")
    cm = CollisionModel.from_robot(z1)
    q = _configurations(z1, 5000, np.random.default_rng(0))
    d = cm.distances(q)
    assert np.isfinite(d).all() and (d > EPA_FAILED).all()
    data = z1.model.createData()
    primitive = np.array([a not in cm.meshes and b not in cm.meshes for a, b in cm.pair_names])
    rows = np.flatnonzero((d[:, primitive] < 0).any(axis=1))
    assert len(rows) > 100  # the overlaps the test is about
    for n in rows:
        gdata = pin.GeometryData(cm.geometry)
        pin.computeCollisions(z1.model, data, cm.geometry, gdata, q[n], False)
        hit = np.array([r.isCollision() for r in gdata.collisionResults])
        keep = primitive & (np.abs(d[n]) > 1e-9)
        assert np.array_equal(hit[keep], d[n, keep] < 0)


def _alive(pid: int) -> bool:
    """Whether process `pid` runs (a zombie, exited but not yet reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@fork
@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads process states from /proc")
def test_workers_exit_when_their_parent_is_killed():
    """A parent killed outright (SIGKILL; SIGTERM without a handler, as `timeout` sends) cannot shut
    its pool down: its workers notice within WATCH_PERIOD and exit instead of waiting for work
    forever (before the watch, both were still there 10 s later)."""
    script = (
        "import numpy as np, multiprocessing, time\n"
        "from kinematics.generic import coal_pool\n"
        "from kinematics.generic.collision import ROWS, CollisionModel\n"
        "from kinematics.model.robot import load_robot\n"
        "coal_pool.START_AFTER, coal_pool.WORKERS = 0.0, 2\n"
        "robot = load_robot('ur5')\n"
        "q = np.random.default_rng(0).uniform(-3, 3, (2 * ROWS, robot.model.nq))\n"
        "cm = CollisionModel.from_robot(robot)\n"
        "cm.distances(q)\n"
        "print(*[p.pid for p in multiprocessing.active_children()], flush=True)\n"
        "time.sleep(600)\n")
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(p) for p in parent.stdout.readline().split()]
        assert len(pids) == 2 and all(_alive(p) for p in pids)
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 20 * coal_pool.WATCH_PERIOD + 10.0  # generous: a loaded CI machine
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(p) for p in pids)
