"""Model-space curves into a surface's parameters, and parameter maps applied to 2-D curves.

Inversion (for boundaries written only as 3-D curves): the curve is sampled
-- 8 points per knot span to start with -- and every sample is carried to
the surface's parameters, in closed form for the analytic surfaces (angles
unwrapped along the curve) or by closest-point inversion on a B-spline surface
(Gauss-Newton on |S(u, v) - P|^2 from the nearest point of a grid over the
surface for the first samples, and from the midpoint of the neighbouring
samples' answers for the later ones). Intervals whose midpoint's (u, v) is
further than ``tol`` from the segment between their ends' are halved until
none is, and the result is the degree-1 polyline through the samples: within
``tol`` of the true parameter-space curve at the tested midpoints. Planes need none of this: their inverse is affine, so the curve's
control points are mapped exactly.

Mapping (for trim curves written in an analytic surface's (angle, height)
parameters, whose B-spline parameter is a monotone function of the angle):
a curve over which both maps are affine, or which is an iso-line in one
direction and affine or monotone in the other, is mapped exactly; any other is
replaced by C1 cubic Hermite pieces of the mapped curve (same parameter),
halved until they are within ``tol / 2`` of it at 16 points each: measured
within ``tol`` everywhere (e.g. 4.8e-10 x the domain's size with 104 pieces for a
quadratic Bezier across 150 degrees of a cone).
"""

from __future__ import annotations

import numpy as np

from bsrt.geometry.bspline import BSplineSurface, basis_functions, find_span
from bsrt.geometry.bspline import evaluate as surface_eval
from bsrt.io.iges.bspline import Curve, ParamMap, clamp, evaluate, from_bezier, line_curve, polyline_curve
from bsrt.io.invert import invert

TWO_PI = 2 * np.pi
_MAX_POINTS = 100_000


def _start_samples(c: Curve) -> np.ndarray:
    lo, hi = c.domain
    breaks = np.unique(np.clip(c.knots, lo, hi))
    t = [np.linspace(a, b, 9)[:-1] for a, b in zip(breaks[:-1], breaks[1:])]
    return np.concatenate(t + [[hi]])


def _near(values, reference, angular):
    """Shift angular columns by multiples of 2 pi to lie nearest ``reference``."""
    out = values.copy()
    for k in range(2):
        if angular[k]:
            out[:, k] += TWO_PI * np.round((reference[:, k] - out[:, k]) / TWO_PI)
    return out


def invert_curve(c: Curve, to_uv, tol: float, angular=(False, False)) -> Curve | None:
    """The 3-D curve c as a 2-D polyline in the parameters given by to_uv(points, hint).

    to_uv: (N, 3) points and (N, 2) hints (or None) -> (N, 2), NaN where a
    parameter is undetermined (at a pole or an apex: the neighbouring samples'
    value is taken). angular: which parameters are angles (unwrapped along the
    curve). tol: see the module text (or a function of the first samples' (u, v)
    giving it). None if the whole curve lies where a parameter is undetermined
    (a collapsed edge, which the loop then crosses in a straight line).
    """
    t = _start_samples(c)
    uv = to_uv(evaluate(c, t), None)
    for k in range(2):  # NaN: any value (a pole, an apex): the neighbours' one
        bad = np.isnan(uv[:, k])
        if bad.all():
            return None
        if bad.any():
            good = np.flatnonzero(~bad)
            uv[:, k] = uv[good[np.clip(np.searchsorted(good, np.arange(len(uv))), 0, len(good) - 1)], k]
        if angular[k]:
            uv[:, k] = np.unwrap(uv[:, k])
    seams = [(k, lo, hi) for k, (lo, hi, closed) in enumerate(getattr(to_uv, "seams", ())) if closed]
    for k, lo, hi in seams:
        _snap(uv[:, k], lo, hi)
    if callable(tol):
        tol = tol(uv)
    while len(t) < _MAX_POINTS:
        mid_t = 0.5 * (t[:-1] + t[1:])
        chord = 0.5 * (uv[:-1] + uv[1:])
        mid = to_uv(evaluate(c, mid_t), chord)
        mid = _near(np.where(np.isnan(mid), chord, mid), chord, angular)
        for k, lo, hi in seams:  # on the seam: the side of the chord
            on = np.minimum(np.abs(mid[:, k] - lo), np.abs(mid[:, k] - hi)) <= 1e-12 * (hi - lo)
            mid[on, k] = np.where(np.abs(chord[on, k] - lo) <= np.abs(chord[on, k] - hi), lo, hi)
        bad = _off_segment(mid, uv[:-1], uv[1:]) > tol
        bad &= (t[1:] - t[:-1]) > 1e-12 * (abs(t[-1]) + abs(t[0]) + 1)
        if not bad.any():
            break
        t = np.insert(t, np.flatnonzero(bad) + 1, mid_t[bad])
        uv = np.insert(uv, np.flatnonzero(bad) + 1, mid[bad], axis=0)
    return polyline_curve(uv)


