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
from functools import cached_property, partial

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.rendering import gpu
from bsrt.rendering.bvh import (
    DEFAULT_MAX_ITERATIONS,
    build_bvh,
    intersect,
    out_of_budget,
    ray_budget,
)
from bsrt.rendering.film import Film
from bsrt.rendering.gpu_shade import trace_gpu
from bsrt.rendering.hits import Hits
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.prelim import PrelimMap
from bsrt.rendering.shade import Shader, facing_frames
from bsrt.rendering.stats import Stats
from bsrt.rendering.trace import make_primary_tracer
from bsrt.scene import Scene
from bsrt.scene.camera import pixel_rays

MAX_BAND_SAMPLES = 1 << 19  # samples traced at once: bounds the memory of primary and secondary rays


@dataclass(eq=False)
class RenderResult:
    """pixels: (H, W, 3) uint8 sRGB. linear: (H, W, 3) float64.
    hits: Hits for the H * W pixel-centre rays (row-major).
    linear and hits are None for a render with ``keep=False`` (a streamed
    film: memory bounded by the band; no AOVs).
    position, normal: (H * W, 3) float64, NaN where no hit: the shading's own for a render with
      ``aovs=True`` and one sample a pixel, else computed from the hits on first use.
    prelim: the preliminary map of the last band traced, the whole film's
      when it fits in one band (None for method "martin").
    stats: timings (seconds) and counters, JSON-serialisable.
    options: the settings it was rendered with; geometry: the scene's Geometry.
    coverage: (H, W) float64, the fraction of each pixel's samples that hit a surface
      (the alpha of a transparent picture)."""

    pixels: np.ndarray
    linear: np.ndarray
    hits: Hits
    prelim: PrelimMap | None
    stats: dict
    options: RenderOptions
    geometry: Geometry
    coverage: np.ndarray | None = None
    frames: tuple[np.ndarray, np.ndarray] | None = None  # (position, normal) the shading kept (render's aovs)

    @property
    def image(self) -> np.ndarray:
        """What ``save`` writes: (H, W, 3) RGB, or (H, W, 4) RGBA with the coverage as alpha when
        options.transparent; uint8, or uint16 when options.bit_depth is 16 (sRGB)."""
        return encode_picture_8(self) if self.options.bit_depth == 8 else self._encoded(16)

    def _encoded(self, bits: int) -> np.ndarray:
        from bsrt.rendering.image import encode_picture

        coverage = np.ones(self.linear.shape[:2]) if self.coverage is None else self.coverage
        return encode_picture(self.linear, coverage, self.options.background, self.options.transparent, bits)

    @cached_property
    def _frames(self):
        if self.hits is None:
            raise ValueError("this render kept no hits (keep=False): no positions, normals or AOVs")
        if self.frames is not None:
            return self.frames
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
        """The image as a ``PIL.Image.Image`` (8-bit sRGB: RGB, or RGBA when transparent)."""
        from PIL import Image

        if self.options.transparent:
            return Image.fromarray(encode_picture_8(self), "RGBA")
        return Image.fromarray(self.pixels, "RGB")

    def save(self, path) -> None:
        """Write the image in the format its extension names (``.png``, ``.jpg``/``.jpeg``,
        ``.webp``: bsrt.rendering.image.IMAGE_FORMATS), atomically: a failure leaves no file. Another
        extension, or one that cannot hold the picture (JPEG with transparency, 16 bits but PNG),
        is an InputError, before anything is written."""
        from bsrt.rendering.image import write_image

        write_image(path, self.image)

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


def encode_picture_8(result: RenderResult) -> np.ndarray:
    """The result's picture as 8-bit (H, W, 3|4) uint8, whatever its bit depth. Opaque, it is the
    film's pixels: every path that writes the linear image writes their sRGB bytes with it
    (kernels/film.py's add_samples, the adaptive samples, the edges: the same bytes as
    srgb_encode of the linear image, tests/test_render.py), so they are not encoded again (1.2 s
    of one core at 2048 x 2048)."""
    if result.linear is None or not result.options.transparent:  # (a streamed film: opaque and 8-bit)
        return result.pixels
    return result._encoded(8)


class Geometry:
    """A scene's surfaces prepared for tracing: the patch table and, built on
    first use, the Martin et al. hierarchy. Reuse it across renders of the
    same scene (the preview window does). cache: both come from the
    prepared-geometry cache (rendering/prepared.py), built and stored there
    if they are not in it."""

    def __init__(self, scene: Scene, cache: bool = False):
        surfaces = [s.geometry for s in scene.surfaces]
        if cache:
            from bsrt.rendering import prepared

            self.patches, self._bvh = prepared.load(surfaces, lambda: _prepare(surfaces))
        else:
            self.patches, self._bvh = PatchSet(surfaces), None
        self.material = np.array([s.material for s in scene.surfaces], dtype=np.int64)
        self.diagonal = max(self.patches.scene_diagonal(), 1e-300)
        self.out_of_budget = 0  # rays that spent their budget in the hierarchy (bvh.py, "Budget"), all renders

    @property
    def bvh(self):
        if self._bvh is None:
            self._bvh = build_bvh(self.patches)
        return self._bvh

    def intersect(self, origins, directions, gpu=None, **kwargs) -> Hits:
        """bvh.intersect with this geometry's hierarchy (see there for the arguments), the rays that
        spent their budget counted in out_of_budget. gpu: a context (gpu.choose_device's) whose
        nearest-hit walk traces the rays instead (gpu_shade.trace_gpu: the same hits, t within a
        few roundings; not any_hit)."""
        budget = kwargs.pop("budget", None) or ray_budget(kwargs.get("max_iterations", DEFAULT_MAX_ITERATIONS))
        trace = intersect if gpu is None else partial(trace_gpu, gpu)
        hits = trace(self.bvh, origins, directions, budget=budget, **kwargs)
        self.out_of_budget += out_of_budget(hits, budget)
        return hits


