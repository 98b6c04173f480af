"""The compiled kernels' bookkeeping: warm-up, the on-disk cache, the thread runner."""

from __future__ import annotations

import os

import numba
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bsrt.kernels import compile as kernels
from bsrt.kernels import threads
from bsrt.kernels.search import first_at_least
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.warm_up import warm_up


def test_warm_up_leaves_every_entry_kernel_cached(ctx):
    seconds = warm_up()
    assert seconds > 0
    assert kernels.is_cached()
    folder = kernels.cache_folder()
    assert folder and os.path.isdir(folder) and any(name.endswith(".nbi") for name in os.listdir(folder))


def test_run_chunks_covers_every_index_once():
    seen = np.zeros(100_003, dtype=np.int64)

    def kernel(start, stop, out):
        out[start:stop] += 1

    run_chunks(kernel, seen.size, seen)
    assert np.all(seen == 1)
    empty = np.zeros(0, dtype=np.int64)
    run_chunks(kernel, 0, empty)


def test_run_chunks_last_slices_shrink_with_what_is_left():
    """Slices tile [0, n) once; toward the end each takes at most a 1/(2 x threads) share of what
    is left, so no thread is left with a long last slice, but no less than TAIL_SECONDS of the
    measured work per two threads (or FIRST_SLICE items, or what is left)."""
    n, cost = 200_000, 2e-8  # seconds per item: the tail's floor is 5,000 items
    floor = int(threads.TAIL_SECONDS / cost)
    cursor = threads._Cursor(n, threads.FIRST_SLICE, n // 8, threads=2)
    seen = np.zeros(n, dtype=np.int64)
    sizes, lefts = [], []
    while True:
        start, stop = cursor.take()
        if start >= stop:
            break
        seen[start:stop] += 1
        sizes.append(stop - start)
        lefts.append(n - start)
        assert stop - start <= max(floor, (n - start) // 4), (start, stop)  # a quarter of what is left: 2 threads
        cursor.measured(stop - start, (stop - start) * cost)
    assert np.all(seen == 1)
    assert sizes[:3] == [threads.FIRST_SLICE, 8 * threads.FIRST_SLICE, 64 * threads.FIRST_SLICE]  # the ramp
    full = sizes.index(n // 8)
    assert all(size >= min(floor, left) for size, left in zip(sizes[full:], lefts[full:]))
    assert sizes[-2] == floor  # the tail stopped shrinking at the floor
    # items 100x dearer: the floor follows the measured cost down to FIRST_SLICE
    cursor.measured(100, 100 * 1e-3)
    assert cursor.smallest == threads.FIRST_SLICE
    # 16 threads: each slice's GIL-held dispatch is paid in turn by more threads; the floor is 8x
    many = threads._Cursor(10 * n, threads.FIRST_SLICE, 10 * n // 8, threads=16)
    many.measured(n // 2, n // 2 * cost)
    assert many.smallest == 8 * floor


@numba.njit
def _first_at_least(a, value):  # first_at_least has no Python wrapper: called from a kernel
    return first_at_least(a, value)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-5, 5), max_size=12), st.integers(-7, 7))
def test_first_at_least_is_numpys_searchsorted_on_the_left(values, value):
    """Empty arrays, runs of equal values, and values below, among and above them."""
    a = np.sort(np.array(values, dtype=np.int64))
    assert _first_at_least(a, value) == np.searchsorted(a, value)
