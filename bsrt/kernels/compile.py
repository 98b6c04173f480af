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

from . import flatten, patches, prelim, roots, shading, tables, traverse, trim

# the kernels called from Python (the rest are compiled as part of them)
ENTRY_KERNELS = (roots.solve_items, traverse.trace_rays, patches.evaluate_many, patches.locate_many,
                 flatten.count_leaves, flatten.flatten_patches, flatten.leaf_boxes, flatten.build_tree,
                 tables.permute_rows, tables.power_coefficients,
                 shading.frames_many, shading.blinn_phong,
                 prelim.decode_tile, prelim.pixel_rays_into, prelim.normalise_rows, prelim.map_suspects,
                 prelim.seeded_hits,
                 trim._kept_many, trim._rect_states, trim.classify_grid, trim.bezier_spans, trim.monotone_pieces)


def cache_folder() -> str | None:
    """Where the machine code is cached (None if numba cannot cache here)."""
    cache = getattr(roots.solve_items, "_cache", None)
    path = getattr(getattr(cache, "_cache_file", None), "_cache_path", None)
    return path


def is_cached() -> bool:
    """Whether every entry kernel has machine code on disk from an earlier run."""
    for kernel in ENTRY_KERNELS:
        cache_file = getattr(getattr(kernel, "_cache", None), "_cache_file", None)
        index = getattr(cache_file, "_index_path", None)
        if index is None or not os.path.exists(index):
            return False
    return True


def warm_up() -> float:
    """Compile (or load) every kernel by rendering a tiny trimmed scene with each method and a
    shadow-casting light (GL included); returns the seconds it took."""
    from ..pipeline import render
    from ..scene import parse_scene
    from ..settings import METHODS, RenderOptions

    square = [{"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]} for a, b in
              (([0.2, 0.2], [0.8, 0.2]), ([0.8, 0.2], [0.8, 0.8]), ([0.8, 0.8], [0.2, 0.8]), ([0.2, 0.8], [0.2, 0.2]))]
    plate = {"degree": [1, 1], "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
             "points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]]}
    scene = parse_scene({
        "film": {"width": 8, "height": 8},
        "camera": {"eye": [0.5, -1.0, 2.0], "look_at": [0.5, 0.5, 0.0]},
        "light": [{"kind": "point", "position": [0.5, 0.5, 3.0], "intensity": 9.0}],
        "material": [{"name": "mirror", "reflectance": 0.5}],
        "surface": [{**plate, "material": "mirror"}, {**plate, "trim": [{"curves": square}],
                                                      "transform": {"translate": [0.0, 0.0, 0.5]}}],
    }, "<warm-up>")
    clock = time.perf_counter()
    for method in METHODS:
        render(scene, RenderOptions.resolve(scene, method=method))
    return time.perf_counter() - clock
