"""The converted-model cache: a second load of an unchanged file in well under a second.

Reading a CAD part through OpenCASCADE (or a large IGES file through bsrt's
own reader) takes seconds to minutes; the result, a :class:`bsrt.io.Model`,
unpickles in milliseconds. :func:`load` wraps a reader call with the cache;
``bsrt.io.load_model(path, format, cache=True)`` is its one caller.

- **Which formats**: those whose reader says ``cached``
  (:data:`bsrt.io.formats.READERS`: OpenCASCADE's STEP, BREP and IGES, and
  bsrt's own IGES reader). The small text formats (bez, bpt, g2,
  nurbs, obj) read in about 10 ms, no faster from a cache, and skip it.
- **Key**: SHA-256 of the file's bytes, the file's name (surface names
  start with it), the format name, bsrt's version,
  :data:`FORMAT_VERSION`, a fingerprint of the reader code (the source of
  ``bsrt/io`` and the geometry modules it builds on, so an edited reader in a
  development checkout never meets its old results) and, for the
  OpenCASCADE formats, the installed ``OCP`` (its path and time stamp).
  Not the folder: a copy of the file elsewhere (a batch worker's unpacked
  copy) is a hit, and the entry's ``Model.path`` is set to the path given.
  So the readers of these formats name the folder nowhere but in
  ``Model.path`` (tests/test_cache.py checks it).
- **Where**: ``$BSRT_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/bsrt/models``
  (default ``~/.cache/bsrt/models``), created on demand (mode 0700). One file
  per entry, ``<key>.model``: :data:`MAGIC`, then the key (32 bytes), the
  payload's length (8 bytes, big-endian) and its SHA-256 (32 bytes), then the
  payload, the Model pickled with protocol 5 (new dataclass fields are carried
  without any change here). A per-user cache: entries owned by someone else
  are never unpickled.
- **Writes**: a temporary file in the same folder, fsynced, then
  ``os.replace``: atomic, so concurrent writers of one key both succeed (the
  last one wins) and a reader sees a whole entry or none. A file that changed
  while it was read is not stored.
- **Damage**: an entry that is unreadable, truncated, of another key or whose
  checksum fails is rebuilt and rewritten, with one note on stderr
  (``bsrt: note: model cache: ...``). It is a note about the cache, not a
  warning about the model, so it is not in ``Model.warnings`` (a cached model
  equals a freshly read one). A folder that cannot be created or written gives
  one note per process and the model is loaded without the cache.
- **Eviction**: after each write, if the entries together exceed
  ``$BSRT_CACHE_MAX_MB`` (default 2048 MB), the least recently used (by
  modification time: a hit touches its entry) are deleted until they fit;
  temporary files over an hour old (a writer that was killed) go too.
  ``rm -r ~/.cache/bsrt/models`` clears it at any time.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
import os
import pickle
import secrets
import struct
import sys
import time
from pathlib import Path

from bsrt.io.formats import READERS

FORMAT_VERSION = 1  # of the entry files; part of the key, so a new layout never opens an old file
MAGIC = b"bsrt model cache\n"
_HEADER = struct.Struct(">32sQ32s")  # key, payload length, SHA-256 of the payload
SUFFIX = ".model"
DEFAULT_MAX_MB = 2048
_STALE_TEMPORARY = 3600.0  # seconds: an older temporary file is a killed writer's

_fingerprints: dict[tuple, str] = {}  # source_fingerprint's, per process


def folder() -> Path:
    """The cache folder (not created here): $BSRT_CACHE_DIR, else $XDG_CACHE_HOME/bsrt/models,
    else ~/.cache/bsrt/models."""
    given = os.environ.get("BSRT_CACHE_DIR")
    if given:
        return Path(given)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "bsrt" / "models"


def max_bytes() -> int:
    """The size the entries are kept under: $BSRT_CACHE_MAX_MB megabytes (default 2048)."""
    try:
        mb = float(os.environ.get("BSRT_CACHE_MAX_MB", DEFAULT_MAX_MB))
    except ValueError:
        mb = DEFAULT_MAX_MB
    if not math.isfinite(mb):  # "inf", "nan": the default
        mb = DEFAULT_MAX_MB
    return int(max(0.0, mb) * 1024 * 1024)


def load(path: str, format: str, read):
    """``read()`` (a function returning a Model for ``path``) through the cache.

    Returns (model, cached): cached is True when the model came from an entry.
    Never fails because of the cache: any problem with it means ``read()``.
    """
    try:
        before = os.stat(path)
        with open(path, "rb") as f:
            digest = hashlib.file_digest(f, "sha256").digest()
    except OSError:
        return read(), False  # the reader gives the proper message
    key = entry_key(digest, path, format)
    entry = folder() / (key.hex() + SUFFIX)
    model = _fetch(entry, key)
    if model is not None:
        model.path = path
        return model, True
    model = read()
    try:
        after = os.stat(path)
        unchanged = (before.st_size, before.st_mtime_ns) == (after.st_size, after.st_mtime_ns)
    except OSError:
        unchanged = False
    if unchanged:
        _store(entry, key, model)
    return model, False


def entry_key(digest: bytes, path: str, format: str) -> bytes:
    """The 32-byte key of a file whose bytes have SHA-256 ``digest``, read as ``format``."""
    from bsrt import __version__

    h = hashlib.sha256()
    for part in (
        f"bsrt-model-cache {FORMAT_VERSION}",
        __version__,
        format,
        os.path.basename(path),
        _code_fingerprint(),
        _occt_fingerprint() if READERS[format].module == "occt" else "",
    ):
        data = part.encode("utf-8", "surrogateescape")
        h.update(len(data).to_bytes(8, "big") + data)
    h.update(digest)
    return h.digest()


def _code_fingerprint() -> str:
    """SHA-256 of the readers' source: bsrt/io and bsrt/geometry (all of them) and the checks they use."""
    return source_fingerprint(("io", "geometry", "validate.py", "errors.py", "files.py"))


