"""The preliminary map (paper 2.1): OpenGL seeds for every pixel's root finder.

Each Bezier patch is tessellated into a grid fine enough that its chords stay
within half a pixel of the surface (the second-difference bound of Filip,
Magedson & Markot 1986, with the pixel footprint at the patch's nearest
distance), capped at 64 x 64 quads per patch. OpenGL rasterises the
triangles, then their edges as lines (so slivers thinner than a pixel still
leave fragments), with a depth test into two targets: the map itself (red = surface
index + 1, green/blue = u, v normalised over the surface's domain), either
32-bit float or the paper's 8-bit RGBA decoded with eq. 6, and the distance
from the eye (32-bit float). Arrays leave this module; no GL object does.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from . import gl
from .camera import Camera, clip_from_eye, pixel_footprint
from .errors import InputError, RenderError
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
    """tessellate() for this view, cached (one entry on the PatchSet): the
    bands of one map, and repeated renders of one view, share it."""
    key = (tuple(camera.eye), tuple(camera.look_at), tuple(camera.up), camera.fov, camera.fov_axis, width, height)
    cached = patches.derived.get("tessellation")
    if cached is None or cached[0] != key:
        mesh = tessellate(patches, segments_per_patch(patches, camera, width, height), camera.eye)
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
    vertices, indices = _tessellation(patches, camera, width, height)
    program = gl.program(ctx, "prelim")
    program["id_scale"].value = 1.0 if mode == "float" else 1.0 / 255.0
    program["inv_far"].value = 1.0 / far_distance(patches, camera)
    first, stop = rows if rows is not None else (0, height)
    dtype = "f4" if mode == "float" else "f1"
    raw = np.zeros((stop - first, width, 4), dtype=np.float32 if dtype == "f4" else np.uint8)
    line_raw = np.zeros_like(raw)
    eye_distance = np.zeros((stop - first, width), dtype=np.float32)
    line_distance = np.zeros_like(eye_distance)
    resources = []
    try:
        vbo = ctx.buffer(vertices.tobytes())
        ibo = ctx.buffer(indices.tobytes())
        edges = ctx.buffer(indices[:, [0, 1, 1, 2, 2, 0]].tobytes())
        layout = [(vbo, "3f 2f 1f", "position", "uv", "surface_id")]
        vao = ctx.vertex_array(program, layout, index_buffer=ibo, index_element_size=4)
        lines = ctx.vertex_array(program, layout, index_buffer=edges, index_element_size=4)
        resources = [lines, vao, edges, ibo, vbo]
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        for (r0, r1), (c0, c1) in tiles(first, stop, width, side):
            matrix = window(clip_from_eye(camera, width, height, near, far, (r0, r1)), (c0, c1), width)
            program["clip_from_eye"].write(matrix.T.astype("f4").tobytes())
            out = (slice(r0 - first, r1 - first), slice(c0, c1))
            raw[out], eye_distance[out] = _draw(ctx, (c1 - c0, r1 - r0), dtype, vao, moderngl.TRIANGLES)
            # Every triangle edge again as a line, in a pass of its own: a sliver
            # thinner than a pixel covers no pixel centre, but its edges still
            # leave fragments. They fill pixels the triangles left empty and win
            # where they show a nearer other surface; elsewhere the triangles'
            # exact pixel-centre values stay.
            line_raw[out], line_distance[out] = _draw(ctx, (c1 - c0, r1 - r0), dtype, lines, moderngl.LINES)
        error = ctx.error
        if error != "GL_NO_ERROR":
            raise RenderError(f"OpenGL reported {error} while rendering the preliminary map")
    finally:
        gl.bind_default_framebuffer(ctx)
        for res in resources:
            res.release()
    tri_empty = raw[..., 0] == 0
    other = line_raw[..., 0] != raw[..., 0]  # another surface: a sliver in front
    nearer = (line_raw[..., 0] != 0) & (tri_empty | (other & (line_distance < eye_distance)))
    raw = np.where(nearer[..., None], line_raw, raw)
    eye_distance = np.where(nearer, line_distance, eye_distance)
    return decode_map(patches, raw, eye_distance, mode)


def _draw(ctx, size, dtype, vao, mode):
    """One pass into a fresh framebuffer (released here): (raw (H, W, 4), eye distance (H, W) float32), row 0 at the top."""
    width, height = size
    resources = []
    try:
        color = ctx.texture(size, 4, dtype=dtype)
        resources.append(color)
        dist = ctx.texture(size, 1, dtype="f4")
        resources.append(dist)
        depth = ctx.depth_renderbuffer(size)
        resources.append(depth)
        fbo = ctx.framebuffer(color_attachments=[color, dist], depth_attachment=depth)
        resources.append(fbo)
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        vao.render(mode)
        raw = np.frombuffer(fbo.read(components=4, dtype=dtype, attachment=0),
                            dtype=np.float32 if dtype == "f4" else np.uint8)
        distance = np.frombuffer(fbo.read(components=1, dtype="f4", attachment=1), dtype=np.float32)
    finally:
        gl.bind_default_framebuffer(ctx)
        for res in reversed(resources):
            res.release()
    return raw.reshape(height, width, 4)[::-1], distance.reshape(height, width)[::-1]


def decode_map(patches: PatchSet, raw: np.ndarray, eye_distance: np.ndarray, mode: str) -> PrelimMap:
    """Seeds from the raw map pixels (eq. 6 for the 8-bit map).

    raw: (H, W, 4) float32 (float mode: r = index + 1, g, b in [0, 1]) or
    uint8 (rgba8: r = index + 1, g, b in 0..255).
    """
    if mode == "float":
        ident = np.rint(raw[..., 0]).astype(np.int64) - 1
        g, b = raw[..., 1].astype(np.float64), raw[..., 2].astype(np.float64)
        picture = np.stack([np.clip(ident + 1, 0, 255), np.rint(g * 255), np.rint(b * 255)], axis=-1).astype(np.uint8)
    else:
        ident = raw[..., 0].astype(np.int64) - 1
        g, b = raw[..., 1] / 255.0, raw[..., 2] / 255.0
        picture = raw[..., :3].copy()
    covered = ident >= 0
    safe = np.where(covered, ident, 0)
    d = patches.domain[safe]
    u = np.where(covered, d[..., 0] + (d[..., 1] - d[..., 0]) * g, np.nan)  # eq. 6
    v = np.where(covered, d[..., 2] + (d[..., 3] - d[..., 2]) * b, np.nan)
    distance = np.where(covered, eye_distance.astype(np.float64), np.inf)
    return PrelimMap(np.where(covered, ident, -1), u, v, distance, picture)
