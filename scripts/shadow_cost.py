"""CPU time of the compiled shading pass (its shadow rays) alone, one thread, and its answers.

    python scripts/shadow_cost.py [--size 512] [--repeat 5] [--save DIR] [SCENE ...]

For each scene (default: the bundled column and water-lily), renders once in
process and keeps the arguments of every ``kernels.lighting.shade_hits`` call
(the pass over a slice of hits: frames, shadow rays, Blinn-Phong), then runs
the pass again over all of them in this thread, ``repeat`` times, timed by
``time.process_time`` (the machine may be shared; one thread, so CPU time is
the pass's own). Prints the median and the range, the shadow rays and the
hits. --save DIR writes each scene's colours (``SCENE.npy``, (K, 3) float64
linear RGB) and the hits they were shaded from (``SCENE-hits.npz``); --against
DIR shades those hits instead of this checkout's own (the primary rays of two
checkouts may differ in the last bits) and counts the colours that differ
from DIR's, so that two checkouts' passes are compared to the bit on the
same input.
Run it with PYTHONPATH set to each checkout, interleaved, to compare them.
Reports the load average at start and end.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

import bsrt
from bsrt.rendering import pipeline
from bsrt.rendering.options import RenderOptions

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = [ROOT / "scenes" / "column.toml", ROOT / "scenes" / "water-lily.toml"]


def captured_calls(scene) -> list[tuple]:
    """The argument tuples (after start, stop) of every shade_hits call of one render of ``scene``."""
    calls, kernel = {}, pipeline.shade_hits

    def keep(start, stop, *args):
        calls.setdefault(id(args[3]), args)  # args[3]: the slice's hit flags
        kernel(start, stop, *args)

    pipeline.shade_hits = keep
    try:
        pipeline.render(scene, RenderOptions.resolve(scene, adaptive_spp=0))
    finally:
        pipeline.shade_hits = kernel
    return list(calls.values())


HITS = {"hit": 3, "patch": 4, "surface": 5, "u": 6, "v": 7, "direction": 8}  # shade_hits's inputs (after start, stop)


def with_hits(calls: list[tuple], hits) -> list[tuple]:
    """``calls`` with their hit arrays (HITS) replaced by consecutive parts of the saved ``hits``."""
    out, a = [], 0
    for call in calls:
        call, b = list(call), a + len(call[3])
        for name, i in HITS.items():
            call[i] = np.ascontiguousarray(hits[name][a:b])
        out.append(tuple(call))
        a = b
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", type=Path)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--save", type=Path)
    parser.add_argument("--against", type=Path)
    args = parser.parse_args()
    print(f"load average at start: {Path('/proc/loadavg').read_text().split()[:3]}")
    for path in args.scenes or DEFAULT:
        scene = bsrt.load(path, width=args.size, height=args.size)
        calls = captured_calls(scene)
        if args.against is not None:
            calls = with_hits(calls, np.load(args.against / f"{path.stem}-hits.npz"))
        times = []
        for _ in range(args.repeat):
            clock = time.process_time()
            for call in calls:
                pipeline.shade_hits(0, len(call[3]), *call)
            times.append(time.process_time() - clock)
        colour = np.concatenate([call[-6] for call in calls])
        rays = int(sum(call[-2].sum() for call in calls))
        hits = sum(int(np.count_nonzero(call[3])) for call in calls)
        line = f"{path.stem:12s} shade pass {statistics.median(times):.3f} s CPU (median of {args.repeat}, "
        line += f"{min(times):.3f}-{max(times):.3f}), {rays} shadow rays, {hits} hits"
        if args.against is not None:
            other = np.load(args.against / f"{path.stem}.npy")
            differ = ~np.all((colour == other) | (np.isnan(colour) & np.isnan(other)), axis=1)
            line += f"; colours differing from {args.against}: {int(differ.sum())}"
        if args.save is not None:
            args.save.mkdir(parents=True, exist_ok=True)
            np.save(args.save / f"{path.stem}.npy", colour)
            np.savez(
                args.save / f"{path.stem}-hits.npz",
                **{k: np.concatenate([c[i] for c in calls]) for k, i in HITS.items()},
            )
        print(line, flush=True)
    print(f"load average at end: {Path('/proc/loadavg').read_text().split()[:3]}")


if __name__ == "__main__":
    main()
