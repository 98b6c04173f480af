"""Render scenes with two checkouts and compare the PNGs byte for byte and every --aov array.

    python scripts/compare_renders.py BEFORE [--after DIR] [--size 256] [--out DIR] [SCENE ...]

BEFORE, --after: repository roots (--after defaults to this one); each renders
with ``PYTHONPATH`` set to its root, in a child process. Scenes default to
scenes/*.toml. Per scene: whether the PNGs are identical (else how many
pixels differ, by more than 2/255, and the largest difference), and for each
AOV array that differs how many values and the largest |difference|. Exit
status 1 when any PNG differs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent


def render(root: Path, scene: Path, size: int, stem: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(root), "PYTHONDONTWRITEBYTECODE": "1"}
    args = [sys.executable, "-m", "bsrt", "render", str(scene), "--width", str(size), "--height", str(size)]
    args += ["-o", f"{stem}.png", "--aov", f"{stem}.npz", "--no-progress"]
    subprocess.run(args, env=env, check=True, stdout=subprocess.DEVNULL, cwd=stem.parent)


def _file(stem: Path, suffix: str) -> Path:
    """stem's file with suffix added (a model's stem may hold dots: ``Ring_5.98mm``)."""
    return stem.with_name(stem.name + suffix)


def compare(before: Path, after: Path) -> tuple[bool, str]:
    """(PNGs identical, one report line per scene and per differing array)."""
    same = _file(before, ".png").read_bytes() == _file(after, ".png").read_bytes()
    line = "png identical" if same else "png DIFFERENT"
    if not same:
        a, b = (np.asarray(Image.open(_file(p, ".png")), dtype=int) for p in (before, after))
        d = np.abs(a - b).max(axis=-1)
        line += f" ({int((d > 0).sum())} pixels, {int((d > 2).sum())} by more than 2/255, max {d.max()})"
    with np.load(_file(before, ".npz")) as A, np.load(_file(after, ".npz")) as B:
        for key in A.files:
            x, y = A[key], B[key]
            if np.array_equal(x, y, equal_nan=True):
                continue
            if x.dtype.kind == "f":
                both = ~(np.isnan(x) & np.isnan(y))
                diff = np.abs(x[both] - y[both])
                line += f"\n    {key}: {int((diff != 0).sum())} values differ, max |difference| {np.nanmax(diff):.3g}"
            else:
                line += f"\n    {key}: {int((x != y).sum())} values differ"
    return same, line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("scenes", nargs="*", type=Path)
    parser.add_argument("--after", type=Path, default=ROOT)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--out", type=Path, help="keep the renders here (default: a temporary folder)")
    args = parser.parse_intermixed_args()
    scenes = args.scenes or sorted((ROOT / "scenes").glob("*.toml"))
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        identical = True
        for scene in scenes:
            stems = [out / f"{scene.stem}-before", out / f"{scene.stem}-after"]
            for root, stem in zip((args.before, args.after), stems):
                render(root.resolve(), scene.resolve(), args.size, stem)
            same, line = compare(*stems)
            identical &= same
            print(f"{scene.stem}: {line}", flush=True)
    sys.exit(0 if identical else 1)


if __name__ == "__main__":
    main()
