"""The preliminary map (paper 2.1): OpenGL seeds for every pixel's root finder.

Each Bezier patch is tessellated into a grid fine enough that its chords stay
within half a pixel of the surface (the second-difference bound of Filip,
Magedson & Markot 1986, with the pixel footprint at the patch's nearest
distance), capped at 64 x 64 quads per patch. OpenGL rasterises the
triangles, then their edges as lines (so slivers thinner than a pixel still
leave fragments), with a depth test into two targets: the map itself (red = surface
index + 1, green/blue = u, v normalised over the surface's domain), either
32-bit float or the paper's 8-bit RGBA decoded with eq. 6, and the distance
from the eye (32-bit float). Arrays leave this module; no GL object does (the
framebuffers of small maps stay on the context, gl.keep, for the next map).
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from . import gl
from .camera import Camera, clip_from_eye, pixel_footprint
from .errors import InputError, RenderError
from .kernels.prelim import decode_tile
from .kernels.threads import run_chunks
from .kernels.trim import OUTSIDE, classify_grid
from .patches import PatchSet
from .settings import MAP_MODES

MAX_SEGMENTS = 64
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

    def rows(self, first: int, stop: int) -> "PrelimMap":
        """The map of film rows first..stop-1 (views, not copies)."""
        return PrelimMap(*(a[first:stop] for a in (self.surface, self.u, self.v, self.distance, self.picture)))


def segments_per_patch(patches: PatchSet, camera: Camera, width: int, height: int) -> np.ndarray:
    """(P, 2) int64: quads along u and v for each patch (1..MAX_SEGMENTS)."""
    pixel_at_unit_distance = pixel_footprint(camera, width, height)
    lo, hi = patches.box_min, patches.box_max
    nearest = np.linalg.norm(np.maximum(np.maximum(lo - camera.eye, camera.eye - hi), 0.0), axis=1)
    diag = max(patches.scene_diagonal(), 1e-300)
    tolerance = 0.5 * pixel_at_unit_distance * np.maximum(nearest, 1e-3 * diag)
    m_uu, m_vv, m_uv = patches.bend.T
    # chord error <= (m_uu / n_u^2 + 2 m_uv / (n_u n_v) + m_vv / n_v^2) / 8
    n_u = np.sqrt((m_uu + m_uv) / (4.0 * tolerance))
    n_v = np.sqrt((m_vv + m_uv) / (4.0 * tolerance))
    return np.clip(np.ceil(np.stack([n_u, n_v], axis=1)), 1, MAX_SEGMENTS).astype(np.int64)


def tessellate(patches: PatchSet, segments: np.ndarray, eye: np.ndarray):
    """Watertight triangles of every surface.

    Each surface gets one grid whose lines include all its knots, every span
    cut into the largest segment count of that surface's patches, so patches
    share their border vertices exactly (no T-junctions, no cracks).
    segments: (P, 2) quads per patch. Returns (vertices (V, 6) float32 rows
    (x, y, z eye-relative, u_norm, v_norm, surface index + 1), indices (T, 3)
    uint32). Cells of a trimmed surface that its trims remove entirely are
    left out; cells the trim curves cross stay (the map then shows a little
    more than the kept region, and those pixels' roots are refused and
    repaired as hard pixels), so the map never misses a kept part.
    """
    verts, tris, base = [], [], 0  # every surface's grid vertices; the triangles of its kept cells
    for m in range(len(patches.surfaces)):
        mine = patches.surface == m
        n_u, n_v = segments[mine].max(axis=0)
        b = patches.bounds[mine]
        gu = _refined_breaks(np.unique(b[:, :2]), n_u)
        gv = _refined_breaks(np.unique(b[:, 2:]), n_v)
        u, v = np.meshgrid(gu, gv, indexing="ij")
        u, v = u.ravel(), v.ravel()
        sid = np.full(u.size, m)
        S = patches.evaluate(patches.locate(sid, u, v), u, v, derivatives=False)
        d = patches.domain[m]
        block = np.empty((u.size, 6), dtype=np.float32)
        block[:, :3] = (S.T - eye).astype(np.float32)
        block[:, 3] = (u - d[0]) / (d[1] - d[0])
        block[:, 4] = (v - d[2]) / (d[3] - d[2])
        block[:, 5] = m + 1
        verts.append(block)
        i, j = np.meshgrid(np.arange(gu.size - 1), np.arange(gv.size - 1), indexing="ij")
        i, j = i.ravel(), j.ravel()
        if patches.surfaces[m].is_trimmed:  # leave out the cells the trims remove entirely
            state = np.empty((gu.size - 1, gv.size - 1), dtype=np.int64)
            classify_grid(patches.trims, m, gu, gv, state)
            keep = state[i, j] != OUTSIDE
            i, j = i[keep], j[keep]
        corner = i * gv.size + j
        quad = np.stack([corner, corner + gv.size, corner + gv.size + 1, corner + 1], axis=1)
        tris.append(base + np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]))
        base += u.size
    return np.concatenate(verts), np.concatenate(tris).astype(np.uint32)


def _refined_breaks(breaks: np.ndarray, n: int) -> np.ndarray:
    """Every interval of the sorted breaks (K,) cut into n equal parts -> ((K-1) n + 1,)."""
    steps = np.linspace(0.0, 1.0, n + 1)[:-1]
    inner = (breaks[:-1, None] + np.diff(breaks)[:, None] * steps[None, :]).ravel()
    return np.concatenate([inner, breaks[-1:]])


def depth_range(patches: PatchSet, camera: Camera) -> tuple[float, float]:
    """(near, far) planes enclosing every control point in front of the eye."""
    lo, hi = patches.scene_box()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    _, _, f = camera.basis()
    depth = (corners - camera.eye) @ f
    far = max(float(depth.max()), 1e-300) * 1.1 + 1e-9  # generous: depth is tested on linear distance (far_distance)
    near = max(float(depth.min()) * 0.99, far * 1e-5)
    return near, far


def far_distance(patches: PatchSet, camera: Camera) -> float:
    """Beyond the farthest control point from the eye (the linear depth's scale)."""
    lo, hi = patches.scene_box()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return max(float(np.linalg.norm(corners - camera.eye, axis=1).max()), 1e-300) * 1.01


def render_map(patches: PatchSet, camera: Camera, width: int, height: int, mode: str = "float", ctx=None,
               rows=None, tile: int | None = None) -> PrelimMap:
    """Rasterise the preliminary map for a width x height film.

    mode: "float" (32-bit channels) or "rgba8" (the paper's 8-bit map, at
    most 255 surfaces). ctx: a moderngl context (default: the process's
    headless EGL context). rows: (first, stop) to rasterise only that band
    of film rows (the arrays are then (stop - first, width)). tile: the
    largest framebuffer side drawn at once (default: the context's limit,
    gl.max_framebuffer_side, or TILE when set); a larger film is drawn tile by tile, each tile
    with the off-centre projection of its own pixels.
    """
    if mode not in MAP_MODES:
        raise InputError(f"map: expected one of {', '.join(MAP_MODES)}, got {mode!r}")
    if mode == "rgba8" and len(patches.surfaces) > 255:
        raise InputError(
            f"map: the 8-bit map (rgba8) holds at most 255 surfaces in its red channel, "
            f"the scene has {len(patches.surfaces)}; use map = \"float\""
        )
    ctx = ctx or gl.headless_context()
    with ctx:  # current on this thread for the duration (another context may be current)
        return _rasterise(patches, camera, width, height, mode, ctx, rows, tile or TILE or gl.max_framebuffer_side(ctx))


def _tessellation(patches: PatchSet, camera: Camera, width: int, height: int):
    """tessellate() for this view and its triangles' edges (E, 6) uint32, cached
    (one entry on the PatchSet): the bands of one map, and repeated renders of
    one view, share it."""
    key = (tuple(camera.eye), tuple(camera.look_at), tuple(camera.up), camera.fov, camera.fov_axis, width, height)
    cached = patches.derived.get("tessellation")
    if cached is None or cached[0] != key:
        vertices, indices = tessellate(patches, segments_per_patch(patches, camera, width, height), camera.eye)
        edges = indices[:, [0, 1, 1, 2, 2, 0]]  # every triangle edge as a line
        mesh = tuple(np.ascontiguousarray(a) for a in (vertices, indices, edges))  # GL buffers take C order
        patches.derived["tessellation"] = cached = (key, mesh)
    return cached[1]


def tiles(first: int, stop: int, width: int, side: int):
    """The (rows, columns) ranges, each (start, stop), that cover film rows
    first..stop-1 and all width columns in tiles of at most side x side."""
    return [((r, min(stop, r + side)), (c, min(width, c + side)))
            for r in range(first, stop, side) for c in range(0, width, side)]


def window(matrix: np.ndarray, columns: tuple[int, int], width: int) -> np.ndarray:
    """The (4, 4) projection ``matrix`` of the whole film narrowed to film
    columns columns[0]..columns[1]-1 (the x of clip_from_eye's rows)."""
    left, right = -1.0 + 2.0 * columns[0] / width, -1.0 + 2.0 * columns[1] / width
    centre, half = (left + right) / 2.0, (right - left) / 2.0
    out = matrix.copy()
    out[0] = (matrix[0] - centre * matrix[3]) / half
    return out


def _rasterise(patches, camera, width, height, mode, ctx, rows, side) -> PrelimMap:
    near, far = depth_range(patches, camera)
    vertices, indices, edges = _tessellation(patches, camera, width, height)
    program = gl.program(ctx, "prelim")
    program["id_scale"].value = 1.0 if mode == "float" else 1.0 / 255.0
    program["inv_far"].value = 1.0 / far_distance(patches, camera)
    first, stop = rows if rows is not None else (0, height)
    shape = (stop - first, width)
    out = PrelimMap(np.empty(shape, dtype=np.int64), np.empty(shape), np.empty(shape), np.empty(shape),
                    np.empty(shape + (3,), dtype=np.uint8))
    domain = np.ascontiguousarray(patches.domain, dtype=np.float64)
    dtype = "f4" if mode == "float" else "f1"
    resources = []
    try:
        vbo = ctx.buffer(vertices)
        ibo = ctx.buffer(indices)
        edge_buffer = ctx.buffer(edges)
        layout = [(vbo, "3f 2f 1f", "position", "uv", "surface_id")]
        vao = ctx.vertex_array(program, layout, index_buffer=ibo, index_element_size=4)
        lines = ctx.vertex_array(program, layout, index_buffer=edge_buffer, index_element_size=4)
        resources = [lines, vao, edge_buffer, ibo, vbo]
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        for (r0, r1), (c0, c1) in tiles(first, stop, width, side):
            matrix = window(clip_from_eye(camera, width, height, near, far, (r0, r1)), (c0, c1), width)
            program["clip_from_eye"].write(matrix.T.astype("f4").tobytes())
            size = (c1 - c0, r1 - r0)
            passes = _passes(ctx, size, dtype, resources)
            tri, line = passes.tri, passes.line
            tri.draw(ctx, vao, moderngl.TRIANGLES)
            # Every triangle edge again as a line, in a pass of its own: a sliver
            # thinner than a pixel covers no pixel centre, but its edges still
            # leave fragments. They fill pixels the triangles left empty and win
            # where they show a nearer other surface (decode_tile); elsewhere the
            # triangles' exact pixel-centre values stay.
            line.draw(ctx, lines, moderngl.LINES)
            tri.read()
            line.read()
            run_chunks(decode_tile, size[0] * size[1], tri.raw, tri.distance, line.raw, line.distance, mode == "float",
                       domain, r0 - first, c0, out.surface, out.u, out.v, out.distance, out.picture)
        error = ctx.error
        if error != "GL_NO_ERROR":
            raise RenderError(f"OpenGL reported {error} while rendering the preliminary map")
    finally:
        gl.bind_default_framebuffer(ctx)
        for res in resources:
            res.release()
    return out


# Framebuffers of tiles up to this many pixels (88 bytes each: two passes' GL
# targets and read-back arrays) stay on the context for the next map of that
# size; larger ones are given back after each map, so a large film's bands
# peak no higher than before shading starts.
KEEP_PIXELS = 512 * 512


def _passes(ctx, size, dtype, resources) -> "_Passes":
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
    distance (h, w) float32, row 0 at the bottom (OpenGL's order)."""

    def __init__(self, ctx, size, dtype):
        self.size, self.dtype, self.parts = size, dtype, []
        try:
            for make in (lambda: ctx.texture(size, 4, dtype=dtype), lambda: ctx.texture(size, 1, dtype="f4"),
                         lambda: ctx.depth_renderbuffer(size)):
                self.parts.append(make())
            color, dist, depth = self.parts
            self.fbo = ctx.framebuffer(color_attachments=[color, dist], depth_attachment=depth)
        except BaseException:
            self.release()
            raise
        self.parts.insert(0, self.fbo)
        self.raw = np.empty((size[1], size[0], 4), dtype=np.float32 if dtype == "f4" else np.uint8)
        self.distance = np.empty((size[1], size[0]), dtype=np.float32)

    def draw(self, ctx, vao, mode) -> None:
        self.fbo.use()
        ctx.viewport = (0, 0) + tuple(self.size)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        vao.render(mode)

    def read(self) -> None:
        """Read the pixels into raw and distance (waits for the drawing)."""
        self.fbo.read_into(self.raw, components=4, dtype=self.dtype, attachment=0)
        self.fbo.read_into(self.distance, components=1, dtype="f4", attachment=1)

    def release(self) -> None:
        for res in self.parts:
            res.release()
        self.parts = []
