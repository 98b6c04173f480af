"""The map and the seeded solve on the GPU together, the map never read back before the solve.

``map_roots_gpu`` draws a band's preliminary map tile by tile
(prelim.drawn_tiles) and, while each tile's two passes are still in their
framebuffers' textures on the same context, runs ``shaders/map_solve.glsl``
over the tile's pixels: it merges the passes and decodes the seed as
kernels/prelim.py's decode_tile does, and solves from it (solve_core.glsl,
the loop of kernels/roots.py). Only the camera rays' directions go up; what
comes back, once per band after every tile is solved, is per pixel the
merged map (red, green, blue as drawn and the eye distance: 16 bytes) and
the root (u, v, t, residual, converged, patch, iterations, trimmed: 48
bytes). That is the smallest read-back that keeps the suspect-pixel rules
(hard_pixels.py) exactly as they are: they read the whole map (neighbours'
surfaces, distances and seeds), as does the repair and RenderResult.prelim.
It replaces the two passes' read-back (40 bytes per pixel with the float
map) and the seeds' upload (68 bytes per covered pixel) of the path through
find_roots_gpu.
"""

from __future__ import annotations

import moderngl
import numpy as np

from bsrt import interrupts
from bsrt.geometry.patches import PatchSet
from bsrt.kernels.prelim import decode_merged
from bsrt.kernels.threads import run_chunks
from bsrt.rendering import gpu
from bsrt.rendering.gpu import set_uniform, solver
from bsrt.rendering.prelim import PrelimMap, drawn_tiles
from bsrt.rendering.solve import RootResult, seeded_kernel_id
from bsrt.scene.camera import Camera


def map_roots_gpu(
    ctx: moderngl.Context,
    patches: PatchSet,
    camera: Camera,
    width: int,
    height: int,
    rows: tuple[int, int],
    directions: np.ndarray,
    mode: str,
    method: str,
    tolerance: float,
    max_iterations: int,
    stop_on_growth: bool,
) -> tuple[PrelimMap, np.ndarray, RootResult]:
    """The map of film rows rows[0]..rows[1]-1 (render_map's arguments) and
    the roots of its seeds, solved on ctx (the map's context, with OpenGL
    4.5 and float64: gpu.choose_device).

    directions: (N, 3) float64 unit camera-ray directions of the band's N =
    (rows[1] - rows[0]) * width pixels, row-major; the rays start at
    camera.eye. Returns (the PrelimMap, as render_map's; covered (M,) int64
    the flat indices of the pixels the map covers, sorted; their roots,
    RootResult (M,), as find_roots answers for the same items)."""
    first, stop = rows
    n = (stop - first) * width
    directions = np.ascontiguousarray(directions, dtype=np.float64)
    if directions.shape != (n, 3):
        raise ValueError(f"directions: expected ({n}, 3), got {directions.shape}")
    with drawn_tiles(patches, camera, width, height, mode, ctx, rows) as drawn:  # ctx current from here
        # the rays' directions, then the merged map, the roots' reals and ints (kept between bands)
        buffers = gpu.kept_buffers(ctx, "bsrt_map_solve", n, (24, 16, 32, 16))
        buffers[0].write(directions)
        shader = solver(ctx, "map_solve", patches, seeded_kernel_id(method), tolerance, max_iterations, stop_on_growth)
        set_uniform(shader, "eye", tuple(float(x) for x in camera.eye))
        set_uniform(shader, "float_map", int(mode == "float"))
        set_uniform(shader, "band_width", width)
        for passes, (r0, _), (c0, _) in drawn:
            for binding, buffer in enumerate(buffers, start=2):
                buffer.bind_to_storage_buffer(binding)
            for unit, texture in enumerate(
                (passes.tri.color, passes.tri.eye_distance, passes.line.color, passes.line.eye_distance)
            ):
                texture.use(location=unit)
            set_uniform(shader, "row0", r0 - first)
            set_uniform(shader, "col0", c0)
            texels = passes.tri.size[0] * passes.tri.size[1]
            step = gpu.dispatch_size(ctx)
            for start in range(0, texels, step):  # a signal is taken between dispatches
                count = min(step, texels - start)
                set_uniform(shader, "first_texel", start)
                set_uniform(shader, "texel_count", count)
                gpu.run(ctx, shader, count)
                interrupts.safe_point()
            ctx.memory_barrier()  # the textures are drawn again for the next tile; the buffers are read
        record = gpu.read_array(buffers[1], (n, 4), np.float32)
        reals, ints = gpu.read_array(buffers[2], (n, 4), np.float64), gpu.read_array(buffers[3], (n, 4), np.int32)
    prelim = decode_record(record, mode, patches.domain, (stop - first, width))
    covered = np.flatnonzero(prelim.surface.ravel() >= 0)
    return prelim, covered, gpu.decode_roots(reals, ints, covered)


def decode_record(record: np.ndarray, mode: str, domain: np.ndarray, shape: tuple[int, int]) -> PrelimMap:
    """The PrelimMap of shape (H, W) from map_solve.glsl's merged map: record
    (H * W, 4) float32, per pixel red (surface index + 1, 0 where empty),
    green, blue (u, v over the surface's domain: in [0, 1] for the float map,
    the bytes 0..255 of the 8-bit one) and the eye distance; domain (S, 4)
    float64. kernels/prelim.py's decode_merged, on every core: the same
    arrays as render_map's."""
    out = PrelimMap.blank(shape)
    n = shape[0] * shape[1]
    flat = (out.surface.reshape(n), out.u.reshape(n), out.v.reshape(n), out.distance.reshape(n))
    run_chunks(
        decode_merged, n, record, mode == "float", np.ascontiguousarray(domain, dtype=np.float64), *flat,
        out.picture.reshape(n, 3),
    )  # fmt: skip
    return out
