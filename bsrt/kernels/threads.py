"""Running a compiled loop on every core: short slices of its index range on a thread pool.

The kernels are compiled without ``parallel=True`` (numba's parallel loops
cost most of the compile time) and with ``nogil=True``; ``run_chunks`` calls
one on consecutive slices from as many threads as there are cores, and the
slices run at once because the kernel releases the GIL.

Slices are short, so a signal is acted on within a second at any moment
(issue #28): each thread takes the next slice from a shared cursor, and a
slice's length follows the measured cost of the items before it (aiming at
SLICE_SECONDS; the first slices are FIRST_SLICE items). Toward the end the
slices shrink with what is left (at most a 1/(2 x threads) share of it), so
the threads finish together: one thread finishing a long last slice while
the others wait cost up to half a slice of every core but one per call, and
a render makes a dozen such calls. They shrink no further than TAIL_SECONDS
of measured work per two threads (nor below FIRST_SLICE items): each slice
costs 5-15 us of Python and dispatch with the GIL held (the kernel's
arguments unboxed, the cursor), which the threads take in turn, so the
more threads the more a slice costs them all. A 512x512 map's slices had
shrunk to 64 items, 30 slices a call; on 16 cores a 2048x2048 render made
31,000 slices and ran no faster than on 8 (an H200 machine's 16 cores,
2026-11-26: the floor per two threads and fewer shading calls,
shade.SECONDARY_CHUNK, took it to 8,000 slices and 2.5 -> 1.2 s).

The calling thread waits in steps of POLL_SECONDS and takes
a waiting signal between them (``interrupts.safe_point``); then no further
slice starts, and a kernel run with ``stoppable=True`` (its last argument
is a (1,) uint8 stop flag, read between items) leaves the slice it is in at
its next item.

The pool is this module's own (``_Pool``): threads waiting on one queue of
jobs, each job a cursor to drain, and each call told of its threads' ends
on a queue of its own. concurrent.futures' pool and its ``wait`` cost
80-100 us more per call (measured: 4,096 cheap items 0.33 -> 0.20 ms,
262,144 items 5.3 -> 4.9 ms, with the tail's floor); a render makes 40-60
calls.
"""

from __future__ import annotations

import os
import queue
import threading
import time

import numpy as np

from bsrt import interrupts

_POOL: _Pool | None = None
MIN_CHUNK = 2048
SLICE_SECONDS = 0.05  # a slice's aim: the stop and the cursor are read between slices
TAIL_SECONDS = 1e-4  # the last slices' floor, in measured work, per two threads
FIRST_SLICE = 64  # items in a thread's first slice, before any cost was measured
POLL_SECONDS = 0.02  # the calling thread looks for a signal this often


def workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


class _Cursor:
    """The next slice of [0, n) to take, its length adapted to the measured cost per item and
    shrinking with what is left of n among ``threads`` threads, to no less than TAIL_SECONDS of
    work per two threads (nor below ``first`` items)."""

    def __init__(self, n: int, first: int, largest: int, threads: int = 1):
        self.n, self.next, self.size, self.largest = n, 0, max(1, first), max(1, largest)
        self.share = 2 * max(1, threads)  # a slice takes at most 1 / share of what is left
        self.tail = TAIL_SECONDS * max(1.0, threads / 2)  # the last slices' floor, in seconds
        self.first = self.smallest = max(1, first)
        self.stopped = False
        self.lock = threading.Lock()

    def take(self) -> tuple[int, int]:
        with self.lock:
            if self.stopped:
                return self.n, self.n
            a = self.next
            size = min(self.size, max(self.smallest, (self.n - a) // self.share))
            self.next = min(self.n, a + size)
            return a, self.next

    def measured(self, items: int, seconds: float) -> None:
        """Next slices: about SLICE_SECONDS at this cost per item, growing at most 8-fold a step;
        the last ones no shorter than the tail's floor at it."""
        rate = items / max(seconds, 1e-7)
        with self.lock:
            self.size = max(1, min(int(rate * SLICE_SECONDS), 8 * items, self.largest))
            self.smallest = max(self.first, min(int(rate * self.tail), self.size))


def _drain(kernel, cursor: _Cursor, args) -> None:
    while True:
        a, b = cursor.take()
        if a >= b:
            return
        clock = time.perf_counter()
        kernel(a, b, *args)
        cursor.measured(b - a, time.perf_counter() - clock)


class _Pool:
    """``size`` threads taking jobs from one queue: a job (kernel, cursor, args, ends) drains the
    cursor, then puts None, or the exception a slice raised, on its ``ends`` queue."""

    def __init__(self, size: int):
        self.jobs = queue.SimpleQueue()
        self.threads = [threading.Thread(target=self._work, name=f"bsrt-kernel_{i}", daemon=True) for i in range(size)]
        for thread in self.threads:
            thread.start()

    def _work(self) -> None:
        while True:
            job = self.jobs.get()
            if job is None:
                return
            kernel, cursor, args, ends = job
            try:
                _drain(kernel, cursor, args)
            except BaseException as error:  # the caller raises it
                ends.put(error)
            else:
                ends.put(None)

    def shutdown(self) -> None:
        for _ in self.threads:
            self.jobs.put(None)
        for thread in self.threads:
            thread.join()


def run_chunks(kernel, n: int, *args, min_chunk: int = MIN_CHUNK, per_worker: int = 4, stoppable: bool = False) -> None:
    """kernel(start, stop, *args) over [0, n) in short slices from every core (see the module doc).

    Work of at most min_chunk items runs as one call in this thread; slices
    are at most n / (per_worker x cores) items (items of uneven cost want
    more, smaller slices). stoppable: the kernel takes a (1,) uint8 stop
    flag after args and returns early once it is set (an interruption)."""
    global _POOL
    main = threading.current_thread() is threading.main_thread()
    if main:
        interrupts.safe_point()
    extra = (np.zeros(1, dtype=np.uint8),) if stoppable else ()
    count = min(per_worker * workers(), max(1, n // max(1, min_chunk)))
    if count <= 1 and not stoppable:
        kernel(0, n, *args)
        return
    if _POOL is None:
        _POOL = _Pool(workers())
    first = max(1, min(FIRST_SLICE, min_chunk))
    threads = min(workers(), max(1, -(-n // first)))
    cursor = _Cursor(n, first, -(-n // count), threads)
    ends = queue.SimpleQueue()
    for _ in range(threads):
        _POOL.jobs.put((kernel, cursor, args + extra, ends))
    running = threads
    try:
        while running:
            try:
                error = ends.get(timeout=POLL_SECONDS if main else None)
            except queue.Empty:
                error = None
            else:
                running -= 1
            if error is not None:
                raise error  # a slice's exception ends the others too (below)
            if main:
                interrupts.safe_point()
    except BaseException:
        # An interruption (a signal raises here) or a slice's exception must not free the
        # arrays the running slices still write into: no slice starts any more, a
        # stoppable one ends at its next item, and those running are waited for (short).
        cursor.stopped = True
        if extra:
            extra[0][0] = 1
        while running:
            ends.get()
            running -= 1
        raise


def stop_pool() -> None:
    """End the pool's threads (idle between run_chunks calls); the next call starts a new pool."""
    global _POOL
    pool, _POOL = _POOL, None
    if pool is not None:
        pool.shutdown()


def _forget_pool() -> None:
    """In a forked child: the parent's threads are not there; the next call starts a new pool."""
    global _POOL
    _POOL = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)
