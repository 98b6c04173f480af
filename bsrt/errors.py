"""The kinds of failure a user can see.

``InputError`` is bad input (a scene, a model file, a command-line value): a
``ValueError``, which the CLI prints and exits with code 2;
``MissingFileError``, an input file that does not exist, is both an
InputError and a ``FileNotFoundError``. ``RenderError`` is a failure while
rendering valid input (no OpenGL context): exit code 1. ``OutputError``: an
output that could not be written (exit code 1). Each carries a complete,
user-facing sentence; no traceback is shown.
"""


class InputError(ValueError):
    """Bad input. The message names the file and the table/line and key."""


class MissingFileError(InputError, FileNotFoundError):
    """An input file (scene, model, import) that does not exist: ``PATH: no such file``."""

    def __init__(self, path, message: str | None = None):
        super().__init__(message or f"{path}: no such file")
        self.filename = str(path)

    def __str__(self) -> str:  # OSError's own would be "[Errno None] ..."
        return self.args[0]

    def __reduce__(self):  # pickled (a batch worker's error) with both arguments
        return type(self), (self.filename, self.args[0])


class RenderError(Exception):
    """Valid input that could not be rendered (e.g. no OpenGL context)."""


class OutputError(Exception):
    """An output file could not be written; the message names the user's path and the OS's reason."""
