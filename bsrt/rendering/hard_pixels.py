"""Hard pixels: where a map-seeded root may be wrong, and their repair.

A map rasterised from triangles is right almost everywhere, but near
silhouettes and trim edges it misses pixels the surface covers (and claims
some it does not), at borders between surfaces it names the wrong surface,
and where a surface folds over itself Newton can slide to a root behind the
visible one. After every covered pixel was solved from its own seed, a pixel
is *suspect* when (``suspect_pixels``, pure functions of the map and hits):

- the map covered it but its start did not converge (or t <= 0, or the root
  lies in a trimmed-away part of its surface), or
- one of its 8 neighbours shows a different surface in the map (this rings
  every silhouette, trim edge and border between surfaces, on both sides), or
- the map's distance has a kink there (a fold of a surface over itself), or
- its root's distance differs from the map's by more than LAYER_SLACK_PIXELS
  pixel footprints: a root on another layer.

``repair`` solves every suspect again with Newton from its own and its
neighbours' starts (one per surface among them) and with the exact
intersector (the hierarchy); the nearest valid root of all wins.
"""

from __future__ import annotations

import numpy as np

from bsrt.rendering.hits import Hits, keep_nearest
from bsrt.kernels.prelim import map_suspects
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.prelim import PrelimMap
from bsrt.rendering.solve import Rays, find_roots

# A root farther than this many pixel footprints from the map's rasterised
# distance is on another layer (or the map missed a nearer piece).
LAYER_SLACK_PIXELS = 8.0
# A second difference of the map's distance larger than this many pixel
# footprints marks a fold (the surface's own silhouette) between neighbours.
FOLD_PIXELS = 4.0
NEIGHBOURS = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]
REPAIR_ITERATIONS = 16


def suspect_pixels(prelim: PrelimMap, hits: Hits, failed: np.ndarray, footprint: float, tolerance: float):
    """The suspect pixels (the module doc) of a solved map.

    failed: (N,) bool, covered pixels whose own start gave no valid root.
    footprint: pixel size at unit distance. Returns (suspect (N,) bool,
    layer (N,) bool, the wrong-layer part).
    """
    suspect, layer = np.empty(len(hits), dtype=bool), np.empty(len(hits), dtype=bool)
    run_chunks(map_suspects, len(hits), np.ascontiguousarray(prelim.surface), np.ascontiguousarray(prelim.distance),
               hits.hit, hits.t, np.ascontiguousarray(failed, dtype=bool), FOLD_PIXELS * footprint,
               LAYER_SLACK_PIXELS * footprint, float(tolerance), suspect, layer)
    return suspect, layer


def neighbour_starts(prelim: PrelimMap, hits: Hits, suspects: np.ndarray, surfaces: int):
    """One Newton start per (suspect pixel, surface among its 3x3 neighbourhood), the nearest neighbour's.

    A neighbour gives its converged (u, v) where it has a hit, else its map
    seed. Returns (pixel (K,), surface (K,), u (K,), v (K,)).
    """
    h, w = prelim.surface.shape
    row, col = np.divmod(suspects, w)
    seed_surface, seed_u, seed_v = prelim.surface.ravel(), prelim.u.ravel(), prelim.v.ravel()
    parts = []
    for di, dj in sorted(NEIGHBOURS, key=lambda o: abs(o[0]) + abs(o[1])):  # own start first
        r, c = row + di, col + dj
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        src = (r * w + c)[inside]
        solved = hits.hit[src]
        surf = np.where(solved, hits.surface[src], seed_surface[src])
        keep = surf >= 0
        parts.append((suspects[inside][keep], surf[keep], np.where(solved, hits.u[src], seed_u[src])[keep],
                      np.where(solved, hits.v[src], seed_v[src])[keep]))
    pixel, surface, u, v = (np.concatenate(x) for x in zip(*parts))
    # the first (nearest) start per (pixel, surface): a second layer of the same
    # surface (a fold) is the hierarchy's job
    _, first = np.unique(pixel * surfaces + surface, return_index=True)
    return pixel[first], surface[first], u[first], v[first]


def repair(geometry, rays: Rays, prelim: PrelimMap, hits: Hits, suspects: np.ndarray, tolerance: float,
           max_iterations: int) -> None:
    """Re-solve the suspect pixels (N,) (sorted) from their neighbours' starts, then with the hierarchy.

    The nearest valid root of all wins, so a pixel is wrong only if both the
    neighbour starts and the exact intersector miss its nearest root.
    """
    if not suspects.size:
        return
    patches = geometry.patches
    pixel, surface, u, v = neighbour_starts(prelim, hits, suspects, len(patches.surfaces))
    # Newton from a pixel away converges in a few steps or not at all.
    res = find_roots(patches, rays, pixel, surface, u, v, method="newton", tolerance=tolerance,
                     max_iterations=min(max_iterations, REPAIR_ITERATIONS), stop_on_growth=True)
    spent = np.bincount(np.searchsorted(suspects, pixel), weights=res.iterations, minlength=suspects.size)
    hits.iterations[suspects] += spent.astype(np.int32)  # every start's evaluations, on its pixel
    keep_nearest(hits, pixel, res.as_hits(patches))
    exact = geometry.intersect(rays.origin[suspects], rays.direction[suspects], tolerance=tolerance)
    hits.iterations[suspects] += exact.iterations
    keep_nearest(hits, suspects, exact)
