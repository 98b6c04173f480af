"""Exact ray queries on a prepared scene: nearest, any and all hits, outward normals, a polish.

:class:`RayCaster` holds a scene's :class:`~bsrt.rendering.pipeline.Geometry`
(patch table and hierarchy, built once) and answers batches of rays in chunks
of CHUNK rays (bounded temporaries whatever N is). The public face is
:func:`bsrt.intersect` (bsrt/intersect.py); this module knows no scene
resolution or caching.

* nearest / any: one walk of the hierarchy per ray (``bvh.intersect``).
* all: repeated nearest queries; round k starts each still-open ray past its
  previous hit (t_min = that t plus SAME_T and the kernel's tolerance over
  |cos(normal, ray)|, the t error of a grazing root) and excludes that root's
  parameter box (1e-6 of the diagonal, as secondary rays do), so a ray
  crossing a surface twice at one point (tangent) reports it once. Rounds
  stop when no ray finds more, or after MAX_ALL_HITS hits per ray.
* budget: a query ray may spend QUERY_BUDGET_FACTOR times the Newton
  iterations a rendered ray may (a ray grazing a sphere 1e-6 of its radius
  from the pole needs about 9,000, twice a rendered ray's budget); a ray that
  spends it all is flagged (``exhausted``): its records may lack a hit.
* tolerance: the kernel converges to max(tolerance, KERNEL_TOLERANCE) of the
  diagonal; below that, POLISH_STEPS float64 Newton steps on
  S(u, v) - (o + t d) = 0 (a 3 x 3 solve per hit) take the residual down,
  each step kept only where it lowers the residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bsrt import validate
from bsrt.rendering.bvh import ray_budget
from bsrt.rendering.hits import Hits
from bsrt.rendering.pipeline import Geometry
from bsrt.rendering.shade import facing_frames

CHUNK = 1 << 18  # rays per kernel call: bounds the temporaries of one call
KERNEL_TOLERANCE = 1e-10  # finer tolerances (fractions of the diagonal) are reached by the polish
MIN_TOLERANCE = 1e-13  # what float64 Newton reliably reaches, as a fraction of the diagonal
POLISH_STEPS = 4
EXCLUDE = 1e-6  # all-hits: the found root's exclusion box, as a fraction of the diagonal
SAME_T = 1e-8  # all-hits: a later hit lies at least this much further (fraction of the diagonal)
GRAZING_FLOOR = 1e-4  # all-hits: |cos| floor of that margin's grazing term (at most 1e4 x the tolerance)
POLE = 1e-8  # |S_u x S_v| below this fraction of the patch's typical |S_u| |S_v|: a pole (degenerate)
POLE_STEP = 1e-6  # ... whose normal is taken this fraction of the patch toward its centre
MAX_ALL_HITS = 4096  # all-hits: at most this many hits per ray
QUERY_BUDGET_FACTOR = 64  # a query ray may spend this many times a rendered ray's work (bvh.py, "Budget")


@dataclass(eq=False)
class RayHits:
    """Hits of N rays (nearest/any: one record per ray) or M hits (all: flat, sorted by ray, then t).

    hit: (K,) bool. t: (K,) float64 along the unit direction. point, normal:
    (K, 3) float64 (normal: unit, outward as modelled). front_facing: (K,)
    bool, the outward normal faces the ray's origin. u, v: (K,) float64 in the
    surface's knot domain. surface: (K,) int64 (-1 where none). residual: (K,)
    float64, |S(u, v) - (o + t d)|. ray: (K,) int64, the ray of each record.
    Where hit is False the floats are NaN.
    """

    hit: np.ndarray
    t: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    front_facing: np.ndarray
    u: np.ndarray
    v: np.ndarray
    surface: np.ndarray
    residual: np.ndarray
    ray: np.ndarray


class RayCaster:
    """A scene's geometry prepared once for ray queries.

    reversed: (S,) bool per surface, True where the outward normal is
    -(S_u x S_v) (SceneSurface.reversed).
    """

    def __init__(self, scene):
        self.geometry = Geometry(scene)
        _ = self.geometry.bvh  # built now, not in the first query
        self.reversed = np.array([bool(getattr(s, "reversed", False)) for s in scene.surfaces], dtype=bool)
        self.diagonal = self.geometry.diagonal
        self.budget = QUERY_BUDGET_FACTOR * ray_budget()
        lo, hi = self.geometry.patches.scene_box()
        self._reach = max(float(np.abs(lo).max()), float(np.abs(hi).max()))
        worst = validate.smallest_tolerance_of_high_degrees(
            [s.geometry for s in scene.surfaces], [s.name for s in scene.surfaces], self.diagonal
        )
        self.high_degree = worst  # (tolerance, name, degree) of the least exact high-degree surface, or None

    def least_tolerance(self, origins: np.ndarray) -> float:
        """The smallest tolerance (fraction of the diagonal) float64 resolves for rays from origins
        (K, 3): MIN_TOLERANCE, FLOAT_STEPS steps of the largest coordinate, and what the power-basis
        evaluation of a surface above degree 9 allows (bsrt.validate, as a render checks)."""
        reach = max(self._reach, float(np.abs(origins).max()) if origins.size else 0.0)
        least = max(MIN_TOLERANCE, validate.FLOAT_STEPS * np.finfo(np.float64).eps * reach / self.diagonal)
        return max(least, self.high_degree[0]) if self.high_degree else least

    def cast(self, origins, directions, t_min, t_max, tolerance: float, mode: str) -> tuple[RayHits, np.ndarray]:
        """origins, directions: (N, 3) float64, unit directions; t_min, t_max: (N,) float64;
        tolerance: fraction of the diagonal; mode "nearest", "any" or "all" -> (the records,
        exhausted (N,) bool: the rays that spent their work budget)."""
        n = directions.shape[0]
        parts = []
        self._exhausted = np.zeros(n, dtype=bool)
        for a in range(0, n, CHUNK):
            part = slice(a, min(n, a + CHUNK))
            if mode == "all":
                parts.append(self._all(origins[part], directions[part], t_min[part], t_max[part], tolerance, a))
            else:
                hits = self._trace(origins[part], directions[part], t_min[part], t_max[part], tolerance, mode == "any")
                self._exhausted[part] |= hits.iterations >= self.budget
                parts.append(self._records(hits, origins[part], directions[part], np.arange(a, part.stop), tolerance))
        if not parts:
            parts.append(self._records(Hits.empty(0), origins, directions, np.zeros(0, dtype=np.int64), tolerance))
        found = RayHits(*(np.concatenate([getattr(p, f) for p in parts]) for f in RayHits.__dataclass_fields__))
        return found, self._exhausted

    def _trace(self, origins, directions, t_min, t_max, tolerance, any_hit, exclude=None) -> Hits:
        return self.geometry.intersect(
            origins,
            directions,
            t_min=t_min,
            t_max=t_max,
            tolerance=max(tolerance, KERNEL_TOLERANCE) * self.diagonal,
            any_hit=any_hit,
            exclude=exclude,
            budget=self.budget,
        )

    def _all(self, origins, directions, t_min, t_max, tolerance, first: int) -> RayHits:
        """Every hit of the chunk's rays (first: the chunk's first ray), flat and sorted by (ray, t)."""
        n = directions.shape[0]
        rays = np.arange(n)
        records, found = [], np.zeros(n, dtype=np.int64)
        start = t_min.copy()
        exclude = None
        patches = self.geometry.patches
        while rays.size:
            hits = self._trace(origins[rays], directions[rays], start[rays], t_max[rays], tolerance, False, exclude)
            self._exhausted[first + rays] |= hits.iterations >= self.budget
            keep = np.flatnonzero(hits.hit)
            rays, hits = rays[keep], hits.take(keep)
            if not rays.size:
                break
            records.append(self._records(hits, origins[rays], directions[rays], rays + first, tolerance))
            found[rays] += 1
            _, normal, speed = facing_frames(patches, hits, directions[rays])
            # the kernel's roots are good to its residual tolerance over |cos(normal, ray)|: a later
            # round starts beyond that, or a grazing ray finds this root again in a neighbouring
            # piece (at a pole the same point lies in every piece around it, each at its own u)
            cos = np.maximum(np.abs(np.einsum("ij,ij->i", normal, directions[rays])), GRAZING_FLOOR)
            start[rays] = hits.t + (SAME_T + max(tolerance, KERNEL_TOLERANCE) / cos) * self.diagonal
            eps = EXCLUDE * self.diagonal
            bounds = patches.bounds[hits.patch]
            with np.errstate(divide="ignore", invalid="ignore"):
                ru = np.minimum(eps / speed[:, 0], 0.25 * (bounds[:, 1] - bounds[:, 0]))
                rv = np.minimum(eps / speed[:, 1], 0.25 * (bounds[:, 3] - bounds[:, 2]))
            exclude = (hits.surface, hits.u, hits.v, ru, rv)
            more = found[rays] < MAX_ALL_HITS
            rays = rays[more]
            exclude = tuple(x[more] for x in exclude)
        if not records:
            return self._records(Hits.empty(0), origins[:0], directions[:0], np.zeros(0, dtype=np.int64), tolerance)
        out = RayHits(*(np.concatenate([getattr(r, f) for r in records]) for f in RayHits.__dataclass_fields__))
        order = np.lexsort((out.t, out.ray))
        return RayHits(*(getattr(out, f)[order] for f in RayHits.__dataclass_fields__))

    def _records(self, hits: Hits, origins, directions, ray, tolerance) -> RayHits:
        """The public fields of K hit records (polished below KERNEL_TOLERANCE)."""
        if tolerance < KERNEL_TOLERANCE and hits.hit.any():
            polish(self.geometry.patches, hits, origins, directions)
        point, normal = outward_frames(self.geometry.patches, hits)
        hit = hits.hit
        flip = np.zeros(len(hits), dtype=bool)
        flip[hit] = self.reversed[hits.surface[hit]]
        normal[flip] *= -1.0
        front = np.einsum("ij,ij->i", normal, directions) < 0.0
        return RayHits(hit, hits.t, point, normal, front & hit, hits.u, hits.v, hits.surface, hits.residual, ray)


def outward_frames(patches, hits: Hits):
    """Position and unit S_u x S_v normal (K, 3) of each hit, NaN where none. At a pole (S_u x S_v
    vanishes, or is rounding noise: below POLE of the patch's typical |S_u| |S_v|) the normal is
    taken POLE_STEP of the patch toward its centre: the limit normal to about that angle."""
    n = len(hits)
    position, normal = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    idx = np.flatnonzero(hits.hit)
    if not idx.size:
        return position, normal
    patch, u, v = hits.patch[idx], hits.u[idx], hits.v[idx]
    S, Su, Sv = patches.evaluate(patch, u, v)  # (3, K) each
    nrm = np.empty((idx.size, 3))  # S_u x S_v, as np.cross computes it, from the contiguous rows
    nrm[:, 0] = Su[1] * Sv[2] - Su[2] * Sv[1]
    nrm[:, 1] = Su[2] * Sv[0] - Su[0] * Sv[2]
    nrm[:, 2] = Su[0] * Sv[1] - Su[1] * Sv[0]
    length = np.sqrt(nrm[:, 0] * nrm[:, 0] + nrm[:, 1] * nrm[:, 1] + nrm[:, 2] * nrm[:, 2])
    b = patches.bounds  # (P, 4): u0, u1, v0, v1 of each patch
    extent = np.linalg.norm(patches.box_max - patches.box_min, axis=1)
    typical = (extent**2 / np.maximum((b[:, 1] - b[:, 0]) * (b[:, 3] - b[:, 2]), 1e-300))[patch]  # per patch
    pole = np.flatnonzero(~(length > POLE * typical))
    if pole.size:
        bp = b[patch[pole]]
        cu, cv = 0.5 * (bp[:, 0] + bp[:, 1]), 0.5 * (bp[:, 2] + bp[:, 3])
        pu, pv = u[pole] + 2.0 * POLE_STEP * (cu - u[pole]), v[pole] + 2.0 * POLE_STEP * (cv - v[pole])
        _, Su2, Sv2 = patches.evaluate(patch[pole], pu, pv)
        nrm[pole] = np.cross(Su2.T, Sv2.T)
        length[pole] = np.linalg.norm(nrm[pole], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal[idx] = nrm / length[:, None]
    position[idx] = S.T
    return position, normal


def polish(patches, hits: Hits, origins: np.ndarray, directions: np.ndarray) -> None:
    """Float64 Newton on S(u, v) = o + t d for every hit, in place (hits.t, u, v, patch, residual).

    origins, directions: (K, 3), unit directions. A step is kept only where
    it lowers the residual and (u, v) stays in the surface's domain.
    """
    idx = np.flatnonzero(hits.hit)
    o, d = origins[idx], directions[idx]
    surface = hits.surface[idx]
    u, v, t, patch = hits.u[idx].copy(), hits.v[idx].copy(), hits.t[idx].copy(), hits.patch[idx].copy()
    domain = patches.domain[surface]  # (K, 4): u0, u1, v0, v1
    S, Su, Sv = patches.evaluate(patch, u, v)
    F = S.T - (o + t[:, None] * d)
    res = np.linalg.norm(F, axis=1)
    for _ in range(POLISH_STEPS):
        J = np.stack([Su.T, Sv.T, -d], axis=2)  # (K, 3, 3): columns S_u, S_v, -d
        with np.errstate(all="ignore"):
            try:
                step = np.linalg.solve(J, -F[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                step = np.stack([np.linalg.lstsq(j, -f, rcond=None)[0] for j, f in zip(J, F)])
        nu, nv, nt = u + step[:, 0], v + step[:, 1], t + step[:, 2]
        inside = np.isfinite(step).all(axis=1)
        inside &= (nu >= domain[:, 0]) & (nu <= domain[:, 1]) & (nv >= domain[:, 2]) & (nv <= domain[:, 3])
        nu, nv = np.where(inside, nu, u), np.where(inside, nv, v)
        npatch = patches.locate(surface, nu, nv)
        S2, Su2, Sv2 = patches.evaluate(npatch, nu, nv)
        F2 = S2.T - (o + nt[:, None] * d)
        res2 = np.linalg.norm(F2, axis=1)
        better = inside & (res2 < res)
        if not better.any():
            break
        u[better], v[better], t[better], patch[better], res[better] = (
            nu[better],
            nv[better],
            nt[better],
            npatch[better],
            res2[better],
        )
        F[better], Su[:, better], Sv[:, better] = F2[better], Su2[:, better], Sv2[:, better]
    hits.u[idx], hits.v[idx], hits.t[idx], hits.patch[idx], hits.residual[idx] = u, v, t, patch, res
