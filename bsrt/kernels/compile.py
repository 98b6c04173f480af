"""Compiling the kernels once per machine, and saying so.

numba compiles each kernel on its first call and caches the machine code on
disk (``cache=True``): next to the package (``bsrt/kernels/__pycache__``)
or, where that folder is not writable, in the user's cache folder (numba's
own fallback; ``NUMBA_CACHE_DIR`` overrides both). ``warm_up`` calls every
entry kernel on a tiny scene so the cost is paid (and timed) up front:
``bsrt doctor`` reports it, and the CLI says on a terminal when a first
render is about to compile.
"""

from __future__ import annotations

import os
import time

import numpy as np

from . import patches, roots, traverse, trim

ENTRY_KERNELS = (roots.solve_items, traverse.trace_rays, patches.evaluate_many, patches.locate_many)


def cache_folder() -> str | None:
    """Where the machine code is cached (None if numba cannot cache here)."""
    cache = getattr(roots.solve_items, "_cache", None)
    path = getattr(getattr(cache, "_cache_file", None), "_cache_path", None)
    return path


def is_cached() -> bool:
    """Whether every entry kernel has machine code on disk from an earlier run."""
    for kernel in ENTRY_KERNELS + (trim.kept_many,):
        cache_file = getattr(getattr(kernel, "_cache", None), "_cache_file", None)
        index = getattr(cache_file, "_index_path", None)
        if index is None or not os.path.exists(index):
            return False
    return True


def warm_up() -> float:
    """Compile (or load) every kernel on a one-patch scene; returns the seconds it took."""
    from ..bspline import make_surface
    from ..bvh import build_bvh, intersect
    from ..patches import PatchSet
    from ..solve import Rays, find_roots
    from ..trim import TrimLoop, make_trim_curve

    clock = time.perf_counter()
    plane = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]])
    square = [make_trim_curve(1, [0, 0, 1, 1], [a, b]) for a, b in
              (([0.2, 0.2], [0.8, 0.2]), ([0.8, 0.2], [0.8, 0.8]), ([0.8, 0.8], [0.2, 0.8]), ([0.2, 0.8], [0.2, 0.2]))]
    table = PatchSet([plane, plane.with_trims([TrimLoop(tuple(square))])])
    rays = Rays.from_arrays(np.array([[0.5, 0.5, 1.0]]), np.array([[0.0, 0.0, -1.0]]))
    one = np.zeros(1, dtype=np.int64)
    for method in roots.METHOD_IDS:
        find_roots(table, rays, one, one + 1, np.full(1, 0.4), np.full(1, 0.6), method=method)
    intersect(build_bvh(table), rays.origin, rays.direction, any_hit=False)
    table.evaluate(one, np.full(1, 0.5), np.full(1, 0.5))
    return time.perf_counter() - clock
