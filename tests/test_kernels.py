"""The compiled kernels' bookkeeping: warm-up, the on-disk cache, the thread runner."""

from __future__ import annotations

import os

import numpy as np

from bsrt.kernels import compile as kernels
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