def _prepare(surfaces: list):
    """(PatchSet, BVH) of ``surfaces`` (a list of BSplineSurface), built."""
    patches = PatchSet(surfaces)
    return patches, build_bvh(patches)


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
    cache: bool = False,
    aovs: bool = False,
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
    cache: without ``geometry``, take the scene's patch table and hierarchy from the
    prepared-geometry cache (rendering/prepared.py), storing them there if absent.
    aovs: the caller will ask for the result's AOVs (implies keep): with one sample a pixel,
    shaded on the CPU, the shading's positions and normals of the pixel-centre hits are kept
    (48 bytes a pixel more) rather than evaluated again from the hits (the same values).

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
    radius = None
    with stats.timer("setup"):
        if opts.ground and geometry is None:  # the ground plane: one more surface (bsrt/rendering/occlusion.py)
            from bsrt.rendering.occlusion import with_ground

            scene, radius = with_ground(scene)
        geometry = geometry or Geometry(scene, cache)
        _ = geometry.bvh  # built here, not inside the first stage that needs it
    spent_before = geometry.out_of_budget
    tracer = make_primary_tracer(opts, geometry, stats, report, ctx)
    shader = Shader(scene, opts, geometry, stats, report, radius, gpu.choose_device(opts.device, ctx)[1])
    cols, rows = sample_grid(spp)
    sample_w, sample_h = width * cols, height * rows
    band = max(1, MAX_BAND_SAMPLES // sample_w)  # sample rows; a band may end inside a pixel row
    if prelim is not None and (spp != 1 or prelim.surface.shape != (height, width)):
        raise ValueError(f"a precomputed map needs spp = 1 and the film's size {width}x{height}")
    # a transparent or 16-bit picture is encoded from the linear image; edges read the pixel-centre hits
    keep = keep or aovs or opts.transparent or opts.bit_depth != 8 or opts.edges
    film = Film(width, height, cols, rows, band, keep, frames=aovs and spp == 1 and shader.gpu is None)
    total = sample_h + (height if spp > 1 else 0)  # the AOV pass counts as one more sample
    for first in range(0, sample_h, band):
        stop = min(sample_h, first + band)
        hits, directions = tracer.trace(sample_w, sample_h, (first, stop), prelim, first / total)
        shader.begin_band(hits, (first / total, stop / total))
        with stats.timer("shade"):
            colour = shader.shade(hits, directions, frames=film.frame_rows(first, stop))
            film.add(colour, hits.hit, first, stop)
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
    coverage = film.coverage if keep else None  # (H, W) float64: only a kept film's result holds it
    if spp == 1 and opts.adaptive_spp > 1:
        _adaptive(film.linear, film.pixels, coverage, film.hit_samples, tracer, shader, opts, geometry, stats)
    if opts.edges:
        from bsrt.rendering.edges import draw_over

        coverage = draw_over(film.linear, film.pixels, coverage, film.hits, opts, geometry, stats)
    report("done", 1.0)
    stats.fields.update(
        pixels=width * height,
        hits=film.hit_count,
        iterations_mean=film.iterations_sum / film.iterations_count if film.iterations_count else 0.0,
        iterations_max=film.iterations_max,
    )
    stats.add("out_of_budget", geometry.out_of_budget - spent_before)
    return RenderResult(
        film.pixels, film.linear, film.hits, tracer.last_map, stats.as_dict(), opts, geometry, coverage, film.frames
    )


def _adaptive(
    linear, pixels, coverage, centre_hits, tracer, shader, opts: RenderOptions, geometry: Geometry, stats
) -> None:
    """Adaptive anti-aliasing of a one-sample render (rendering/antialias.py), in place
    (centre_hits: (H, W), the film's samples that hit per pixel)."""
    from bsrt.rendering.antialias import refine

    def trace(directions):  # on the CPU on either device (shade.GPU_SECONDARY)
        return geometry.intersect(opts.camera.eye[None, :], directions, tolerance=tracer.tolerance)

    def shade(hits, directions):
        shader.begin_band(hits, (1.0, 1.0))
        with stats.timer("shade"):
            return shader.shade(hits, directions)

    grid = sample_grid(opts.adaptive_spp)
    refine(linear, pixels, coverage, grid, shade, trace, opts, stats, MAX_BAND_SAMPLES, centre_hits)
