"""Shadow and mirror rays on the GPU: the hierarchy in storage buffers, its walks as compute shaders.

``occluded_gpu`` answers, for shadow rays given as arrays, what the CPU's
any-hit walk (kernels/lighting.py's occluded; bvh.intersect with any_hit)
answers: blocked or not, which rays spent their budget (taken as lit), and
the Newton iterations each took.
``shaders/shadow.glsl`` runs ``shaders/anyhit.glsl``, a port of that walk
in float64, on the hierarchy (rendering/bvh.py's BVHArrays) uploaded once
per hierarchy beside the patch table (gpu.uploaded). ``nearest_gpu`` gives
the nearest hits of rays given as arrays (bvh.intersect) by ``shaders/nearest.glsl``
(the walk of nearest_walk.glsl), which ``trace_gpu`` takes bvh.intersect's
arguments to. ``hierarchy_shader`` compiles and binds a shader that walks
the hierarchy (the lighting's too: gpu_lighting.py). The rays a software
renderer leaves unsettled (llvmpipe's loop limiter: anyhit.glsl's head) are
traced by the CPU's walk instead.
"""

from __future__ import annotations

import dataclasses

import moderngl
import numpy as np

from bsrt import interrupts
from bsrt.kernels.crossings import ROUNDING
from bsrt.kernels.hierarchy import BVHArrays
from bsrt.kernels.shading import LIGHT_KINDS, POLE_STEPS
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
        buffers = gpu.kept_buffers(ctx, "bsrt_shadow", min(n, step), (12 * 8, 2 * 4))  # rays, answers
        for first in range(0, n, step):
            count = min(step, n - first)
            buffers[0].write(rays[first : first + count])
            buffers[0].bind_to_storage_buffer(2)
            buffers[1].bind_to_storage_buffer(3)
            set_uniform(shader, "ray_count", count)
            gpu.run(ctx, shader, count)
            ctx.memory_barrier()
            gpu.read_rows(buffers[1], answer[first : first + count])
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
        buffers = gpu.kept_buffers(ctx, "bsrt_nearest", min(n, step), (13 * 8, 4 * 8, 3 * 4))  # rays, hits
        for first in range(0, n, step):
            part = slice(first, min(n, first + step))
            count = part.stop - part.start
            buffers[0].write(rays[part])
            for binding, buffer in enumerate(buffers, start=2):
                buffer.bind_to_storage_buffer(binding)
            set_uniform(shader, "ray_count", count)
            gpu.run(ctx, shader, count)
            ctx.memory_barrier()
            gpu.read_rows(buffers[1], reals[part])
            gpu.read_rows(buffers[2], ints[part])
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
    any-hit walk, its shadow rays, go through gpu_lighting.shade_hits_gpu)."""
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
