"""The compiled kernels' bookkeeping: warm-up, the on-disk cache, the thread runner."""

from __future__ import annotations

import os

import numpy as np

from bsrt.kernels import compile as kernels
from bsrt.kernels import threads
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
    is left (or FIRST_SLICE items), so no thread is left with a long last slice."""
    slices = []

    def kernel(start, stop, out):
        out[start:stop] += 1
        slices.append((start, stop))

    seen = np.zeros(200_000, dtype=np.int64)
    run_chunks(kernel, seen.size, seen, min_chunk=256)
    assert np.all(seen == 1)
    share = 2 * min(threads.workers(), -(-seen.size // threads.FIRST_SLICE))
    for start, stop in slices:
        assert stop - start <= max(threads.FIRST_SLICE, (seen.size - start) // share)
