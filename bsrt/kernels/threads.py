"""Running a compiled loop on every core: chunks of its index range on a thread pool.

The kernels are compiled without ``parallel=True`` (numba's parallel loops
cost most of the compile time) and with ``nogil=True``; ``run_chunks`` calls
one on consecutive slices from as many threads as there are cores, and the
slices run at once because the kernel releases the GIL.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, wait

from bsrt import interrupts

_POOL: ThreadPoolExecutor | None = None
MIN_CHUNK = 2048


def workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def run_chunks(kernel, n: int, *args, min_chunk: int = MIN_CHUNK, per_worker: int = 4) -> None:
    """kernel(start, stop, *args) over [0, n) in about per_worker slices per core (at least
    min_chunk items each; the pool hands the next slice to the first free thread, so items
    of uneven cost want more, smaller slices)."""
    global _POOL
    interrupts.safe_point()
    count = min(per_worker * workers(), max(1, n // max(1, min_chunk)))
    if count <= 1:
        kernel(0, n, *args)
        return
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=workers(), thread_name_prefix="bsrt-kernel")
    bounds = [n * i // count for i in range(count + 1)]
    futures = [_POOL.submit(kernel, a, b, *args) for a, b in zip(bounds[:-1], bounds[1:])]
    try:
        for future in futures:
            future.result()
    except BaseException:
        # An interruption (a signal raises here) must not free the arrays the
        # running slices still write into: cancel the rest, let those finish.
        for future in futures:
            future.cancel()
        wait(futures)
        raise
