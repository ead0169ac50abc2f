"""Coal on every core: worker processes that evaluate a `CollisionModel`'s distances.

Coal, through Pinocchio's bindings, holds the GIL while it works, so threads do not share its work
(two threads over a ur5 batch took as long as one). A pool is therefore a set of processes, each
with its own copy of one model, each evaluating whole chunks of a batch
(`collision.ROWS` configurations, `CollisionModel.rows`: each from a fresh coal state, so the
values are the same whichever process evaluates a chunk, and the same as inline).

The workers are forked from the process that owns the model, once, when the model has spent
START_AFTER seconds in coal inline: a short analysis (a test, a view) never pays for them, a long
one (the volume of a mesh robot: minutes of coal) runs on every core. Forking copies the model
without pickling or re-importing anything (a spawned worker would import the user's `__main__`,
running an unguarded script again); the workers only call coal, never a Numba kernel, whose
thread pools a fork does not carry over. Where there is no fork (Windows), in a process that is
itself a multiprocessing worker (a Dask worker of a sweep: its parent already spreads the work),
or with WORKERS = 1, everything runs inline. A pool lives as long as its model.
"""

from __future__ import annotations

import itertools
import multiprocessing
import os
import signal
import threading
import time
import warnings
import weakref
from concurrent.futures import ProcessPoolExecutor
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from kinematics.generic.collision import CollisionModel

WORKERS: int | None = None
"""Processes per pool (None: the CPUs this process may use, `chunks.default_workers`); 1 or 0:
no pool, every batch inline."""

WATCH_PERIOD = 0.5
"""[s] How often a worker checks that its parent is alive (it exits within this of the parent's death)."""

START_AFTER = 1.0
"""[s] A model evaluates its batches inline until it has spent this long in coal; its next batch
of two chunks or more starts its pool."""

_MODELS: dict[int, Any] = {}
"""The models whose pool is being forked, by key: a worker finds its own in its copy of this (the
parent lets go of it once the workers are forked)."""

_KEYS = itertools.count()


def _start(parent: int) -> None:
    """A worker's start: Ctrl-C left to the parent (a worker interrupted mid-chunk would print its
    own traceback), and a watch on the parent: killed (SIGKILL, or SIGTERM without a handler, as
    `timeout` sends), it cannot shut its pool down, and the workers would wait for work forever."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch, args=(parent,), daemon=True).start()


def _watch(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(WATCH_PERIOD)
    os._exit(0)


def _rows(key: int, q: np.ndarray, pick: np.ndarray | None, near: bool) -> np.ndarray:
    return _MODELS[key].rows(q, pick, near)


def _ready() -> None:
    """A no-op task: one per worker makes the executor fork them all before the model is let go."""


def workers() -> int:
    """Processes a new pool gets: WORKERS, or the CPUs this process may use; 1 where pools cannot
    start (no fork, or this process is a multiprocessing worker)."""
    from kinematics.chunks import default_workers

    if "fork" not in multiprocessing.get_all_start_methods() or multiprocessing.parent_process() is not None:
        return 1
    return default_workers() if WORKERS is None else max(1, WORKERS)


class CoalPool:
    """Forked worker processes holding one `CollisionModel` (module docstring)."""

    def __init__(self, executor: ProcessPoolExecutor, key: int) -> None:
        self._executor, self._key = executor, key
        # shut down when the pool is collected, before going on: left to the executor's manager
        # thread, a shutdown still under way as the interpreter exits (a model dropped at the end
        # of a command) races concurrent.futures' exit hook, which writes to the wake-up pipe the
        # thread is closing (CPython 3.11: "Exception ignored ... OSError: [Errno 9] Bad file
        # descriptor" after `singularities ur5 --collisions`)
        weakref.finalize(self, executor.shutdown, wait=True)

    @classmethod
    def start(cls, model: CollisionModel) -> CoalPool | None:
        """A pool of `workers()` processes for `model`, or None where there can be none. The
        model holds the pool; when it is collected, the executor is shut down and its workers
        joined."""
        n = workers()
        if n < 2:
            return None
        key = next(_KEYS)
        _MODELS[key] = model
        try:
            executor = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork"), initializer=_start,
                                           initargs=(os.getpid(),))
            with warnings.catch_warnings():
                # Python >= 3.12 warns on any fork of a threaded process; the workers run no
                # thread pool of the parent's (module docstring)
                warnings.filterwarnings("ignore", "This process .* is multi-threaded", DeprecationWarning)
                for done in [executor.submit(_ready) for _ in range(n)]:
                    done.result()
        finally:
            del _MODELS[key]  # forked: the workers hold their copies, the parent no extra reference
        return cls(executor, key)

    def map(self, q: np.ndarray, pick: np.ndarray | None, near: bool, spans: list[slice]) -> list[np.ndarray]:
        """`CollisionModel.rows` of each chunk q[span] (pick[span]), in the workers, in order."""
        jobs = [self._executor.submit(_rows, self._key, q[s], None if pick is None else pick[s], near) for s in spans]
        return [job.result() for job in jobs]


__all__ = ["START_AFTER", "WATCH_PERIOD", "WORKERS", "CoalPool", "workers"]
