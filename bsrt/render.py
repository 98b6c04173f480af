"""The one rendering pipeline: scene -> preliminary map -> roots -> shaded image.

The CLI, the preview window and the benchmarks all call :func:`render`.

Hard pixels. After every pixel the map covers has been solved from its own
seed, suspect pixels (failed, on a border between surfaces in the map, on a
kink of the map's distance, or with a root off the map's layer) are solved
again from their neighbours' starts and by Martin et al.'s hierarchy; the
nearest valid root wins. See the README ("How bsrt finds every hit") and
_solve_from_map / _repair below.

Secondary rays (shadows, mirrors) and method "martin" go through the
hierarchy (bvh.intersect); anti-aliased and large films are traced in bands.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .bvh import build_bvh, intersect
from .camera import pixel_rays
from .errors import InputError
from .hits import Hits
from .image import srgb_encode
from .patches import PatchSet
from .prelim import PrelimMap, render_map
from .scene import Scene
from .shade import light_directions, shade, surface_frames
from .solve import RootResult, Rays, find_roots

# A root farther than this many pixel footprints from the map's rasterised
# distance is on another layer (or the map missed a nearer piece).
LAYER_SLACK_PIXELS = 8.0
# A second difference of the map's distance larger than this many pixel
# footprints marks a fold (the surface's own silhouette) between neighbours.
FOLD_PIXELS = 4.0
NEIGHBOURS = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]
REPAIR_ITERATIONS = 16


@dataclass
class RenderResult:
    """pixels: (H, W, 3) uint8 sRGB. linear: (H, W, 3) float64.
    hits: Hits for the H * W pixel-centre rays (row-major).
    position, normal: (H * W, 3) float64, NaN where no hit.
    prelim: the preliminary map of the last band traced, the whole film's
      when it fits in one band (None for method "martin").
    stats: timings (seconds) and counters, JSON-serialisable."""

    pixels: np.ndarray
    linear: np.ndarray
    hits: Hits
    position: np.ndarray
    normal: np.ndarray
    prelim: PrelimMap | None
    stats: dict = field(default_factory=dict)

    def save(self, path) -> None:
        """Write the image as a PNG (atomically: a failure leaves no file)."""
        from .image import write_png

        write_png(path, self.pixels)

    def png_bytes(self) -> bytes:
        """The image encoded as PNG."""
        import io

        from PIL import Image

        buffer = io.BytesIO()
        Image.fromarray(self.pixels, "RGB").save(buffer, format="PNG")
        return buffer.getvalue()

    def _repr_png_(self) -> bytes:  # Jupyter shows the image
        return self.png_bytes()

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
            self._bvh = build_bvh(self.patches)
        return self._bvh


MAX_BAND_SAMPLES = 1 << 19  # samples traced at once: bounds the memory of primary and secondary rays


def sample_grid(spp: int) -> tuple[int, int]:
    """(columns, rows) of the stratified sub-pixel grid: columns * rows = spp, as square as possible."""
    rows = max(d for d in range(1, int(np.sqrt(spp)) + 1) if spp % d == 0)
    return spp // rows, rows


def render(
    scene: Scene,
    *,
    method: str | None = None,
    map_mode: str | None = None,
    width: int | None = None,
    height: int | None = None,
    spp: int | None = None,
    geometry: Geometry | None = None,
    camera=None,
    ctx=None,
    prelim: PrelimMap | None = None,
    progress=None,
) -> RenderResult:
    """Render a scene. Keyword arguments override the scene's settings.

    camera: a camera.Camera to use instead of the scene's; ctx: a moderngl
    context for the map (default: the process's headless EGL context);
    prelim: a map already rendered for this camera and the whole film (the
    preview window rasterises it on its own context, then solves elsewhere;
    spp = 1 only); progress: called as ``progress(stage, fraction)`` with a
    stage name ("map", "solve", "shade", "aov", "done") as each stage starts
    and the fraction (0..1) of the whole render done so far (bands traced
    and shaded, secondary rays included); it may raise to abandon the render.

    Anti-aliasing: spp samples per pixel sit at the centres of a stratified
    columns x rows grid (sample_grid), which is exactly the pixel-centre grid
    of a film spp times larger; that film is traced band by band (each band
    with its own preliminary map, so every sample is seeded) and box-filtered
    down. The AOVs always describe the pixel-centre rays (a second pass when
    spp > 1).
    """
    settings = scene.render
    method = method or settings.method
    map_mode = map_mode or settings.map
    width = width or scene.film.width
    height = height or scene.film.height
    spp = spp or settings.spp
    camera = camera or scene.camera
    if width < 1 or height < 1:
        raise InputError(f"film size must be at least 1x1, got {width}x{height}")
    report = progress or (lambda stage, fraction=0.0: None)
    stats: dict = {"method": method, "map": map_mode if method != "martin" else None, "width": width,
                   "height": height, "spp": spp, "seconds": {"setup": 0.0, "map": 0.0, "solve": 0.0, "shade": 0.0}}
    clock = time.perf_counter()
    geometry = geometry or Geometry(scene)
    _ = geometry.bvh  # built here, not inside the first stage that needs it (hard pixels, shadows)
    stats["seconds"]["setup"] = time.perf_counter() - clock
    trace = _Tracer(scene, geometry, camera, method, map_mode, ctx, stats, report)

    cols, rows = sample_grid(spp)
    sample_w, sample_h = width * cols, height * rows
    band = max(rows, (MAX_BAND_SAMPLES // sample_w) // rows * rows)
    if prelim is not None and (spp != 1 or prelim.surface.shape != (height, width)):
        raise ValueError(f"a precomputed map needs spp = 1 and the film's size {width}x{height}")
    linear = np.zeros((height, width, 3))
    primary = []
    # Progress: the AOV pass of an anti-aliased render counts as one more sample.
    total = sample_h + (height if spp > 1 else 0)
    for first in range(0, sample_h, band):
        stop = min(sample_h, first + band)
        trace.done = first / total
        hits, directions = trace.primary(sample_w, sample_h, (first, stop), prelim)
        report("shade", trace.done)
        clock = time.perf_counter()
        colour, position, normal = trace.shade(hits, directions)
        block = colour.reshape((stop - first) // rows, rows, width, cols, 3).mean(axis=(1, 3))
        linear[first // rows : stop // rows] = block
        stats["seconds"]["shade"] += time.perf_counter() - clock
        if spp == 1:
            primary.append((hits, position, normal))
    if spp > 1:  # the AOVs: pixel-centre rays
        band = max(1, MAX_BAND_SAMPLES // width)
        for first in range(0, height, band):
            report("aov", (sample_h + first) / total)
            hits, directions = trace.primary(width, height, (first, min(height, first + band)), None)
            position, normal, _ = trace.frames(hits, directions)
            primary.append((hits, position, normal))
    hits = Hits.concatenate([p[0] for p in primary])
    position = np.concatenate([p[1] for p in primary])
    normal = np.concatenate([p[2] for p in primary])
    report("done", 1.0)
    pixels = srgb_encode(linear)
    work = hits.iterations[hits.iterations > 0]
    stats.update(
        pixels=width * height,
        hits=int(hits.hit.sum()),
        iterations_mean=float(work.mean()) if work.size else 0.0,
        iterations_max=int(hits.iterations.max()),
    )
    return RenderResult(pixels, linear, hits, position, normal, trace.last_map, stats)


class _Tracer:
    """Traces and shades rays for one render (holds the settings and accumulates stats)."""

    def __init__(self, scene, geometry, camera, method, map_mode, ctx, stats, report):
        self.scene, self.geometry, self.camera = scene, geometry, camera
        self.method, self.map_mode, self.ctx = method, map_mode, ctx
        self.stats, self.report = stats, report
        self.tolerance = scene.render.tolerance * max(geometry.patches.scene_diagonal(), 1e-300)
        self.max_iterations = scene.render.max_iterations
        self.last_map = None
        self.done = 0.0  # fraction of the render done when the current band started
        for key in ("covered_by_map", "non_converged", "suspect", "wrong_layer", "repaired", "hierarchy"):
            stats[key] = None if method == "martin" and key == "covered_by_map" else 0

    def primary(self, width, height, rows, prelim):
        """Nearest hits of the pixel-centre rays of film rows rows[0]..rows[1]-1.

        The map is rasterised (and solved) with one extra row above and below
        the band, so the neighbour tests of the hard pixels see across band
        borders. Returns (Hits, directions (K, 3)) for the band's pixels only.
        """
        first, stop = rows
        lo, hi = max(0, first - 1), min(height, stop + 1)
        directions = pixel_rays(self.camera, width, height, (lo, hi))
        rays = Rays.from_arrays(self.camera.eye[None, :], directions)
        stats, seconds = self.stats, self.stats["seconds"]
        if self.method == "martin":
            self.report("solve", self.done)
            clock = time.perf_counter()
            hits = _intersect_all(self.geometry, rays, self.tolerance)
            seconds["solve"] += time.perf_counter() - clock
        else:
            self.report("map", self.done)
            clock = time.perf_counter()
            if prelim is None:
                prelim = render_map(self.geometry.patches, self.camera, width, height, self.map_mode, ctx=self.ctx,
                                    rows=(lo, hi))
            else:  # the whole film's map, given: this band's rows of it
                prelim = prelim.rows(lo, hi)
            self.last_map = prelim
            seconds["map"] += time.perf_counter() - clock
            self.report("solve", self.done)
            clock = time.perf_counter()
            hits = _solve_from_map(self.geometry, rays, prelim, self.method, self.tolerance, self.max_iterations,
                                   self.camera, height, stats)
            seconds["solve"] += time.perf_counter() - clock
        keep = slice((first - lo) * width, (stop - lo) * width)
        return hits.take(keep), directions[keep]

    def frames(self, hits: Hits, directions: np.ndarray):
        """Position and viewer-facing unit normal (K, 3) of each hit, NaN where no hit,
        and |S_u|, |S_v| (K, 2)."""
        position = np.full((len(hits), 3), np.nan)
        normal = np.full((len(hits), 3), np.nan)
        speed = np.full((len(hits), 2), np.nan)
        hit = np.flatnonzero(hits.hit)
        if hit.size:
            pos, nrm, speed[hit] = surface_frames(self.geometry.patches, hits, hit)
            flip = np.einsum("ij,ij->i", nrm, directions[hit]) > 0
            nrm[flip] *= -1.0
            position[hit], normal[hit] = pos, nrm
        return position, normal, speed

    def shade(self, hits: Hits, directions: np.ndarray, depth: int = 0):
        """Linear RGB (K, 3) seen along each ray (ending at ``hits``), with the
        hits' positions and normals (K, 3). Shadow rays to every point and
        directional light; mirror reflection up to render.max_depth bounces."""
        position, normal, speed = self.frames(hits, directions)
        colour = np.empty((len(hits), 3))
        colour[:] = self.scene.film.background
        hit = np.flatnonzero(hits.hit)
        if not hit.size:
            return colour, position, normal
        pos, nrm, dirs = position[hit], normal[hit], directions[hit]
        material = self.geometry.material[hits.surface[hit]]
        exclude = self._exclusion(hits, hit, speed[hit])
        visibility = self._visibility(pos, nrm, exclude)
        colour[hit] = shade(self.scene, pos, nrm, dirs, material, visibility)
        reflectance = np.array([m.reflectance for m in self.scene.materials])[material]
        mirror = np.flatnonzero(reflectance > 0)
        if mirror.size and depth < self.scene.render.max_depth:
            d = dirs[mirror]
            n = nrm[mirror]
            r = d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n
            self.stats["reflection_rays"] = self.stats.get("reflection_rays", 0) + int(mirror.size)
            seen = self._trace(pos[mirror], r, tuple(a[mirror] for a in exclude))
            reflected, _, _ = self.shade(seen, r, depth + 1)
            k = reflectance[mirror][:, None]
            colour[hit[mirror]] = (1.0 - k) * colour[hit[mirror]] + k * reflected
        return colour, position, normal

    def _exclusion(self, hits: Hits, hit: np.ndarray, speed: np.ndarray):
        """The parameter box around each hit that its secondary rays must not hit again.

        Half-widths: 1e-6 of the scene diagonal in scene units, converted with
        |S_u|, |S_v| (a thousand times the root finder's tolerance), at most a
        quarter of the patch (where S_u or S_v vanishes, at poles).
        """
        eps = 1e-6 * self.geometry.patches.scene_diagonal()
        bounds = self.geometry.patches.bounds[hits.patch[hit]]
        with np.errstate(divide="ignore"):
            ru = np.minimum(eps / speed[:, 0], 0.25 * (bounds[:, 1] - bounds[:, 0]))
            rv = np.minimum(eps / speed[:, 1], 0.25 * (bounds[:, 3] - bounds[:, 2]))
        return hits.surface[hit], hits.u[hit], hits.v[hit], ru, rv

    def _trace(self, origins, directions, exclude, t_max=np.inf, any_hit=False) -> Hits:
        clock = time.perf_counter()
        out = intersect(self.geometry.bvh, origins, directions, t_min=0.0, t_max=t_max, tolerance=self.tolerance,
                        any_hit=any_hit, exclude=exclude)
        self.stats["seconds"]["secondary"] = self.stats["seconds"].get("secondary", 0.0) + time.perf_counter() - clock
        return out

    def _visibility(self, position, normal, exclude) -> np.ndarray:
        """(K, L) 1.0 where light L reaches the point, 0.0 in shadow (any-hit shadow rays)."""
        visibility = np.ones((position.shape[0], len(self.scene.lights)))
        for index, light in enumerate(self.scene.lights):
            if light.kind == "ambient":
                continue
            to_light, dist = light_directions(light, position)
            facing = np.flatnonzero(np.einsum("ij,ij->i", normal, to_light) > 0)
            if not facing.size:
                continue
            self.stats["shadow_rays"] = self.stats.get("shadow_rays", 0) + int(facing.size)
            blocked = self._trace(position[facing], to_light[facing], tuple(a[facing] for a in exclude),
                                  t_max=dist[facing], any_hit=True)
            visibility[facing[blocked.hit], index] = 0.0
        return visibility


def _intersect_all(geometry: Geometry, rays: Rays, tolerance: float) -> Hits:
    return intersect(geometry.bvh, rays.origin.T, rays.direction.T, tolerance=tolerance)


def _record(hits: Hits, pixels: np.ndarray, res: RootResult, patches: PatchSet, take: np.ndarray) -> None:
    """Store items ``take`` of ``res`` as the hits of ``pixels`` (same length as take)."""
    hits.hit[pixels] = True
    hits.t[pixels] = res.t[take]
    hits.patch[pixels] = res.patch[take]
    hits.surface[pixels] = patches.surface[res.patch[take]]
    hits.u[pixels], hits.v[pixels] = res.u[take], res.v[take]
    hits.residual[pixels] = res.residual[take]


def _solve_from_map(geometry, rays, prelim, method, tolerance, max_iterations, camera, film_height, stats) -> Hits:
    patches = geometry.patches
    h, w = prelim.surface.shape
    n = h * w
    hits = Hits.empty(n)
    seed_surface = prelim.surface.ravel()
    covered = np.flatnonzero(seed_surface >= 0)
    res = find_roots(
        patches, rays, covered, seed_surface[covered], prelim.u.ravel()[covered], prelim.v.ravel()[covered],
        method=method, tolerance=tolerance, max_iterations=max_iterations,
        stop_on_growth=method == "newton",  # a failure here is re-solved as a suspect below
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
    # A jump in the map's distance between neighbours on the same surface: a
    # fold of the surface over itself (its own silhouette) runs there.
    dist = np.where(np.isfinite(prelim.distance), prelim.distance, 0.0)
    fold = np.zeros((h, w), dtype=bool)
    for axis in (0, 1):
        curve = np.abs(np.diff(dist, 2, axis=axis))
        jump = curve > FOLD_PIXELS * footprint_of(camera, w, film_height) * dist.take(range(1, dist.shape[axis] - 1), axis=axis)
        pad = [(0, 0), (0, 0)]
        pad[axis] = (1, 1)
        fold |= np.pad(jump, pad)
    suspect = (border | fold).ravel()
    suspect[covered[~ok]] = True
    footprint = footprint_of(camera, w, film_height)
    map_distance = prelim.distance.ravel()
    t = hits.t
    layer = hits.hit & (np.abs(t - map_distance) > LAYER_SLACK_PIXELS * footprint * map_distance + tolerance)
    suspect |= layer
    suspects = np.flatnonzero(suspect)
    before = (hits.hit[suspects].copy(), hits.surface[suspects].copy(), hits.t[suspects].copy())
    traced = _repair(geometry, rays, prelim, hits, suspects, tolerance, max_iterations)
    changed = (before[0] != hits.hit[suspects]) | (before[1] != hits.surface[suspects]) | (
        np.abs(np.nan_to_num(before[2]) - np.nan_to_num(hits.t[suspects])) > tolerance * 10
    )
    for key, value in (("covered_by_map", covered.size), ("non_converged", (~res.converged).sum()),
                       ("suspect", suspects.size), ("wrong_layer", layer.sum()), ("repaired", changed.sum()),
                       ("hierarchy", traced)):
        stats[key] += int(value)
    return hits


def _repair(geometry, rays, prelim, hits: Hits, suspects: np.ndarray, tolerance, max_iterations) -> int:
    """Re-solve suspect pixels from their neighbours' starts, then with the hierarchy.

    Then every suspect also goes to the exact intersector (Martin et al.'s
    hierarchy): the nearest valid root of all wins, so a pixel is wrong only
    if both the neighbour starts and the hierarchy miss its nearest root.
    """
    if not suspects.size:
        return 0
    patches = geometry.patches
    h, w = prelim.surface.shape
    row, col = np.divmod(suspects, w)
    item_pixel, item_surface, item_u, item_v = [], [], [], []
    seed_surface, seed_u, seed_v = prelim.surface.ravel(), prelim.u.ravel(), prelim.v.ravel()
    for di, dj in sorted(NEIGHBOURS, key=lambda o: abs(o[0]) + abs(o[1])):  # own start first
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
    item_pixel, item_surface = np.concatenate(item_pixel), np.concatenate(item_surface)
    # One start per (pixel, surface), the nearest neighbour's: a second layer of
    # the same surface (a fold) is the hierarchy's job below.
    _, first = np.unique(item_pixel * len(patches.surfaces) + item_surface, return_index=True)
    item_pixel, item_surface = item_pixel[first], item_surface[first]
    # Newton from a pixel away converges in a few steps or not at all.
    res = find_roots(
        patches, rays, item_pixel, item_surface, np.concatenate(item_u)[first], np.concatenate(item_v)[first],
        method="newton", tolerance=tolerance, max_iterations=min(max_iterations, REPAIR_ITERATIONS),
        stop_on_growth=True,
    )
    np.add.at(hits.iterations, item_pixel, res.iterations)
    valid = res.converged & (res.t > 0)
    _keep_nearest(hits, patches, item_pixel[valid], res, np.flatnonzero(valid))
    hard = suspects
    if hard.size:
        exact = intersect(geometry.bvh, rays.origin[:, hard].T, rays.direction[:, hard].T, tolerance=tolerance)
        hits.iterations[hard] += exact.iterations
        better = exact.hit & (~hits.hit[hard] | (exact.t < hits.t[hard]))
        for name in ("hit", "t", "surface", "patch", "u", "v", "residual"):
            getattr(hits, name)[hard[better]] = getattr(exact, name)[better]
    return int(hard.size)


def footprint_of(camera, width: int, film_height: int) -> float:
    """Size of a pixel at unit distance from the eye (scene units)."""
    _, ty = camera.half_extents(width, film_height)
    return 2.0 * ty / film_height


def _keep_nearest(hits: Hits, patches: PatchSet, pixel: np.ndarray, res: RootResult, take: np.ndarray) -> None:
    """Keep, for each pixel, the nearest of its current hit and the roots ``take`` of ``res``.

    pixel, take: (K,) the pixel of each candidate root and its item in res.
    """
    if not pixel.size:
        return
    t = res.t[take]
    order = np.lexsort((t, pixel))  # nearest first within each pixel
    pixel, take, t = pixel[order], take[order], t[order]
    first = np.concatenate([[True], pixel[1:] != pixel[:-1]])
    pixel, take, t = pixel[first], take[first], t[first]
    better = ~hits.hit[pixel] | (t < hits.t[pixel])
    _record(hits, pixel[better], res, patches, take[better])
