"""Model-space curves into a surface's parameters, and parameter maps applied to 2-D curves.

Inversion (for boundaries written only as 3-D curves): the curve is sampled
-- 8 points per knot span to start with -- and every sample is carried to
the surface's parameters, in closed form for the analytic surfaces (angles
unwrapped along the curve) or by closest-point inversion on a B-spline surface
(:class:`bsrt.io.invert.CurveInverse`: the OpenCASCADE import's inverter
:class:`~bsrt.io.invert.SurfaceInverse` with its Newton steps on the surface's
Bezier pieces; from the nearest point of a grid over the surface for the first
samples, and from hints on the polyline for the later ones), all curves of a
composite together. Along a closed direction of the inverter (a seam: its two bounds
are the same points) the samples are unwrapped by its period, so that a curve
touching or just crossing the seam stays on one side of it. Intervals whose midpoint's (u, v) is
further than ``tol`` from the segment between their ends' are cut (in 2 to 8 pieces,
as many as the miss asks for: see ``_Refinement``) until none is, and the result is
the degree-1 polyline through the samples: within ``tol`` of the true parameter-space
curve at the tested midpoints. Planes need none of this: their inverse is affine, so the curve's
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

from bsrt.geometry.trim import TrimCurve
from bsrt.io.iges.bspline import clamp, from_bezier, line_curve, polyline_curve
from bsrt.io.param_map import ParamMap

TWO_PI = 2 * np.pi
_MAX_POINTS = 100_000
SEAM_NEAR = 1e-6  # samples this close to a seam (x the period) across it are put on it


def _start_samples(c: TrimCurve) -> np.ndarray:
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


def invert_curves(curves: list[TrimCurve], to_uv, tol, angular=(False, False)) -> list[TrimCurve | None]:
    """The 3-D curves as 2-D polylines in the parameters given by to_uv(points, hint), all
    curves' samples carried together (one call of to_uv per round of cutting).

    to_uv: (N, 3) points and (N, 2) hints (or None) -> (N, 2), NaN where a
    parameter is undetermined (at a pole or an apex: the neighbouring samples'
    value is taken). angular: which parameters are angles (unwrapped along the
    curve). tol: see the module text (or a function of a curve's first samples' (u, v)
    giving it). None for a curve that lies wholly where a parameter is undetermined
    (a collapsed edge, which the loop then crosses in a straight line).
    """
    ts = [_start_samples(c) for c in curves]
    cuts = np.cumsum([0] + [len(t) for t in ts])
    uv_all = to_uv(np.concatenate([c.evaluate(t) for c, t in zip(curves, ts)]), None)
    seams = [(k, lo, hi) for k, (lo, hi, closed) in enumerate(getattr(to_uv, "seams", ())) if closed]
    out: list[TrimCurve | None] = [None] * len(curves)
    todo = []
    for i, t in enumerate(ts):
        uv = uv_all[cuts[i] : cuts[i + 1]]
        for k in range(2):  # NaN: any value (a pole, an apex): the neighbours' one
            bad = np.isnan(uv[:, k])
            if bad.all():
                break
            if bad.any():
                good = np.flatnonzero(~bad)
                uv[:, k] = uv[good[np.clip(np.searchsorted(good, np.arange(len(uv))), 0, len(good) - 1)], k]
            if angular[k]:
                uv[:, k] = np.unwrap(uv[:, k])
        else:
            for k, lo, hi in seams:
                _snap(uv[:, k], lo, hi)
            todo.append(_Refinement(i, t, uv, tol(uv) if callable(tol) else tol))
    while todo:
        pts = np.concatenate([curves[r.index].evaluate(r.want_t) for r in todo])
        hint = np.concatenate([r.want_hint for r in todo])
        new = to_uv(pts, hint)
        new = _near(np.where(np.isnan(new), hint, new), hint, angular)
        for k, lo, hi in seams:  # the hint's turn; on the seam: the side of the hint
            new[:, k] += (hi - lo) * np.round((hint[:, k] - new[:, k]) / (hi - lo))
            _onto_seam(new[:, k], lo, hi)
        first = 0
        for r in todo:
            first, mine = first + len(r.want_t), new[first : first + len(r.want_t)]
            r.take(mine)
            if not len(r.want_t) or len(r.t) >= _MAX_POINTS:
                out[r.index] = polyline_curve(r.uv)
        todo = [r for r in todo if out[r.index] is None]
    return out


class _Refinement:
    """One curve's polyline being refined: vertices t (M,) and uv (M, 2), vertices to add
    (parameters ``new_t`` (V,)) and intervals to test (ends ``test_a``, ``test_b`` (T,), both
    vertices once the new ones are in); ``want_t`` (V + T,) and ``want_hint`` (V + T, 2): the
    points to carry into (u, v) next, the new vertices and then the tested intervals' midpoints.

    An interval whose midpoint is further than tol from its chord is cut into m = 2, 4, 6 or
    8 equal pieces, m from the miss (on a smooth curve it falls as the square of the piece's
    length): the midpoint becomes a vertex at once, the other new vertices and the pieces'
    midpoints are carried in the next round, from hints on the parabola through the interval's
    ends and midpoint (so that a curve that needs many points takes few rounds)."""

    def __init__(self, index: int, t, uv, tol: float):
        self.index, self.t, self.uv, self.tol = index, t, uv, tol
        self.new_t = np.empty(0)
        self.test_a, self.test_b = t[:-1], t[1:]
        self.want_t = 0.5 * (t[:-1] + t[1:])
        self.want_hint = 0.5 * (uv[:-1] + uv[1:])
        self.floor = 1e-12 * (abs(t[-1]) + abs(t[0]) + 1)  # intervals no shorter are cut

    def _insert(self, t, uv) -> None:
        at = np.searchsorted(self.t, t)
        self.t = np.insert(self.t, at, t)
        self.uv = np.insert(self.uv, at, uv, axis=0)

    def take(self, new: np.ndarray) -> None:
        """The carried points' (u, v) (len(want_t), 2): the next round's points chosen."""
        v = len(self.new_t)
        if v:
            self._insert(self.new_t, new[:v])
        mid = new[v:]
        ia = np.searchsorted(self.t, self.test_a)
        a, b = self.uv[ia], self.uv[ia + 1]
        miss = _off_segment(mid, a, b)
        bad = (miss > self.tol) & (self.test_b - self.test_a > self.floor)
        ta, tb, a, b, mid = self.test_a[bad], self.test_b[bad], a[bad], b[bad], mid[bad]
        m = 2 * np.ceil(np.clip(np.ceil(1.2 * np.sqrt(miss[bad] / self.tol)), 2, 8) / 2).astype(np.int64)
        self._insert(0.5 * (ta + tb), mid)
        k = np.repeat(np.arange(len(m)), m + 1)  # the pieces' ends j / m, j = 0..m, of every cut interval
        j = np.arange(len(k)) - np.repeat(np.cumsum(m + 1) - (m + 1), m + 1)
        f = j / m[k]
        ends = ta[k] * (1 - f) + tb[k] * f  # exactly ta, tb and the midpoint at j = 0, m and m / 2
        hint = _parabola(a[k], mid[k], b[k], f)
        vertex = (j > 0) & (j < m[k]) & (2 * j != m[k])
        piece = j < m[k]  # a piece starts here
        self.new_t = ends[vertex]
        self.test_a, self.test_b = ends[piece], ends[np.flatnonzero(piece) + 1]
        fm = (f[piece] + f[np.flatnonzero(piece) + 1]) / 2
        kp = k[piece]
        self.want_t = np.concatenate([self.new_t, 0.5 * (self.test_a + self.test_b)])
        self.want_hint = np.concatenate([hint[vertex], _parabola(a[kp], mid[kp], b[kp], fm)])


def _parabola(a, m, b, f):
    """(N, 2): the parabola through a (at f = 0), m (at 1/2) and b (at 1) (each (N, 2)) at f (N,)."""
    f = f[:, None]
    return a * ((2 * f - 1) * (f - 1)) + m * (4 * f * (1 - f)) + b * (f * (2 * f - 1))


def _snap(x: np.ndarray, lo: float, hi: float) -> None:
    """Samples x (in order along a curve) of a closed direction (lo and hi: the same points of
    the surface) made continuous, in place: unwrapped by the period hi - lo, shifted by whole
    periods to centre in [lo, hi], and those outside by at most ``SEAM_NEAR`` x the period (a
    sample on the seam, or just across it, given the far side's value) set on the bound (a curve
    wholly on the seam keeps its side: its loop decides)."""
    period = hi - lo
    x[:] = np.unwrap(x, period=period)
    centre = 0.5 * (x.min() + x.max())
    if not lo <= centre <= hi:
        x -= period * np.floor((centre - lo) / period)
    _onto_seam(x, lo, hi)


def _onto_seam(x: np.ndarray, lo: float, hi: float) -> None:
    """Values x on the bounds of a closed direction (within 1e-12 x the period: rounding) or
    just across them (by ``SEAM_NEAR`` x the period at most) set on them, in place."""
    near, on = SEAM_NEAR * (hi - lo), 1e-12 * (hi - lo)
    x[(x >= lo - near) & (x <= lo + on)] = lo
    x[(x >= hi - on) & (x <= hi + near)] = hi


def _off_segment(p, a, b) -> np.ndarray:
    """(N,) distances of points p from the segments a-b (all (N, 2))."""
    d = b - a
    length2 = np.einsum("nk,nk->n", d, d)
    t = np.clip(np.einsum("nk,nk->n", p - a, d) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return np.hypot(*(p - a - t[:, None] * d).T)


# ---------------------------------------------------------------------------
# Parameter maps applied to 2-D curves


def _monotone(values) -> bool:
    d = np.diff(values)
    return bool(np.all(d >= 0) or np.all(d <= 0))


def map_curve(c: TrimCurve, mu: ParamMap, mv: ParamMap, tol: float) -> tuple[TrimCurve, bool]:
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
        return TrimCurve(c.degree, c.knots, np.stack([nx, ny], 1), c.weights), True
    if (iso_x and _monotone(y)) or (iso_y and _monotone(x)):
        a, b = clamp(c).points[[0, -1]]
        ends = np.stack([mu(np.array([a[0], b[0]])), mv(np.array([a[1], b[1]]))], 1)
        return line_curve(ends[0], ends[1]), True
    return _hermite(c, mu, mv, tol), False


def _hermite(c: TrimCurve, mu: ParamMap, mv: ParamMap, tol: float) -> TrimCurve:
    def g(t):
        p, dp = c.evaluate(t, derivative=True)
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
