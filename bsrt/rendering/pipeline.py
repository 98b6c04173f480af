"""The one rendering pipeline: scene -> camera rays -> hits -> shaded image.

The CLI, the preview window, the Python API and the benchmarks all call
:func:`render` with a :class:`~bsrt.rendering.options.RenderOptions`. Camera rays go
through the tracer the method picks (trace.py); shading sends shadow and
mirror rays through the hierarchy. Anti-aliased and large films are traced in
bands of at most MAX_BAND_SAMPLES samples (at least one row of the sample
film, width * columns <= width * sqrt(spp) samples), which bounds memory
whatever spp is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.lighting import shade_hits
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.bvh import DEFAULT_RETRY_DEPTH, build_bvh, intersect
from bsrt.rendering.film import Film
from bsrt.rendering.hits import Hits
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.prelim import PrelimMap
from bsrt.rendering.shade import facing_frames, light_arrays
from bsrt.rendering.stats import Stats
from bsrt.rendering.trace import make_primary_tracer
from bsrt.scene import Scene
from bsrt.scene.camera import pixel_rays

MAX_BAND_SAMPLES = 1 << 19  # samples traced at once: bounds the memory of primary and secondary rays
SECONDARY_CHUNK = 1 << 16  # rays (hits shaded, mirror rays) per kernel call: progress and cancellation points
SHADOW_ITERATIONS = 16  # Newton iterations of a shadow ray on one piece (bvh.intersect's default)


@dataclass(eq=False)
class RenderResult:
    """pixels: (H, W, 3) uint8 sRGB. linear: (H, W, 3) float64.
    hits: Hits for the H * W pixel-centre rays (row-major).
    linear and hits are None for a render with ``keep=False`` (a streamed
    film: memory bounded by the band; no AOVs).
    position, normal: (H * W, 3) float64, NaN where no hit, computed from the
      hits on first use (a large film keeps only its hits).
    prelim: the preliminary map of the last band traced, the whole film's
      when it fits in one band (None for method "martin").
    stats: timings (seconds) and counters, JSON-serialisable.
    options: the settings it was rendered with; geometry: the scene's Geometry."""

    pixels: np.ndarray
    linear: np.ndarray
    hits: Hits
    prelim: PrelimMap | None
    stats: dict
    options: RenderOptions
    geometry: Geometry

    @cached_property
    def _frames(self):
        if self.hits is None:
            raise ValueError("this render kept no hits (keep=False): no positions, normals or AOVs")
        h, w = self.pixels.shape[:2]
        directions = pixel_rays(self.options.camera, w, h)
        return facing_frames(self.geometry.patches, self.hits, directions)[:2]

    @property
    def position(self) -> np.ndarray:
        return self._frames[0]

    @property
    def normal(self) -> np.ndarray:
        return self._frames[1]

    def __repr__(self) -> str:
        h, w = self.pixels.shape[:2]
        hit = self.stats.get("hits", 0)
        took = f", {sum(self.stats.get('seconds', {}).values()):.2f} s"
        return (
            f"<RenderResult {w}x{h}, {self.options.spp} spp, {self.options.method}, {hit} of {w * h} pixel rays "
            f"hit{took}>"
        )

    def to_pil(self):
        """The image as a ``PIL.Image.Image`` (RGB, 8-bit sRGB)."""
        from PIL import Image

        return Image.fromarray(self.pixels, "RGB")

    def save(self, path) -> None:
        """Write the image in the format its extension names (``.png``, ``.jpg``/``.jpeg``,
        ``.webp``: bsrt.rendering.image.IMAGE_FORMATS), atomically: a failure leaves no file. Another
        extension is an InputError, before anything is written."""
        from bsrt.rendering.image import write_image

        write_image(path, self.pixels)

    def png_bytes(self) -> bytes:
        """The image encoded as PNG."""
        import io

        buffer = io.BytesIO()
        self.to_pil().save(buffer, format="PNG")
        return buffer.getvalue()

    def _repr_png_(self) -> bytes:  # Jupyter shows the image
        return self.png_bytes()

    def aovs(self) -> dict:
        """The arrays of ``--aov`` (keys, dtypes and shapes of the scene format)."""
        h, w = self.pixels.shape[:2]
        normal, hits = self.normal, self.hits  # (raises first if the render kept no hits)
        return {
            "hit": hits.hit.reshape(h, w),
            "t": hits.t.reshape(h, w),
            "surface": hits.surface.astype(np.int32).reshape(h, w),
            "u": hits.u.reshape(h, w),
            "v": hits.v.reshape(h, w),
            "position": self.position.reshape(h, w, 3),
            "normal": normal.reshape(h, w, 3),
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
        self.diagonal = max(self.patches.scene_diagonal(), 1e-300)
        self._bvh = None

    @property
    def bvh(self):
        if self._bvh is None:
            self._bvh = build_bvh(self.patches)
        return self._bvh

    def intersect(self, origins, directions, **kwargs) -> Hits:
        """bvh.intersect with this geometry's hierarchy (see there for the arguments)."""
        return intersect(self.bvh, origins, directions, **kwargs)


def sample_grid(spp: int) -> tuple[int, int]:
    """(columns, rows) of the stratified sub-pixel grid: columns * rows = spp, as
    square as possible, columns <= rows (so a row of the sample film is at most
    width * sqrt(spp) samples, even for a prime spp: 1 x spp)."""
    columns = max(d for d in range(1, int(np.sqrt(spp)) + 1) if spp % d == 0)
    return columns, spp // columns


def render(
    scene: Scene,
    options: RenderOptions | None = None,
    *,
    geometry: Geometry | None = None,
    ctx=None,
    prelim: PrelimMap | None = None,
    progress=None,
    keep: bool = True,
) -> RenderResult:
    """Render a scene with ``options`` (default: the scene's own settings).

    geometry: the scene's Geometry, when the caller keeps one across renders.
    ctx: a moderngl context for the map (default: the process's headless EGL
    context). prelim: a map already rendered for options.camera and the whole
    film (the preview window rasterises it on its own context, then solves
    elsewhere; spp = 1 only). progress: called as ``progress(stage,
    fraction)`` with a stage name ("map", "solve", "shade", "aov", "done") and
    the fraction (0..1) of the whole render done (bands traced and shaded,
    secondary rays included); it may raise to abandon the render. keep: hold
    the linear image and every pixel-centre ray's hit for the result (its
    ``linear``, ``hits``, ``aovs()``); False streams the film (rendering/film.py):
    memory bounded by the band whatever the film's size, pixels and stats only.

    Anti-aliasing: spp samples per pixel sit at the centres of a stratified
    columns x rows grid (sample_grid), which is exactly the pixel-centre grid
    of a film spp times larger; that film is traced band by band (each band
    with its own preliminary map, so every sample is seeded; a band may end
    inside a pixel row) and box-filtered down. The AOVs always describe the pixel-centre rays (a second pass when
    spp > 1).
    """
    opts = options or RenderOptions.resolve(scene)
    width, height, spp = opts.width, opts.height, opts.spp
    report = progress or (lambda stage, fraction=0.0: None)
    stats = Stats(method=opts.method, map=opts.map if opts.uses_map else None, width=width, height=height, spp=spp)
    stats.loaded(getattr(scene, "loads", ()))  # the model files' load, which came before (bsrt/scene/loading.py)
    with stats.timer("setup"):
        geometry = geometry or Geometry(scene)
        _ = geometry.bvh  # built here, not inside the first stage that needs it
    tracer = make_primary_tracer(opts, geometry, stats, report, ctx)
    shader = _Shader(scene, opts, geometry, stats, report)
    cols, rows = sample_grid(spp)
    sample_w, sample_h = width * cols, height * rows
    band = max(1, MAX_BAND_SAMPLES // sample_w)  # sample rows; a band may end inside a pixel row
    if prelim is not None and (spp != 1 or prelim.surface.shape != (height, width)):
        raise ValueError(f"a precomputed map needs spp = 1 and the film's size {width}x{height}")
    film = Film(width, height, cols, rows, band, keep)
    total = sample_h + (height if spp > 1 else 0)  # the AOV pass counts as one more sample
    for first in range(0, sample_h, band):
        stop = min(sample_h, first + band)
        hits, directions = tracer.trace(sample_w, sample_h, (first, stop), prelim, first / total)
        shader.begin_band(hits, (first / total, stop / total))
        with stats.timer("shade"):
            colour = shader.shade(hits, directions)
            film.add(colour, first, stop)
        del colour, directions
        if spp == 1:
            film.put_hits(first * width, hits)
    if spp > 1:  # the AOVs: pixel-centre rays
        band = max(1, MAX_BAND_SAMPLES // width)
        for first in range(0, height, band):
            report("aov", (sample_h + first) / total)
            stop = min(height, first + band)
            hits, _ = tracer.trace(width, height, (first, stop), None)
            film.put_hits(first * width, hits)
    report("done", 1.0)
    stats.fields.update(
        pixels=width * height,
        hits=film.hit_count,
        iterations_mean=film.iterations_sum / film.iterations_count if film.iterations_count else 0.0,
        iterations_max=film.iterations_max,
    )
    return RenderResult(film.pixels, film.linear, film.hits, tracer.last_map, stats.as_dict(), opts, geometry)


class _Shader:
    """Colour along rays: Blinn-Phong with shadow rays to every point and
    directional light (one compiled pass per slice of hits: kernels/lighting.py),
    and mirror reflection up to options.max_depth bounces."""

    def __init__(self, scene: Scene, options: RenderOptions, geometry: Geometry, stats: Stats, report):
        self.scene, self.options, self.geometry, self.stats, self.report = scene, options, geometry, stats, report
        self.tolerance = options.tolerance * geometry.diagonal
        self.reflectance = np.array([m.reflectance for m in scene.materials])
        mats = scene.materials
        self.materials = (
            np.array([m.color for m in mats], dtype=np.float64).reshape(-1, 3),
            np.array([m.specular for m in mats], dtype=np.float64),
            np.array([m.shininess for m in mats], dtype=np.float64),
        )
        self.lights = light_arrays(scene.lights)
        self.background = np.array(options.background, dtype=np.float64).reshape(3)
        self.span, self.expected, self.traced, self.shown = (0.0, 1.0), 1, 0, 0.0
        self.casting = sum(light.kind != "ambient" for light in scene.lights)
        stats.add("shadow_rays", 0)
        stats.add("reflection_rays", 0)

    def begin_band(self, hits: Hits, span: tuple[float, float]) -> None:
        """Progress of the band's shading is reported within span (fractions of the render),
        against an estimate of its secondary rays (one shadow ray per hit and light, and a bounce where mirrors are)."""
        mirrors = 2 if np.any(self.reflectance > 0) and self.options.max_depth > 0 else 1
        self.span, self.traced = span, 0
        self.expected = max(1, int(hits.hit.sum()) * max(self.casting, 1) * mirrors)

    def _advance(self, rays: int) -> None:
        lo, hi = self.span
        self.traced += rays
        self.shown = max(self.shown, lo + (hi - lo) * min(0.99, self.traced / self.expected))
        self.report("shade", self.shown)

    def shade(self, hits: Hits, directions: np.ndarray, depth: int = 0):
        """Linear RGB (K, 3) seen along each ray (ending at ``hits``); directions: (K, 3) unit."""
        n = len(hits)
        directions = np.ascontiguousarray(directions, dtype=np.float64)
        colour, position, normal = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        radius, shadow_rays = np.empty((n, 2)), np.empty(n, dtype=np.int64)
        geometry = self.geometry
        bvh = geometry.bvh
        for a in range(0, n, SECONDARY_CHUNK):  # progress and cancellation points
            part = slice(a, min(n, a + SECONDARY_CHUNK))
            run_chunks(
                shade_hits,
                part.stop - part.start,
                geometry.patches.arrays,
                geometry.patches.trims,
                bvh.arrays,
                hits.hit[part],
                hits.patch[part],
                hits.surface[part],
                hits.u[part],
                hits.v[part],
                directions[part],
                geometry.material,
                *self.materials,
                *self.lights,
                self.background,
                1e-6 * geometry.diagonal,
                float(self.tolerance),
                SHADOW_ITERATIONS,
                DEFAULT_RETRY_DEPTH,
                bvh.padding + float(self.tolerance),
                colour[part],
                position[part],
                normal[part],
                radius[part],
                shadow_rays[part],
                min_chunk=256,
            )
            rays = int(shadow_rays[part].sum())
            self.stats.add("shadow_rays", rays)
            self._advance(rays)
        hit = np.flatnonzero(hits.hit)
        if not hit.size or depth >= self.options.max_depth:
            return colour
        reflectance = self.reflectance[geometry.material[hits.surface[hit]]]
        mirror = hit[reflectance > 0]
        if mirror.size:
            d, nrm = directions[mirror], normal[mirror]
            r = d - 2.0 * np.einsum("ij,ij->i", d, nrm)[:, None] * nrm
            self.stats.add("reflection_rays", mirror.size)
            exclude = (hits.surface[mirror], hits.u[mirror], hits.v[mirror], radius[mirror, 0], radius[mirror, 1])
            seen = self._trace(position[mirror], r, exclude)
            reflected = self.shade(seen, r, depth + 1)
            k = reflectance[reflectance > 0][:, None]
            colour[mirror] = (1.0 - k) * colour[mirror] + k * reflected
        return colour

    def _trace(self, origins, directions, exclude) -> Hits:
        """Mirror rays through the hierarchy, nearest hits, in chunks (progress, cancellation)."""
        parts = []
        n = directions.shape[0]
        with self.stats.timer("secondary"):
            for a in range(0, n, SECONDARY_CHUNK):
                part = slice(a, min(n, a + SECONDARY_CHUNK))
                parts.append(
                    self.geometry.intersect(
                        origins[part],
                        directions[part],
                        t_min=0.0,
                        tolerance=self.tolerance,
                        exclude=tuple(x[part] for x in exclude),
                    )
                )
                self._advance(part.stop - part.start)
        return Hits.concatenate(parts) if parts else Hits.empty(0)
