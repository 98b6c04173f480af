"""Scenes with one control point far out (issue #28 item 5): write them, render them, time them.

Takes scenes of ``scenes/`` and moves one control point of one surface to
x = 1e9 (a legal scene of size about 10 with one point very far away), then
renders each at 40x40 with ``bsrt render --stats`` in a child process and
prints the wall and CPU time (the child's, all threads), the stages' wall
times and the rays that ran out of their budget (bvh.py, "Budget"):

    python scripts/far_point.py [--width 40] [--x 1e9] [--write DIR] [--no-render]

``--write DIR`` keeps the scenes (``<scene>-s<surface>.toml``; with
``--no-render`` it prints their paths): tests/test_interrupts.py runs it so,
so that the way such a scene is made has one owner.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# (scene, surface index, control point row, column): a point inside the net, on several surfaces
CASES = (
    ("column", 0, 2, 2),
    ("column", 20, 1, 2),
    ("water-lily", 3, 2, 1),
    ("quad", 0, 1, 1),
)
_POINT = re.compile(r"\[\s*([^\[\],]+),\s*([^\[\],]+),\s*([^\[\],]+)\]")


def far_scene(text: str, surface: int, row: int, column: int, x: float = 1e9) -> str:
    """The scene text (a TOML scene with inline ``points``) with control point
    [row][column] of its ``surface``-th [[surface]] moved to x (y, z kept)."""
    lines = text.splitlines(keepends=True)
    starts = [i for i, line in enumerate(lines) if line.strip() == "[[surface]]"]
    first = starts[surface]
    at = next(i for i in range(first, len(lines)) if lines[i].lstrip().startswith("points = ["))
    line = lines[at + 1 + row]
    points = list(_POINT.finditer(line))
    m = points[column]
    lines[at + 1 + row] = line[: m.start(1)] + repr(float(x)) + line[m.end(1) :]
    return "".join(lines)


def write_scenes(folder: Path, x: float = 1e9) -> list[Path]:
    """Every case of CASES as folder/<scene>-s<surface>.toml; returns their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for scene, surface, row, column in CASES:
        src = ROOT / "scenes" / f"{scene}.toml"
        path = folder / f"{scene}-s{surface}.toml"
        path.write_text(far_scene(src.read_text(), surface, row, column, x))
        out.append(path)
    return out


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=40, help="film width and height")
    ap.add_argument("--x", type=float, default=1e9, help="the far control point's x")
    ap.add_argument("--write", type=Path, help="write the scenes into this directory (and keep them)")
    ap.add_argument("--no-render", action="store_true", help="only write the scenes")
    ap.add_argument("--method", default=None, help="render method (default: the scene's)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.write or Path(tmp)
        scenes = write_scenes(folder, args.x)
        if args.no_render:
            print("\n".join(map(str, scenes)))
            return 0
        print(f"load average {open('/proc/loadavg').read().split()[:3]}", flush=True)
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        for path in scenes:
            cmd = [sys.executable, "-m", "bsrt", "render", str(path), "-o", str(folder / (path.stem + ".png"))]
            cmd += ["--width", str(args.width), "--height", str(args.width), "--stats"]
            if args.method:
                cmd += ["--method", args.method]
            clock, used = time.perf_counter(), _children_cpu()
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
            wall, cpu = time.perf_counter() - clock, _children_cpu() - used
            if proc.returncode != 0:
                print(f"{path.stem}: exit {proc.returncode}: {proc.stderr.strip()[-300:]}")
                continue
            record = json.loads(proc.stdout)
            keys = ("leaves", "out_of_budget", "hierarchy")
            counts = ", ".join(f"{k} {record[k]}" for k in keys if k in record)
            stages = ", ".join(f"{k} {v:.2f}" for k, v in record["seconds"].items())
            print(f"{path.stem}: {wall:.2f} s wall, {cpu:.2f} s CPU; stages (wall s): {stages}; {counts}", flush=True)
        print(f"load average {open('/proc/loadavg').read().split()[:3]}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
