"""All surfaces of a scene as one table of (rational) Bezier patches.

Every surface is split at its knots (``bspline.bezier_patches``) into
polynomial pieces. Patch k belongs to surface ``surface[k]`` and covers the
rectangle ``bounds[k] = (u0, u1, v0, v1)`` of that surface's own knot domain.
Each patch is stored in the power basis of its local parameters (s, t) in
[0, 1]^2 as flat arrays (``kernels.patches.PatchArrays``) that the compiled
kernels evaluate with Horner's scheme; ``PatchSet.evaluate`` is their batch
entry point for NumPy code.
"""

from __future__ import annotations

from functools import cached_property
from math import comb

import numpy as np

from bsrt.geometry.bspline import BSplineSurface, bezier_patches
from bsrt.kernels import patches as kp
from bsrt.kernels.tables import power_coefficients

CHUNK = 1 << 16  # patches whose boxes and second differences are computed at once


def power_from_bernstein(n: int) -> np.ndarray:
    """(n + 1, n + 1) matrix M with B_{k,n}(s) = sum_j M[k, j] s^j."""
    m = np.zeros((n + 1, n + 1))
    for k in range(n + 1):
        for j in range(k, n + 1):
            m[k, j] = comb(n, j) * comb(j, k) * (-1) ** (j - k)
    return m