def source_fingerprint(parts: tuple[str, ...]) -> str:
    """SHA-256 of the source of ``parts`` of the package (folders, all their .py files, or
    files), computed once per process: an edited checkout never meets its old entries."""
    if parts not in _fingerprints:
        package = Path(__file__).resolve().parent.parent
        files = sorted(
            q
            for part in parts
            for q in ((package / part).rglob("*.py") if (package / part).is_dir() else [package / part])
        )
        h = hashlib.sha256()
        for q in files:
            try:
                h.update(q.relative_to(package).as_posix().encode() + b"\0" + q.read_bytes() + b"\0")
            except OSError:
                h.update(b"?")
        _fingerprints[parts] = h.hexdigest()
    return _fingerprints[parts]


def _occt_fingerprint() -> str:
    """Which OpenCASCADE bindings are installed: their path and time stamp ("" if none)."""
    try:
        spec = importlib.util.find_spec("OCP")
        origin = spec.origin if spec is not None else None
        return f"{origin} {os.stat(origin).st_mtime_ns}" if origin else ""
    except (OSError, ImportError, ValueError):
        return ""


# ---------------------------------------------------------------------------
# Entries (shared with the prepared-geometry cache, bsrt/rendering/prepared.py)


class Notes:
    """Who a cache's notes on stderr speak for: ``bsrt: note: <name> cache: ...``; ``without``
    says what happens when the folder cannot be used ("models are read without the cache")."""

    def __init__(self, name: str, without: str):
        self.name, self.without = name, without
        self.noted: set[str] = set()  # "read", "write": a folder that cannot be read or written is noted once

    def once(self, kind: str, text: str) -> None:
        if kind not in self.noted:
            self.noted.add(kind)
            self(text)

    def __call__(self, text: str) -> None:
        """One line on stderr, after erasing a progress bar that may be drawn."""
        from bsrt.progress import clear_active

        clear_active()
        print(f"bsrt: note: {self.name} cache: {text}", file=sys.stderr, flush=True)


MODEL_NOTES = Notes("model", "models are read without the cache")


def _fetch(entry: Path, key: bytes):
    """The Model in ``entry``, or None (no entry, or a damaged one: noted, to be rebuilt)."""
    payload = read_entry(entry, key, MODEL_NOTES)
    if payload is None:
        return None
    try:
        model = pickle.loads(payload)
    except Exception as exc:  # an entry from an incompatible environment: rebuilt like any damage
        return _damaged(entry, f"cannot unpickle it: {type(exc).__name__}", MODEL_NOTES)
    from bsrt.io.model import Model

    if not isinstance(model, Model):
        return _damaged(entry, f"it holds a {type(model).__name__}, not a model", MODEL_NOTES)
    return model


