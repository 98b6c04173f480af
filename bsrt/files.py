"""Input files: refuse what is not a regular file before opening it.

Opening a FIFO blocks until someone writes to it, and a device such as
/dev/zero reads forever, so scene and model paths are checked with stat()
(following symlinks) first.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from bsrt.errors import InputError, MissingFileError

_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def check_input_file(path, what: str = "file") -> Path:
    """``path`` as a Path if it names an existing regular file (after symlinks); else InputError."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise MissingFileError(path) from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    for test, kind in _KINDS:
        if test(mode):
            raise InputError(f"{path}: is {kind}, not a {what}")
    return path
