"""Shading on the GPU: the direct lighting and the mirror chain as compute shaders.

``shade_hits_gpu`` is kernels/lighting.py's shade_hits by ``shaders/shade.glsl``
(a dispatch per light), and with mirrors the bounces rendering/shade.py's
Shader makes on the CPU: ``shaders/bounce.glsl`` sends each reflecting hit's
mirror ray through the hierarchy (nearest_walk.glsl, the walk of the mirror
rays that gpu_shade.nearest_gpu traces), shade.glsl shades what it sees, a
level of the chain in buffers of its own, and ``shaders/mix.glsl`` mixes each
level into the one before, the deepest first. Only the first level's colour
(and, where the caller asks, its frames) comes back. The hits whose walks a
software renderer leaves unsettled (llvmpipe's loop limiter: anyhit.glsl's
head) are shaded again on the CPU.
"""

from __future__ import annotations

from types import SimpleNamespace

import moderngl
import numpy as np

from bsrt import interrupts
from bsrt.kernels.lighting import shade_hits
from bsrt.kernels.threads import run_chunks
from bsrt.rendering import gl, gpu
from bsrt.rendering.bvh import DEFAULT_RETRY_DEPTH, ray_budget
from bsrt.rendering.gpu import pack_tables, set_uniform
from bsrt.rendering.gpu_shade import hierarchy_shader, set_shadow_uniforms

SHADE_OUTPUTS = (((3,), np.float64),) * 3 + (((2,), np.float64), ((), np.int64), ((), np.int64))  # per hit
LOOK_REAL = (
    "albedo", "specular", "shininess", "light_position", "light_direction", "strength", "background", "reflectance"
)  # fmt: skip
LOOK_INT = ("material_of", "kind", "patch_surface")
HIT_BYTES = (5 * 8, 3 * 4)  # a slot of a level's hits (shade.glsl's HitReals, HitInts)
OUT_BYTES = (11 * 8, 4 * 4)  # a slot of a level's outputs (OutReals, OutInts)
SLOT_BYTES = 4  # a slot's entry in a list of the level's slots (Slots)
BOUNCE_BYTES = 4 * 4  # a slot's bounce (bounce.glsl's BounceInts)
LEVEL_BYTES = HIT_BYTES + OUT_BYTES + (SLOT_BYTES, SLOT_BYTES)  # a slot of a level, buffer by buffer


class _Level:
    """One level of the mirror chain's buffers: hits (reals, ints), outputs (reals, ints), the lists
    of the slots its dispatches run over and, below the first, the bounce that led to it (buffers:
    in that order, LEVEL_BYTES and BOUNCE_BYTES a slot). slots: the slots shaded (a mirror ray
    reached them; None: every slot, the first level); mirrors: those whose hit reflects (bounce.glsl's)."""

    def __init__(self, buffers: list):
        self.hit_reals, self.hit_ints, self.out_reals, self.out_ints = buffers[:4]
        self.slot_list, self.mirror_list = buffers[4:6]
        self.bounce = buffers[6] if len(buffers) > 6 else None
        self.slots, self.mirrors = None, np.zeros(0, dtype=np.int32)

    def list_slots(self, slots: np.ndarray, mirrors: np.ndarray) -> None:
        """Set the level's lists (slots: (A,) int32, mirrors: (B,) int32) and upload them."""
        self.slots, self.mirrors = slots, mirrors
        for array, buffer in ((slots, self.slot_list), (mirrors, self.mirror_list)):
            if array is not None and array.size:
                buffer.write(array)

    def items(self, count: int) -> int:
        """Invocations of a dispatch over the level's slots (count: the slice's slots)."""
        return count if self.slots is None else self.slots.size

    def bind_slots(self, program, mirrors: bool = False) -> None:
        """The list a dispatch runs over, on program: the slots shaded, or the mirrors."""
        (self.mirror_list if mirrors else self.slot_list).bind_to_storage_buffer(13)
        set_uniform(program, "use_slots", int(mirrors or self.slots is not None))


