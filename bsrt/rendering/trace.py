"""The tracing seam: camera rays to nearest hits, by one of two tracers.

``make_primary_tracer`` turns the method name into a tracer once:

- ``MapTracer`` (gradient, fast, newton): the preliminary map (GL) seeds
  every pixel's root finder; suspect pixels are repaired (hard_pixels.py).
- ``HierarchyTracer`` (martin): every ray through the hierarchy, no map.

Both answer ``trace(width, height, rows, prelim) -> (Hits, directions)`` for
a band of film rows. Secondary rays always use ``Geometry.intersect`` (the
hierarchy): they do not start at the eye, so no map can seed them.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from bsrt.kernels.prelim import seeded_hits
from bsrt.kernels.threads import run_chunks
from bsrt.methods import METHODS
from bsrt.rendering import gl, gpu, gpu_map, hard_pixels
from bsrt.rendering.hits import Hits
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.prelim import PrelimMap, render_map
from bsrt.rendering.solve import Rays, RootResult, find_pixel_hits, find_roots
from bsrt.rendering.stats import Stats
from bsrt.scene.camera import pixel_footprint, pixel_ray_arrays, pixel_rays


class HierarchyTracer:
    """Martin et al.: every camera ray through the hierarchy."""

    def __init__(self, options: RenderOptions, geometry, stats: Stats, report):
        self.options, self.geometry, self.stats, self.report = options, geometry, stats, report
        self.tolerance = options.tolerance * geometry.diagonal
        self.last_map = None
        _count_repairs(stats)
        stats.fields["covered_by_map"] = None  # no map
        stats.fields["solve_device"] = "cpu"  # the hierarchy is traversed on the CPU only
        stats.fields["devices"] = {"solve": "cpu"}  # and pipeline's shading

    def trace(self, width: int, height: int, rows: tuple[int, int], prelim=None, done: float = 0.0):
        """Nearest hits of the pixel-centre rays of film rows rows[0]..rows[1]-1:
        (Hits (K,), unit directions (K, 3)), K = band rows x width."""
        directions = pixel_rays(self.options.camera, width, height, rows)
        self.report("solve", done)
        with self.stats.timer("solve"):
            hits = self.geometry.intersect(self.options.camera.eye[None, :], directions, tolerance=self.tolerance)
        return hits, directions


class MapTracer:
    """The paper's tracer: map seeds, root finder, hard-pixel repair."""

    def __init__(self, options: RenderOptions, geometry, stats: Stats, report, ctx=None):
        self.options, self.geometry, self.stats, self.report, self.ctx = options, geometry, stats, report, ctx
        self.tolerance = options.tolerance * geometry.diagonal
        self.last_map: PrelimMap | None = None
        _count_repairs(stats)
        stats.add("covered_by_map", 0)
        # the seeded solve's device (rendering/gpu.py); the repair of what it does not settle stays on the CPU
        device, compute_ctx = gpu.choose_device(options.device, ctx)
        stats.fields["solve_device"] = device
        stats.fields["devices"] = {"map": "gl", "solve": device, "repair": "cpu"}  # and pipeline's shading
        self.find_roots = find_roots if device == "cpu" else partial(gpu.find_roots_gpu, compute_ctx)
        # the GPU solve on the map's own context reads the map where it is drawn (gpu_map.py)
        self.in_place = compute_ctx if device == "gpu" and compute_ctx is (ctx or gl.headless_context()) else None

    def trace(self, width: int, height: int, rows: tuple[int, int], prelim: PrelimMap | None = None, done: float = 0.0):
        """As HierarchyTracer.trace. The map is rasterised (and solved) with one
        extra row above and below the band, so the neighbour tests of the hard
        pixels see across band borders. prelim: the whole film's map, given."""
        first, stop = rows
        lo, hi = max(0, first - 1), min(height, stop + 1)
        camera = self.options.camera
        rays = Rays(*pixel_ray_arrays(camera, width, height, (lo, hi)))
        directions = rays.direction
        roots = None
        self.report("map", done)
        if prelim is not None:
            prelim = prelim.rows(lo, hi)
        elif self.in_place is not None:  # the map and its seeds' roots together ("map" stays 0)
            with self.stats.timer("solve"):
                prelim, *roots = gpu_map.map_roots_gpu(
                    self.in_place, self.geometry.patches, camera, width, height, (lo, hi), rays.direction,
                    *self._solve_arguments(),
                )  # fmt: skip
        else:
            with self.stats.timer("map"):
                prelim = render_map(
                    self.geometry.patches, camera, width, height, self.options.map, ctx=self.ctx, rows=(lo, hi)
                )
        self.last_map = prelim
        self.report("solve", done)
        with self.stats.timer("solve"):
            hits = self._solve(rays, prelim, pixel_footprint(camera, width, height), roots)
        keep = slice((first - lo) * width, (stop - lo) * width)
        return hits.take(keep), directions[keep]

    def _solve_arguments(self):
        """(map mode, method, tolerance, max_iterations, stop_on_growth) of the seeded solve."""
        method = self.options.method
        return self.options.map, method, self.tolerance, self.options.max_iterations, METHODS[method].stops_on_growth

    def _solve(self, rays: Rays, prelim: PrelimMap, footprint: float, roots=None) -> Hits:
        """Hits of the map's pixels: roots (covered (M,), RootResult (M,)) of its seeds when given
        (solved with the map: gpu_map.py), else solved here, then the suspects repaired."""
        patches, options, stats = self.geometry.patches, self.options, self.stats
        _, method, tolerance, max_iterations, stop_on_growth = self._solve_arguments()
        # (a seed whose root fails is solved again below, as a suspect)
        if roots is None and self.find_roots is find_roots:  # on the CPU: from the seeds to the hits in one pass
            hits, failed, counts = _solved_seeds(
                patches, rays, prelim, method, tolerance, max_iterations, stop_on_growth
            )
        else:
            if roots is None:  # on the GPU, from the map read back
                seed = prelim.surface.ravel()
                covered = np.flatnonzero(seed >= 0)
                res = self.find_roots(
                    patches,
                    rays,
                    covered,
                    seed[covered],
                    prelim.u.ravel()[covered],
                    prelim.v.ravel()[covered],
                    method=method,
                    tolerance=tolerance,
                    max_iterations=max_iterations,
                    stop_on_growth=stop_on_growth,
                )
            else:
                covered, res = roots
            hits, failed = _seeded_hits(len(rays), covered, res, patches.surface)
            counts = (covered.size, np.count_nonzero(~res.converged), np.count_nonzero(res.trimmed))
        suspect, layer, seam = hard_pixels.suspect_pixels(
            prelim, hits, failed, footprint, self.tolerance, patches.domain, hard_pixels.MAP_QUANTUM[options.map]
        )
        suspects = np.flatnonzero(suspect)
        repaired, changed = hard_pixels.repair(self.geometry, rays, prelim, hits, suspects, self.tolerance, footprint)
        for key, value in (
            *zip(("covered_by_map", "non_converged", "trimmed_roots"), counts),
            ("suspect", suspects.size),
            ("wrong_layer", layer.sum()),
            ("seam", seam.sum()),
            ("repaired", changed),
            ("hierarchy", repaired.size),
        ):
            stats.add(key, value)
        return hits