class PatchSet:
    """The Bezier patches of a list of surfaces.

    Attributes (P patches, M surfaces):
      surfaces: the M BSplineSurface objects.
      surface: (P,) int64, the surface each patch belongs to.
      bounds: (P, 4) float64, (u0, u1, v0, v1) in the surface's knot domain.
      groups: list of (ids (K,) int64, nets (K, p + 1, q + 1, 4) float64), the
        homogeneous Bezier points of the patches of one degree (p, q), one
        entry per degree; ids are increasing.
      box_min, box_max: (P, 3) float64, bounding box of each patch's control
        points (it contains the patch: convex hull, positive weights).
      bend: (P, 3) float64, (m_uu, m_vv, m_uv): bounds on |S_ss|, |S_tt|,
        |S_st| over the patch in its local (s, t), from the projected
        control points' second differences (the map's tessellation counts).
      domain: (M, 4) float64, (umin, umax, vmin, vmax) of each surface.
      arrays: kernels.patches.PatchArrays, the same table for the kernels.
    Patches are numbered surface by surface, u-major within a surface.
    Set-up is vectorised over the patches (per surface and degree, no
    per-patch Python loop).
    """

    def __init__(self, surfaces: list[BSplineSurface]):
        self.surfaces = list(surfaces)
        self.derived: dict = {}  # data other modules derive from the table, cached (prelim's tessellation)
        m_count = len(self.surfaces)
        self.domain = np.zeros((m_count, 4))
        by_degree: dict = {}  # (p, q) -> [(ids, nets)] of the surfaces of that degree
        bounds, surface = [], []
        breaks_u, breaks_v, grid_start = [], [], np.zeros(m_count, dtype=np.int64)
        size = 0
        for m, surf in enumerate(self.surfaces):
            ctrl, bnd = bezier_patches(surf)
            grid_start[m] = size
            by_degree.setdefault(tuple(surf.degree), []).append((np.arange(size, size + len(ctrl)), ctrl))
            size += len(ctrl)
            bounds.append(bnd)
            surface.append(np.full(len(ctrl), m, dtype=np.int64))
            self.domain[m] = (*surf.domain_u, *surf.domain_v)
            breaks_u.append(np.unique(bnd[:, :2]))
            breaks_v.append(np.unique(bnd[:, 2:]))
        self.size = size
        self.groups = [
            parts[0]
            if len(parts) == 1
            # one surface: its array as it is (no copy)
            else (np.concatenate([i for i, _ in parts]), np.concatenate([c for _, c in parts]))
            for parts in by_degree.values()
        ]
        self.surface = np.concatenate(surface) if surface else np.zeros(0, np.int64)
        self.bounds = np.concatenate(bounds).reshape(self.size, 4) if bounds else np.zeros((0, 4))
        self.box_min, self.box_max = np.empty((self.size, 3)), np.empty((self.size, 3))
        self.bend = np.empty((self.size, 3))
        for ids, nets in self.groups:
            for part in range(0, ids.size, CHUNK):  # bounded temporaries
                which = slice(part, part + CHUNK)
                pts = nets[which, ..., :3] / nets[which, ..., 3:4]
                at = ids[which]
                self.box_min[at], self.box_max[at] = pts.min(axis=(1, 2)), pts.max(axis=(1, 2))
                self.bend[at] = _second_differences(pts)
        self.arrays = kp.PatchArrays(
            *_power_coefficients(self.groups, self.size),
            bounds=self.bounds,
            inv_size=1.0 / np.stack([self.bounds[:, 1] - self.bounds[:, 0], self.bounds[:, 3] - self.bounds[:, 2]], 1),
            surface=self.surface,
            domain=self.domain,
            breaks_u=np.concatenate(breaks_u) if breaks_u else np.zeros(0),
            break_start_u=_starts(breaks_u),
            breaks_v=np.concatenate(breaks_v) if breaks_v else np.zeros(0),
            break_start_v=_starts(breaks_v),
            grid_start=grid_start,
            patch_grid=np.arange(self.size, dtype=np.int64),  # u-major per surface, as bezier_patches orders them
        )

    def net(self, k: int) -> np.ndarray:
        """(p + 1, q + 1, 4) homogeneous Bezier points of patch k."""
        for ids, nets in self.groups:
            at = np.searchsorted(ids, k)
            if at < ids.size and ids[at] == k:
                return nets[at]
        raise IndexError(f"patch {k} of {self.size}")

    @cached_property
    def trims(self):
        """trim.TrimTable of the surfaces' trim loops, for the kernels (built on first use)."""
        from bsrt.geometry.trim_table import build_trim_table

        return build_trim_table(self.surfaces)

    @property
    def trimmed(self) -> bool:
        return any(s.is_trimmed for s in self.surfaces)

    def scene_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) corners, each (3,), of all control points."""
        return self.box_min.min(axis=0), self.box_max.max(axis=0)

    def scene_diagonal(self) -> float:
        lo, hi = self.scene_box()
        return float(np.linalg.norm(hi - lo))

    def clamp(self, surface: np.ndarray, u: np.ndarray, v: np.ndarray):
        """Clip (u, v), each (N,), into the domain of each entry's surface."""
        d = self.domain[surface]
        return np.clip(u, d[:, 0], d[:, 1]), np.clip(v, d[:, 2], d[:, 3])

    def locate(self, surface: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Patch id (N,) int64 of each (surface, u, v); parameters outside the domain get the nearest patch."""
        surface = np.ascontiguousarray(surface, dtype=np.int64)
        out = np.empty(surface.shape[0], dtype=np.int64)
        kp.locate_many(self.arrays, surface, _f64(u), _f64(v), out)
        return out

    def evaluate(self, patch: np.ndarray, u: np.ndarray, v: np.ndarray, derivatives: bool = True):
        """S, S_u, S_v of each patch at global parameters, component-major.

        patch: (N,) int; u, v: (N,) float64 in the owning surface's knot
        domain (values outside the patch extend its polynomial). Returns
        (S, S_u, S_v), each (3, N) float64 (S alone if not derivatives);
        derivatives are with respect to the surface's own u and v.
        """
        patch = np.ascontiguousarray(patch, dtype=np.int64)
        n = patch.shape[0]
        S = np.empty((3, n))
        Su, Sv = (np.empty((3, n)), np.empty((3, n))) if derivatives else (S, S)
        kp.evaluate_many(self.arrays, patch, _f64(u), _f64(v), S, Su, Sv, derivatives)
        return (S, Su, Sv) if derivatives else S


def _second_differences(pts: np.ndarray) -> np.ndarray:
    """(K, 3) bounds (m_uu, m_vv, m_uv) on a degree (p, q) patch's second
    derivatives in (s, t), from its projected control points (K, p + 1, q + 1, 3)."""
    p, q = pts.shape[1] - 1, pts.shape[2] - 1
    return np.stack(
        [
            p * (p - 1) * _max_norm(pts[:, 2:] - 2 * pts[:, 1:-1] + pts[:, :-2]),
            q * (q - 1) * _max_norm(pts[:, :, 2:] - 2 * pts[:, :, 1:-1] + pts[:, :, :-2]),
            p * q * _max_norm(pts[:, 1:, 1:] - pts[:, 1:, :-1] - pts[:, :-1, 1:] + pts[:, :-1, :-1]),
        ],
        axis=1,
    )


def _max_norm(a: np.ndarray) -> np.ndarray:
    """Largest vector length per patch: a (K, ..., 3) -> (K,), zeros if a has no vectors."""
    if a.size == 0:
        return np.zeros(a.shape[0])
    return np.sqrt((a * a).sum(axis=-1)).reshape(a.shape[0], -1).max(axis=1)


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _starts(parts: list) -> np.ndarray:
    return np.concatenate([[0], np.cumsum([len(x) for x in parts])]).astype(np.int64)


def _power_coefficients(groups: list, n: int):
    """(coef, coef_start, degree, dim) of PatchArrays from PatchSet.groups (n patches).

    A patch whose weights are all equal is stored polynomial (x, y, z), else
    homogeneous (x w, y w, z w, w). Compiled (kernels/tables.py): no table-sized temporaries."""
    degree = np.zeros((n, 2), dtype=np.int64)
    dim = np.full(n, 3, dtype=np.int64)
    for ids, nets in groups:
        degree[ids] = (nets.shape[1] - 1, nets.shape[2] - 1)
        dim[ids] = np.where(np.all(nets[..., 3] == nets[:, :1, :1, 3], axis=(1, 2)), 3, 4)
    sizes = (degree[:, 0] + 1) * (degree[:, 1] + 1) * dim
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64) if n else np.zeros(0, np.int64)
    coef = np.empty(int(sizes.sum()))
    for ids, nets in groups:
        p, q = nets.shape[1] - 1, nets.shape[2] - 1
        power_coefficients(nets, ids, start, dim, power_from_bernstein(p), power_from_bernstein(q), coef)
    return coef, start, degree, dim
