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

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Interrupted(KeyboardInterrupt):
    """The run was ended by ``signum``."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


_handling = False


def _raise_interrupted(signum, frame) -> None:
    global _handling
    if _handling:
        return
    _handling = True
    raise Interrupted(signum)


def install() -> None:
    """Route SIGINT, SIGTERM and SIGHUP to Interrupted (call from the main thread)."""
    for sig in SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, _raise_interrupted)


def ignore() -> None:
    """Ignore these signals from now on: the run is over, only exiting is left.
    (Process-wide: blocking them in the main thread alone would let a kernel
    thread take one after Python has restored the default handlers.)"""
    for sig in SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


def describe(exc: KeyboardInterrupt) -> tuple[str, int]:
    """(one-line message, exit code) for an interruption."""
    signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
    return f"bsrt: interrupted ({signal.Signals(signum).name})", 128 + signum
