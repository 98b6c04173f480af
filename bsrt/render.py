"""The one rendering pipeline: scene -> preliminary map -> roots -> shaded image.

The CLI, the preview window and the benchmarks all call :func:`render`.

Hard pixels. A map rasterised from a tessellation is right almost
everywhere, but near silhouettes it can miss pixels the surface covers (or
claim pixels it does not), at borders between surfaces and knot spans it can
name the wrong surface, and where a surface folds over itself Newton can
slide to a root behind the visible one. After every covered pixel has been
solved from its own seed, a pixel is *suspect* when

- it is covered but its root finder did not converge (or t <= 0), or
- one of its 8 neighbours shows a different surface in the map (this rings
  every silhouette and every border between surfaces, on both sides), or
- its root's distance disagrees with the map's rasterised distance by more
  than a few pixel footprints (a root on another layer).

Each suspect pixel is solved again (Newton) from up to nine starts, its own
and its neighbours' (their solved (u, v) where they converged, else their map
seeds), and, when the exact intersector is available, by Martin et al.'s
hierarchy; the nearest valid root wins. Everything else keeps its map-seeded
root. See docs in the README ("How bsrt finds every hit").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .camera import pixel_rays
from .errors import InputError
from .hits import Hits
from .patches import PatchSet
from .prelim import PrelimMap, render_map
from .scene import Scene
from .shade import shade, surface_frames
from .solve import RootResult, Rays, find_roots

# A root farther than this many pixel footprints from the map's rasterised
# distance is on another layer (or the map missed a nearer piece).
LAYER_SLACK_PIXELS = 8.0
NEIGHBOURS = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]


@dataclass
class RenderResult:
    """pixels: (H, W, 3) uint8 sRGB. linear: (H, W, 3) float64.
    hits: Hits for the H * W pixel-centre rays (row-major).
    position, normal: (H * W, 3) float64, NaN where no hit.
    prelim: the preliminary map (None for method "martin").
    stats: timings (seconds) and counters, JSON-serialisable."""

    pixels: np.ndarray
    linear: np.ndarray
    hits: Hits
    position: np.ndarray
    normal: np.ndarray
    prelim: PrelimMap | None
    stats: dict = field(default_factory=dict)

    def aovs(self) -> dict:
        """The arrays of ``--aov`` (keys, dtypes and shapes of the scene format)."""
        h, w = self.pixels.shape[:2]
        hits = self.hits
        return {
            "hit": hits.hit.reshape(h, w),
            "t": hits.t.reshape(h, w),
            "surface": hits.surface.astype(np.int32).reshape(h, w),
            "u": hits.u.reshape(h, w),
            "v": hits.v.reshape(h, w),
            "position": self.position.reshape(h, w, 3),
            "normal": self.normal.reshape(h, w, 3),
            "iterations": hits.iterations.astype(np.int32).reshape(h, w),
            "residual": hits.residual.reshape(h, w),
        }


class Geometry:
    """A scene's surfaces prepared for tracing: the patch table and, built on
    first use, the Martin et al. hierarchy. Reuse it across renders of the
    same scene (the preview window does)."""

    def __init__(self, scene: Scene):
        self.patches = PatchSet([s.geometry for s in scene.surfaces])
        self.material = np.array([s.material for s in scene.surfaces], dtype=np.int64)
        self._bvh = None

    @property
    def bvh(self):
        if self._bvh is None:
            from .bvh import build_bvh

            self._bvh = build_bvh(self.patches)
        return self._bvh


def render(
    scene: Scene,
    *,
    method: str | None = None,
    map_mode: str | None = None,
    width: int | None = None,
    height: int | None = None,
    geometry: Geometry | None = None,
    camera=None,
    ctx=None,
    prelim: PrelimMap | None = None,
    progress=None,
) -> RenderResult:
    """Render a scene. Keyword arguments override the scene's settings.

    camera: a camera.Camera to use instead of the scene's; ctx: a moderngl
    context for the map (default: the process's headless EGL context);
    prelim: a map already rendered for this camera and size (the preview
    window rasterises it on its own context, then solves elsewhere);
    progress: called with a stage name ("map", "solve", "shade") as each
    stage starts.
    """
    settings = scene.render
    method = method or settings.method
    map_mode = map_mode or settings.map
    width = width or scene.film.width
    height = height or scene.film.height
    camera = camera or scene.camera
    if width < 1 or height < 1:
        raise InputError(f"film size must be at least 1x1, got {width}x{height}")
    report = progress or (lambda stage: None)
    stats: dict = {"method": method, "map": map_mode if method != "martin" else None,
                   "width": width, "height": height, "seconds": {}}
    clock = time.perf_counter()
    geometry = geometry or Geometry(scene)
    patches = geometry.patches
    tolerance = settings.tolerance * max(patches.scene_diagonal(), 1e-300)
    directions = pixel_rays(camera, width, height)
    rays = Rays.from_arrays(camera.eye[None, :], directions)
    stats["seconds"]["setup"] = time.perf_counter() - clock

    prelim = None
    if method == "martin":
        report("solve")
        clock = time.perf_counter()
        hits = _intersect_all(geometry, rays, tolerance, settings.max_iterations)
        stats["seconds"]["map"] = 0.0
        stats["seconds"]["solve"] = time.perf_counter() - clock
        stats.update(covered_by_map=None, non_converged=0, suspect=0, repaired=0)
    else:
        report("map")
        clock = time.perf_counter()
        if prelim is None:
            prelim = render_map(patches, camera, width, height, map_mode, ctx=ctx)
        elif prelim.surface.shape != (height, width):
            raise ValueError(f"prelim map is {prelim.surface.shape[::-1]}, the film {width}x{height}")
        stats["seconds"]["map"] = time.perf_counter() - clock
        report("solve")
        clock = time.perf_counter()
        hits = _solve_from_map(geometry, rays, prelim, method, tolerance, settings.max_iterations, camera, stats)
        stats["seconds"]["solve"] = time.perf_counter() - clock

    report("shade")
    clock = time.perf_counter()
    n = width * height
    position = np.full((n, 3), np.nan)
    normal = np.full((n, 3), np.nan)
    linear = np.empty((n, 3))
    linear[:] = scene.film.background
    hit = np.flatnonzero(hits.hit)
    if hit.size:
        pos, nrm = surface_frames(patches, hits, hit)
        view = directions[hit]
        flip = np.einsum("ij,ij->i", nrm, view) > 0
        nrm[flip] *= -1.0
        position[hit], normal[hit] = pos, nrm
        linear[hit] = shade(scene, pos, nrm, view, geometry.material[hits.surface[hit]])
    linear = linear.reshape(height, width, 3)
    from .image import srgb_encode

    pixels = srgb_encode(linear)
    stats["seconds"]["shade"] = time.perf_counter() - clock
    covered_iters = hits.iterations[hits.iterations > 0]
    stats.update(
        pixels=n,
        hits=int(hits.hit.sum()),
        iterations_mean=float(covered_iters.mean()) if covered_iters.size else 0.0,
        iterations_max=int(hits.iterations.max()) if n else 0,
    )
    return RenderResult(pixels, linear, hits, position, normal, prelim, stats)


def _intersect_all(geometry: Geometry, rays: Rays, tolerance: float, max_iterations: int) -> Hits:
    from .bvh import intersect

    return intersect(
        geometry.bvh, rays.origin.T, rays.direction.T, tolerance=tolerance, max_iterations=max_iterations
    )


def _record(hits: Hits, pixels: np.ndarray, res: RootResult, patches: PatchSet, take: np.ndarray) -> None:
    """Store items ``take`` of ``res`` as the hits of ``pixels`` (same length as take)."""
    hits.hit[pixels] = True
    hits.t[pixels] = res.t[take]
    hits.patch[pixels] = res.patch[take]
    hits.surface[pixels] = patches.surface[res.patch[take]]
    hits.u[pixels], hits.v[pixels] = res.u[take], res.v[take]
    hits.residual[pixels] = res.residual[take]


def _solve_from_map(geometry, rays, prelim, method, tolerance, max_iterations, camera, stats) -> Hits:
    patches = geometry.patches
    h, w = prelim.surface.shape
    n = h * w
    hits = Hits.empty(n)
    seed_surface = prelim.surface.ravel()
    covered = np.flatnonzero(seed_surface >= 0)
    res = find_roots(
        patches, rays, covered, seed_surface[covered], prelim.u.ravel()[covered], prelim.v.ravel()[covered],
        method=method, tolerance=tolerance, max_iterations=max_iterations,
    )
    ok = res.converged & (res.t > 0)
    hits.iterations[covered] = res.iterations
    _record(hits, covered[ok], res, patches, np.flatnonzero(ok))

    # Suspect pixels (see the module docstring).
    sid = prelim.surface
    padded = np.pad(sid, 1, mode="edge")
    border = np.zeros((h, w), dtype=bool)
    for di, dj in NEIGHBOURS:
        border |= padded[1 + di : 1 + di + h, 1 + dj : 1 + dj + w] != sid
    suspect = border.ravel()
    suspect[covered[~ok]] = True
    _, ty = camera.half_extents(w, h)
    footprint = 2.0 * ty / h
    map_distance = prelim.distance.ravel()
    t = hits.t
    layer = hits.hit & (np.abs(t - map_distance) > LAYER_SLACK_PIXELS * footprint * map_distance + tolerance)
    suspect |= layer
    suspects = np.flatnonzero(suspect)
    before = (hits.hit[suspects].copy(), hits.surface[suspects].copy(), hits.t[suspects].copy())
    _repair(geometry, rays, prelim, hits, suspects, tolerance, max_iterations)
    changed = (before[0] != hits.hit[suspects]) | (before[1] != hits.surface[suspects]) | (
        np.abs(np.nan_to_num(before[2]) - np.nan_to_num(hits.t[suspects])) > tolerance * 10
    )
    stats.update(
        covered_by_map=int(covered.size),
        non_converged=int((~res.converged).sum()),
        suspect=int(suspects.size),
        wrong_layer=int(layer.sum()),
        repaired=int(changed.sum()),
    )
    return hits


def _repair(geometry, rays, prelim, hits: Hits, suspects: np.ndarray, tolerance, max_iterations) -> None:
    """Re-solve suspect pixels from their neighbours' starts (and the hierarchy)."""
    if not suspects.size:
        return
    patches = geometry.patches
    h, w = prelim.surface.shape
    row, col = np.divmod(suspects, w)
    item_pixel, item_surface, item_u, item_v = [], [], [], []
    seed_surface, seed_u, seed_v = prelim.surface.ravel(), prelim.u.ravel(), prelim.v.ravel()
    for di, dj in NEIGHBOURS:
        r, c = row + di, col + dj
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        src = (r * w + c)[inside]
        pix = suspects[inside]
        solved = hits.hit[src]
        surf = np.where(solved, hits.surface[src], seed_surface[src])
        uu = np.where(solved, hits.u[src], seed_u[src])
        vv = np.where(solved, hits.v[src], seed_v[src])
        keep = surf >= 0
        item_pixel.append(pix[keep])
        item_surface.append(surf[keep])
        item_u.append(uu[keep])
        item_v.append(vv[keep])
    item_pixel = np.concatenate(item_pixel)
    res = find_roots(
        patches, rays, item_pixel, np.concatenate(item_surface), np.concatenate(item_u), np.concatenate(item_v),
        method="newton", tolerance=tolerance, max_iterations=max_iterations,
    )
    np.add.at(hits.iterations, item_pixel, res.iterations)
    valid = res.converged & (res.t > 0)
    candidates = [(item_pixel[valid], res, np.flatnonzero(valid))]
    _keep_nearest(hits, patches, candidates, suspects)


def _keep_nearest(hits: Hits, patches: PatchSet, candidates, suspects: np.ndarray) -> None:
    """For each suspect pixel keep the nearest of its current hit and the candidate roots.

    candidates: list of (pixel (K,), RootResult, item index (K,)).
    """
    for pixel, res, take in candidates:
        if not pixel.size:
            continue
        t = res.t[take]
        order = np.lexsort((t, pixel))  # nearest first within each pixel
        pixel, take, t = pixel[order], take[order], t[order]
        first = np.concatenate([[True], pixel[1:] != pixel[:-1]])
        pixel, take, t = pixel[first], take[first], t[first]
        better = ~hits.hit[pixel] | (t < hits.t[pixel])
        _record(hits, pixel[better], res, patches, take[better])
