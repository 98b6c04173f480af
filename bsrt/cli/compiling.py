"""The first run's kernel compile, for the commands that render: announced, ahead of the work."""

from __future__ import annotations

import sys
import time


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
        if progress:
            progress.clear()
        print(
            f"bsrt: compiling bsrt's kernels once for this machine (about {kernels.estimate_seconds():.0f} s)...",
            file=sys.stderr,
            flush=True,
        )
        if progress:
            progress("compile", 0.0)
        kernels.compile_all()
        if progress:
            progress("compile", 0.9)
    if warm:
        warm_up()
    return ("loaded from the cache" if cached else "compiled"), time.perf_counter() - clock
