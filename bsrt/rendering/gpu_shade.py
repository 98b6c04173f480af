"""Shadow rays on the GPU: the hierarchy in storage buffers and the any-hit walk as a compute shader.

``occluded_gpu`` answers, for shadow rays given as arrays, what the CPU's
any-hit walk (kernels/lighting.py's occluded; bvh.intersect with any_hit)
answers: blocked or not, which rays spent their budget (taken as lit), and
the Newton iterations each took.
``shaders/shadow.glsl`` runs ``shaders/anyhit.glsl``, a port of that walk
in float64, on the hierarchy (rendering/bvh.py's BVHArrays) uploaded once
per hierarchy beside the patch table (gpu.uploaded). ``shade_hits_gpu`` is
kernels/lighting.py's shade_hits by ``shaders/shade.glsl``; ``nearest_gpu``
the nearest hits of mirror rays (bvh.intersect) by ``shaders/nearest.glsl``, which ``trace_gpu``
takes bvh.intersect's arguments to. The rays a
software renderer leaves unsettled (llvmpipe's loop limiter: anyhit.glsl's
head) are traced, and their hits shaded, by those CPU kernels instead.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import moderngl
import numpy as np

from bsrt import interrupts
from bsrt.kernels.crossings import ROUNDING
from bsrt.kernels.hierarchy import BVHArrays
from bsrt.kernels.lighting import shade_hits
from bsrt.kernels.shading import LIGHT_KINDS, POLE_STEPS
from bsrt.kernels.threads import run_chunks
from bsrt.kernels.traverse import GRAZING_COSINE, RECT_SLACK, STACK
from bsrt.rendering import gl, gpu
from bsrt.rendering.bvh import DEFAULT_MAX_ITERATIONS, DEFAULT_RETRY_DEPTH, intersect, ray_budget
from bsrt.rendering.gpu import Uploaded, bind_patch_table, pack_tables, set_uniform, uploaded
from bsrt.rendering.hits import Hits
from bsrt.rendering.solve import Rays


def hierarchy_arrays(arrays: BVHArrays) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(float64 names, integer names) of BVHArrays' fields, as anyhit.glsl reads them (offsets off_NAME)."""
    real = tuple(f for f in BVHArrays._fields if getattr(arrays, f).dtype.kind == "f")
    return real, tuple(f for f in BVHArrays._fields if f not in real)


def uploaded_hierarchy(ctx: moderngl.Context, bvh) -> Uploaded:
    """bvh's table (BVHArrays) on ctx in two storage buffers, uploaded once per
    hierarchy, kept with its patches' table (gpu.uploaded: released with it)."""
    table = uploaded(ctx, bvh.patches)
    kept = table.dependents.get("hierarchy")
    if kept is not None and kept.source is bvh:
        return kept
    if kept is not None:
        table.dependents.pop("hierarchy").release()
    real, integer = hierarchy_arrays(bvh.arrays)
    packed = pack_tables([(bvh.arrays, "", real, integer)], {})
    table.dependents["hierarchy"] = made = Uploaded(ctx, bvh, packed, "hierarchy")
    return made


def hierarchy_shader(ctx: moderngl.Context, name: str, bvh, retry_depth: int = DEFAULT_RETRY_DEPTH):
    """The compute shader NAME (one that includes anyhit.glsl) on ctx (current),
    compiled for bvh's nets and retry_depth, the patch table bound to storage
    buffers 0 and 1, the hierarchy to 6 and 7, their offsets set."""
    pm, qm = bvh.arrays.patch_net.shape[1:3]
    defines = gpu.compute_defines(
        ctx,
        f"NET_PM {pm}",
        f"NET_QM {qm}",
        f"RETRY_DEPTH {int(retry_depth)}",
        f"STACK {STACK}",
        f"GRAZING_COSINE {GRAZING_COSINE!r}LF",
        f"RECT_SLACK {RECT_SLACK!r}LF",
        f"ROUNDING {ROUNDING!r}LF",
        f"LIGHT_AMBIENT {LIGHT_KINDS['ambient']}",
        f"LIGHT_POINT {LIGHT_KINDS['point']}",
        "POLE_STEPS double[](" + ", ".join(f"{s!r}LF" for s in POLE_STEPS) + ")",
    )
    shader = gl.program(ctx, name, defines + (("TRIM_TEST",) if bvh.patches.trimmed else ()), compute=True)
    bind_patch_table(ctx, shader, bvh.patches)
    table = uploaded_hierarchy(ctx, bvh)
    for key, offset in table.offsets.items():
        set_uniform(shader, f"off_{key}", offset)
    table.reals.bind_to_storage_buffer(6)
    table.ints.bind_to_storage_buffer(7)
    set_uniform(shader, "canary_turns", 2)
    return shader