def _solved_seeds(patches, rays: Rays, prelim: PrelimMap, method, tolerance, max_iterations, stop_on_growth):
    """The CPU's seeded solve of a map's N pixels, straight into their hits (solve.find_pixel_hits):
    (Hits (N,), failed (N,) bool: a seed without a hit, (pixels with a seed, their roots not
    converged, their roots trimmed away)); the same as find_roots of the seeded pixels, then
    _seeded_hits."""
    hits, failed, converged, trimmed = find_pixel_hits(
        patches, rays, prelim.surface, prelim.u, prelim.v, method, tolerance, max_iterations, stop_on_growth
    )
    covered = np.count_nonzero(prelim.surface >= 0)
    return hits, failed, (covered, covered - np.count_nonzero(converged), np.count_nonzero(trimmed))


def _seeded_hits(n: int, covered: np.ndarray, res: RootResult, patch_surface: np.ndarray):
    """(Hits (n,), failed (n,) bool) of n pixels from the roots res of the covered
    pixels' seeds (covered: (M,) sorted), one item per covered pixel: hits as
    res.as_hits() puts them there, no hit elsewhere; failed: covered, no hit."""
    hits = Hits(
        np.empty(n, dtype=bool),
        np.empty(n),
        np.empty(n, dtype=np.int64),
        np.empty(n, dtype=np.int64),
        np.empty(n),
        np.empty(n),
        np.empty(n, dtype=np.int32),
        np.empty(n),
    )
    failed = np.empty(n, dtype=bool)
    run_chunks(
        seeded_hits,
        n,
        covered,
        res.converged,
        res.t,
        res.u,
        res.v,
        res.patch,
        res.residual,
        res.iterations,
        np.ascontiguousarray(patch_surface, dtype=np.int64),
        hits.hit,
        hits.t,
        hits.surface,
        hits.patch,
        hits.u,
        hits.v,
        hits.iterations,
        hits.residual,
        failed,
    )
    return hits, failed


def _count_repairs(stats: Stats) -> None:
    """The hard-pixel counters, present (0 for martin) whatever the tracer."""
    for key in ("non_converged", "trimmed_roots", "suspect", "wrong_layer", "seam", "repaired", "hierarchy"):
        stats.add(key, 0)


def make_primary_tracer(options: RenderOptions, geometry, stats: Stats, report, ctx=None):
    """The tracer for options.method: the one place the method name picks an algorithm."""
    if options.uses_map:
        return MapTracer(options, geometry, stats, report, ctx)
    return HierarchyTracer(options, geometry, stats, report)
