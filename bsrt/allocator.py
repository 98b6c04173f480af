"""The C allocator's settings for the ``bsrt`` program: freed memory kept for the next arrays.

A render allocates its per-pixel arrays afresh: a 512x512 film's are about 2 MB
each, 40-45 MB in all per render. glibc's malloc serves requests of 128 KB and
up with new memory maps and unmaps them when freed, and its own threshold
rises only to the largest block freed so far, so most of them arrive as
fresh pages: 6,000-11,000 page faults per 512x512 render (about 4 us each on
this project's machines, mostly in one thread while the other cores wait).
With blocks up to MMAP_THRESHOLD taken from the heap and up to
TRIM_THRESHOLD of freed memory kept there, the next render reuses them: a
dozen faults per render. The peak is unchanged (larger blocks, a big film's
bands, are still mapped and returned); what stays resident after a render is
at most TRIM_THRESHOLD more.

Only bsrt's own processes set this: the program (bsrt/__main__.py) and the
preview's solver processes. It is process-wide, and a library must not change
the allocator under its host: Python code that renders often can call
:func:`keep_freed_memory` itself. Dask's workers keep Dask's own setting (it
trims freed memory at once, so that their memory limits see it). Settings the
user gave glibc's thresholds (THRESHOLD_VARIABLES) are left as they are.
"""

from __future__ import annotations

import os
import sys

# glibc's mallopt parameters (malloc.h)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD = 32 << 20  # glibc's own ceiling for its rising threshold (64-bit)
TRIM_THRESHOLD = 256 << 20


# what sets glibc's thresholds from the environment (GLIBC_TUNABLES: any, even empty)
THRESHOLD_VARIABLES = (
    "MALLOC_MMAP_THRESHOLD_",
    "MALLOC_TRIM_THRESHOLD_",
    "MALLOC_TOP_PAD_",
    "MALLOC_MMAP_MAX_",
    "GLIBC_TUNABLES",
)


def user_settings(environ=os.environ) -> list[str]:
    """The THRESHOLD_VARIABLES set in ``environ``."""
    return [name for name in THRESHOLD_VARIABLES if name in environ]


def keep_freed_memory() -> bool:
    """Have glibc's malloc keep freed blocks of up to MMAP_THRESHOLD in the heap, and up to
    TRIM_THRESHOLD of freed memory in all, for the next allocations. Returns whether it was set:
    False off Linux, with another C library, or where the environment tunes glibc's malloc
    (user_settings: even an empty GLIBC_TUNABLES)."""
    if not sys.platform.startswith("linux") or user_settings():
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None)  # the process's own C library
    except OSError:
        return False
    if not hasattr(libc, "gnu_get_libc_version"):  # not glibc (musl's mallopt does nothing)
        return False
    mallopt = libc.mallopt
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
