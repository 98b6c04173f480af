"""Compiled (numba) kernels: the per-ray loops over flat float64/int64 arrays.

No Python objects inside a kernel; one implementation per algorithm. The
first use on a machine compiles them (cached on disk, see ``compile.py``).
Imports nothing of bsrt outside this package (but the version, below).
"""

from pathlib import Path as _Path

#: bump when a type the kernels take as an argument (a NamedTuple) moves to another module
CACHE_EPOCH = 3


def _drop_stale_machine_code() -> None:
    """Empty the machine-code cache next to the package when bsrt's version or CACHE_EPOCH changed.

    numba's cache index pickles the argument types of each kernel by module path, and loads it
    before it compares the source's time stamp: an index written before such a type moved (an
    upgrade) would fail to load with ModuleNotFoundError instead of being recompiled. Where the
    folder is not writable numba caches elsewhere, and nothing is done here."""
    from bsrt import __version__

    folder = _Path(__file__).resolve().parent / "__pycache__"
    marker = folder / "bsrt-kernels-epoch"
    stamp = f"{__version__} {CACHE_EPOCH}\n"
    try:
        if marker.read_text() == stamp:
            return
    except OSError:
        pass
    try:
        folder.mkdir(exist_ok=True)
        for path in folder.glob("*.nb[ic]"):
            path.unlink(missing_ok=True)
        marker.write_text(stamp)
    except OSError:
        pass


_drop_stale_machine_code()
