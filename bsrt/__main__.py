"""The program, ``bsrt ...`` or ``python -m bsrt ...``.

The signal handlers are installed before anything else is imported, so
Ctrl-C, SIGTERM or SIGHUP at any moment, even while NumPy and OpenGL load,
ends the run with one line and no traceback (bsrt/interrupts.py).
"""

import sys

from bsrt import interrupts

interrupts.install()


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    try:
        from bsrt.cli import main as run

        code = run(argv)
        interrupts.ignore()  # finished: a late signal must not turn into a traceback on the way out
    except KeyboardInterrupt as exc:
        interrupts.ignore()
        message, code = interrupts.describe(exc)
        print(message, file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
