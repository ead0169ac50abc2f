"""kinematics.chunks: every index evaluated once, results independent of chunk size and worker
count, errors propagate, no progress bar unless asked."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.chunks import map_chunks, slices
from kinematics.errors import InvalidInputError


@settings(max_examples=200, deadline=None)
@given(n=st.integers(0, 5000), chunk=st.integers(1, 700))
def test_slices_cover_every_index_once(n, chunk):
    seen = np.zeros(n, int)
    parts = list(slices(n, chunk))
    for s in parts:
        assert 0 < s.stop - s.start <= chunk
        seen[s] += 1
    assert np.all(seen == 1)
    assert len(parts) == -(-n // chunk)  # ceil(n / chunk) slices, in order
    assert [s.start for s in parts] == sorted(s.start for s in parts)


def test_bad_chunk_is_refused():
    with pytest.raises(InvalidInputError, match="chunk"):
        list(slices(10, 0))


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 3000), chunk=st.integers(1, 400), workers=st.integers(1, 4))
def test_results_independent_of_chunk_size_and_workers(n, chunk, workers):
    x = np.random.default_rng(n).standard_normal(n)

    def kernel(s: slice) -> np.ndarray:
        return np.sin(x[s]) * x[s] ** 2

    got = np.concatenate(map_chunks(kernel, n, chunk=chunk, workers=workers))
    assert np.array_equal(got, np.sin(x) * x**2)  # pointwise kernel: bit-identical whatever the split


def test_each_index_evaluated_once_across_threads():
    n = 10_000
    count = np.zeros(n, int)
    lock = threading.Lock()

    def kernel(s: slice) -> int:
        with lock:
            count[s] += 1
        return s.stop - s.start

    assert sum(map_chunks(kernel, n, chunk=97, workers=4)) == n
    assert np.all(count == 1)


@pytest.mark.parametrize("workers", [1, 3])
def test_errors_propagate(workers):
    def kernel(s: slice) -> int:
        if s.start >= 200:
            raise InvalidInputError("x", f"bad chunk at {s.start}")
        return 0

    with pytest.raises(InvalidInputError, match="bad chunk at"):
        map_chunks(kernel, 1000, chunk=100, workers=workers)


def test_no_progress_bar_unless_asked(capsys):
    map_chunks(lambda s: s.stop - s.start, 10, chunk=3)
    assert capsys.readouterr().err == ""