def _snap(x: np.ndarray, lo: float, hi: float) -> None:
    """Samples x (in order along a curve) on the seam of a closed direction (at lo or hi, the
    same points of the surface) moved, in place, to the side of their nearest neighbour off
    the seam (a curve wholly on the seam is left as it is: its loop decides)."""
    on = np.minimum(np.abs(x - lo), np.abs(x - hi)) <= 1e-12 * (hi - lo)
    if not on.any() or on.all():
        return
    off = np.flatnonzero(~on)
    for i in np.flatnonzero(on):
        j = off[np.argmin(np.abs(off - i))]
        x[i] = lo if abs(x[j] - lo) <= abs(x[j] - hi) else hi


def _off_segment(p, a, b) -> np.ndarray:
    """(N,) distances of points p from the segments a-b (all (N, 2))."""
    d = b - a
    length2 = np.einsum("nk,nk->n", d, d)
    t = np.clip(np.einsum("nk,nk->n", p - a, d) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return np.hypot(*(p - a - t[:, None] * d).T)


def _grid_points(s: BSplineSurface, gu, gv) -> np.ndarray:
    """(len(gu), len(gv), 3) float64: S at the grid gu x gv, as a tensor product (one
    basis matrix per direction)."""
    mats = []
    for g, knots, p, n in ((gu, s.knots_u, s.degree[0], s.shape[0]), (gv, s.knots_v, s.degree[1], s.shape[1])):
        span = find_span(knots, p, n, g)
        vals, _ = basis_functions(knots, p, span, g)
        m = np.zeros((len(g), n))
        np.add.at(m, (np.arange(len(g))[:, None], span[:, None] - p + np.arange(p + 1)[None, :]), vals)
        mats.append(m)
    h = np.einsum("ia,abk->ibk", mats[0], s.homogeneous())
    h = np.einsum("jb,ibk->ijk", mats[1], h)
    return h[..., :3] / h[..., 3:]


class SurfaceInverse:
    """Closest-point inversion onto a B-spline surface: points (N, 3) -> (u, v) (N, 2),
    by :func:`invert` from a hint, or from the nearest point of a grid over the surface
    (3 points per knot span, at most 256 per direction, less its collapsed rows and
    columns) where there is no hint or the hint leads to a far-off local minimum."""

    def __init__(self, s: BSplineSurface):
        self.s = s
        (u0, u1), (v0, v1) = s.domain_u, s.domain_v
        self.lo, self.hi = np.array([u0, v0]), np.array([u1, v1])
        ku = np.unique(np.clip(s.knots_u, u0, u1))
        kv = np.unique(np.clip(s.knots_v, v0, v1))
        gu = np.unique(np.concatenate([np.linspace(a, b, 4) for a, b in zip(ku[:-1], ku[1:])]))
        gv = np.unique(np.concatenate([np.linspace(a, b, 4) for a, b in zip(kv[:-1], kv[1:])]))
        gu, gv = gu[:: max(1, -(-len(gu) // 256))], gv[:: max(1, -(-len(gv) // 256))]
        grid = _grid_points(s, gu, gv)
        self.size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
        # rows and columns collapsed to a point (a pole, an apex) are left out: a start there
        # could not move along the collapsed parameter
        keep_u = np.ptp(grid, axis=1).max(axis=1) > 1e-12 * self.size
        keep_v = np.ptp(grid, axis=0).max(axis=1) > 1e-12 * self.size
        if keep_u.any() and keep_v.any():
            grid, gu, gv = grid[keep_u][:, keep_v], gu[keep_u], gv[keep_v]
        uu, vv = np.meshgrid(gu, gv, indexing="ij")
        self.grid_uv = np.stack([uu.ravel(), vv.ravel()], 1)
        self.grid = grid.reshape(-1, 3)
        # closed directions (the surface's two edges across them coincide): their seam samples
        # are put on the side their neighbours along a curve are on (``invert_curve``)
        self.closed = tuple(
            bool(np.abs(np.take(grid, 0, axis=k) - np.take(grid, -1, axis=k)).max() <= 1e-9 * self.size)
            for k in range(2)
        )
        self.grid_t = np.ascontiguousarray(self.grid.T)
        self.grid_sq = 0.5 * np.einsum("gk,gk->g", self.grid, self.grid)

    def _nearest(self, pts):
        out = np.empty((len(pts), 2))
        step = max(1, 1_000_000 // len(self.grid))
        for a in range(0, len(pts), step):
            # p.g - |g|^2 / 2: the nearest has the most (einsum: no threaded BLAS, which a busy
            # machine slows down many times over for this thin product)
            d = np.einsum("nk,kg->ng", pts[a : a + step], self.grid_t)
            d -= self.grid_sq
            out[a : a + step] = self.grid_uv[np.argmax(d, axis=1)]
        return out

    def _newton(self, pts, uv):
        """(uv (N, 2), S (N, 3), S_u, S_v there, distances (N,)) from starts uv."""
        u, v = invert(self.s, pts, uv[:, 0], uv[:, 1], self.size)
        s, su, sv = surface_eval(self.s, u, v)
        return np.stack([u, v], 1), su, sv, np.linalg.norm(s - pts, axis=1)

    @property
    def seams(self):
        """((u0, u1, closed in u), (v0, v1, closed in v)) for ``invert_curve``."""
        return tuple((self.lo[k], self.hi[k], self.closed[k]) for k in range(2))

    def __call__(self, pts, hint=None):
        """(u, v) of the points' closest points, from ``hint`` or the nearest grid point;
        NaN in a parameter along which the surface does not move there (a collapsed edge)."""
        pts = np.asarray(pts, float)
        uv, su, sv, dist = self._newton(pts, self._nearest(pts) if hint is None else np.clip(hint, self.lo, self.hi))
        if hint is not None and len(pts):  # far further than the rest: a wrong local minimum?
            far = np.flatnonzero(dist > 10 * np.median(dist) + 1e-9 * self.size)
            if far.size:
                again, su2, sv2, d2 = self._newton(pts[far], self._nearest(pts[far]))
                better = d2 < dist[far]
                uv[far[better]], su[far[better]], sv[far[better]] = again[better], su2[better], sv2[better]
        for k, d in enumerate((su, sv)):
            still = np.linalg.norm(d, axis=1) * (self.hi[k] - self.lo[k]) <= 1e-9 * self.size
            uv[still, k] = np.nan
        return uv


# ---------------------------------------------------------------------------
# Parameter maps applied to 2-D curves


def _monotone(values) -> bool:
    d = np.diff(values)
    return bool(np.all(d >= 0) or np.all(d <= 0))


def map_curve(c: Curve, mu: ParamMap, mv: ParamMap, tol: float) -> tuple[Curve, bool]:
    """The 2-D curve c (in the maps' x) in the maps' s: (curve, exact).

    Exact when both maps are affine over the curve, or when the curve is an
    iso-line in one parameter and affine or monotone in the other (then its
    image is the segment between its mapped ends); otherwise C1 cubic pieces
    within ``tol`` of the mapped curve.
    """
    x, y = c.points[:, 0], c.points[:, 1]
    au, av = mu.affine_on(x.min(), x.max()), mv.affine_on(y.min(), y.max())
    iso_x, iso_y = x.min() == x.max(), y.min() == y.max()
    if (au is not None or iso_x) and (av is not None or iso_y):
        nx = au[0] * x + au[1] if au is not None else np.full_like(x, mu(x[:1])[0])
        ny = av[0] * y + av[1] if av is not None else np.full_like(y, mv(y[:1])[0])
        return Curve(c.degree, c.knots, np.stack([nx, ny], 1), c.weights), True
    if (iso_x and _monotone(y)) or (iso_y and _monotone(x)):
        a, b = clamp(c).points[[0, -1]]
        ends = np.stack([mu(np.array([a[0], b[0]])), mv(np.array([a[1], b[1]]))], 1)
        return line_curve(ends[0], ends[1]), True
    return _hermite(c, mu, mv, tol), False


def _hermite(c: Curve, mu: ParamMap, mv: ParamMap, tol: float) -> Curve:
    def g(t):
        p, dp = evaluate(c, t, derivative=True)
        val = np.stack([mu(p[:, 0]), mv(p[:, 1])], 1)
        der = np.stack([mu.derivative(p[:, 0]) * dp[:, 0], mv.derivative(p[:, 1]) * dp[:, 1]], 1)
        return val, der

    lo, hi = c.domain
    breaks = np.unique(np.clip(c.knots, lo, hi))
    todo = list(zip(breaks[:-1], breaks[1:]))
    done = []
    while todo:
        a, b = todo.pop()
        (pa, pb), (da, db) = g(np.array([a, b]))
        h = b - a
        bez = np.array([pa, pa + h / 3 * da, pb - h / 3 * db, pb])
        s = np.linspace(0, 1, 18)[1:-1]
        basis = np.stack([(1 - s) ** 3, 3 * s * (1 - s) ** 2, 3 * s * s * (1 - s), s**3], 1)
        err = np.abs(basis @ bez - g(a + s * h)[0]).max()
        if err > 0.5 * tol and h > 1e-9 * (hi - lo) and len(done) + len(todo) < 20000:
            todo += [(a + h / 2, b), (a, a + h / 2)]
        else:
            done.append((a, b, bez))
    done.sort(key=lambda item: item[0])
    breaks = np.array([d[0] for d in done] + [done[-1][1]])
    segs = np.stack([np.concatenate([d[2], np.ones((4, 1))], 1) for d in done])
    return from_bezier(breaks, segs)
