"""Set-up of a surface of about a million Bezier patches: time and peak memory.

Writes one bicubic B-spline surface of (n + 3) x (n + 3) control points
(n x n = about 10^6 knot spans, so n^2 patches) as a GLScene .nurbs file,
renders it with ``bsrt render --stats`` in a child process and prints the
stage timings, the wall time and the child's peak resident memory:

    python scripts/big_surface.py [--spans 1000] [--width 64] [--method newton] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_surface(path: Path, spans: int) -> None:
    """A gently waving bicubic surface over [0, 1]^2 with spans x spans knot spans (uniform knots)."""
    n = spans + 3
    knots = np.concatenate([[0.0] * 3, np.linspace(0.0, 1.0, spans + 1), [1.0] * 3])
    x, y = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
    z = 0.05 * np.sin(6.0 * x) * np.cos(4.0 * y)
    points = np.stack([x, y, z], axis=-1).transpose(1, 0, 2).reshape(-1, 3)  # u fastest
    with open(path, "w") as f:
        f.write(f"uOrder 4\nvOrder 4\nuDimension {n}\nvDimension {n}\n")
        f.write("uKnot [ " + " ".join(f"{k:.9g}" for k in knots) + " ]\n")
        f.write("vKnot [ " + " ".join(f"{k:.9g}" for k in knots) + " ]\n")
        f.write("controlPoint [\n")
        np.savetxt(f, points, fmt="%.7g", delimiter=" ", newline=",\n")
        f.write("]\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spans", type=int, default=1000, help="knot spans per direction (patches = spans^2)")
    ap.add_argument("--width", type=int, default=64, help="film width and height")
    ap.add_argument("--method", default="newton")
    ap.add_argument("--keep", type=Path, help="write the model and image into this directory")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        where = args.keep or Path(tmp)
        where.mkdir(parents=True, exist_ok=True)
        model = where / f"surface-{args.spans}.nurbs"
        t0 = time.perf_counter()
        write_surface(model, args.spans)
        print(
            f"wrote {model.name}: {args.spans**2} patches, {model.stat().st_size / 1e6:.1f} MB "
            f"in {time.perf_counter() - t0:.1f} s",
            flush=True,
        )
        cmd = [
            sys.executable,
            "-m",
            "bsrt",
            "render",
            str(model),
            "-o",
            str(where / "big.png"),
            "--width",
            str(args.width),
            "--height",
            str(args.width),
            "--method",
            args.method,
            "--stats",
            "--camera-eye",
            "0.5,-0.8,1.2",
            "--camera-look-at",
            "0.5,0.5,0",
            "--camera-up",
            "0,0,1",
        ]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            print(proc.stderr, file=sys.stderr)
            return proc.returncode
        stats = json.loads(proc.stdout)
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
        print("stages (s):", json.dumps({k: round(v, 2) for k, v in stats["seconds"].items()}))
        print(
            f"hits {stats['hits']} of {stats['pixels']}; wall {wall:.1f} s (reading the model included); "
            f"peak RSS {peak_mb:.0f} MB"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
