"""Exact ray queries: bsrt.intersect beside OpenCASCADE's IntCurvesFace_ShapeIntersector, same run.

    python scripts/ray_bench.py [MODEL ...] [--rays 200000] [--occt-rays 1500] [--repeat 3] [--json FILE]

For each model (default: a trimmed STEP part and the 160-face as1 assembly
of tests/data/models/step): random rays (origins on a sphere of twice the
diagonal round the box's centre, aimed at uniform points of the box) and a
spinning LIDAR at the default camera's eye. bsrt: the geometry is prepared
once (its time is shown), then the median of --repeat timed calls, as rays
per second of wall time and per CPU second (time.process_time, all threads),
for modes nearest and any. OpenCASCADE: the first --occt-rays rays, one
Perform per ray (nearest of its points), from Python. Agreement on those
rays: the share with the same hit/miss, and the largest |dt| where both hit,
as a fraction of the diagonal; the ratio of rays/s in wall time and per CPU
second (on a busy machine bsrt's threads share the cores with other jobs).
Scene-file models (.toml) are timed without OpenCASCADE. Needs the ``cad`` extra for STEP. Report the load average
printed at the top and bottom: the machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import bsrt  # noqa: E402
from bsrt.queries import prepared  # noqa: E402

STEP = ROOT / "tests" / "data" / "models" / "step"
DEFAULT_MODELS = [
    STEP / "trimesh" / "featuretype.STEP",
    STEP / "pythonocc-core" / "as1-oc-214.stp",
    ROOT / "scenes" / "column.toml",
]


def random_rays(scene, n: int, seed: int = 7):
    """(origins (n, 3), unit directions (n, 3), diagonal): from a sphere of radius 2 diag round the
    box's centre toward uniform points of the box."""
    pts = np.concatenate([s.geometry.points.reshape(-1, 3) for s in scene.surfaces])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    rng = np.random.default_rng(seed)
    s = rng.normal(size=(n, 3))
    s /= np.linalg.norm(s, axis=1)[:, None]
    origins = 0.5 * (lo + hi) + 2.0 * diag * s
    target = lo + rng.uniform(size=(n, 3)) * (hi - lo)
    d = target - origins
    return origins, d / np.linalg.norm(d, axis=1)[:, None], diag


def timed(fn, repeat: int):
    walls, cpus, out = [], [], None
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return statistics.median(walls), statistics.median(cpus), out


def occt_nearest(path: str, origins, directions, diag: float):
    """(hit, t, wall seconds, CPU seconds) of OpenCASCADE's IntCurvesFace_ShapeIntersector, one Perform
    per ray."""
    from OCP.gp import gp_Dir, gp_Lin, gp_Pnt
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector
    from OCP.STEPControl import STEPControl_Reader

    reader = STEPControl_Reader()
    if reader.ReadFile(path) != IFSelect_RetDone:
        raise SystemExit(f"{path}: OpenCASCADE cannot read it")
    reader.TransferRoots()
    shape = reader.OneShape()
    intersector = IntCurvesFace_ShapeIntersector()
    intersector.Load(shape, 1e-9 * diag)
    n = len(directions)
    hit, t = np.zeros(n, dtype=bool), np.full(n, np.nan)
    clock, cpu = time.perf_counter(), time.process_time()
    for k in range(n):
        intersector.Perform(gp_Lin(gp_Pnt(*origins[k]), gp_Dir(*directions[k])), 0.0, math.inf)
        if intersector.IsDone() and intersector.NbPnt() > 0:
            hit[k] = True
            t[k] = min(intersector.WParameter(i) for i in range(1, intersector.NbPnt() + 1))
    return hit, t, time.perf_counter() - clock, time.process_time() - cpu


def bench_model(path: Path, n: int, n_occt: int, repeat: int) -> dict:
    clock = time.perf_counter()
    scene = bsrt.load(path)
    loaded = time.perf_counter() - clock
    clock = time.perf_counter()
    prepared(scene)
    built = time.perf_counter() - clock
    origins, directions, diag = random_rays(scene, n)
    row = {"model": path.name, "surfaces": len(scene.surfaces), "rays": n, "load_s": loaded, "prepare_s": built}
    bsrt.intersect(scene, origins[:1000], directions[:1000])  # compiled and warm
    for mode in ("nearest", "any"):
        wall, cpu, result = timed(lambda m=mode: bsrt.intersect(scene, origins, directions, mode=m), repeat)
        row[mode] = {"rays_per_s": n / wall, "rays_per_cpu_s": n / cpu, "hit_share": float(result.hit.mean())}
    cam = scene.camera
    look = np.asarray(cam.look_at) - np.asarray(cam.eye)
    lidar = bsrt.sensors.lidar(cam.eye, up=cam.up, forward=look, channels=64, horizontal_resolution=0.1)
    wall, cpu, result = timed(lambda: bsrt.intersect(scene, lidar.origins[:1], lidar.directions), repeat)
    row["lidar"] = {"rays": len(lidar), "rays_per_s": len(lidar) / wall, "rays_per_cpu_s": len(lidar) / cpu}
    if path.suffix.lower() in (".step", ".stp") and n_occt:
        k = min(n_occt, n)
        ours = bsrt.intersect(scene, origins[:k], directions[:k])
        hit, t, seconds, cpu = occt_nearest(str(path), origins[:k], directions[:k], diag)
        both = ours.hit & hit
        row["occt"] = {
            "rays": k,
            "rays_per_s": k / seconds,
            "rays_per_cpu_s": k / cpu,
            "speedup": row["nearest"]["rays_per_s"] / (k / seconds),
            "speedup_per_cpu_s": row["nearest"]["rays_per_cpu_s"] / (k / cpu),
            "same_hit_share": float(np.mean(ours.hit == hit)),
            "max_dt_of_diagonal": float(np.max(np.abs(ours.t[both] - t[both])) / diag) if both.any() else 0.0,
        }
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", type=Path, default=DEFAULT_MODELS)
    parser.add_argument("--rays", type=int, default=200_000)
    parser.add_argument("--occt-rays", type=int, default=1500)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    rows = []
    print(f"load average {os.getloadavg()}, {os.cpu_count()} cores")
    for path in args.models:
        row = bench_model(path, args.rays, args.occt_rays, args.repeat)
        rows.append(row)
        line = (
            f"{row['model']}: {row['surfaces']} surfaces, prepared in {row['prepare_s']:.2f} s; "
            f"nearest {row['nearest']['rays_per_s'] / 1e3:.0f} k rays/s "
            f"({row['nearest']['rays_per_cpu_s'] / 1e3:.0f} k per CPU s, {row['nearest']['hit_share']:.0%} hit), "
            f"any {row['any']['rays_per_s'] / 1e3:.0f} k/s, lidar {row['lidar']['rays_per_s'] / 1e3:.0f} k/s"
        )
        if "occt" in row:
            o = row["occt"]
            line += (
                f"; OpenCASCADE {o['rays_per_s'] / 1e3:.1f} k rays/s ({o['rays_per_cpu_s'] / 1e3:.1f} k per CPU s, "
                f"{o['rays']} rays): {o['speedup']:.1f}x ({o['speedup_per_cpu_s']:.1f}x per CPU s), "
                f"same hit/miss {o['same_hit_share']:.2%}, max |dt| {o['max_dt_of_diagonal']:.1e} of the diagonal"
            )
        print(line, flush=True)
    print(f"load average {os.getloadavg()}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
