"""The trim table on the GPU: the textures that shaders/trim.glsl reads, and
:func:`kept_gl`, that test at given points (for tests and diagnostics).

The table is ``bsrt.kernels.trim.TrimTable`` (built once per scene,
``PatchSet.trims``); every array goes into a float32 or int32 texture read
with texelFetch, so the test runs on an OpenGL 3.3 core context (no storage
buffers). Whoever makes a :class:`TrimTextures` releases it.
"""

from __future__ import annotations

import moderngl
import numpy as np

from bsrt.errors import RenderError
from bsrt.kernels.trim import TrimTable
from bsrt.rendering import gl

ROW = 4096  # texels per texture row (fewer when the context's textures are narrower)

# The sampler uniforms of trim.glsl, in the order TrimTextures binds them (units first_unit, first_unit + 1, ...).
SAMPLERS = ("trim_surface", "trim_band", "trim_band_start", "trim_entry", "trim_entry_box", "trim_ends", "trim_coef")


def texture_arrays(table: TrimTable) -> dict[str, np.ndarray]:
    """trim.glsl's textures' contents, by sampler name: (N, 4) int32 or float32
    (a texel per item; at least one item each). coef holds piece k's power
    i at row k * stride + i, stride = table.coef.shape[1] (see
    :func:`coef_stride`)."""
    m = table.trimmed.size
    k, stride = table.coef.shape[:2]
    e = table.entry_piece.size
    surface = np.zeros((m, 4), dtype=np.int32)
    surface[:, 0] = table.trimmed
    surface[:, 1] = table.band_first
    surface[:, 2] = table.band_count
    band = np.zeros((m, 4), dtype=np.float32)
    band[:, 0] = table.band_v0
    band[:, 1] = table.band_scale
    band_start = np.zeros((table.band_start.size - 1, 4), dtype=np.int32)
    band_start[:, 0] = table.band_start[:-1]
    band_start[:, 1] = table.band_start[1:]
    entry = np.zeros((e, 4), dtype=np.int32)
    entry[:, 0] = table.entry_piece
    entry[:, 1] = table.degree[table.entry_piece]
    coef = np.zeros((k * stride, 4), dtype=np.float32)
    coef[:, :3] = table.coef.reshape(k * stride, 3)
    arrays = {
        "trim_surface": surface,
        "trim_band": band,
        "trim_band_start": band_start,
        "trim_entry": entry,
        "trim_entry_box": table.entry_box.astype(np.float32),
        "trim_ends": table.ends.astype(np.float32),
        "trim_coef": coef,
    }
    for name, a in arrays.items():
        if a.shape[0] == 0:  # a texture needs one texel
            arrays[name] = np.zeros((1, 4), dtype=a.dtype)
    return arrays


def coef_stride(table: TrimTable) -> int:
    """trim.glsl's trim_coef_stride: texels per piece in trim_coef (the largest degree + 1)."""
    return int(table.coef.shape[1])


class TrimTextures:
    """trim.glsl's textures of one table on ctx. :meth:`use` binds them for a
    program; :meth:`release` frees them."""

    def __init__(self, ctx: moderngl.Context, table: TrimTable):
        self.stride = coef_stride(table)
        self.any_trimmed = bool(np.any(table.trimmed))
        limit = int(ctx.info.get("GL_MAX_TEXTURE_SIZE") or 1024)  # OpenGL 3.3 promises 1024
        row = min(ROW, limit)
        self.textures: dict[str, moderngl.Texture] = {}
        try:
            for name, a in texture_arrays(table).items():
                rows = -(-a.shape[0] // row)
                width = min(row, a.shape[0])
                if rows > limit:
                    raise RenderError(f"the trim table is too large for this OpenGL ({a.shape[0]} items in {name})")
                data = np.zeros((rows * width, 4), dtype=a.dtype)
                data[: a.shape[0]] = a
                tex = ctx.texture((width, rows), 4, data.tobytes(), dtype="i4" if a.dtype == np.int32 else "f4")
                self.textures[name] = tex
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # an integer texture must not filter linearly
                tex.repeat_x = tex.repeat_y = False
        except BaseException:
            self.release()
            raise

    def use(self, program: moderngl.Program, first_unit: int = 1) -> None:
        """Bind the textures to units first_unit.. and point program's samplers at them."""
        for offset, name in enumerate(SAMPLERS):
            self.textures[name].use(first_unit + offset)
            if name in program:
                program[name].value = first_unit + offset
        if "trim_coef_stride" in program:
            program["trim_coef_stride"].value = self.stride

    def release(self) -> None:
        for tex in self.textures.values():
            tex.release()
        self.textures = {}


def kept_gl(table: TrimTable, surface, u, v, ctx: moderngl.Context | None = None) -> np.ndarray:
    """(N,) bool: shaders/trim.glsl's answer for each (surface[i], u[i], v[i])
    (surface: index into the table; u, v: parameters; scalars or (N,)),
    evaluated in a fragment shader as the preview's fast view does.
    ctx: default the process's headless context."""
    surface, u, v = (np.atleast_1d(np.asarray(a)).ravel() for a in (surface, u, v))
    surface, u, v = np.broadcast_arrays(surface, u, v)
    n = u.size
    if n == 0:
        return np.zeros(0, dtype=bool)
    ctx = ctx or gl.headless_context()
    width = min(n, 1024)
    height = -(-n // width)
    points = np.zeros((n, 3), dtype=np.float32)
    points[:, 0], points[:, 1], points[:, 2] = u, v, surface
    with ctx:
        program = gl.program(ctx, "trim_probe")
        textures = TrimTextures(ctx, table)
        objects = [textures]
        try:
            target = ctx.texture((width, height), 1, dtype="f4")
            objects.append(target)
            fbo = ctx.framebuffer(color_attachments=[target])
            objects.append(fbo)
            vbo = ctx.buffer(points.tobytes())
            objects.append(vbo)
            vao = ctx.vertex_array(program, [(vbo, "2f 1f", "param", "surface")])
            objects.append(vao)
            textures.use(program)
            program["target_size"].value = (width, height)
            fbo.use()
            ctx.viewport = (0, 0, width, height)
            ctx.disable(moderngl.DEPTH_TEST)
            fbo.clear(-1.0, 0.0, 0.0, 0.0)
            vao.render(moderngl.POINTS)
            out = np.frombuffer(fbo.read(components=1, dtype="f4", alignment=1), dtype=np.float32)[:n]
            error = ctx.error
        finally:
            gl.bind_default_framebuffer(ctx)
            for obj in reversed(objects):
                obj.release()
    if error != "GL_NO_ERROR":
        raise RenderError(f"OpenGL reported {error} in the trim test")
    if np.any(out < 0.0):
        raise RenderError(f"the trim test drew {int(np.sum(out < 0.0))} of {n} points nowhere")
    return out > 0.5
