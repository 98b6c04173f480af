"""Output files written all or nothing: staged, flushed to disk, then committed.

A render's outputs (PNG, AOV archive, a JSON file) are each written to an
anonymous temporary file in the target folder (Linux ``O_TMPFILE``: it has
no name, so a crash or SIGKILL leaves nothing behind), fsynced, and only
when every one of them is complete are they linked into place, each under a
short temporary name renamed over the final one, and the folder fsynced.
So a failure at any point before the commit leaves no file at all; after it,
every output is complete. Where the file system has no anonymous files the
staged file has a visible name, ``.bsrt-<pid>-<hex>.tmp`` (removed on
failure, and the only thing a SIGKILL can leave).

OS errors become :class:`OutputError`, whose message names the user's path
(``out.png: No space left on device``), never the temporary file.
"""

from __future__ import annotations

import errno
import os
import secrets
from contextlib import contextmanager
from pathlib import Path

from bsrt import interrupts
from bsrt.errors import OutputError

__all__ = ["OutputError", "Outputs", "outputs_at_safe_points", "write_file"]


def _temporary_name(folder: Path) -> Path:
    # Short and independent of the final name, so a legal 255-byte name never overflows.
    return folder / f".bsrt-{os.getpid()}-{secrets.token_hex(4)}.tmp"


class _Staged:
    """One output being written: an open descriptor, and a name once it has one."""

    def __init__(self, path: Path):
        self.path = path
        self.folder = path.parent if str(path.parent) else Path(".")
        self.named: Path | None = None
        try:
            self.fd = os.open(self.folder, os.O_TMPFILE | os.O_WRONLY, 0o666)
        except OSError as exc:
            if exc.errno not in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL):
                raise
            self.named = _temporary_name(self.folder)  # mode 0o666 less the umask, like any new file
            self.fd = os.open(self.named, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)

    def link(self) -> Path:
        """Give the anonymous file a temporary name (a no-op for a named one)."""
        if self.named is None:
            name = _temporary_name(self.folder)
            # linkat(AT_SYMLINK_FOLLOW) on the descriptor's /proc entry; os.link
            # only passes that flag when given a src_dir_fd (else it calls link()).
            fds = os.open("/proc/self/fd", os.O_RDONLY | os.O_DIRECTORY)
            try:
                os.link(str(self.fd), name, src_dir_fd=fds, follow_symlinks=True)
            finally:
                os.close(fds)
            self.named = name
        return self.named

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def discard(self) -> None:
        self.close()
        if self.named is not None:
            self.named.unlink(missing_ok=True)
            self.named = None


class Outputs:
    """Stage several output files, then commit them together (or none).

    with Outputs() as outputs:
        outputs.write("out.png", lambda f: image.save(f, format="PNG"))
        outputs.write("out.npz", npz.writer(arrays))
        ...                       # anything that can still fail (printing stats)
        outputs.commit()          # all renamed into place; before this, nothing exists

    Leaving the block without ``commit()`` (an exception, a signal) discards
    everything staged.
    """

    def __init__(self):
        self._staged: list[_Staged] = []
        self.committed = False  # commit() has run to its end

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, *exc) -> None:
        self.discard()

    def write(self, path, write) -> None:
        """Stage ``path``: ``write(binary_file)`` fills it; it is flushed to disk at once."""
        interrupts.safe_point()
        path = Path(path)
        with _os_errors(path):
            staged = _Staged(path)
            self._staged.append(staged)
            with os.fdopen(staged.fd, "wb", closefd=False) as f:
                write(f)
                f.flush()
            os.fsync(staged.fd)

    def commit(self) -> None:
        """Link and rename every staged file into place, then fsync their folders."""
        interrupts.safe_point()  # the last moment a signal can still leave nothing behind
        for staged in self._staged:
            with _os_errors(staged.path):
                staged.link()
        for staged in self._staged:
            with _os_errors(staged.path):
                os.replace(staged.named, staged.path)
                staged.named = None
                staged.close()
        for folder in {s.folder for s in self._staged}:
            with _os_errors(folder):
                _fsync_folder(folder)
        self._staged = []
        self.committed = True

    def discard(self) -> None:
        for staged in self._staged:
            staged.discard()
        self._staged = []


@contextmanager
def outputs_at_safe_points():
    """Outputs in an ``interrupts.at_safe_points`` block (the render and map commands: a run's
    last outputs; once they are committed the run counts as finished): signals wait for a safe
    point. One that arrives during ``commit()``, after its last safe point, or at any moment once
    the body has committed (``interrupts.finished``: the command's frames still return and free
    their arrays) came too late to stop anything: the command ends as finished (as after a signal
    once it has returned, bsrt/__main__.py), not as interrupted with its outputs left behind."""
    outputs = Outputs()
    try:
        with interrupts.at_safe_points(), outputs:
            yield outputs
            if outputs.committed:
                interrupts.finished()  # a signal after this is too late, wherever it lands
    except KeyboardInterrupt:
        if not outputs.committed:
            raise


def write_file(path, write) -> None:
    """One output file, all or nothing: ``write(binary_file)`` fills it."""
    with Outputs() as outputs:
        outputs.write(path, write)
        outputs.commit()


def _fsync_folder(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class _os_errors:
    """Turn an OSError into OutputError naming ``path`` (the user's, not a temporary one)."""

    def __init__(self, path: Path):
        self.path = path

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            reason = exc.strerror or str(exc)
            raise OutputError(f"{self.path}: {reason}") from None
        return False
