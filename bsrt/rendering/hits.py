"""Ray-surface hit records shared by every root finder."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Hits:
    """The nearest hit of each of N rays.

    hit: (N,) bool. t: (N,) float64 distance along the unit direction, NaN
    where no hit. surface: (N,) int64 surface index, -1 where no hit.
    patch: (N,) int64 PatchSet patch id, -1 where no hit. u, v: (N,) float64
    parameters in the surface's knot domain, NaN where no hit.
    iterations: (N,) int32 root-finding iterations spent on the ray (all
    attempts). residual: (N,) float64 distance between the ray and S(u, v),
    NaN where no hit.
    """

    hit: np.ndarray
    t: np.ndarray
    surface: np.ndarray
    patch: np.ndarray
    u: np.ndarray
    v: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray

    @classmethod
    def empty(cls, n: int) -> Hits:
        nan = np.full(n, np.nan)
        return cls(
            hit=np.zeros(n, dtype=bool),
            t=nan.copy(),
            surface=np.full(n, -1, dtype=np.int64),
            patch=np.full(n, -1, dtype=np.int64),
            u=nan.copy(),
            v=nan.copy(),
            iterations=np.zeros(n, dtype=np.int32),
            residual=nan,
        )

    @classmethod
    def blank(cls, n: int) -> Hits:
        """n records left uninitialised (np.empty, empty()'s dtypes), for a caller that writes every field of each."""
        template = cls.empty(0)
        return cls(*(np.empty(n, dtype=getattr(template, name).dtype) for name in cls.FIELDS))

    def __len__(self) -> int:
        return self.hit.shape[0]

    FIELDS = ("hit", "t", "surface", "patch", "u", "v", "iterations", "residual")

    def take(self, index) -> Hits:
        """The rays at ``index`` (a slice or an index array)."""
        return Hits(*(getattr(self, name)[index] for name in self.FIELDS))

    def put(self, index, other: Hits) -> None:
        """Store ``other``'s records at ``index`` (a slice or an index array)."""
        for name in self.FIELDS:
            getattr(self, name)[index] = getattr(other, name)


def keep_nearest(hits: Hits, ray: np.ndarray, candidates: Hits) -> np.ndarray:
    """Keep, for every ray, the nearest of its current hit and its candidate hits.

    ray: (K,) int, the ray (index into ``hits``) of each of the K candidates;
    candidates: K hit records (only those with ``hit`` count; their
    ``iterations`` are ignored). Returns the rays whose hit changed.
    This is the one "nearest wins" rule of every tracer.
    """
    valid = np.flatnonzero(candidates.hit)
    if not valid.size:
        return np.zeros(0, dtype=np.int64)
    r, t = ray[valid], candidates.t[valid]
    if np.any(r[1:] < r[:-1]):  # not grouped by ray yet: nearest first within each ray
        order = np.lexsort((t, r))
        valid, r, t = valid[order], r[order], t[order]
    valid, r, t = _nearest_of_each_run(valid, r, t)
    better = ~hits.hit[r] | (t < hits.t[r])
    valid, r = valid[better], r[better]
    for name in ("hit", "t", "surface", "patch", "u", "v", "residual"):
        getattr(hits, name)[r] = getattr(candidates, name)[valid]
    return r


def _nearest_of_each_run(index: np.ndarray, ray: np.ndarray, t: np.ndarray):
    """(index, ray, t) (K,) with ray non-decreasing -> the first record of least t of each run of
    one ray, in ray order (the repair's candidates come grouped by pixel: no sort needed)."""
    starts = np.flatnonzero(np.concatenate([[True], ray[1:] != ray[:-1]]))
    if starts.size == ray.size:  # one record per ray
        return index, ray, t
    counts = np.diff(np.append(starts, ray.size))
    least = np.flatnonzero(t == np.repeat(np.minimum.reduceat(t, starts), counts))
    first = least[np.concatenate([[True], ray[least[1:]] != ray[least[:-1]]])]
    return index[first], ray[first], t[first]


def away_from_silhouettes(hit: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose 8 neighbours have the same hit and surface as they do (hit, surface:
    (H, W)): where two renders of one scene must agree exactly, whatever their last bits (the
    GPU path against the CPU's: tests/test_gpu.py, scripts/gpu_render.py)."""
    key = np.where(hit, surface, -1)
    padded = np.pad(key, 1, mode="edge")
    same = np.ones(key.shape, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            same &= padded[1 + dy : 1 + dy + key.shape[0], 1 + dx : 1 + dx + key.shape[1]] == key
    return same
