"""Time `bsrt batch` on Dask against a plain loop of `bsrt render` processes.

    python scripts/batch_bench.py [--size 256] [--count 32] [--repeat 3] [--json FILE]

Each repeat times, in the same run (the machine may be shared: compare the
ratios, not the seconds):
  * loop:      `bsrt render` as a new process per input, one after another;
  * 1 worker:  bsrt.batch on a new local cluster of 1 worker process;
  * 2 workers: the same with 2 worker processes (cluster start included);
and the per-task overhead of the cluster: ``--count`` trivial 8x8 renders of
quad.toml through a running 1-worker cluster vs the same renders in this
process (the difference per task). The inputs are the bundled scenes
(column, water-lily, bench-64, quad), copied round-robin to ``--count`` files.
Medians over the repeats are printed.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENES = Path(__file__).resolve().parent.parent / "scenes"
BUNDLED = ("column", "water-lily", "bench-64", "quad")


def inputs(folder: Path, count: int) -> list[Path]:
    files = []
    for k in range(count):
        target = folder / f"{k:03d}-{BUNDLED[k % len(BUNDLED)]}.toml"
        shutil.copy(SCENES / f"{BUNDLED[k % len(BUNDLED)]}.toml", target)
        files.append(target)
    return files


def loop(files, out: Path, size: int) -> float:
    start = time.perf_counter()
    for f in files:
        subprocess.run(
            [
                sys.executable,
                "-m",
                "bsrt",
                "render",
                str(f),
                "-o",
                str(out / f"{f.stem}.png"),
                "--width",
                str(size),
                "--height",
                str(size),
            ],
            check=True,
            capture_output=True,
        )
    return time.perf_counter() - start


def batch(files, out: Path, size: int, workers: int) -> float:
    import bsrt

    start = time.perf_counter()
    summary = bsrt.batch(files, out, width=size, height=size, workers=workers)
    assert summary.exit_code == 0, [i.message for i in summary.items if i.status == "failed"]
    return time.perf_counter() - start


def overhead(files, out: Path) -> tuple[float, float]:
    """(seconds through a running 1-worker cluster, seconds in this process) for 8x8 renders."""
    import logging

    from distributed import Client, LocalCluster

    import bsrt
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import render

    warm = bsrt.load(files[0], width=8, height=8)
    render(warm, RenderOptions.resolve(warm))  # this process's kernels and GL loaded, as the worker's will be
    start = time.perf_counter()
    for f in files:
        scene = bsrt.load(f, width=8, height=8)
        render(scene, RenderOptions.resolve(scene)).png_bytes()
    in_process = time.perf_counter() - start
    with (
        LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=":0", silence_logs=logging.ERROR) as c,
        Client(c) as client,
    ):
        bsrt.batch(files[:2], out / "warm", width=8, height=8, client=client)  # the worker's kernels and GL loaded
        start = time.perf_counter()
        bsrt.batch(files, out / "cluster", width=8, height=8, client=client)
        through = time.perf_counter() - start
    return through, in_process


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--count", type=int, default=32)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", help="also write the timings as JSON")
    args = parser.parse_args()
    runs: dict[str, list[float]] = {
        "loop": [],
        "1 worker": [],
        "2 workers": [],
        "cluster 8x8": [],
        "in-process 8x8": [],
    }
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = inputs(folder, args.count)
        quads = [shutil.copy(SCENES / "quad.toml", folder / f"q{k:03d}.toml") for k in range(args.count)]
        for r in range(args.repeat):
            for name, call in (
                ("loop", lambda o: loop(files, o, args.size)),
                ("1 worker", lambda o: batch(files, o, args.size, 1)),
                ("2 workers", lambda o: batch(files, o, args.size, 2)),
            ):
                out = folder / f"out-{r}-{name.replace(' ', '')}"
                out.mkdir()
                runs[name].append(call(out))
            through, local = overhead([Path(q) for q in quads], folder / f"over-{r}")
            runs["cluster 8x8"].append(through)
            runs["in-process 8x8"].append(local)
            print(f"repeat {r + 1}: " + ", ".join(f"{k} {v[-1]:.1f} s" for k, v in runs.items()), flush=True)
    med = {k: statistics.median(v) for k, v in runs.items()}
    print(f"\n{args.count} renders of the bundled scenes at {args.size}x{args.size}, medians of {args.repeat}:")
    for name in ("loop", "1 worker", "2 workers"):
        print(f"  {name:10s} {med[name]:7.1f} s   loop / this = {med['loop'] / med[name]:.2f}")
    print(f"  2 workers vs 1 worker: {med['1 worker'] / med['2 workers']:.2f}x faster")
    per_task = (med["cluster 8x8"] - med["in-process 8x8"]) / args.count
    print(
        f"per-task overhead of the cluster ({args.count} renders of 8x8): {med['cluster 8x8']:.2f} s through "
        f"it vs {med['in-process 8x8']:.2f} s in-process: {per_task * 1000:.0f} ms per task"
    )
    if args.json:
        Path(args.json).write_text(json.dumps({"runs": runs, "medians": med, "per_task_overhead": per_task}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
