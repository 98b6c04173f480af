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
  pixel footprints: a root on another layer, or
- the map's (u, v) jumps there between two layers of one surface (a *seam*:
  along the row or column, a step of the seeds is more than SEAM_RATIO
  times the other step, or than half the step over both). Where two layers
  of a surface (a thin fold, a self-intersection) lie within the
  tessellation's chord error of each other along the ray, the depth test
  may keep either layer's triangles, so the map and the root found from it
  may be the farther layer; the layer test cannot see that (the roots are
  far closer than a pixel footprint), but where the depth test switches
  between layers the seeds jump.

``repair`` solves every suspect again with the exact intersector (the
hierarchy). The hierarchy searches only nearer than the suspect's root
(pieces behind it are not solved: the same answers, 5-19% less time on the
repair) and skips the piece holding that root unless the ray meets it
grazing (it found the same root again; the hierarchy's time on the column's
suspects 8.8 -> 5.9 ms, the same pictures); the nearer root wins. A suspect
without a root is searched whole. Newton from its neighbours' starts once
came first, for a root to search nearer than, and for every suspect before
that; but they only found what the hierarchy finds, and cost more than they
saved (without them, on scenes/ and 65 model files: the same pictures, and
the same hits but for one pixel on the edge of two faces, either face's
root; the column's repair 11.3 -> 8.5 ms; for the suspects without a root,
on scenes/ and 71 model files: the same pictures and hits, t within the
residual over |cos| at grazing roots, 1 ms less on the column and on
water-lily). A pixel
whose repair found a nearer root than its own start's, within the layer
slack (the map showed the farther of two close layers), makes its 8
neighbours suspect too, round after round until a round finds no such
root: the region where the map showed the farther layer is repaired from
its seams inwards, however wide.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.prelim import map_suspects
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.hits import Hits, keep_nearest
from bsrt.rendering.prelim import PrelimMap
from bsrt.rendering.solve import Rays

# A root farther than this many pixel footprints from the map's rasterised
# distance is on another layer (or the map missed a nearer piece).
LAYER_SLACK_PIXELS = 8.0
# A second difference of the map's distance larger than this many pixel
# footprints marks a fold (the surface's own silhouette) between neighbours.
FOLD_PIXELS = 4.0
# A step of the map's (u, v) along a row or column (normalised by the
# surface's domain) longer than this many times the next step, or than half
# the step over both, marks a seam between two layers (kernels.prelim._seam),
# when longer by SEAM_QUANTA times the map's resolution of (u, v).
SEAM_RATIO = 4.0
SEAM_QUANTA = 4.0
MAP_QUANTUM = {"float": 2.0**-22, "rgba8": 1.0 / 255.0}  # the map's (u, v) step (float32: a few ulps below 1)
NEIGHBOURS = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]
SAME_ROOT = 100.0  # tolerances: the hierarchy's search of a suspect ends this far past its root


def suspect_pixels(
    prelim: PrelimMap,
    hits: Hits,
    failed: np.ndarray,
    footprint: float,
    tolerance: float,
    domain: np.ndarray,
    quantum: float = MAP_QUANTUM["float"],
):
    """The suspect pixels (the module doc) of a solved map.

    failed: (N,) bool, covered pixels whose own start gave no valid root.
    footprint: pixel size at unit distance. domain: (S, 4) the surfaces'
    (u0, u1, v0, v1). quantum: the map's resolution of normalised (u, v)
    (MAP_QUANTUM of its mode). Returns (suspect (N,) bool, layer (N,) bool,
    the wrong-layer part, seam (N,) bool, the seam part).
    """
    n = len(hits)
    suspect, layer, seam = np.empty(n, dtype=bool), np.empty(n, dtype=bool), np.empty(n, dtype=bool)
    run_chunks(
        map_suspects,
        n,
        np.ascontiguousarray(prelim.surface),
        np.ascontiguousarray(prelim.distance),
        np.ascontiguousarray(prelim.u),
        np.ascontiguousarray(prelim.v),
        np.ascontiguousarray(domain, dtype=np.float64),
        hits.hit,
        hits.t,
        np.ascontiguousarray(failed, dtype=bool),
        FOLD_PIXELS * footprint,
        LAYER_SLACK_PIXELS * footprint,
        float(tolerance),
        SEAM_RATIO,
        SEAM_QUANTA * float(quantum),
        suspect,
        layer,
        seam,
    )
    return suspect, layer, seam


