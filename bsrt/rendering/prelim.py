"""The preliminary map (paper 2.1): OpenGL seeds for every pixel's root finder.

Each Bezier patch is tessellated into a grid fine enough that its chords stay
within half a pixel of the surface (map_mesh.py). OpenGL rasterises the
triangles, then the edges that outline each surface's picture as lines (so
slivers thinner than a pixel still leave fragments; map_mesh.outline_edges),
with a depth test into two targets: the map itself (red = surface
index + 1, green/blue = u, v normalised over the surface's domain), either
32-bit float or the paper's 8-bit RGBA decoded with eq. 6, and the distance
from the eye (32-bit float). Arrays leave this module; no GL object does (the
framebuffers of small maps stay on the context, gl.keep, for the next map).

Trimmed surfaces: map_mesh.py cuts the cells trim curves cross into pieces
drawn plainly or with shaders/trim.glsl's test per fragment (the TRIM_TEST
variant of shaders/prelim.glsl), so the depth test keeps the nearest *kept*
surface.
"""

from __future__ import annotations

from contextlib import closing, contextmanager
from dataclasses import dataclass

import moderngl
import numpy as np

from bsrt.errors import InputError, RenderError
from bsrt.geometry.patches import PatchSet
from bsrt.kernels.prelim import decode_tile
from bsrt.kernels.threads import run_chunks
from bsrt.rendering import gl
from bsrt.rendering.map_mesh import _tessellation, depth_range, far_distance
from bsrt.rendering.trim_gl import TrimTextures
from bsrt.scene.camera import Camera, clip_from_eye
from bsrt.settings import MAP_MODES

TILE: int | None = None  # largest framebuffer side drawn at once; None: the GL context's limit


@dataclass
class PrelimMap:
    """Per-pixel seeds, row 0 at the top.

    surface: (H, W) int64 surface index, -1 where the map is empty.
    u, v: (H, W) float64 starting parameters in the surface's knot domain
      (NaN where empty). distance: (H, W) float64 eye distance of the
      rasterised triangle (inf where empty). picture: (H, W, 3) uint8 the map
      as the paper's Figure 1 shows it (r = index + 1, g, b = u, v in 0..255).
    """

    surface: np.ndarray
    u: np.ndarray
    v: np.ndarray
    distance: np.ndarray
    picture: np.ndarray

    @classmethod
    def blank(cls, shape: tuple[int, int]) -> PrelimMap:
        """A map of shape (H, W) left uninitialised (np.empty), for a decode that writes every pixel."""
        return cls(
            np.empty(shape, dtype=np.int64),
            np.empty(shape),
            np.empty(shape),
            np.empty(shape),
            np.empty(shape + (3,), dtype=np.uint8),
        )

    def rows(self, first: int, stop: int) -> PrelimMap:
        """The map of film rows first..stop-1 (views, not copies)."""
        return PrelimMap(*(a[first:stop] for a in (self.surface, self.u, self.v, self.distance, self.picture)))


def render_map(
    patches: PatchSet,
    camera: Camera,
    width: int,
    height: int,
    mode: str = "float",
    ctx=None,
    rows=None,
    tile: int | None = None,
) -> PrelimMap:
    """Rasterise the preliminary map for a width x height film.

    mode: "float" (32-bit channels) or "rgba8" (the paper's 8-bit map, at
    most 255 surfaces). ctx: a moderngl context (default: the process's
    headless EGL context). rows: (first, stop) to rasterise only that band
    of film rows (the arrays are then (stop - first, width)). tile: the
    largest framebuffer side drawn at once (default: the context's limit,
    gl.max_framebuffer_side, or TILE when set); a larger film is drawn tile by tile, each tile
    with the off-centre projection of its own pixels.
    """
    first, stop = rows if rows is not None else (0, height)
    out = PrelimMap.blank((stop - first, width))
    domain = np.ascontiguousarray(patches.domain, dtype=np.float64)
    with drawn_tiles(patches, camera, width, height, mode, ctx, rows, tile) as drawn:
        for passes, (r0, _), (c0, _) in drawn:
            passes.tri.read()
            passes.line.read()
            tri, line = passes.tri, passes.line
            run_chunks(
                decode_tile,
                tri.size[0] * tri.size[1],
                tri.raw,
                tri.distance,
                line.raw,
                line.distance,
                mode == "float",
                domain,
                r0 - first,
                c0,
                out.surface,
                out.u,
                out.v,
                out.distance,
                out.picture,
            )
    return out


