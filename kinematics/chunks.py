"""Chunked, threaded evaluation of vectorised kernels over long index ranges.

NumPy releases the GIL inside ufunc loops, so a thread pool over cache-sized chunks uses every
core without copying inputs to other processes. Chunks keep memory bounded whatever the total
size; results are returned in chunk order, so they do not depend on scheduling or chunk size
(as long as the kernel is pointwise). A tqdm bar appears only when asked for (the CLI asks when
stderr is a terminal), and then only once a map has run for a second.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from kinematics.errors import InvalidInputError

T = TypeVar("T")

DEFAULT_CHUNK = 32768
"""Points per chunk: small enough for the working set of a kernel to stay in cache."""


def slices(n: int, chunk: int = DEFAULT_CHUNK) -> Iterator[slice]:
    """Consecutive slices of length `chunk` covering range(n)."""
    if chunk <= 0:
        raise InvalidInputError("chunk", f"must be positive, got {chunk}")
    for start in range(0, n, chunk):
        yield slice(start, min(start + chunk, n))


def default_workers() -> int:
    """Worker threads: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def map_chunks(
    fn: Callable[[slice], T],
    n: int,
    *,
    chunk: int = DEFAULT_CHUNK,
    workers: int | None = None,
    progress: bool = False,
    desc: str = "",
    unit: str = "pt",
) -> list[T]:
    """[fn(s) for s in slices(n, chunk)], run on `workers` threads, in order.

    Args:
        fn: evaluates one slice of the index range; must be thread-safe.
        progress: show a tqdm bar (on stderr) if the map takes longer than one second.
    """
    parts = list(slices(n, chunk))
    workers = default_workers() if workers is None else max(1, workers)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc=desc, unit=unit, unit_scale=True, delay=1.0, leave=False)
    try:
        if workers == 1 or len(parts) == 1:
            out = []
            for s in parts:
                out.append(fn(s))
                if bar is not None:
                    bar.update(s.stop - s.start)
            return out
        with ThreadPoolExecutor(workers) as pool:
            futures = [pool.submit(fn, s) for s in parts]
            results = []
            for s, f in zip(parts, futures, strict=True):
                results.append(f.result())
                if bar is not None:
                    bar.update(s.stop - s.start)
            return results
    finally:
        if bar is not None:
            bar.close()