def read_entry(entry: Path, key: bytes, notes: Notes) -> memoryview | None:
    """The payload of ``entry`` (checked: magic, key, length, checksum; the entry is then
    marked recently used), or None: no entry, or a damaged one (noted, to be rebuilt)."""
    try:
        fd = os.open(entry, os.O_RDONLY)
    except (FileNotFoundError, NotADirectoryError):  # no entry (or no folder: noted when writing)
        return None
    except OSError as exc:
        notes.once("read", f"cannot read {entry} ({exc.strerror or exc}); {notes.without}")
        return None
    try:
        with os.fdopen(fd, "rb") as f:
            if hasattr(os, "getuid") and os.fstat(f.fileno()).st_uid != os.getuid():
                notes(f"{entry} belongs to another user; not using it")
                return None
            data = f.read()
    except OSError as exc:
        notes.once("read", f"cannot read {entry} ({exc.strerror or exc}); {notes.without}")
        return None
    problem, payload = _payload(data, key)
    if problem:
        return _damaged(entry, problem, notes)
    try:
        os.utime(entry)  # recently used: the last to be evicted
    except OSError:
        pass
    return payload


def _damaged(entry: Path, problem: str, notes: Notes) -> None:
    notes(f"{entry} was damaged ({problem}); rebuilt it")


def _payload(data: bytes, key: bytes):
    """(problem, payload): problem is None and payload the entry's checked payload, or a short
    reason and None."""
    head = len(MAGIC) + _HEADER.size
    if len(data) < head or not data.startswith(MAGIC):
        return "not a cache entry" if not data.startswith(MAGIC[: len(data)]) else "truncated", None
    stored_key, length, checksum = _HEADER.unpack_from(data, len(MAGIC))
    if stored_key != key:
        return "it holds another key", None
    payload = memoryview(data)[head:]
    if len(payload) != length:
        return f"{len(payload)} of {length} bytes", None
    if hashlib.sha256(payload).digest() != checksum:
        return "checksum mismatch", None
    return None, payload


def encode(payload: bytes, key: bytes) -> bytes:
    """The bytes of an entry holding ``payload`` under ``key``."""
    return MAGIC + _HEADER.pack(key, len(payload), hashlib.sha256(payload).digest()) + payload


def _store(entry: Path, key: bytes, model) -> None:
    """Write the model's entry (write_entry); a model that does not pickle is noted."""
    try:
        payload = pickle.dumps(model, protocol=5)
    except Exception as exc:  # something in the model that does not pickle: a bug, but never a failed load
        MODEL_NOTES(f"cannot store {entry.name} ({type(exc).__name__}: {exc})")
        return
    write_entry(entry, key, payload, MODEL_NOTES)


def write_entry(entry: Path, key: bytes, payload: bytes, notes: Notes, suffix: str = SUFFIX) -> None:
    """Write the entry atomically (temporary file, fsync, rename), then evict the folder's least
    recently used ``suffix`` entries over max_bytes(); a folder that cannot be written is noted
    once and otherwise ignored."""
    where = entry.parent
    temporary = where / f".{entry.stem[:16]}-{os.getpid()}-{secrets.token_hex(4)}.tmp"
    data = encode(payload, key)
    try:
        where.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(temporary, entry)
        except BaseException:
            temporary.unlink(missing_ok=True)
            raise
    except OSError as exc:
        notes.once(
            "write",
            f"cannot write to {where} ({exc.strerror or exc}); {notes.without} "
            f"(set BSRT_CACHE_DIR to another folder, or use --no-cache)",
        )
        return
    evict(where, max_bytes(), suffix)


def evict(where: Path, limit: int, suffix: str = SUFFIX) -> None:
    """Delete the least recently used entries of ``where`` until they total at most ``limit``
    bytes, and temporary files over an hour old. Files others delete meanwhile are skipped."""
    now = time.time()
    entries = []
    try:
        with os.scandir(where) as listing:
            for item in listing:
                try:
                    st = item.stat(follow_symlinks=False)
                except OSError:
                    continue
                if item.name.endswith(".tmp") and item.name.startswith("."):
                    if now - st.st_mtime > _STALE_TEMPORARY:
                        _unlink(item.path)
                elif item.name.endswith(suffix):
                    entries.append((st.st_mtime, st.st_size, item.path))
    except OSError:
        return
    total = sum(size for _, size, _ in entries)
    for _, size, name in sorted(entries):
        if total <= limit:
            break
        _unlink(name)
        total -= size


def _unlink(name: str) -> None:
    try:
        os.unlink(name)
    except OSError:
        pass