def set_shadow_uniforms(shader, bvh, tolerance: float, max_iterations: int) -> None:
    """The shadow rays' solve as bvh.intersect sets it: tolerance (scene units),
    max_iterations of Newton per piece, the hull test's slack, the ray's budget."""
    set_uniform(shader, "shadow_tol", float(tolerance))
    set_uniform(shader, "shadow_iterations", int(max_iterations))
    set_uniform(shader, "cull_tol", float(bvh.padding + tolerance))
    set_uniform(shader, "budget", ray_budget(max_iterations))


def occluded_gpu(
    ctx: moderngl.Context,
    bvh,
    origins,
    directions,
    t_max,
    tolerance: float,
    exclude=None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Any-hit shadow rays on ctx (OpenGL 4.5 with float64: gpu.choose_device).

    origins, directions: (N, 3) float64 (directions of unit length); t_max:
    (N,) or a scalar, a blocker needs 0 < t < t_max; tolerance: scene units;
    exclude: (surface, u, v, radius_u, radius_v), each (N,), the root each ray
    starts from (bvh.intersect's). Returns (blocked (N,) bool, exhausted (N,)
    bool: not blocked within the budget, taken as lit), what bvh.intersect
    with any_hit and max_iterations (Newton's per piece) answers on the CPU,
    and iterations (N,) int64: each ray's Newton iterations. The rays the
    shader leaves unsettled (anyhit.glsl's -3) are traced by bvh.intersect."""
    d = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
    n = d.shape[0]
    rays = np.zeros((n, 12))
    rays[:, 0:3] = np.broadcast_to(np.asarray(origins, dtype=np.float64).reshape(-1, 3), (n, 3))
    rays[:, 3:6] = d
    rays[:, 6] = np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))
    rays[:, 7] = -1.0
    if exclude is not None:
        for c, a in enumerate(exclude, start=7):
            rays[:, c] = a
    answer = np.zeros((n, 2), dtype=np.int32)  # occluded's answer, iterations
    if n == 0 or bvh.leaf_total == 0:
        return answer[:, 0] == 1, answer[:, 0] == -2, answer[:, 1].astype(np.int64)
    with ctx:
        shader = hierarchy_shader(ctx, "shadow", bvh)
        set_shadow_uniforms(shader, bvh, tolerance, max_iterations)
        step = gpu.dispatch_size(ctx)
        for first in range(0, n, step):
            count = min(step, n - first)
            buffers = []
            try:
                buffers.append(ctx.buffer(rays[first : first + count]))
                buffers.append(ctx.buffer(reserve=8 * count))
                buffers[0].bind_to_storage_buffer(2)
                buffers[1].bind_to_storage_buffer(3)
                set_uniform(shader, "ray_count", count)
                gpu.run(ctx, shader, count)
                ctx.memory_barrier()
                gpu.read_rows(buffers[1], answer[first : first + count])
            finally:
                for buffer in buffers:
                    buffer.release()
            interrupts.safe_point()
    redo = np.flatnonzero(answer[:, 0] == -3)
    if redo.size:
        cpu = intersect(
            bvh,
            rays[redo, 0:3],
            d[redo],
            t_max=rays[redo, 6],
            tolerance=tolerance,
            max_iterations=max_iterations,
            any_hit=True,
            exclude=(rays[redo, 7].astype(np.int64),) + tuple(rays[redo, c] for c in range(8, 12)),
        )
        answer[redo, 0] = np.where(cpu.hit, 1, np.where(cpu.iterations >= ray_budget(max_iterations), -2, 0))
        answer[redo, 1] = cpu.iterations
    return answer[:, 0] == 1, answer[:, 0] == -2, answer[:, 1].astype(np.int64)


def nearest_gpu(
    ctx: moderngl.Context,
    bvh,
    origins,
    directions,
    t_min,
    t_max,
    tolerance: float,
    exclude=None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> Hits:
    """Nearest hits (mirror rays) on ctx (OpenGL 4.5 with float64) by shaders/nearest.glsl: what
    bvh.intersect answers without any_hit. origins, directions: (N, 3) float64 (unit directions);
    t_min, t_max: (N,) or scalars, a hit needs t_min < t < t_max; tolerance: scene units; exclude:
    (surface, u, v, radius_u, radius_v), each (N,), the root each ray starts from. Returns Hits
    (N,). The rays the shader leaves unsettled (llvmpipe's loop limiter) are traced by bvh.intersect."""
    d = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
    n = d.shape[0]
    rays = np.zeros((n, 13))
    rays[:, 0:3] = np.broadcast_to(np.asarray(origins, dtype=np.float64).reshape(-1, 3), (n, 3))
    rays[:, 3:6] = d
    rays[:, 6] = np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,))
    rays[:, 7] = np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))
    rays[:, 8] = -1.0
    if exclude is not None:
        for c, a in enumerate(exclude, start=8):
            rays[:, c] = a
    hits = Hits.empty(n)
    if n == 0 or bvh.leaf_total == 0:
        return hits
    reals, ints = np.empty((n, 4)), np.empty((n, 3), dtype=np.int32)
    with ctx:
        shader = hierarchy_shader(ctx, "nearest", bvh)
        set_shadow_uniforms(shader, bvh, tolerance, max_iterations)
        step = gpu.dispatch_size(ctx)
        for first in range(0, n, step):
            part = slice(first, min(n, first + step))
            count = part.stop - part.start
            buffers = []
            try:
                buffers.append(ctx.buffer(rays[part]))
                buffers.append(ctx.buffer(reserve=32 * count))
                buffers.append(ctx.buffer(reserve=12 * count))
                for binding, buffer in enumerate(buffers, start=2):
                    buffer.bind_to_storage_buffer(binding)
                set_uniform(shader, "ray_count", count)
                gpu.run(ctx, shader, count)
                ctx.memory_barrier()
                gpu.read_rows(buffers[1], reals[part])
                gpu.read_rows(buffers[2], ints[part])
            finally:
                for buffer in buffers:
                    buffer.release()
            interrupts.safe_point()
    hit = np.flatnonzero(ints[:, 0] == 1)
    hits.hit[hit] = True
    hits.u[hit], hits.v[hit], hits.t[hit], hits.residual[hit] = reals[hit].T
    hits.patch[hit] = ints[hit, 1]
    hits.surface[hit] = bvh.patches.surface[ints[hit, 1]]
    hits.iterations[:] = ints[:, 2]
    redo = np.flatnonzero(ints[:, 0] == -3)
    if redo.size:
        cpu = intersect(
            bvh,
            rays[redo, 0:3],
            d[redo],
            t_min=rays[redo, 6],
            t_max=rays[redo, 7],
            tolerance=tolerance,
            max_iterations=max_iterations,
            exclude=(rays[redo, 8].astype(np.int64),) + tuple(rays[redo, c] for c in range(9, 13)),
        )
        for field in dataclasses.fields(Hits):
            getattr(hits, field.name)[redo] = getattr(cpu, field.name)
    return hits