@contextmanager
def drawn_tiles(
    patches: PatchSet, camera: Camera, width: int, height: int, mode="float", ctx=None, rows=None, tile=None
):
    """The map of render_map's arguments drawn tile by tile on the GPU, left there.

    Yields an iterator of (passes, (r0, r1), (c0, c1)): film rows r0..r1-1
    and columns c0..c1-1 drawn into passes (_Passes: the triangle and the
    line pass, each a _Target whose color and eye_distance textures hold
    the tile, OpenGL's row 0 at the bottom, until the next tile is drawn).
    ctx (default: the headless context) is current throughout; what was
    made is released on leaving, and an OpenGL error raises RenderError.
    render_map reads the passes back and decodes them; the GPU path
    (rendering/gpu_map.py) solves from the textures where they are.
    """
    if mode not in MAP_MODES:
        raise InputError(f"map: expected one of {', '.join(MAP_MODES)}, got {mode!r}")
    if mode == "rgba8" and len(patches.surfaces) > 255:
        raise InputError(
            f"map: the 8-bit map (rgba8) holds at most 255 surfaces in its red channel, "
            f'the scene has {len(patches.surfaces)}; use map = "float"'
        )
    ctx = ctx or gl.headless_context()
    first, stop = rows if rows is not None else (0, height)
    with ctx:  # current on this thread for the duration (another context may be current)
        side = tile or TILE or gl.max_framebuffer_side(ctx)
        with closing(_draw_tiles(patches, camera, width, mode, ctx, (first, stop), height, side)) as drawn:
            yield drawn


def tiles(first: int, stop: int, width: int, side: int):
    """The (rows, columns) ranges, each (start, stop), that cover film rows
    first..stop-1 and all width columns in tiles of at most side x side."""
    return [
        ((r, min(stop, r + side)), (c, min(width, c + side)))
        for r in range(first, stop, side)
        for c in range(0, width, side)
    ]


def window(matrix: np.ndarray, columns: tuple[int, int], width: int) -> np.ndarray:
    """The (4, 4) projection ``matrix`` of the whole film narrowed to film
    columns columns[0]..columns[1]-1 (the x of clip_from_eye's rows)."""
    left, right = -1.0 + 2.0 * columns[0] / width, -1.0 + 2.0 * columns[1] / width
    centre, half = (left + right) / 2.0, (right - left) / 2.0
    out = matrix.copy()
    out[0] = (matrix[0] - centre * matrix[3]) / half
    return out


def _draw_tiles(patches, camera, width, mode, ctx, rows, height, side):
    """drawn_tiles' iterator (a generator: closing it releases what it made)."""
    near, far = depth_range(patches, camera)
    mesh = _tessellation(patches, camera, width, height)
    program = gl.program(ctx, "prelim")
    programs = [program]
    trim_program = None
    if mesh.tested.shape[0]:  # the variant only where a trim curve crosses a drawn cell
        trim_program = gl.program(ctx, "prelim", ("TRIM_TEST",))
        programs.append(trim_program)
    for prog in programs:
        prog["id_scale"].value = 1.0 if mode == "float" else 1.0 / 255.0
        prog["inv_far"].value = 1.0 / far_distance(patches, camera)
    first, stop = rows
    dtype = "f4" if mode == "float" else "f1"
    resources = []
    draws = []  # (vertex array, primitive, pass): triangles into the triangle pass, lines into the line pass
    try:
        if mesh.indices.shape[0]:
            vbo = ctx.buffer(mesh.vertices)
            resources.insert(0, vbo)
            layout = [(vbo, "3f 2f 1f", "position", "uv", "surface_id")]
            for index, primitive, target in (
                (mesh.indices, moderngl.TRIANGLES, "tri"),
                (mesh.edges, moderngl.LINES, "line"),
            ):
                ibo = ctx.buffer(index)
                resources.insert(0, ibo)
                resources.insert(0, ctx.vertex_array(program, layout, index_buffer=ibo, index_element_size=4))
                draws.append((resources[0], primitive, target))
        if trim_program is not None:
            trims = TrimTextures(ctx, patches.trims)
            resources.insert(0, trims)
            trims.use(trim_program)
            vbo = ctx.buffer(mesh.tested)
            resources.insert(0, vbo)
            layout = [(vbo, "3f 2f 1f 2f 2f", "position", "uv", "surface_id", "param", "reach")]
            resources.insert(0, ctx.vertex_array(trim_program, layout))
            draws.append((resources[0], moderngl.TRIANGLES, "tri"))
            ibo = ctx.buffer(mesh.tested_edges)
            resources.insert(0, ibo)
            resources.insert(0, ctx.vertex_array(trim_program, layout, index_buffer=ibo, index_element_size=4))
            draws.append((resources[0], moderngl.LINES, "line"))
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        for (r0, r1), (c0, c1) in tiles(first, stop, width, side):
            matrix = window(clip_from_eye(camera, width, height, near, far, (r0, r1)), (c0, c1), width)
            for prog in programs:
                prog["clip_from_eye"].write(matrix.T.astype("f4").tobytes())
            size = (c1 - c0, r1 - r0)
            passes = _passes(ctx, size, dtype, resources)
            # The outline's edges (map_mesh.outline_edges) as lines, in a pass of
            # its own: a sliver thinner than a pixel covers no pixel centre, but
            # its edges still leave fragments. They fill pixels the triangles left empty and win
            # where they show a nearer other surface (decode_tile); elsewhere the
            # triangles' exact pixel-centre values stay.
            for name in ("tri", "line"):
                target = getattr(passes, name)
                target.start(ctx)
                for vao, primitive, into in draws:
                    if into == name:
                        vao.render(primitive)
            yield passes, (r0, r1), (c0, c1)
        error = ctx.error
        if error != "GL_NO_ERROR":
            raise RenderError(f"OpenGL reported {error} while rendering the preliminary map")
    finally:
        gl.bind_default_framebuffer(ctx)
        for res in resources:
            res.release()


