"""The compile state of Numba kernels: whether this process compiled them, and whether the next
call will have to (so a command can say "compiling kernels (first run only)" before the wait).

Numba's on-disk cache (``@njit(cache=True)``) names a kernel's index file
``<module file stem>.<qualified name>-<line>.py<version>.nbi`` in the kernel's cache directory;
`cached` looks for exactly that, so it follows a kernel when its module moves or is renamed.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Iterable
from typing import Any

__all__ = ["cached", "compiled"]


def _index_pattern(kernel: Any) -> str | None:
    path = kernel.stats.cache_path
    if path is None:
        return None
    stem = os.path.splitext(os.path.basename(kernel.py_func.__code__.co_filename))[0]
    return os.path.join(glob.escape(path), f"{stem}.{glob.escape(kernel.py_func.__qualname__)}-*.nbi")


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
