"""Adaptive anti-aliasing against uniform supersampling: camera samples, CPU time and error.

    python scripts/antialias_cost.py [--size 256] [--repeat 1] [INPUT ...]

For each input (default: the bundled scenes water-lily and column, and the
STEP screw of the tests), renders in one process, after a warm-up: one
sample per pixel (adaptive_spp 0), adaptive anti-aliasing with 4, 9 and
16 samples (adaptive_spp 4, 9, 16), uniform --spp 4 and --spp 16; prints
per render the camera samples (pixels x spp, plus adaptive_samples), their
ratio to --spp 4 and --spp 16, the process CPU time (time.process_time: the
machine may be shared; with --repeat N, each render N times in turn, the
median), the CPU time above the one-sample render's as a
fraction of --spp 4's above it (``extra/spp4``) and the error against
--spp 16 (mean and max over pixels of the largest channel difference,
linear RGB). Reports the load average at start and end.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import bsrt
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = [
    ROOT / "scenes" / "water-lily.toml",
    ROOT / "scenes" / "column.toml",
    ROOT / "tests" / "data" / "models" / "step" / "occt" / "screw.step",
]
CASES = (
    ("spp1", 1, 0),
    ("adaptive4", 1, 4),
    ("adaptive9", 1, 9),
    ("adaptive16", 1, 16),
    ("spp4", 4, 0),
    ("spp16", 16, 0),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("inputs", nargs="*", type=Path)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--repeat", type=int, default=1, help="renders of each case, in turn; the median CPU time")
    args = parser.parse_args()
    print(f"load average at start: {Path('/proc/loadavg').read_text().split()[:3]}")
    for path in args.inputs or DEFAULT:
        scene = bsrt.load(path, width=args.size, height=args.size)
        geometry = Geometry(scene)
        render(scene, RenderOptions.resolve(scene, spp=1, adaptive_spp=0), geometry=geometry)  # warm-up
        out, cpus = {}, {name: [] for name, _, _ in CASES}
        for _ in range(args.repeat):
            for name, spp, adaptive in CASES:
                clock = time.process_time()
                res = render(scene, RenderOptions.resolve(scene, spp=spp, adaptive_spp=adaptive), geometry=geometry)
                cpus[name].append(time.process_time() - clock)
                samples = res.stats["pixels"] * spp + res.stats.get("adaptive_samples", 0)
                out[name] = (res.linear, samples, float(np.median(cpus[name])))
        ref = out["spp16"][0]
        pixels = args.size * args.size
        print(f"\n{path.name} {args.size}x{args.size}")
        print("render        samples  /spp4  /spp16   cpu s  extra/spp4  err mean  err max")
        one, four = out["spp1"][2], out["spp4"][2]
        for name, (linear, samples, cpu) in out.items():
            err = np.abs(linear - ref).max(axis=2)
            print(
                f"{name:12s} {samples:8d}  {samples / (4 * pixels):5.2f}  {samples / (16 * pixels):5.3f}  "
                f"{cpu:6.2f}  {(cpu - one) / max(four - one, 1e-9):10.2f}  {err.mean():8.5f}  {err.max():6.3f}"
            )
    print(f"\nload average at end: {Path('/proc/loadavg').read_text().split()[:3]}")


if __name__ == "__main__":
    main()
