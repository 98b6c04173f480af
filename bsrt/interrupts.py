"""Signals that end a run cleanly: SIGINT, SIGTERM and SIGHUP.

Each raises :class:`Interrupted` (a KeyboardInterrupt) in the main thread,
so every ``finally`` and every staged output (bsrt/outputs.py) is cleaned up
on the way out, and the program exits with 128 + the signal number (130,
143, 129), as a shell reports a process killed by that signal. A second
signal while the first is being handled is ignored: clean-up is short and
must not be cut in half. A signal the parent set to be ignored (``nohup``,
a background job's SIGINT) stays ignored.
"""

from __future__ import annotations

import signal
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Interrupted(KeyboardInterrupt):
    """The run was ended by ``signum``."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


_handling = False
_finished = False


def _raise_interrupted(signum, frame) -> None:
    global _handling
    if _handling or _finished:
        return
    _handling = True
    raise Interrupted(signum)


def install() -> None:
    """Route SIGINT, SIGTERM and SIGHUP to Interrupted (call from the main thread)."""
    global _finished
    _finished = False
    for sig in SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, _raise_interrupted)


def finished() -> None:
    """The run's outputs are in place (bsrt/outputs.py, once committed): a signal from now on is
    too late to stop anything, and the handlers installed here take it without raising, so the
    run ends as finished, not as interrupted with its outputs left behind. (Between the outputs'
    block and the program's end there are still frames to return from and arrays to free: a
    signal there ended a run with exit 143 and its outputs in place.)"""
    global _finished
    _finished = True


def ignore() -> None:
    """Ignore these signals from now on: the run is over, only exiting is left.
    (Process-wide: blocking them in the main thread alone would let a kernel
    thread take one after Python has restored the default handlers.)"""
    for sig in SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


def behind(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (a signal) behind ``exc`` in its chain of causes and
    contexts, if any: code between the signal and bsrt may wrap it (numba's imports
    raise ImportError; a class body's ``__set_name__`` during an import, RuntimeError)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def describe(exc: KeyboardInterrupt) -> tuple[str, int]:
    """(one-line message, exit code) for an interruption."""
    signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
    return f"bsrt: interrupted ({signal.Signals(signum).name})", 128 + signum


_deferring = False


@contextmanager
def at_safe_points():
    """Within this block the signals wait (blocked in this thread and in every
    thread started inside it: the kernel pool, Mesa's) and are taken only at
    :func:`safe_point` or at the end of the block. An exception raised at an
    arbitrary bytecode could land inside numba's loading of a cached kernel,
    which then crashed the process (SIGSEGV) in about one run in ten when the
    signal came in the first second of a render. The program's imports run in
    such a block too (bsrt/__main__.py, the render's first lines): raised inside
    importlib, the exception could leave the import lock held while a library
    that wrapped it carried on, and the next import waiting on the set-up
    thread's then hung the process for good."""
    global _deferring
    old = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    outer, _deferring = _deferring, True
    try:
        yield
    finally:
        _deferring = outer  # a block inside another leaves the outer one deferring
        signal.pthread_sigmask(signal.SIG_SETMASK, old)  # a waiting signal is taken here (the outermost block)


def safe_point() -> None:
    """Take a waiting signal now (raising Interrupted), if inside at_safe_points."""
    if _deferring and set(signal.sigpending()) & set(SIGNALS):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)  # the handler runs and raises here
        signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
