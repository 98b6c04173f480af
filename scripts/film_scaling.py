"""How a whole render scales with the film: time ratio 2048² / 512² and peak memory.

Time (wall and CPU): one process renders the scene at 512x512 and at 2048x2048 in
alternating rounds (after an untimed render of each, so kernels, the GL
context and the hierarchy are warm); prints each size's median and the
median of the per-round ratios. Memory: each size in a fresh child process
(the whole `bsrt render` as a user runs it, PNG written), its peak resident
memory from the kernel (ru_maxrss). Usage:

    python scripts/film_scaling.py [SCENE] [--rounds 3] [--sizes 512 2048] [--peak-sizes 512 2048 4096]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def timed_rounds(scene_path: Path, sizes: list[int], rounds: int):
    """Whole-render seconds per size, rendered in alternating rounds in this process:
    ({size: wall seconds per round}, {size: CPU seconds per round}, all threads)."""
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import Geometry, render
    from bsrt.scene import load_scene

    scene = load_scene(scene_path)
    geometry = Geometry(scene)
    options = {n: RenderOptions.resolve(scene, width=n, height=n) for n in sizes}
    for n in sizes:
        render(scene, options[n], geometry=geometry)  # warm-up
    times: dict[int, list[float]] = {n: [] for n in sizes}
    cpu: dict[int, list[float]] = {n: [] for n in sizes}
    for _ in range(rounds):
        for n in sizes:
            clock, used = time.perf_counter(), time.process_time()
            render(scene, options[n], geometry=geometry, keep=False)  # as bsrt render without --aov
            times[n].append(time.perf_counter() - clock)
            cpu[n].append(time.process_time() - used)
    return times, cpu


def peak_mb(scene_path: Path, size: int) -> float:
    """Peak RSS (MB) of `bsrt render SCENE --width size --height size` in a fresh process."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [
            sys.executable,
            "-m",
            "bsrt",
            "render",
            str(scene_path),
            "-o",
            os.path.join(tmp, "out.png"),
            "--width",
            str(size),
            "--height",
            str(size),
        ]
        from bsrt.errors import InputError
        from bsrt.rendering.bench_memory import peak_rss

        try:
            return peak_rss(cmd, dict(os.environ)) / 2**20
        except InputError as exc:
            raise SystemExit(f"render at {size} failed: {exc}") from None


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=str(ROOT / "scenes" / "water-lily.toml"))
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--sizes", type=int, nargs=2, default=[512, 2048], metavar=("SMALL", "LARGE"))
    p.add_argument("--peak-sizes", type=int, nargs="*", default=[512, 2048, 4096])
    a = p.parse_args()
    scene = Path(a.scene)
    small, large = a.sizes
    print(f"load average before: {os.getloadavg()[0]:.2f}", flush=True)
    times, cpu = timed_rounds(scene, [small, large], a.rounds)
    ratios = [b / s for s, b in zip(times[small], times[large])]
    cpu_ratios = [b / s for s, b in zip(cpu[small], cpu[large])]
    print(
        f"{scene.name}: whole render, median of {a.rounds} rounds: {small}x{small} {statistics.median(times[small]):.2f} s, "
        f"{large}x{large} {statistics.median(times[large]):.2f} s; ratio {statistics.median(ratios):.1f}x "
        f"(pixels {(large / small) ** 2:.0f}x; per round {', '.join(f'{r:.1f}' for r in ratios)})",
        flush=True,
    )
    print(
        f"{scene.name}: CPU time, median: {small}x{small} {statistics.median(cpu[small]):.2f} s, "
        f"{large}x{large} {statistics.median(cpu[large]):.2f} s; ratio {statistics.median(cpu_ratios):.1f}x; "
        f"load average after: {os.getloadavg()[0]:.2f}",
        flush=True,
    )
    for n in a.peak_sizes:
        print(f"{scene.name}: peak memory of bsrt render at {n}x{n}: {peak_mb(scene, n):.0f} MB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