# Framebuffers of tiles up to this many pixels (88 bytes each: two passes' GL
# targets and read-back arrays) stay on the context for the next map of that
# size: the bands of a film (pipeline.MAX_BAND_SAMPLES and two rows) and the
# preview's frames reuse theirs. Made anew for each of a 4096x4096 film's 32
# bands they cost 0.1 s of its 0.6 s map; kept, 47 MB more at its peak.
# Larger ones are given back after each map.
KEEP_PIXELS = 1 << 20


def _passes(ctx, size, dtype, resources) -> _Passes:
    """The two passes' framebuffers for a tile of size (w, h): kept on ctx
    (gl.keep) when small enough, else made here and appended to resources
    (released by the caller)."""
    if size[0] * size[1] <= KEEP_PIXELS:
        return gl.keep(ctx, ("prelim", size, dtype), lambda: _Passes(ctx, size, dtype))
    passes = _Passes(ctx, size, dtype)
    resources.insert(0, passes)
    return passes


class _Passes:
    """The triangle pass's and the line pass's framebuffers (_Target) of one tile size."""

    def __init__(self, ctx, size, dtype):
        self.tri = _Target(ctx, size, dtype)
        try:
            self.line = _Target(ctx, size, dtype)
        except BaseException:
            self.tri.release()
            raise

    def release(self) -> None:
        self.tri.release()
        self.line.release()


class _Target:
    """A framebuffer (map colour, eye distance, depth) of size (w, h) and the
    arrays its pixels are read into: raw (h, w, 4) float32 or uint8 and
    distance (h, w) float32, row 0 at the bottom (OpenGL's order). color,
    eye_distance: its two colour attachments (textures)."""

    def __init__(self, ctx, size, dtype):
        self.size, self.dtype, self.parts = size, dtype, []
        try:
            for make in (
                lambda: ctx.texture(size, 4, dtype=dtype),
                lambda: ctx.texture(size, 1, dtype="f4"),
                lambda: ctx.depth_renderbuffer(size),
            ):
                self.parts.append(make())
            self.color, self.eye_distance, depth = self.parts
            self.fbo = ctx.framebuffer(color_attachments=[self.color, self.eye_distance], depth_attachment=depth)
        except BaseException:
            self.release()
            raise
        self.parts.insert(0, self.fbo)
        self.raw = np.empty((size[1], size[0], 4), dtype=np.float32 if dtype == "f4" else np.uint8)
        self.distance = np.empty((size[1], size[0]), dtype=np.float32)

    def start(self, ctx) -> None:
        """Bind and clear the framebuffer for drawing."""
        self.fbo.use()
        ctx.viewport = (0, 0) + tuple(self.size)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)

    def read(self) -> None:
        """Read the pixels into raw and distance (waits for the drawing)."""
        self.fbo.read_into(self.raw, components=4, dtype=self.dtype, attachment=0)
        self.fbo.read_into(self.distance, components=1, dtype="f4", attachment=1)

    def release(self) -> None:
        for res in self.parts:
            res.release()
        self.parts = []
