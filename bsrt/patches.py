"""All surfaces of a scene as one table of (rational) Bezier patches.

Every surface is split at its knots (``bspline.bezier_patches``) into
polynomial pieces. Patch k belongs to surface ``surface[k]`` and covers the
rectangle ``bounds[k] = (u0, u1, v0, v1)`` of that surface's own knot domain.
Evaluation at global (u, v) maps to the local (s, t) in [0, 1]^2 and uses the
Bernstein basis, which is numerically stable at any degree; a pixel costs one
gather of its patch's control points instead of a knot search per basis
function. Patches are grouped by (degree, rational) so each group is one
vectorised contraction.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

from .bspline import BSplineSurface, bezier_patches, rational_quotient


def power_from_bernstein(n: int) -> np.ndarray:
    """(n + 1, n + 1) matrix M with B_{k,n}(s) = sum_j M[k, j] s^j."""
    m = np.zeros((n + 1, n + 1))
    for k in range(n + 1):
        for j in range(k, n + 1):
            m[k, j] = comb(n, j) * comb(j, k) * (-1) ** (j - k)
    return m


@dataclass(frozen=True, eq=False)
class PatchGroup:
    """Patches sharing a degree and rationality, with ids first..first+K-1.

    coeffs: (K, (p + 1) d, q + 1) float64 power-basis coefficients;
    coeffs[k, i d + c, j] multiplies s^i t^j in component c, with d = 4
    (homogeneous) if rational else 3 and (s, t) the patch-local parameters.
    """

    degree: tuple[int, int]
    rational: bool
    first: int
    coeffs: np.ndarray

    @property
    def dim(self) -> int:
        return 4 if self.rational else 3


class PatchSet:
    """The Bezier patches of a list of surfaces.

    Patch ids are grouped so that each PatchGroup owns a contiguous id range.
    Attributes (P patches, M surfaces):
      surface: (P,) int64, the surface each patch belongs to.
      bounds: (P, 4) float64, (u0, u1, v0, v1) in the surface's knot domain.
      bezier: list of P arrays (p + 1, q + 1, 4), homogeneous Bezier points.
      box_min, box_max: (P, 3) float64, bounding box of each patch's control
        points (it contains the patch: convex hull, positive weights).
      domain: (M, 4) float64, (umin, umax, vmin, vmax) of each surface.
    """

    def __init__(self, surfaces: list[BSplineSurface]):
        self.surfaces = list(surfaces)
        self.derived: dict = {}  # data other modules derive from the table, cached (prelim's tessellation)
        m_count = len(self.surfaces)
        self.domain = np.zeros((m_count, 4))
        pieces = []  # (group key, surface, natural index, bezier, bounds)
        breaks_u, breaks_v = [], []
        self._natural_base = np.zeros(m_count, dtype=np.int64)
        self._count_u = np.zeros(m_count, dtype=np.int64)
        self._count_v = np.zeros(m_count, dtype=np.int64)
        n = 0
        for m, surf in enumerate(self.surfaces):
            ctrl, bnd = bezier_patches(surf)
            key = (surf.degree, surf.is_rational)
            pieces += [(key, m, n + k, ctrl[k], bnd[k]) for k in range(len(ctrl))]
            self.domain[m] = (*surf.domain_u, *surf.domain_v)
            bu, bv = np.unique(bnd[:, 0]), np.unique(bnd[:, 2])
            breaks_u.append(bu)
            breaks_v.append(bv)
            self._natural_base[m], self._count_u[m], self._count_v[m] = n, bu.size, bv.size
            n += len(ctrl)
        self.size = n
        keys = list(dict.fromkeys(piece[0] for piece in pieces))
        pieces.sort(key=lambda piece: keys.index(piece[0]))  # stable: group-major
        self.surface = np.array([piece[1] for piece in pieces], dtype=np.int64)
        self._patch_of_natural = np.zeros(n, dtype=np.int64)
        self._patch_of_natural[[piece[2] for piece in pieces]] = np.arange(n)
        self.bezier = [piece[3] for piece in pieces]
        self.bounds = np.array([piece[4] for piece in pieces]).reshape(n, 4)
        pts = [b[..., :3] / b[..., 3:4] for b in self.bezier]
        self.box_min = np.array([x.min(axis=(0, 1)) for x in pts]).reshape(n, 3)
        self.box_max = np.array([x.max(axis=(0, 1)) for x in pts]).reshape(n, 3)
        self.inv_du = 1.0 / (self.bounds[:, 1] - self.bounds[:, 0])
        self.inv_dv = 1.0 / (self.bounds[:, 3] - self.bounds[:, 2])
        self.groups: list[PatchGroup] = []
        first = 0
        for (p, q), rational in keys:
            members = [piece[3] for piece in pieces if piece[0] == ((p, q), rational)]
            ctrl = np.array(members)  # (K, p+1, q+1, 4)
            if not rational:
                ctrl = ctrl[..., :3] / ctrl[..., 3:4]
            coeffs = np.einsum("ai,bj,kabc->kicj", power_from_bernstein(p), power_from_bernstein(q), ctrl)
            coeffs = coeffs.reshape(len(members), (p + 1) * ctrl.shape[-1], q + 1)
            self.groups.append(PatchGroup((p, q), rational, first, np.ascontiguousarray(coeffs)))
            first += len(members)
        # Sorted lookup keys: 2 * surface + normalised break, so one
        # searchsorted locates the span of every (surface, u) pair at once.
        self._key_u = self._lookup_keys(breaks_u, self.domain[:, 0], self.domain[:, 1])
        self._key_v = self._lookup_keys(breaks_v, self.domain[:, 2], self.domain[:, 3])
        self._offset_u = np.concatenate([[0], np.cumsum(self._count_u)[:-1]]).astype(np.int64)
        self._offset_v = np.concatenate([[0], np.cumsum(self._count_v)[:-1]]).astype(np.int64)

    @staticmethod
    def _lookup_keys(breaks, lo, hi) -> np.ndarray:
        if not breaks:
            return np.zeros(0)
        return np.concatenate([2.0 * m + (b - lo[m]) / (hi[m] - lo[m]) for m, b in enumerate(breaks)])

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
        """Patch id (N,) int64 of each (surface, u, v); parameters are clamped."""
        d = self.domain[surface]
        ku = 2.0 * surface + np.clip((u - d[:, 0]) / (d[:, 1] - d[:, 0]), 0.0, 1.0)
        kv = 2.0 * surface + np.clip((v - d[:, 2]) / (d[:, 3] - d[:, 2]), 0.0, 1.0)
        iu = np.searchsorted(self._key_u, ku, side="right") - 1 - self._offset_u[surface]
        iv = np.searchsorted(self._key_v, kv, side="right") - 1 - self._offset_v[surface]
        iu = np.clip(iu, 0, self._count_u[surface] - 1)
        iv = np.clip(iv, 0, self._count_v[surface] - 1)
        return self._patch_of_natural[self._natural_base[surface] + iu * self._count_v[surface] + iv]

    def evaluate(self, patch: np.ndarray, u: np.ndarray, v: np.ndarray, derivatives: bool = True):
        """S, S_u, S_v of each patch at global parameters, component-major.

        patch: (N,) int; u, v: (N,) float64 in the owning surface's knot
        domain (values outside the patch extend its polynomial). Returns
        (S, S_u, S_v), each (3, N) float64 (S alone if not derivatives);
        derivatives are with respect to the surface's own u and v.
        Fastest when ``patch`` is sorted: each run of equal ids is one
        small matrix product (BLAS) instead of a per-pixel gather.
        """
        patch = np.asarray(patch, dtype=np.int64)
        n = patch.shape[0]
        if n and np.any(patch[1:] < patch[:-1]):
            order = np.argsort(patch, kind="stable")
            out = self.evaluate(patch[order], u[order], v[order], derivatives)
            back = np.empty_like(order)
            back[order] = np.arange(n)
            return tuple(a[:, back] for a in out) if derivatives else out[:, back]
        cuts = np.flatnonzero(patch[1:] != patch[:-1]) + 1
        starts = np.concatenate([[0], cuts]) if n else np.zeros(0, np.int64)
        lengths = np.diff(np.concatenate([starts, [n]]))
        run_patch = patch[starts]
        # Per-run constants, repeated over each run (cheaper than a gather).
        s = (u - np.repeat(self.bounds[run_patch, 0], lengths)) * np.repeat(self.inv_du[run_patch], lengths)
        t = (v - np.repeat(self.bounds[run_patch, 2], lengths)) * np.repeat(self.inv_dv[run_patch], lengths)
        S = np.empty((3, n))
        Su, Sv = (np.empty((3, n)), np.empty((3, n))) if derivatives else (None, None)
        starts, ends, run_patch = starts.tolist(), (starts + lengths).tolist(), run_patch.tolist()
        g_bounds = [grp.first for grp in self.groups[1:]] + [self.size]
        lo = 0
        for g, group in enumerate(self.groups):
            hi = int(np.searchsorted(run_patch, g_bounds[g]))
            if hi > lo:
                a, b = starts[lo], ends[hi - 1]
                res = self._evaluate_runs(group, run_patch[lo:hi], starts[lo:hi], ends[lo:hi], a, s[a:b], t[a:b], derivatives)
                S[:, a:b] = res[0]
                if derivatives:
                    Su[:, a:b], Sv[:, a:b] = res[1], res[2]
            lo = hi
        if not derivatives:
            return S
        Su *= np.repeat(self.inv_du[run_patch], lengths)
        Sv *= np.repeat(self.inv_dv[run_patch], lengths)
        return S, Su, Sv

    @staticmethod
    def _evaluate_runs(group: PatchGroup, run_patch, starts, ends, offset, s, t, derivatives):
        """Evaluate one group's contiguous runs; s, t: (n,) local parameters."""
        (p, q), d, n = group.degree, group.dim, s.shape[0]
        tp = np.empty((2 * (q + 1) if derivatives else q + 1, n))
        tp[0] = 1.0
        for j in range(1, q + 1):
            np.multiply(tp[j - 1], t, out=tp[j])
        if derivatives:  # d/dt t^j = j t^(j-1)
            tp[q + 1] = 0.0
            for j in range(1, q + 1):
                np.multiply(tp[j - 1], j, out=tp[q + 1 + j])
        x = np.empty((tp.shape[0] // (q + 1), (p + 1) * d, n))
        for k, a, b in zip(run_patch, starts, ends):
            c = group.coeffs[k - group.first]
            a, b = a - offset, b - offset
            np.matmul(c, tp[: q + 1, a:b], out=x[0, :, a:b])
            if derivatives:
                np.matmul(c, tp[q + 1 :, a:b], out=x[1, :, a:b])
        x = x.reshape(x.shape[0], p + 1, d, n)
        # Horner in s: value from x[0]; d/ds from x[0]; d/dt from x[1].
        h = x[0, p].copy()
        for i in range(p - 1, -1, -1):
            h *= s
            h += x[0, i]
        if not derivatives:
            return (h if d == 3 else h[:3] / h[3],)
        hu = x[0, p] * float(p)
        for i in range(p - 1, 0, -1):
            hu *= s
            hu += x[0, i] * float(i)
        hv = x[1, p].copy()
        for i in range(p - 1, -1, -1):
            hv *= s
            hv += x[1, i]
        if d == 3:
            return h, hu, hv
        return tuple(a.T for a in rational_quotient(h.T, hu.T, hv.T))
