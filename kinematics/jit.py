"""The compile state of Numba kernels: whether this process compiled them, and whether the next
call will have to (so a command can say "compiling kernels (first run only)" before the wait).

Numba's on-disk cache (``@njit(cache=True)``) names a kernel's index file
``<module file stem>.<qualified name>-<line>.py<version>.nbi`` in the kernel's cache directory;
`cached` looks for exactly that, so it follows a kernel when its module moves or is renamed.

Numba has no lock between processes: two processes that call an uncached kernel at the same time
both compile it (the closed-loop solver's kernels take minutes), e.g. the workers of a Dask sweep or
of a parallel test run. `call` makes the first call of such a kernel wait while another
process compiles it, then load that compilation from the cache.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Iterable
from typing import Any

__all__ = ["cached", "call", "compiled", "on_cores"]


def _entry(kernel: Any) -> tuple[str, str] | None:
    """(cache directory, "<module file stem>.<qualified name>") of a kernel's cache entries."""
    path = kernel.stats.cache_path
    if path is None:
        return None
    stem = os.path.splitext(os.path.basename(kernel.py_func.__code__.co_filename))[0]
    return path, f"{stem}.{kernel.py_func.__qualname__}"


def _index_pattern(kernel: Any) -> str | None:
    entry = _entry(kernel)
    return None if entry is None else os.path.join(glob.escape(entry[0]), f"{glob.escape(entry[1])}-*.nbi")


def cached(kernels: Iterable[Any]) -> bool:
    """True when Numba's cache holds every one of `kernels` (compiled dispatchers), so calling
    them will load rather than compile."""
    for kernel in kernels:
        pattern = _index_pattern(kernel)
        if pattern is None or not glob.glob(pattern):
            return False
    return True


def compiled(kernels: Iterable[Any]) -> bool:
    """True when this process compiled any of `kernels` instead of loading it from the cache."""
    return any(sum(kernel.stats.cache_misses.values()) for kernel in kernels)


def call(kernel: Any, *args: Any) -> Any:
    """kernel(*args), compiled (or loaded) first for the arguments' types; when neither this
    process nor Numba's cache has the kernel yet, the compilation holds an exclusive lock (a file
    beside its cache entries), so that processes calling it together compile it once: the others
    wait and load it from the cache.

    Without `fcntl` (Windows) or with a read-only cache directory nothing is locked, and every
    process compiles for itself, as with Numba alone.
    """
    entry, pattern = _entry(kernel), _index_pattern(kernel)
    if kernel.signatures or entry is None or pattern is None or glob.glob(pattern):
        return kernel(*args)
    try:
        import fcntl

        os.makedirs(entry[0], exist_ok=True)
        lock = open(os.path.join(entry[0], f"{entry[1]}.lock"), "a")  # noqa: SIM115
    except (ImportError, OSError):
        return kernel(*args)
    with lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        kernel.compile(tuple(kernel.typeof_pyval(a) for a in args))  # loads it if another process just did
    return kernel(*args)


def on_cores(kernel: Any, items: int, smallest: int, *args: Any) -> Any:
    """kernel(*args), a `parallel=True` kernel over `items` work items, on every core, or on this
    thread alone when items < smallest: a parallel launch costs more than a small batch (milliseconds
    on a loaded machine, while it waits for a busy core), and the same loop compiled without
    parallel=True ran ~2.8x slower (the closed-form pair distances: 2.8 against 1.0 us per
    configuration on one core)."""
    if items >= smallest:
        return kernel(*args)
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return kernel(*args)
    finally:
        numba.set_num_threads(before)
