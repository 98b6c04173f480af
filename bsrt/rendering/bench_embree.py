"""``bsrt bench --embree``: bsrt's exact primary rays beside Embree's on tessellations.

The comparison a user makes before choosing bsrt: tessellate the surfaces (a
uniform grid of ``segments`` x ``segments`` quads per Bezier patch, two
triangles each, the map's watertight grid of bsrt/rendering/map_mesh.py) and
trace the same camera rays with Embree (the optional ``embreex`` package, float32,
one thread). Reported per segment count: Embree's build and trace seconds
(medians), its trace time as a ratio to bsrt's exact primary rays (map + solve,
measured in the same bench run), and its error against bsrt's exact hits:
pixels that one hits and the other misses, and the depth error |t_embree -
t_exact| / the scene's diagonal (median and largest over the pixels both hit).

The tessellation keeps every cell that a trim crosses, so on trimmed models
the miss counts include the trimmed-away slivers; the bundled paper scenes have
no trims.
"""

from __future__ import annotations

import importlib.util
import statistics
import time

import numpy as np

from bsrt.rendering.map_mesh import tessellate
from bsrt.scene.camera import pixel_rays

DEFAULT_SEGMENTS = (8, 32, 128)


def available() -> bool:
    """Whether the optional ``embreex`` package is installed."""
    return importlib.util.find_spec("embreex") is not None


def compare(geometry, camera, size: int, exact_hits, exact_seconds: float, segments=DEFAULT_SEGMENTS, repeat=3) -> dict:
    """Embree on tessellations of ``geometry`` (a pipeline.Geometry) for ``camera``'s size x size
    primary rays, against bsrt's ``exact_hits`` (rendering.hits.Hits of the same pixels, row-major)
    whose map + solve took ``exact_seconds`` (median). Returns {str(segments): row} with row keys
    triangles, build_seconds, trace_seconds, trace_cpu_seconds, ratio (bsrt / Embree trace time),
    missed, extra (pixels Embree misses / hits where bsrt hits / misses), depth_error_median,
    depth_error_p99, depth_error_max (of the diagonal); medians over ``repeat`` traces."""
    from embreex.mesh_construction import TriangleMesh
    from embreex.rtcore_scene import EmbreeScene

    patches = geometry.patches
    eye = np.asarray(camera.eye, dtype=np.float64)
    directions = pixel_rays(camera, size, size).astype(np.float32)  # (N, 3)
    origins = np.zeros_like(directions)  # the tessellation is eye-relative: float32 keeps its precision there
    exact_hit = np.asarray(exact_hits.hit)
    out = {}
    for n in segments:
        vertices, indices = tessellate(patches, np.full((patches.size, 2), n, dtype=np.int64), eye)
        clock = time.perf_counter()
        scene = EmbreeScene()
        TriangleMesh(scene, np.ascontiguousarray(vertices[:, :3]), indices.astype(np.int32))
        scene.run(origins[:1], directions[:1], query="DISTANCE")  # commits: the build
        build = time.perf_counter() - clock
        walls, cpus = [], []
        for _ in range(repeat):
            clock, cpu = time.perf_counter(), time.process_time()
            t = scene.run(origins, directions, query="DISTANCE")
            walls.append(time.perf_counter() - clock)
            cpus.append(time.process_time() - cpu)
        hit = t < 1e30
        both = hit & exact_hit
        error = np.abs(t[both].astype(np.float64) - exact_hits.t[both]) / geometry.diagonal
        trace = statistics.median(walls)
        out[str(n)] = {
            "triangles": int(indices.shape[0]),
            "build_seconds": build,
            "trace_seconds": trace,
            "trace_cpu_seconds": statistics.median(cpus),
            "ratio": exact_seconds / trace if trace > 0 else float("inf"),
            "missed": int((exact_hit & ~hit).sum()),
            "extra": int((hit & ~exact_hit).sum()),
            "depth_error_median": float(np.median(error)) if error.size else 0.0,
            "depth_error_p99": float(np.percentile(error, 99)) if error.size else 0.0,
            "depth_error_max": float(error.max()) if error.size else 0.0,
        }
    return out


def format_rows(results: dict) -> str:
    """The comparison's lines, per scene and segment count (bench.run's results with "embree" entries)."""
    lines = [
        "Embree on tessellations (n x n quads per patch, float32, one thread) against bsrt's exact primary "
        "rays (newton map + solve); depth error of the scene diagonal"
    ]
    head = (
        "scene",
        "n",
        "triangles",
        "build s",
        "trace s",
        "bsrt/embree",
        "missed",
        "extra",
        "err med",
        "err p99",
        "err max",
    )
    lines.append(f"{head[0]:12s}{head[1]:>5s}" + "".join(f"{h:>12s}" for h in head[2:]))
    for name, entry in results["scenes"].items():
        for n, row in entry.get("embree", {}).items():
            lines.append(
                f"{name:12s}{n:>5s}{row['triangles']:>12d}{row['build_seconds']:>12.3f}{row['trace_seconds']:>12.4f}"
                f"{row['ratio']:>12.2f}{row['missed']:>12d}{row['extra']:>12d}"
                f"{row['depth_error_median']:>12.1e}{row['depth_error_p99']:>12.1e}{row['depth_error_max']:>12.1e}"
            )
    return "\n".join(lines)
