"""The seeded solve on both devices side by side: the CPU kernels
(kernels/roots.py, threads) and the GPU compute shader (shaders/solve.glsl
through the process's EGL context), on the preliminary map's seeds of a
scene, with the time of each and how far apart their answers are.

    python scripts/gpu_solve.py [scenes/column.toml model.igs ...] [--size 512] [--method newton] [--repeat 3]

Prints one row per scene and method: items (covered pixels), the median
seconds of the map drawn and read back (map_s, render_map), of each device's
solve alone from the read-back seeds (cpu_s, gpu_s: find_roots vs
find_roots_gpu, trims included) and of the map drawn and solved on the GPU
without the read-back in between (in_place_s, gpu_map.map_roots_gpu: compare
it with map_s + gpu_s), how many
items converge on each, items whose converged flag differs, and the
largest |dt| over items both converged, in units of the scene's diagonal.
The first lines say the GL renderer and the load average. On llvmpipe the
GPU figures are the shader on the CPU (Mesa's LLVM); on a GPU they are the
GPU's.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bsrt.methods import METHODS  # noqa: E402
from bsrt.rendering import gl  # noqa: E402
from bsrt.rendering.gpu import find_roots_gpu  # noqa: E402
from bsrt.rendering.gpu_map import map_roots_gpu  # noqa: E402
from bsrt.rendering.options import RenderOptions  # noqa: E402
from bsrt.rendering.pipeline import Geometry  # noqa: E402
from bsrt.rendering.prelim import render_map  # noqa: E402
from bsrt.rendering.solve import Rays, find_roots  # noqa: E402
from bsrt.scene.camera import pixel_rays  # noqa: E402
from bsrt.scene.loading import load_input  # noqa: E402


def compare(path, size, method, repeat):
    """One scene: the row's numbers as a dict."""
    scene = load_input(path, width=size, height=size)  # a scene file, or a model file framed automatically
    options = RenderOptions.resolve(scene, width=size, height=size, method=method)
    geometry = Geometry(scene)
    patches = geometry.patches
    camera = options.camera
    prelim = render_map(patches, camera, size, size, options.map)
    rays = Rays.from_arrays(camera.eye[None, :], pixel_rays(camera, size, size, (0, size)))
    seed = prelim.surface.ravel()
    covered = np.flatnonzero(seed >= 0)
    args = (patches, rays, covered, seed[covered], prelim.u.ravel()[covered], prelim.v.ravel()[covered])
    kw = dict(
        method=method,
        tolerance=options.tolerance * geometry.diagonal,
        max_iterations=options.max_iterations,
        stop_on_growth=METHODS[method].stops_on_growth,
    )
    ctx = gl.headless_context()
    times = {"cpu": [], "gpu": [], "map": [], "in_place": []}
    results = {}
    solve = (options.map, method, kw["tolerance"], kw["max_iterations"], kw["stop_on_growth"])
    for _ in range(repeat + 1):  # the first of each: compiling and uploading, not counted
        for device in ("cpu", "gpu", "map", "in_place"):
            clock = time.perf_counter()
            if device == "map":  # drawn, read back and decoded (what the solves above start from)
                render_map(patches, camera, size, size, options.map, ctx=ctx)
            elif device == "in_place":  # drawn and solved on the GPU, read back once (gpu_map.py)
                map_roots_gpu(ctx, patches, camera, size, size, (0, size), rays.direction, *solve)
            else:
                res = find_roots(*args, **kw) if device == "cpu" else find_roots_gpu(ctx, *args, **kw)
                results[device] = res
            times[device].append(time.perf_counter() - clock)
    cpu, gpu = results["cpu"], results["gpu"]
    both = cpu.converged & gpu.converged
    dt = np.abs(cpu.t[both] - gpu.t[both]) / geometry.diagonal
    row = {"scene": Path(path).stem, "method": method, "items": int(covered.size)}
    for device in ("map", "in_place"):
        row[f"{device}_s"] = statistics.median(times[device][1:])
    for device in ("cpu", "gpu"):
        seconds = statistics.median(times[device][1:])
        row[f"{device}_s"] = seconds
        row[f"{device}_rays_per_s"] = covered.size / seconds if seconds > 0 else float("inf")
        row[f"{device}_converged"] = int(results[device].converged.sum())
    row["converged_differ"] = int((cpu.converged != gpu.converged).sum())
    row["max_dt"] = float(dt.max()) if dt.size else 0.0
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "scenes", nargs="*", default=[str(ROOT / "scenes" / f"{n}.toml") for n in ("column", "water-lily")]
    )
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--method", action="append", choices=[m for m in METHODS if METHODS[m].kernel_id is not None])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    caps = gl.capabilities(gl.headless_context())
    print(
        f"GL: {caps.renderer}, {caps.version_string}, compute {caps.compute}, fp64 {caps.fp64}, hardware {caps.hardware}"
    )
    print(f"load average: {os.getloadavg()[0]:.2f}, cores: {len(os.sched_getaffinity(0))}")
    header = ("scene", "method", "items", "map_s", "cpu_s", "gpu_s", "in_place_s", "cpu_conv", "gpu_conv", "differ",
              "max|dt|/diag")  # fmt: skip
    print("  ".join(f"{h:>12}" for h in header))
    for path in args.scenes:
        for method in args.method or ["newton"]:
            r = compare(path, args.size, method, args.repeat)
            print(
                f"{r['scene']:>12}  {r['method']:>12}  {r['items']:>12}  {r['map_s']:>12.4f}  {r['cpu_s']:>12.4f}  "
                f"{r['gpu_s']:>12.4f}  {r['in_place_s']:>12.4f}  "
                f"{r['cpu_converged']:>12}  {r['gpu_converged']:>12}  {r['converged_differ']:>12}  {r['max_dt']:>12.2e}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
