"""The program, ``bsrt ...`` or ``python -m bsrt ...``.

The signal handlers are installed before anything else is imported, so
Ctrl-C, SIGTERM or SIGHUP at any moment, even while NumPy and OpenGL load,
ends the run with one line and no traceback (bsrt/interrupts.py); during
the imports a signal waits for their end (interrupts.at_safe_points).
"""

import sys

from bsrt import interrupts

interrupts.install()


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    try:
        with interrupts.at_safe_points():  # a signal waits for the imports' end (bsrt/interrupts.py)
            from bsrt.allocator import keep_freed_memory

            keep_freed_memory()  # the program only: process-wide (bsrt/allocator.py)
            from bsrt.cli import main as run

        code = run(argv)
        interrupts.ignore()  # finished: a late signal must not turn into a traceback on the way out
    except BaseException as exc:
        signal = interrupts.behind(exc)  # wrapped where it landed: an import's class body raises RuntimeError
        if signal is None:
            raise
        interrupts.ignore()
        message, code = interrupts.describe(signal)
        print(message, file=sys.stderr)
        _leave_now(code)
    return code


def run() -> None:
    """The ``bsrt`` program: :func:`main`, then the process ends without the interpreter's
    teardown (freeing numba's and LLVM's objects one by one: 0.1-0.15 s, as long as a small
    render's own stages). Every output was committed and closed by then; the kernels' idle
    threads are stopped first, and where any other thread or a child process still runs,
    Python ends as usual (waiting for the thread, ending the child)."""
    code = main()
    threads = sys.modules.get("bsrt.kernels.threads")
    if threads is not None:
        threads.stop_pool()
    import threading

    processes = sys.modules.get("multiprocessing")
    if (processes is not None and processes.active_children()) or any(
        t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()
    ):
        sys.exit(code)
    _leave_now(code)


def _leave_now(code: int) -> None:
    """Exit at once, without the interpreter's shutdown, after an interruption
    (kernel threads may still be inside a compiled loop, and tearing Python and
    the GL context down under them can crash; staged outputs were already
    discarded on the way here) or a finished run (:func:`run`: the outputs are
    committed). Only the standard streams need flushing."""
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":
    run()
