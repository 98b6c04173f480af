"""The two kinds of failure a user can see.

``InputError`` is bad input (a scene, a model file, a command-line value): the
CLI prints its message and exits with code 2. ``RenderError`` is a failure
while rendering valid input (no OpenGL context, out of memory): exit code 1.
Both carry a complete, user-facing sentence; no traceback is shown.
"""


class InputError(Exception):
    """Bad input. The message names the file and the table/line and key."""


class RenderError(Exception):
    """Valid input that could not be rendered (e.g. no OpenGL context)."""


class OutputError(Exception):
    """An output file could not be written; the message names the user's path and the OS's reason."""
