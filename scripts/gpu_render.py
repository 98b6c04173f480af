"""Whole renders on both devices side by side: ``device = "cpu"`` against
``device = "gpu"`` (the map solved in place, the direct lighting with its
shadow rays in the compute shaders; repair, mirrors and AO on the CPU), in
process, the scene's geometry kept between renders as the preview keeps it.

    python scripts/gpu_render.py [scenes/column.toml model.igs ...] [--size 512 | --width W --height H]
                                 [--repeat 3] [--spp N] [--adaptive-spp N] [--devices cpu,gpu] [--json FILE]
                                 [--dispatches]

Prints the GL renderer, the cores and the load average, then one row per
scene and device: the median wall and CPU seconds of the render (the first
render of each device, compiling and uploading, not counted; the devices
interleaved) and the median seconds of its stages (stats["seconds"]). With
both devices, one more row per scene says how far apart their answers are,
by the rule of tests/test_gpu.py: pixels away from silhouettes (all 8
neighbours with the same hit and surface on the CPU) whose hit or surface
differs, the largest |dt| over pixels both hit in units of the scene's
diagonal, and the largest 8-bit image difference there and anywhere. On
llvmpipe the GPU figures are the shaders run on the CPU cores by Mesa's LLVM.
--dispatches waits for each compute dispatch to finish (glFinish) and splits
each render's wall into the seconds in dispatches and the rest, the host's
(the GPU's work then no longer overlaps the host's: a split, not a speed).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bsrt.rendering import gl  # noqa: E402
from bsrt.rendering.hits import away_from_silhouettes  # noqa: E402
from bsrt.rendering.options import RenderOptions  # noqa: E402
from bsrt.rendering.pipeline import Geometry, render  # noqa: E402
from bsrt.scene.loading import load_input  # noqa: E402

DISPATCHED = [0.0]  # seconds in compute dispatches so far (--dispatches)


def time_dispatches() -> None:
    """Make every compute dispatch wait for its end (glFinish) and add its seconds to DISPATCHED."""
    import moderngl

    run = moderngl.ComputeShader.run

    def timed(self, *args, **kwargs):
        clock = time.perf_counter()
        try:
            return run(self, *args, **kwargs)
        finally:
            self.ctx.finish()
            DISPATCHED[0] += time.perf_counter() - clock

    moderngl.ComputeShader.run = timed


def agreement(cpu, gpu, shape, diagonal) -> dict:
    """How far the GPU render's answers are from the CPU's (the reference)."""
    hit_c, hit_g = cpu.hits.hit.reshape(shape), gpu.hits.hit.reshape(shape)
    surf_c, surf_g = cpu.hits.surface.reshape(shape), gpu.hits.surface.reshape(shape)
    inner = away_from_silhouettes(hit_c, surf_c)
    both = (hit_c & hit_g).ravel()
    dt = np.abs(cpu.hits.t[both] - gpu.hits.t[both])
    diff = np.abs(cpu.pixels.astype(int) - gpu.pixels.astype(int)).max(axis=-1)
    return {
        "inner_pixels": int(inner.sum()),
        "hit_differs": int((hit_c != hit_g)[inner].sum()),
        "surface_differs": int(((surf_c != surf_g) & hit_c & hit_g)[inner].sum()),
        "max_dt_over_diagonal": float(dt.max() / diagonal) if dt.size else 0.0,
        "max_diff_inner": int(diff[inner].max()) if inner.any() else 0,
        "max_diff": int(diff.max()),
    }


def compare(path, width, height, repeat, devices, extra) -> dict:
    """One scene: {device: {wall, cpu, stages}} and, with both devices, the agreement."""
    scene = load_input(path, width=width, height=height)
    geometry = Geometry(scene)
    wall = {d: [] for d in devices}
    cpu = {d: [] for d in devices}
    stages: dict[str, dict[str, list[float]]] = {d: {} for d in devices}
    results = {}
    for run in range(repeat + 1):
        for device in devices:
            options = RenderOptions.resolve(scene, width=width, height=height, device=device, **extra)
            clock, processor, dispatched = time.perf_counter(), time.process_time(), DISPATCHED[0]
            result = render(scene, options, geometry=geometry)
            if run:
                wall[device].append(time.perf_counter() - clock)
                cpu[device].append(time.process_time() - processor)
                for stage, seconds in result.stats["seconds"].items():
                    stages[device].setdefault(stage, []).append(seconds)
                stages[device].setdefault("dispatches", []).append(DISPATCHED[0] - dispatched)
                stages[device].setdefault("host", []).append(wall[device][-1] - (DISPATCHED[0] - dispatched))
            results[device] = result
    row = {"scene": Path(path).stem, "width": width, "height": height}
    for device in devices:
        row[device] = {
            "wall": statistics.median(wall[device]),
            "cpu": statistics.median(cpu[device]),
            "stages": {k: statistics.median(v) for k, v in stages[device].items()},
            "devices": results[device].stats["devices"],
        }
    if set(devices) == {"cpu", "gpu"}:
        row["agreement"] = agreement(results["cpu"], results["gpu"], (height, width), geometry.diagonal)
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "scenes", nargs="*", default=[str(ROOT / "scenes" / f"{n}.toml") for n in ("column", "water-lily")]
    )
    parser.add_argument("--size", type=int, default=512, help="a square film's side (unless --width/--height)")
    parser.add_argument("--width", type=int)
    parser.add_argument("--height", type=int)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    parser.add_argument("--adaptive-spp", type=int, help="adaptive anti-aliasing's samples (default: the scene's)")
    parser.add_argument("--devices", default="cpu,gpu", help="comma-separated, interleaved in this order")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON here")
    parser.add_argument(
        "--dispatches", action="store_true", help="split the wall into compute dispatches (each waited for) and host"
    )
    args = parser.parse_args(argv)
    if args.dispatches:
        time_dispatches()
    width, height = args.width or args.size, args.height or args.size
    devices = tuple(args.devices.split(","))
    extra = {k: v for k, v in (("spp", args.spp), ("adaptive_spp", args.adaptive_spp)) if v is not None}
    caps = gl.capabilities(gl.headless_context())
    print(f"GL: {caps.renderer}, {caps.version_string}, hardware {caps.hardware}")
    print(
        f"film {width}x{height}, {extra or 'the scenes own samples'}; cores: {len(os.sched_getaffinity(0))}, "
        f"load average: {os.getloadavg()[0]:.2f}"
    )
    rows = []
    for path in args.scenes:
        r = compare(path, width, height, args.repeat, devices, extra)
        rows.append(r)
        for device in devices:
            d = r[device]
            parts = "  ".join(f"{k} {v:.4f}" for k, v in d["stages"].items())
            print(f"{r['scene']:>14} {device}: wall {d['wall']:.4f} s, cpu {d['cpu']:.3f} s;  {parts}")
        if "agreement" in r:
            print(f"{r['scene']:>14} agreement: {r['agreement']}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    if args.json:
        args.json.write_text(json.dumps({"renderer": caps.renderer, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
