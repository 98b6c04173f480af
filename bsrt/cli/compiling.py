"""The first run's kernel compile, for the commands that render: announced, ahead of the work."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager


def start_set_up():
    """Begin on a thread what a render's first steps wait for, while this thread imports the
    renderer: the GL driver's load (the EGL display) and numba's runtime. Both are mostly C
    outside the GIL: 40-70 ms of a small render's start on two cores. Returns the thread (the
    render waits for it with its imports, signals held: bsrt/interrupts.py). Best effort: what
    fails here fails again where the render needs it, and is reported there."""
    import threading

    def set_up() -> None:
        try:
            from bsrt.rendering.gl import load_driver

            load_driver()
            from bsrt.kernels.jit import prepare_runtime

            prepare_runtime()
        except Exception:  # noqa: BLE001 - only a head start (above)
            pass

    thread = threading.Thread(target=set_up, name="bsrt-set-up", daemon=True)
    thread.start()
    return thread


@contextmanager
def compiling_if_cold(progress=None):
    """The first render on a machine: the kernels compile in worker processes while the block
    runs (the render's imports, the model's load and the checks before the render), and are
    waited for after it, said on stderr then with the time left (an error in the block ends the
    workers and is the only message: bad input stays one line); nothing is done where they are
    cached. The block is given ``start()``: the workers begin when it is called (as early as the
    block may: they need bsrt.kernels imported), else at the block's end. The render then loads
    the kernels it uses from the cache (those the workers could not compile it compiles itself).
    progress: shown the stage "compile" (bsrt/progress.py keeps it out of the render's time
    left)."""
    started: dict = {}

    def start() -> None:
        from bsrt.kernels import compile as kernels

        if not started and not kernels.is_cached():
            started["clock"], started["workers"] = time.perf_counter(), kernels.start()
        started.setdefault("clock", None)

    try:
        yield start
    except BaseException:
        if started.get("workers"):
            from bsrt.kernels import compile as kernels

            kernels.finish(started["workers"], stop=True)
        raise
    start()
    if started["clock"] is None:
        return
    from bsrt.kernels import compile as kernels

    _announce(progress, max(1.0, kernels.estimate_seconds() - (time.perf_counter() - started["clock"])))
    kernels.finish(started["workers"])


def compile_if_cold(progress=None, warm: bool = True) -> None:
    """The first render on a machine compiles the kernels before it starts (said on stderr).
    warm: also load them here (a GL context; False for a batch, whose workers render)."""
    from bsrt.kernels import compile as kernels

    if not kernels.is_cached():
        compile_kernels(progress, warm)


def compile_kernels(progress=None, warm: bool = True) -> tuple[str, float]:
    """Compile every kernel into the cache if it is not there (announced on stderr, terminal or
    not), in parallel worker processes, then (``warm``) load them all here by the warm-up, which
    also compiles whatever the workers could not, so that a render that follows compiles
    nothing. Returns what was done ("loaded from the cache" or "compiled") and the seconds it
    took. progress: shown the stage "compile" (bsrt/progress.py keeps it out of the render's
    time left)."""
    from bsrt.kernels import compile as kernels
    from bsrt.rendering.warm_up import warm_up

    clock = time.perf_counter()
    cached = kernels.is_cached()
    if not cached:
        _announce(progress)
        kernels.compile_all()
        if progress:
            progress("compile", 0.9)
    if warm:
        warm_up()
    return ("loaded from the cache" if cached else "compiled"), time.perf_counter() - clock


def _announce(progress=None, seconds: float | None = None) -> None:
    """Say on stderr (terminal or not) that the kernels compile now, and for about how long
    (seconds: the time left, default the whole compile's estimate)."""
    from bsrt.kernels import compile as kernels

    if progress:
        progress.clear()
    seconds = kernels.estimate_seconds() if seconds is None else seconds
    print(
        f"bsrt: compiling bsrt's kernels once for this machine (about {seconds:.0f} s)...",
        file=sys.stderr,
        flush=True,
    )
    if progress:
        progress("compile", 0.0)