def repair(
    geometry,
    rays: Rays,
    prelim: PrelimMap,
    hits: Hits,
    suspects: np.ndarray,
    tolerance: float,
    footprint: float,
) -> tuple[np.ndarray, int]:
    """Re-solve the suspect pixels (N,) (sorted), then the neighbours of those that had a farther layer.

    Each round is _repair_once. A pixel whose repair replaced its hit by one
    nearer by more than 10 tolerances but within the layer slack
    (LAYER_SLACK_PIXELS footprints: two layers closer than the map can
    order) makes its 8 neighbours not yet repaired the next round's pixels.
    footprint: pixel size at unit distance. Returns every pixel repaired
    (sorted) and how many of them changed: hit or miss, surface, or t by
    more than 10 tolerances.
    """
    h, w = prelim.surface.shape
    visited = np.zeros(h * w, dtype=bool)
    visited[suspects] = True
    front = suspects
    changed = 0
    while front.size:
        layer, count = _repair_once(geometry, rays, hits, front, tolerance, footprint)
        changed += count
        if not layer.size:
            break
        row, col = np.divmod(layer, w)
        grown = [
            (r * w + c)[(r >= 0) & (r < h) & (c >= 0) & (c < w)]
            for r, c in ((row + di, col + dj) for di, dj in NEIGHBOURS)
        ]
        front = np.unique(np.concatenate(grown))
        front = front[~visited[front]]
        visited[front] = True
    return np.flatnonzero(visited), changed


def _repair_once(geometry, rays: Rays, hits: Hits, front: np.ndarray, tolerance: float, footprint: float):
    """Re-solve the pixels front (N,) (sorted) with the hierarchy; the nearest valid root wins, so a
    pixel is wrong only if the exact intersector misses a root nearer than the one it has.

    Returns (the pixels (K,) whose hit was replaced by one nearer by more than 10 tolerances and
    within the layer slack, how many pixels changed: a hit where there was none, another surface,
    or t by more than 10 tolerances). The pixels' old hits are read once, into (N,) arrays (each
    read of the film's arrays at scattered pixels misses the cache: this way 1 ms less of the
    column's 512x512 repair than reading them again for each question).
    """
    # the hierarchy only has to find what lies nearer than the pixel's root (a root within
    # SAME_ROOT tolerances of it is the same root): pieces behind it are not solved, and neither is
    # the piece holding that root unless the ray meets it grazing (bvh.py: a piece's normals lie
    # within its cone, so only a grazing ray crosses it twice), as a secondary ray its start's
    had, t, surface = hits.hit[front], hits.t[front], hits.surface[front]
    bound = np.where(had, t + SAME_ROOT * tolerance, np.inf)
    none = np.zeros(front.size)
    found = (
        np.where(had, surface, -1),
        np.where(had, hits.u[front], 0.0),
        np.where(had, hits.v[front], 0.0),
        none,
        none,
    )
    exact = geometry.intersect(
        np.take(rays.origin, front, axis=0),
        np.take(rays.direction, front, axis=0),
        t_max=bound,
        tolerance=tolerance,
        exclude=found,
    )
    hits.iterations[front] += exact.iterations
    replaced = np.searchsorted(front, keep_nearest(hits, front, exact))  # positions in front
    was, now, new_t = had[replaced], exact.surface[replaced], exact.t[replaced]
    gap = np.where(was, t[replaced] - new_t, 0.0)
    count = np.count_nonzero(~was | (surface[replaced] != now) | (np.abs(gap) > 10 * tolerance))
    layer = (gap > 10.0 * tolerance) & (gap <= LAYER_SLACK_PIXELS * footprint * t[replaced] + tolerance)
    return front[replaced[layer]], int(count)