def _chain(ctx, slots: int, levels: int) -> list[_Level]:
    """The mirror chain's levels for at least ``slots`` slots, their buffers kept on ctx between
    calls (gpu.kept_buffers)."""
    sizes = LEVEL_BYTES + (LEVEL_BYTES + (BOUNCE_BYTES,)) * (levels - 1)
    buffers = gpu.kept_buffers(ctx, "bsrt_lighting", slots, sizes)
    first, chain = len(LEVEL_BYTES), [_Level(buffers[: len(LEVEL_BYTES)])]
    for _ in range(levels - 1):
        chain.append(_Level(buffers[first : first + len(LEVEL_BYTES) + 1]))
        first += len(LEVEL_BYTES) + 1
    return chain


def shade_hits_gpu(
    ctx: moderngl.Context,
    bvh,
    hits,
    directions,
    material_of,
    materials,
    lights,
    background,
    eps: float,
    tolerance: float,
    max_iterations: int,
    out,
    reflectance=None,
    max_depth: int = 0,
    reflections=None,
    first_level=None,
    redo=None,
) -> None:
    """kernels/lighting.py's shade_hits for K hits on ctx (OpenGL 4.5 with
    float64), by shaders/shade.glsl: the same arguments and outputs; with
    reflectance and max_depth, also the pipeline's mirror bounces, on the GPU.

    hits: Hits (K,) (hit, patch, surface, u, v used); directions: (K, 3)
    unit ray directions; material_of: (S,) int64; materials: (albedo (M, 3),
    specular (M,), shininess (M,)); lights: rendering/shade.py's
    light_arrays; background: (3,); eps: the exclusion half-width (scene
    units); tolerance, max_iterations: the shadow rays' solve (bvh.intersect's).
    out: (colour (K, 3), position (K, 3), normal (K, 3), radius (K, 2),
    shadow_rays (K,) int64, exhausted (K,) int64), written here; position,
    normal and radius may be None where the caller needs no frames (then
    they are not read back: 64 of the 100 bytes a hit).

    The mirror chain: reflectance (S,) per surface and max_depth > 0 send a
    mirror ray from each hit on a reflecting surface (bounce.glsl, the walk of
    nearest_walk.glsl: the mirror rays' solve is the shadow rays'), shade what it
    sees (shade.glsl again, a level of the chain) and so on up to max_depth
    bounces, then mix each level into the one before (mix.glsl, the deepest
    first), as rendering/shade.py's Shader does on the CPU: the colour is the
    whole one, exhausted counts the mirror rays out of budget too, and
    reflections (K,) int64, when given, gets each hit's mirror rays. Only the
    first level's outputs come back. first_level(rows, colour, position,
    normal, radius), when given, is called with each dispatch's slice of the
    first level (rows: a slice of the K hits; the arrays those rows, frames
    included) and may change the colour in place before the mirrors are mixed
    in (the pipeline's ambient occlusion).

    The hits with a walk the shader leaves unsettled (llvmpipe's loop limiter,
    anyhit.glsl: a shadow ray, or a mirror ray anywhere along the chain) are
    shaded again on the CPU: redo(indices) (R,) int64 shades them and writes
    their outputs (the counts included); by default the CPU kernel's direct
    lighting does, which is the whole answer only without mirrors (with
    mirrors, redo is required)."""
    colour, position, normal, radius, shadow_rays, exhausted = out
    n = len(hits)
    if n == 0:
        return
    kind = lights[0]
    surfaces = material_of.shape[0]
    reflectance = np.zeros(surfaces) if reflectance is None else np.asarray(reflectance, dtype=np.float64)
    levels = 1 + (int(max_depth) if (reflectance > 0).any() else 0)
    if levels > 1 and redo is None:
        raise ValueError("shade_hits_gpu with mirrors needs redo: the CPU shading of the hits it leaves unsettled")
    look = SimpleNamespace(
        material_of=material_of,
        albedo=materials[0],
        specular=materials[1],
        shininess=materials[2],
        kind=kind,
        light_position=lights[1],
        light_direction=lights[2],
        strength=lights[3],
        background=background,
        reflectance=reflectance,
        patch_surface=bvh.patches.surface,
    )
    look_reals, look_ints, look_offsets = pack_tables([(look, "", LOOK_REAL, LOOK_INT)], {})
    hit_reals = np.column_stack([hits.u, hits.v, np.asarray(directions, dtype=np.float64).reshape(-1, 3)])
    hit_ints = np.column_stack([hits.hit, hits.patch, hits.surface]).astype(np.int32)
    mirror_hit = hits.hit & (reflectance[hits.surface] > 0)  # (a miss's surface -1 is masked)
    unsettled = np.zeros(n, dtype=bool)
    framed = position is not None or first_level is not None
    frames = (
        (position, normal, radius) if position is not None else (np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2)))
    )
    step = min(n, gpu.dispatch_size(ctx))
    with ctx:
        shade = hierarchy_shader(ctx, "shade", bvh)
        bounce = hierarchy_shader(ctx, "bounce", bvh) if levels > 1 else None
        mix = gl.program(ctx, "mix", gpu.compute_defines(ctx), compute=True) if levels > 1 else None
        for program in (shade, bounce):
            if program is not None:
                set_shadow_uniforms(program, bvh, tolerance, max_iterations)
                for key, offset in look_offsets.items():
                    set_uniform(program, f"off_{key}", offset)
        if mix is not None:
            set_uniform(mix, "off_reflectance", look_offsets["reflectance"])
        set_uniform(shade, "eps", float(eps))
        chain = _chain(ctx, step, levels)
        tables = []
        try:  # the tables, then one slice's levels, written and read again for each slice
            tables.append(ctx.buffer(look_reals))
            tables.append(ctx.buffer(look_ints))
            for first in range(0, n, step):
                part = slice(first, min(n, first + step))
                count = part.stop - part.start
                chain[0].hit_reals.write(hit_reals[part])
                chain[0].hit_ints.write(hit_ints[part])
                if levels > 1:  # the first level's hits on reflecting surfaces
                    chain[0].list_slots(None, np.flatnonzero(mirror_hit[part]).astype(np.int32))
                _shade_level(ctx, shade, tables, chain[0], count, kind.shape[0])
                if framed:  # the first level's colour and frames, for the caller
                    first_colour = colour[part] if first_level is not None else None
                    at = 0
                    for array, width in ((first_colour, 3),) + tuple(zip((a[part] for a in frames), (3, 3, 2))):
                        if array is not None:
                            gpu.read_rows(chain[0].out_reals, array, at)
                        at += count * width * 8
                    if first_level is not None:
                        first_level(part, colour[part], *(a[part] for a in frames))
                        chain[0].out_reals.write(np.ascontiguousarray(colour[part]))
                deepest = 0
                for depth in range(levels - 1):
                    if not _bounce(ctx, bounce, tables, chain[depth], chain[depth + 1], count):
                        break  # no mirror ray left this level
                    _shade_level(ctx, shade, tables, chain[depth + 1], count, kind.shape[0])
                    deepest = depth + 1
                for depth in range(deepest - 1, -1, -1):
                    _mix(ctx, mix, tables, chain[depth], chain[depth + 1], count)
                gpu.read_rows(chain[0].out_reals, colour[part])  # the colour's block comes first
                ints = gpu.read_array(chain[0].out_ints, (4, count), np.int32)  # out_ints' blocks
                shadow_rays[part], exhausted[part], unsettled[part] = ints[0], ints[1], ints[2] != 0
                if reflections is not None:
                    reflections[part] = ints[3]
                interrupts.safe_point()
        finally:
            for buffer in tables:
                buffer.release()
    again = np.flatnonzero(unsettled)
    if again.size and redo is not None:
        redo(again)
    elif again.size:
        _shade_on_cpu(bvh, hits, directions, material_of, materials, lights, background, eps, tolerance,
                      max_iterations, again, out)  # fmt: skip
        if reflections is not None:
            reflections[again] = 0