def trace_gpu(
    ctx: moderngl.Context,
    bvh,
    origins,
    directions,
    t_min=0.0,
    t_max=np.inf,
    tolerance: float | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    any_hit: bool = False,
    exclude=None,
    budget: int | None = None,
    out: Hits | None = None,
) -> Hits:
    """bvh.intersect's nearest hits (the same arguments) on ctx by nearest_gpu, the directions
    normalised as intersect normalises them; the budget is ray_budget(max_iterations), the
    shader's. any_hit, or another budget, is a ValueError (the rays a render sends to the GPU's
    any-hit walk, its shadow rays, go through shade_hits_gpu)."""
    if any_hit:
        raise ValueError("trace_gpu traces nearest hits; any-hit rays go through occluded_gpu")
    if budget is not None and budget != ray_budget(max_iterations):
        raise ValueError(
            f"the GPU's walk takes the budget of max_iterations, {ray_budget(max_iterations)}, not {budget}"
        )
    rays = Rays.from_arrays(origins, directions)
    if tolerance is None:
        tolerance = 1e-9 * bvh.patches.scene_diagonal()
    found = nearest_gpu(ctx, bvh, rays.origin, rays.direction, t_min, t_max, tolerance, exclude, max_iterations)
    if out is None:
        return found
    out.put(slice(None), found)
    return out


