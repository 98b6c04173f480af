"""The preview's fast GL view and its textures: the preliminary map's
tessellation shaded with the scene's lights (no shadows, no mirrors) while
the camera moves, trimmed per fragment by the scene's trim table (the CPU
kernels' even-odd test in shaders/trim.glsl), and the solver's images (or
the map's picture) drawn as a full-window quad once they come. Owns every GL
object it creates and releases them in :meth:`View.close`.
shaders/preview.glsl.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import moderngl
import numpy as np

from bsrt.rendering import gl
from bsrt.rendering.trim_gl import TrimTextures
from bsrt.scene.camera import Camera, clip_from_eye

MAX_LIGHTS = 8
# The fast view's mesh is the map's tessellation for a film this fraction of
# the window (chord error <= 1 / (2 * FAST_VIEW_DETAIL) pixels): a quarter of
# the triangles at 0.5, which llvmpipe needs for many frames a second.
FAST_VIEW_DETAIL = 0.5
# A trimmed surface's fragments within about this many pixels (along x and y)
# of its trim curves are drawn too: the two faces on either side of a trimmed
# edge are tessellated apart, so their trimmed edges miss each other by up to
# about a pixel and the background would show through. On bearing.iges 0.5
# closes nearly all of those pinholes, as 1.0 does; 1.0 shrinks holes visibly.
TRIM_GROW_PIXELS = 0.5


def fast_view_mesh(scene, geometry, camera: Camera, width: int, height: int):
    """The shaded tessellation: (vertices (V, 14) float32 rows (x, y, z
    relative to origin, normal, albedo, specular, shininess, u, v in the
    surface's knot domain, surface index), indices (T, 3) uint32, origin (3,)
    float64 the scene box centre, untested int: the first untested triangles
    lie wholly inside their surface's trim loops (or on an untrimmed
    surface; ``kernels.trim.rect_states`` of their (u, v) box is INSIDE), so
    they are drawn without the per-fragment trim test, the rest with it).

    Vertices come from ``map_mesh.tessellate`` (the map's own grid, as dense as
    the map needs at this camera and size); normals are the exact S_u x S_v
    at each vertex, or the mesh's area-weighted normal where that vanishes.
    """
    from bsrt.rendering.map_mesh import segments_per_patch, tessellate

    patches = geometry.patches
    lo, hi = patches.scene_box()
    origin = 0.5 * (lo + hi)
    coarse = max(1, round(width * FAST_VIEW_DETAIL)), max(1, round(height * FAST_VIEW_DETAIL))
    verts, tris = tessellate(patches, segments_per_patch(patches, camera, *coarse), origin)
    surface = np.rint(verts[:, 5]).astype(np.int64) - 1
    d = patches.domain[surface]
    u = d[:, 0] + (d[:, 1] - d[:, 0]) * verts[:, 3].astype(np.float64)
    v = d[:, 2] + (d[:, 3] - d[:, 2]) * verts[:, 4].astype(np.float64)
    param = np.stack([u, v], axis=1)
    u, v = patches.clamp(surface, u, v)
    _, su, sv = patches.evaluate(patches.locate(surface, u, v), u, v)
    normal = np.cross(su.T, sv.T)
    length = np.linalg.norm(normal, axis=1)
    scale = np.linalg.norm(su, axis=0) * np.linalg.norm(sv, axis=0)
    good = length > 1e-9 * np.maximum(scale, 1e-300)
    normal[good] /= length[good, None]
    if not good.all():
        p = verts[:, :3].astype(np.float64)
        a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
        face = np.cross(b - a, c - a)
        mesh = np.zeros_like(p)
        for k in range(3):
            np.add.at(mesh, tris[:, k], face)
        mesh_len = np.linalg.norm(mesh, axis=1)
        mesh_len[mesh_len == 0] = 1.0
        normal[~good] = mesh[~good] / mesh_len[~good, None]
    material = geometry.material[surface]
    mats = scene.materials
    out = np.empty((verts.shape[0], 14), dtype=np.float32)
    out[:, :3] = verts[:, :3]
    out[:, 3:6] = normal
    out[:, 6:9] = np.array([m.color for m in mats], dtype=np.float64).reshape(-1, 3)[material]
    out[:, 9] = np.array([m.specular for m in mats], dtype=np.float64)[material]
    out[:, 10] = np.array([m.shininess for m in mats], dtype=np.float64)[material]
    out[:, 11:13] = param
    out[:, 13] = surface
    if not patches.trimmed:
        return out, tris, origin, int(tris.shape[0])
    tris, untested = order_by_trims(param, tris, surface, patches.trims)
    return out, tris, origin, untested


def order_by_trims(param: np.ndarray, tris: np.ndarray, surface: np.ndarray, table) -> tuple[np.ndarray, int]:
    """The triangles (T, 3) reordered: (tris, untested), the first untested
    wholly inside their surface's trim loops (``kernels.trim.rect_states`` of
    their (u, v) box is INSIDE), the rest crossed by a curve or near one.

    param: (V, 2) float64 the vertices' (u, v); surface: (V,) int64 their
    surface. (Cutting the crossed triangles smaller, so that the test would
    run in a thinner band along the curves, made the frames slower on
    llvmpipe: the triangles' count costs more than the test saves.)"""
    from bsrt.kernels.trim import INSIDE, rect_states

    uv = param[tris]  # (T, 3, 2)
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    tested = rect_states(table, surface[tris[:, 0]], lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1]) != INSIDE
    order = np.argsort(tested, kind="stable")
    return np.ascontiguousarray(tris[order]), int(tris.shape[0] - tested.sum())