def _shade_level(ctx, shade, tables, level: _Level, count: int, lights: int) -> None:
    """shade.glsl over a level's slots (count in the slice), one dispatch per light (none: one, the
    colour 0)."""
    for buffer, binding in zip((tables[0], tables[1], level.hit_reals, level.hit_ints, level.out_reals, level.out_ints),
                               (4, 5, 2, 3, 8, 9)):  # fmt: skip
        buffer.bind_to_storage_buffer(binding)
    level.bind_slots(shade)
    set_uniform(shade, "hit_count", count)
    set_uniform(shade, "item_count", level.items(count))
    for light in range(lights) if lights else (-1,):  # no light: colour 0 (a sum over none)
        set_uniform(shade, "light", light)
        gpu.run(ctx, shade, level.items(count))
        ctx.memory_barrier()
        interrupts.safe_point()  # between dispatches: a waiting signal is taken


def _bounce(ctx, bounce, tables, level: _Level, below: _Level, count: int) -> bool:
    """bounce.glsl from the mirrors of a level (count slots in the slice) into the next level's hits,
    and the next level's lists: the slots that sent a mirror ray, and those of them whose mirror
    ray found a reflecting hit. Whether a mirror ray was sent."""
    for buffer, binding in zip(
        (tables[0], tables[1], level.hit_reals, level.hit_ints, level.out_reals, below.hit_reals, below.hit_ints,
         below.bounce),
        (4, 5, 2, 3, 8, 10, 11, 12),
    ):  # fmt: skip
        buffer.bind_to_storage_buffer(binding)
    if not level.mirrors.size:
        return False
    level.bind_slots(bounce, mirrors=True)
    set_uniform(bounce, "hit_count", count)
    set_uniform(bounce, "item_count", level.mirrors.size)
    gpu.run(ctx, bounce, level.mirrors.size)
    ctx.memory_barrier()
    interrupts.safe_point()
    blocks = gpu.read_array(below.bounce, (4, count), np.int32)  # (the listed slots' are written)
    listed = level.mirrors
    sent = listed[blocks[0, listed] != 0]
    below.list_slots(sent, sent[blocks[3, sent] != 0])
    return sent.size > 0


