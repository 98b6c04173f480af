"""Whole renders on both devices side by side: ``device = "cpu"`` against
``device = "gpu"`` (the map solved in place, the direct lighting with its
shadow rays in the compute shaders; repair, mirrors and AO on the CPU), in
process, the scene's geometry kept between renders as the preview keeps it.

    python scripts/gpu_render.py [scenes/column.toml model.igs ...] [--size 512] [--repeat 3]

Prints the GL renderer and the load average, then one row per scene: the
median wall and CPU seconds of each device's render (the first render of
each, compiling and uploading, not counted; the two devices interleaved),
the GPU render's map+solve and shade seconds, and how far apart the two
images are (the largest 8-bit difference). On llvmpipe the GPU figures are
the shaders run on the CPU cores by Mesa's LLVM.
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

from bsrt.rendering import gl  # noqa: E402
from bsrt.rendering.options import RenderOptions  # noqa: E402
from bsrt.rendering.pipeline import Geometry, render  # noqa: E402
from bsrt.scene.loading import load_input  # noqa: E402

DEVICES = ("cpu", "gpu")


def compare(path, size, repeat):
    """One scene: the row's numbers as a dict."""
    scene = load_input(path, width=size, height=size)
    geometry = Geometry(scene)
    wall, cpu = {d: [] for d in DEVICES}, {d: [] for d in DEVICES}
    stages = {"solve": [], "shade": []}
    pixels = {}
    for run in range(repeat + 1):
        for device in DEVICES:
            options = RenderOptions.resolve(scene, width=size, height=size, device=device)
            clock, processor = time.perf_counter(), time.process_time()
            result = render(scene, options, geometry=geometry)
            if run:
                wall[device].append(time.perf_counter() - clock)
                cpu[device].append(time.process_time() - processor)
                if device == "gpu":
                    seconds = result.stats["seconds"]
                    stages["solve"].append(seconds["map"] + seconds["solve"])
                    stages["shade"].append(seconds["shade"])
            pixels[device] = result.pixels
    row = {"scene": Path(path).stem}
    for device in DEVICES:
        row[f"{device}_wall"] = statistics.median(wall[device])
        row[f"{device}_cpu"] = statistics.median(cpu[device])
    row["gpu_map_solve"] = statistics.median(stages["solve"])
    row["gpu_shade"] = statistics.median(stages["shade"])
    row["max_diff"] = int(np.abs(pixels["cpu"].astype(int) - pixels["gpu"].astype(int)).max())
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "scenes", nargs="*", default=[str(ROOT / "scenes" / f"{n}.toml") for n in ("column", "water-lily")]
    )
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    caps = gl.capabilities(gl.headless_context())
    print(f"GL: {caps.renderer}, {caps.version_string}, hardware {caps.hardware}")
    print(f"load average: {os.getloadavg()[0]:.2f}, cores: {len(os.sched_getaffinity(0))}")
    header = ("scene", "cpu_wall", "cpu_cpu", "gpu_wall", "gpu_cpu", "gpu_map+solve", "gpu_shade", "max_diff")
    print("  ".join(f"{h:>13}" for h in header))
    for path in args.scenes:
        r = compare(path, args.size, args.repeat)
        print(
            f"{r['scene']:>13}  {r['cpu_wall']:>13.3f}  {r['cpu_cpu']:>13.3f}  {r['gpu_wall']:>13.3f}  "
            f"{r['gpu_cpu']:>13.3f}  {r['gpu_map_solve']:>13.3f}  {r['gpu_shade']:>13.3f}  {r['max_diff']:>13}"
        )
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