SHADE_OUTPUTS = (((3,), np.float64),) * 3 + (((2,), np.float64), ((), np.int64), ((), np.int64))  # per hit
LOOK_REAL = ("albedo", "specular", "shininess", "light_position", "light_direction", "strength", "background")
LOOK_INT = ("material_of", "kind")


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
) -> None:
    """kernels/lighting.py's shade_hits for K hits on ctx (OpenGL 4.5 with
    float64), by shaders/shade.glsl: the same arguments and outputs.

    hits: Hits (K,) (hit, patch, surface, u, v used); directions: (K, 3)
    unit ray directions; material_of: (S,) int64; materials: (albedo (M, 3),
    specular (M,), shininess (M,)); lights: rendering/shade.py's
    light_arrays; background: (3,); eps: the exclusion half-width (scene
    units); tolerance, max_iterations: the shadow rays' solve (bvh.intersect's).
    out: (colour (K, 3), position (K, 3), normal (K, 3), radius (K, 2),
    shadow_rays (K,) int64, exhausted (K,) int64), written here; position,
    normal and radius may be None where the caller needs no frames (then
    they are not read back: 64 of the 100 bytes a hit). The hits
    with a shadow ray the shader leaves unsettled (anyhit.glsl's -3) are
    shaded again by the CPU kernel."""
    colour, position, normal, radius, shadow_rays, exhausted = out
    n = len(hits)
    if n == 0:
        return
    kind = lights[0]
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
    )
    look_reals, look_ints, look_offsets = pack_tables([(look, "", LOOK_REAL, LOOK_INT)], {})
    hit_reals = np.column_stack([hits.u, hits.v, np.asarray(directions, dtype=np.float64).reshape(-1, 3)])
    hit_ints = np.column_stack([hits.hit, hits.patch, hits.surface]).astype(np.int32)
    unsettled = np.zeros(n, dtype=bool)
    step = min(n, gpu.dispatch_size(ctx))
    with ctx:
        shader = hierarchy_shader(ctx, "shade", bvh)
        set_shadow_uniforms(shader, bvh, tolerance, max_iterations)
        for key, offset in look_offsets.items():
            set_uniform(shader, f"off_{key}", offset)
        set_uniform(shader, "eps", float(eps))
        buffers = []
        try:  # the tables, then one slice's hits and outputs, written and read again for each slice
            for make in (
                lambda: ctx.buffer(look_reals),
                lambda: ctx.buffer(look_ints),
                lambda: ctx.buffer(reserve=step * 5 * 8),
                lambda: ctx.buffer(reserve=step * 3 * 4),
                lambda: ctx.buffer(reserve=step * 11 * 8),
                lambda: ctx.buffer(reserve=step * 3 * 4),
            ):
                buffers.append(make())
            for buffer, binding in zip(buffers, (4, 5, 2, 3, 8, 9)):
                buffer.bind_to_storage_buffer(binding)
            for first in range(0, n, step):
                part = slice(first, min(n, first + step))
                count = part.stop - part.start
                buffers[2].write(hit_reals[part])
                buffers[3].write(hit_ints[part])
                set_uniform(shader, "hit_count", count)
                for light in range(kind.shape[0]) if kind.shape[0] else (-1,):  # no light: colour 0 (a sum over none)
                    set_uniform(shader, "light", light)
                    gpu.run(ctx, shader, count)
                    ctx.memory_barrier()
                at = 0
                for array, width in ((colour, 3), (position, 3), (normal, 3), (radius, 2)):  # out_reals' blocks
                    if array is not None:  # straight into the outputs
                        gpu.read_rows(buffers[4], array[part], at)
                    at += count * width * 8
                ints = gpu.read_array(buffers[5], (3, count), np.int32)  # out_ints' blocks
                shadow_rays[part], exhausted[part], unsettled[part] = ints[0], ints[1], ints[2] != 0
                interrupts.safe_point()
        finally:
            for buffer in buffers:
                buffer.release()
    redo = np.flatnonzero(unsettled)
    if redo.size:
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
