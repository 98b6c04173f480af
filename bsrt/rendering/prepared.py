"""The prepared-geometry cache: a scene's patch table and hierarchy kept on disk, found again by
the content of its surfaces.

Cutting the surfaces into Bezier patches and flat pieces and building the
tree over them costs most of a small render's start-up (the column: 0.4 s
of 1.3 s) and seconds for a large model; unpickling the result takes
milliseconds. :func:`load` wraps the build with the cache;
``Geometry(scene, cache=True)`` (rendering/pipeline.py) is its one caller,
and ``bsrt render`` asks for it unless ``--no-cache``.

- **Key**: SHA-256 of the surfaces' content (every field of each
  ``BSplineSurface``, trims included, as pickled), :data:`FORMAT_VERSION`,
  bsrt's version, :data:`bsrt.kernels.jit.CACHE_EPOCH` and a fingerprint of
  the source that builds the table and the hierarchy (``bsrt/geometry``,
  ``bsrt/kernels``, ``rendering/bvh.py``): a new column of ``BVHArrays`` or
  an edited flattening never meets an old entry. Materials, lights and the
  camera are not part of it.
- **Payload**: ``(PatchSet, BVH)`` pickled with protocol 5, whole (every
  field of their NamedTuples, whatever they become), except the surfaces
  themselves: they are the scene's, referred to by index and put back on load.
- **Where, writes, damage, eviction**: as the model cache's entries
  (bsrt/io/cache.py, whose helpers these are): ``<model cache>/geometry``,
  ``<key>.geometry``, atomic writes safe with concurrent writers, a damaged
  entry rebuilt with one note, least recently used entries evicted over
  ``$BSRT_CACHE_MAX_MB``.
"""

from __future__ import annotations

import hashlib
import pickle
from io import BytesIO
from pathlib import Path

from bsrt.io import cache as model_cache

FORMAT_VERSION = 1  # of the payload; part of the key
SUFFIX = ".geometry"
NOTES = model_cache.Notes("geometry", "the hierarchy is built without the cache")
SOURCE = ("geometry", "kernels", "rendering/bvh.py")  # what builds the payload: part of the key


def folder() -> Path:
    """The entries' folder (created on demand): the model cache's folder / geometry."""
    return model_cache.folder() / "geometry"


def load(surfaces: list, build):
    """``build()`` (a function returning (patches, bvh) for ``surfaces``, a list of
    BSplineSurface) through the cache: the pair stored for surfaces of the same content, else
    built and stored. Never fails because of the cache."""
    key = entry_key(surfaces)
    entry = folder() / (key.hex() + SUFFIX)
    payload = model_cache.read_entry(entry, key, NOTES)
    if payload is not None:
        try:
            return _Unpickler(BytesIO(payload), surfaces).load()
        except Exception as exc:  # an entry from an incompatible environment: rebuilt like any damage
            NOTES(f"{entry} was damaged (cannot unpickle it: {type(exc).__name__}); rebuilt it")
    prepared = build()
    stream = BytesIO()
    _Pickler(stream, surfaces).dump(prepared)
    model_cache.write_entry(entry, key, stream.getvalue(), NOTES, SUFFIX)
    return prepared


def entry_key(surfaces: list) -> bytes:
    """The 32-byte key of ``surfaces`` (a list of BSplineSurface)."""
    from bsrt import __version__
    from bsrt.kernels.jit import CACHE_EPOCH

    h = hashlib.sha256()
    for part in (f"bsrt-geometry-cache {FORMAT_VERSION}", __version__, str(CACHE_EPOCH)):
        h.update(part.encode() + b"\0")
    h.update(model_cache.source_fingerprint(SOURCE).encode())
    buffers: list[pickle.PickleBuffer] = []  # the arrays' data, hashed where they lie (no copy)
    h.update(pickle.dumps(surfaces, protocol=5, buffer_callback=buffers.append))
    for buffer in buffers:
        h.update(buffer.raw())
    return h.digest()


class _Pickler(pickle.Pickler):
    """Pickles the payload with the scene's surfaces as references (their index)."""

    def __init__(self, file, surfaces: list):
        super().__init__(file, protocol=5)
        self.index = {id(s): i for i, s in enumerate(surfaces)}

    def persistent_id(self, obj):
        return self.index.get(id(obj))


class _Unpickler(pickle.Unpickler):
    def __init__(self, file, surfaces: list):
        super().__init__(file)
        self.surfaces = surfaces

    def persistent_load(self, pid):
        return self.surfaces[pid]
