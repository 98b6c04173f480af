"""Compiling the kernels once per machine, and saying so.

numba compiles each kernel on its first call and caches the machine code on
disk (``cache=True``): next to the package (``bsrt/kernels/__pycache__``)
or, where that folder is not writable, in the user's cache folder (numba's
own fallback; ``NUMBA_CACHE_DIR`` overrides both).
:func:`bsrt.rendering.warm_up.warm_up` calls every entry kernel on a tiny
scene so the cost is paid (and timed) up front: ``bsrt doctor`` reports it,
and the CLI says on a terminal when a first render is about to compile.
"""

from __future__ import annotations

import os

from bsrt.kernels import film, flatten, lighting, patches, prelim, roots, shading, tables, traverse, trim, trim_pieces

# the kernels called from Python (the rest are compiled as part of them)
ENTRY_KERNELS = (
    roots.solve_items,
    traverse.trace_rays,
    patches.evaluate_many,
    patches.locate_many,
    flatten.count_leaves,
    flatten.flatten_patches,
    flatten.leaf_boxes,
    flatten.build_tree,
    tables.permute_rows,
    tables.power_coefficients,
    shading.frames_many,
    lighting.shade_hits,
    film.add_samples,
    film.encode_rows,
    prelim.decode_tile,
    prelim.pixel_rays_into,
    prelim.normalise_rows,
    prelim.map_suspects,
    prelim.seeded_hits,
    trim._kept_many,
    trim._rect_states,
    trim.classify_grid,
    trim_pieces.bezier_spans,
    trim_pieces.monotone_pieces,
)


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