def light_uniforms(lights, origin: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """The shader's lights: (count, kind (MAX_LIGHTS,) int32 0 ambient 1 point
    2 directional, vector (MAX_LIGHTS, 3) float32 position - origin or the
    direction towards the light, strength (MAX_LIGHTS, 3) float32 colour x
    intensity). All ambient lights share the first slot."""
    lights = list(lights)
    ambient = [light for light in lights if light.kind == "ambient"]
    others = [light for light in lights if light.kind != "ambient"]
    if ambient:
        total = sum(np.array(light.color) * light.intensity for light in ambient)
        others.insert(0, replace(ambient[0], color=tuple(total), intensity=1.0))
    if len(others) > MAX_LIGHTS:
        print(f"bsrt preview: the fast view uses the first {MAX_LIGHTS} of {len(others)} lights", file=sys.stderr)
        others = others[:MAX_LIGHTS]
    kind = np.zeros(MAX_LIGHTS, dtype=np.int32)
    vector = np.zeros((MAX_LIGHTS, 3), dtype=np.float32)
    strength = np.zeros((MAX_LIGHTS, 3), dtype=np.float32)
    for k, light in enumerate(others):
        strength[k] = np.array(light.color) * light.intensity
        if light.kind == "point":
            kind[k] = 1
            vector[k] = np.array(light.position) - origin
        elif light.kind == "directional":
            kind[k] = 2
            d = np.array(light.direction, dtype=np.float64)
            vector[k] = -d / np.linalg.norm(d)
    return len(others), kind, vector, strength


class View:
    """GL drawing on the window's context: the fast view's mesh, a quad for
    images, textures, screenshots. Main thread only."""

    def __init__(self, ctx, scene, geometry, camera: Camera, fb_size: tuple[int, int]):
        from bsrt.rendering.image import srgb_encode

        self.ctx, self.scene, self.geometry = ctx, scene, geometry
        self.owned: list = []  # GL objects created here, released at close
        self.program = self._own(gl.load_program(ctx, "preview"))
        verts, tris, self.origin, self.untested = fast_view_mesh(scene, geometry, camera, *fb_size)
        self.triangles = tris.shape[0]
        programs = [self.program]
        self.trim_program = self.trim_vao = self.trims = None  # only for triangles that trim curves cross
        self.vbo = self._own(ctx.buffer(verts.tobytes()))
        self.ibo = self._own(ctx.buffer(tris.astype(np.uint32).tobytes()))
        self.mesh_vao = self._own(
            ctx.vertex_array(
                self.program,
                [(self.vbo, "3f 3f 3f 2f 12x", "position", "normal", "albedo", "gloss")],
                index_buffer=self.ibo,
                index_element_size=4,
            )
        )
        if self.untested < self.triangles:
            self.trim_program = self._own(gl.load_program(ctx, "preview", ("TRIM_TEST",)))
            self.trim_vao = self._own(
                ctx.vertex_array(
                    self.trim_program,
                    [(self.vbo, "3f 3f 3f 2f 2f 1f", "position", "normal", "albedo", "gloss", "param", "surface")],
                    index_buffer=self.ibo,
                    index_element_size=4,
                )
            )
            self.trims = self._own(TrimTextures(ctx, geometry.patches.trims))  # units 1..7; the image is on 0
            self.trim_program["trim_grow"].value = TRIM_GROW_PIXELS
            self.trims.use(self.trim_program)
            programs.append(self.trim_program)
        self.quad_vao = self._own(ctx.vertex_array(self.program, []))
        count, kind, vector, strength = light_uniforms(scene.lights, self.origin)
        for program in programs:
            program["image_pass"].value = False
            program["light_count"].value = count
            program["light_kind"].write(kind.tobytes())
            program["light_vector"].write(vector.tobytes())
            program["light_strength"].write(strength.tobytes())
        self.program["image"].value = 0
        self.background = srgb_encode(np.asarray(scene.film.background, dtype=np.float64)) / 255.0
        gl.program(ctx, "prelim")  # compile the map's program now, not in the first map band

    def _own(self, obj):
        self.owned.append(obj)
        return obj

    def release(self, obj) -> None:
        """Release one GL object made here (None: nothing)."""
        if obj is not None:
            obj.release()
            self.owned.remove(obj)

    def texture(self, pixels: np.ndarray):
        """An RGB8 texture of pixels (H, W, 3) uint8, row 0 at the top."""
        h, w = pixels.shape[:2]
        tex = self._own(self.ctx.texture((w, h), 3, np.ascontiguousarray(pixels[::-1]).tobytes(), alignment=1))
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex

    def draw(self, target, size: tuple[int, int], image, camera: Camera) -> None:
        """The image texture stretched over target, or (None) the fast view of camera."""
        ctx = self.ctx
        target.use()
        ctx.viewport = (0, 0, *size)
        if image is not None:
            ctx.disable(moderngl.DEPTH_TEST)
            image.use(0)
            self.program["image_pass"].value = True
            self.quad_vao.render(moderngl.TRIANGLE_STRIP, vertices=4)
        else:
            self._draw_fast(size, camera)

    def _draw_fast(self, size: tuple[int, int], cam: Camera) -> None:
        from bsrt.rendering.map_mesh import depth_range

        ctx = self.ctx
        near, far = depth_range(self.geometry.patches, cam)
        local_eye = cam.eye - self.origin
        eye_from_local = np.eye(4)
        eye_from_local[:3, 3] = -local_eye
        clip_from_local = clip_from_eye(cam, *size, near, far) @ eye_from_local
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        bg = self.background
        ctx.clear(float(bg[0]), float(bg[1]), float(bg[2]), 1.0, depth=1.0)
        # the triangles inside their trim loops (or untrimmed) with the plain program, then those
        # that trim curves cross with the trim test
        parts = [
            (self.program, self.mesh_vao, 0, self.untested),
            (self.trim_program, self.trim_vao, self.untested, self.triangles - self.untested),
        ]
        for program, vao, first, count in parts:
            if count == 0:
                continue
            program["image_pass"].value = False
            program["clip_from_local"].write(clip_from_local.T.astype("f4").tobytes())
            program["eye"].value = tuple(float(x) for x in local_eye)
            if program is self.trim_program:
                self.trims.use(program)
            vao.render(moderngl.TRIANGLES, vertices=3 * count, first=3 * first)

    def screenshot(self, size: tuple[int, int], image, camera: Camera) -> np.ndarray:
        """The frame draw() would show, drawn offscreen and read back: (H, W, 3)
        uint8, row 0 at the top (reading the window's own framebuffer sets
        GL_INVALID_OPERATION in moderngl)."""
        w, h = size
        color = depth = fbo = None
        try:
            color = self._own(self.ctx.texture((w, h), 3))
            depth = self._own(self.ctx.depth_renderbuffer((w, h)))
            fbo = self._own(self.ctx.framebuffer(color_attachments=[color], depth_attachment=depth))
            self.draw(fbo, size, image, camera)
            raw = fbo.read(viewport=(0, 0, w, h), components=3, dtype="f1", alignment=1)
        finally:
            gl.bind_default_framebuffer(self.ctx)
            for obj in (fbo, depth, color):
                self.release(obj)
        return np.frombuffer(raw, dtype=np.uint8).reshape(h, w, 3)[::-1].copy()

    def close(self) -> int:
        """Release every GL object made here and the context's cached ones; returns how many."""
        released = len(self.owned)
        for obj in reversed(list(self.owned)):
            self.release(obj)
        return released + gl.release_cached(self.ctx)
