"""Command line: ``bsrt render | map | info | doctor | bench | preview | batch | animate | scan``.

Exit codes: 0 success, 2 bad usage or bad input (scene, model, options),
1 a render failure (e.g. no OpenGL context) or an output that could not be
written (``bsrt: error: PATH: <reason>``), 130 / 143 / 129 ended by SIGINT /
SIGTERM / SIGHUP (bsrt/interrupts.py). Errors are one line on stderr, never a
traceback (set BSRT_DEBUG=1 to see one). A render's outputs are written all
or nothing (bsrt/outputs.py): a failure or a signal leaves none behind.
"""

from __future__ import annotations

import os
import sys

from bsrt import interrupts
from bsrt.cli import commands
from bsrt.cli.parser import _join_negative_values, _parser
from bsrt.errors import InputError, OutputError, RenderError

__all__ = ["COMMANDS", "main"]


def _cmd_scan(args) -> int:
    from bsrt.cli.scan import cmd_scan  # a user of commands.py's helpers: registered here, not there

    return cmd_scan(args)


COMMANDS = {**commands.COMMANDS, "scan": _cmd_scan}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    args = _parser().parse_args(_join_negative_values(argv))
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"bsrt: error: {exc}", file=sys.stderr)
        return 2
    except OutputError as exc:
        print(f"bsrt: error: {exc}", file=sys.stderr)
        return 1
    except RenderError as exc:
        print(f"bsrt: render failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        raise  # bsrt/__main__.py reports it and leaves at once
    except MemoryError:
        print(
            "bsrt: render failed: out of memory (a smaller film, fewer samples per pixel or a simpler model "
            "needs less)",
            file=sys.stderr,
        )
        return 1
    except Exception as exc:  # a bug: still one line, the traceback on request
        signal = interrupts.behind(exc)
        if signal is not None:  # a signal inside a library that wrapped it (numba's imports: ImportError)
            raise signal from None
        if os.environ.get("BSRT_DEBUG", "").strip().lower() in ("1", "true", "yes"):
            raise
        print(f"bsrt: internal error: {type(exc).__name__}: {exc} (set BSRT_DEBUG=1 for a traceback)", file=sys.stderr)
        return 1