def _mix(ctx, mix, tables, level: _Level, below: _Level, count: int) -> None:
    """mix.glsl: the level below mixed into the slots of level (count in the slice) that sent it a
    mirror ray (the level below's list), its counts added."""
    for buffer, binding in zip(
        (tables[0], level.hit_ints, level.out_reals, level.out_ints, below.out_reals, below.out_ints, below.bounce),
        (4, 3, 8, 9, 10, 11, 12),
    ):  # fmt: skip
        buffer.bind_to_storage_buffer(binding)
    below.bind_slots(mix)
    set_uniform(mix, "hit_count", count)
    set_uniform(mix, "item_count", below.items(count))
    gpu.run(ctx, mix, below.items(count))
    ctx.memory_barrier()


def _shade_on_cpu(bvh, hits, directions, material_of, materials, lights, background, eps, tolerance, max_iterations,
                  redo, out) -> None:  # fmt: skip
    """kernels/lighting.py's shade_hits for the hits redo (R,) into out's rows redo (shade_hits_gpu's)."""
    again = tuple(np.empty((redo.size,) + shape, dtype=kind) for shape, kind in SHADE_OUTPUTS)
    P, rays = bvh.patches, np.ascontiguousarray(directions, dtype=np.float64)
    run_chunks(
        shade_hits, redo.size, P.arrays, P.trims, bvh.arrays, hits.hit[redo], hits.patch[redo],
        hits.surface[redo], hits.u[redo], hits.v[redo], rays[redo], material_of, *materials, *lights,
        background, eps, float(tolerance), max_iterations, DEFAULT_RETRY_DEPTH,
        bvh.padding + float(tolerance), ray_budget(max_iterations), bvh.packet_spread, *again,
    )  # fmt: skip
    for whole, part in zip(out, again):
        if whole is not None:
            whole[redo] = part
