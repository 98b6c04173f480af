"""Root finding for batches of (ray, start) items (paper 2.2, 2.3).

The per-item loops are compiled (``kernels/roots.py``, where the methods are
described); this module holds the ray batch and the result record, and
applies the surfaces' trims to converged roots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.prelim import normalise_rows
from bsrt.kernels.roots import solve_items
from bsrt.kernels.threads import run_chunks
from bsrt.methods import METHODS, REFERENCE_METHOD
from bsrt.rendering.hits import Hits

NORMALISE_INLINE = 1 << 15  # rays normalised in the calling thread (Rays.from_arrays)


@dataclass
class Rays:
    """A batch of N rays. origin, direction: (N, 3) float64, C-contiguous; directions of unit length."""

    origin: np.ndarray
    direction: np.ndarray

    @classmethod
    def from_arrays(cls, origins: np.ndarray, directions: np.ndarray) -> Rays:
        """origins: (N, 3) or (1, 3) (broadcast); directions: (N, 3), normalised here."""
        d = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
        o = np.require(np.asarray(origins, dtype=np.float64).reshape(-1, 3), np.float64, ("C", "W"))
        if o.shape[0] not in (1, d.shape[0]):
            raise ValueError(f"{o.shape[0]} origins for {d.shape[0]} directions")
        # writable C arrays always (numba compiles a kernel again per flag), the origins broadcast there
        unit, origin = np.empty_like(d), np.empty_like(d)
        # d / |d|, row by row; a few ns a row, so a batch of up to NORMALISE_INLINE rows (a repair's,
        # a shading slice's) runs in this thread: handing it to the pool cost 170 us for 7,337 rows, 37 here
        run_chunks(normalise_rows, d.shape[0], d, unit, o, origin, min_chunk=NORMALISE_INLINE)
        return cls(origin, unit)

    def __len__(self) -> int:
        return self.direction.shape[0]


@dataclass
class RootResult:
    """Outcome for M (ray, start) items.

    converged: (M,) bool, the ray-surface distance fell under the tolerance
      at a kept (untrimmed) point.
    trimmed: (M,) bool, it converged, but to a point its surface's trims remove.
    u, v: (M,) float64 final parameters (inside the surface's domain).
    patch: (M,) int64 patch of the final (u, v).
    t: (M,) float64 distance along the ray of S(u, v).
    residual: (M,) float64 ray-surface distance at the final (u, v).
    iterations: (M,) int32 evaluations spent.
    """

    converged: np.ndarray
    trimmed: np.ndarray
    u: np.ndarray
    v: np.ndarray
    patch: np.ndarray
    t: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray

    def as_hits(self, patches: PatchSet) -> Hits:
        """The items as hit candidates: a hit where converged (and kept) with t > 0."""
        hit = self.converged & (self.t > 0)
        nan = np.where(hit, 0.0, np.nan)
        return Hits(
            hit=hit,
            t=self.t + nan,
            surface=np.where(hit, patches.surface[self.patch], -1),
            patch=np.where(hit, self.patch, -1),
            u=self.u + nan,
            v=self.v + nan,
            iterations=self.iterations,
            residual=self.residual + nan,
        )

    @classmethod
    def empty(cls, m: int) -> RootResult:
        """M items not converged yet (the outputs a solve fills)."""
        return cls(
            converged=np.zeros(m, dtype=bool),
            trimmed=np.zeros(m, dtype=bool),
            u=np.empty(m),
            v=np.empty(m),
            patch=np.empty(m, dtype=np.int64),
            t=np.empty(m),
            residual=np.empty(m),
            iterations=np.zeros(m, dtype=np.int32),
        )


def seeded_kernel_id(method: str) -> int:
    """The kernel id of a seeded method (bsrt/methods.py); ValueError for another name."""
    kernel_id = METHODS[method].kernel_id if method in METHODS else None
    if kernel_id is None:
        raise ValueError(f"not a seeded method: {method!r}")
    return kernel_id


def find_roots(
    patches: PatchSet,
    rays: Rays,
    ray: np.ndarray,
    surface: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    method: str = REFERENCE_METHOD,
    tolerance: float = 1e-9,
    max_iterations: int = 64,
    stop_on_growth: bool = False,
) -> RootResult:
    """Solve Qx = Qy = 0 for M items, each a ray and a starting (surface, u, v).

    ray: (M,) int index into ``rays`` (a ray may appear in several items);
    surface: (M,) int; u, v: (M,) float64 starting parameters.
    tolerance: absolute ray-surface distance (scene units) that counts as
    converged. stop_on_growth: give up on an item as soon as a Newton step
    increases the residual (Martin et al.'s rule, for starts that may be far).
    """
    seeded_kernel_id(method)  # an unknown method is an error, items or not
    m = np.shape(ray)[0]
    out = RootResult.empty(m)
    if m == 0:
        return out
    fields = (out.converged, out.trimmed, out.u, out.v, out.patch, out.t, out.residual, out.iterations)
    _solve_items(patches, rays, ray, surface, u, v, method, tolerance, max_iterations, stop_on_growth, fields)
    return out


def find_pixel_hits(
    patches: PatchSet,
    rays: Rays,
    surface: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    method: str = REFERENCE_METHOD,
    tolerance: float = 1e-9,
    max_iterations: int = 64,
    stop_on_growth: bool = False,
):
    """find_roots for N rays, each from its own start (surface (N,), -1: none; u, v (N,)), written
    as hits: (Hits (N,), failed (N,) bool: a start without a hit, converged (N,), trimmed (N,) as
    RootResult's). The same numbers as find_roots of the rays with a start, then their roots put at
    those rays as RootResult.as_hits (no hit, 0 iterations, where there is no start)."""
    n = len(rays)
    hits = Hits.blank(n)
    converged, trimmed, failed = (np.empty(n, dtype=bool) for _ in range(3))
    fields = (converged, trimmed, hits.u, hits.v, hits.patch, hits.t, hits.residual, hits.iterations)
    as_hits = (np.ascontiguousarray(patches.surface, dtype=np.int64), hits.hit, hits.surface, failed)
    every = np.empty(0, dtype=np.int64)  # ray i is item i
    _solve_items(
        patches, rays, every, surface, u, v, method, tolerance, max_iterations, stop_on_growth, fields, as_hits
    )
    return hits, failed, converged, trimmed


def _solve_items(
    patches, rays, ray, surface, u, v, method, tolerance, max_iterations, stop_on_growth, fields, as_hits=None
):
    """kernels/roots.solve_items over the items (surface, u, v: M values, any shape) into fields (converged, trimmed, u, v,
    patch, t, residual, iterations), each (M,); as_hits: (patch_surface, hit, hit_surface, failed)
    to write them as hits (the kernel's doc)."""
    if as_hits is None:
        as_hits = (
            np.empty(0, dtype=np.int64),
            np.empty(0, dtype=bool),
            np.empty(0, dtype=np.int64),
            np.empty(0, dtype=bool),
        )
    surface = np.ascontiguousarray(surface, dtype=np.int64).reshape(-1)
    run_chunks(
        solve_items,
        surface.size,
        patches.arrays,
        patches.trims,
        rays.origin,
        rays.direction,
        np.ascontiguousarray(ray, dtype=np.int64),
        surface,
        np.ascontiguousarray(u, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(v, dtype=np.float64).reshape(-1),
        seeded_kernel_id(method),
        float(tolerance),
        int(max_iterations),
        bool(stop_on_growth),
        *fields,
        *as_hits,
    )
