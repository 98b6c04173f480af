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

from bsrt.geometry.trim import CurveSet, TrimCurve
from bsrt.io.iges.bspline import clamp, from_bezier, line_curve, polyline_curve
from bsrt.io.param_map import ParamMap

TWO_PI = 2 * np.pi
_MAX_POINTS = 100_000
SEAM_NEAR = 1e-6  # samples this close to a seam (x the period) across it are put on it


def _start_samples(c: TrimCurve) -> np.ndarray:
    """(8 k + 1,): 8 equal steps over each of the curve's k knot spans (as np.linspace takes them)."""
    lo, hi = c.domain
    breaks = np.unique(np.clip(c.knots, lo, hi))
    a = breaks[:-1, None]
    t = np.arange(8.0) * ((breaks[1:, None] - a) / 8) + a
    return np.append(t.ravel(), hi)


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
    at = CurveSet(curves)
    uv_all = to_uv(at(np.concatenate(ts), np.repeat(np.arange(len(curves)), np.diff(cuts))), None)
    seams = [(k, lo, hi) for k, (lo, hi, closed) in enumerate(getattr(to_uv, "seams", ())) if closed]
    started = []
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
            started.append((i, t, uv, tol(uv) if callable(tol) else tol))
    out: list[TrimCurve | None] = [None] * len(curves)
    if not started:
        return out
    r = _Refinement(started)
    while len(r.want_t):
        pts = at(r.want_t, r.index[r.want_curve])
        hint = r.want_hint
        new = to_uv(pts, hint)
        new = _near(np.where(np.isnan(new), hint, new), hint, angular)
        for k, lo, hi in seams:  # the hint's turn; on the seam: the side of the hint
            new[:, k] += (hi - lo) * np.round((hint[:, k] - new[:, k]) / (hi - lo))
            _onto_seam(new[:, k], lo, hi)
        r.take(new)
    for i, uv in r.polylines():
        out[i] = polyline_curve(uv)
    return out


class _Refinement:
    """The polylines of many curves being refined together, one round per call of ``take``.

    Vertices (kept in the order found, in ``t``, ``uv`` and ``curve``: (M,), (M, 2), (M,);
    ``polylines`` sorts them along each curve); points to carry into (u, v) next, in
    ``want_t`` and ``want_hint`` ((W,), (W, 2), of the curves ``want_curve`` (W,)): first the
    new vertices (which become vertices ``fresh`` (V,)), then the midpoints of the tested
    intervals, whose ends are vertices ``ends`` (T, 2).

    A tested interval whose midpoint is further than its curve's tol from its chord is cut
    into m = 2, 4, 6 or 8 equal pieces, m from the miss (on a smooth curve it falls as the square
    of the piece's length): the midpoint becomes a vertex at once, the other new vertices and
    the pieces' midpoints are carried in the next round, from hints on the parabola through the
    interval's ends and midpoint (so that a curve that needs many points takes few rounds).
    Intervals no longer than 1e-12 of the curve's parameter range (plus one) are not cut, nor
    those of a curve with ``_MAX_POINTS`` vertices."""

    def __init__(self, started):
        """started: (index, t (n,), uv (n, 2), tol) per curve (its first samples carried)."""
        sizes = [len(t) for _, t, _, _ in started]
        self.index = np.array([i for i, _, _, _ in started])
        self.t = np.concatenate([t for _, t, _, _ in started])
        self.uv = np.concatenate([uv for _, _, uv, _ in started])
        self.curve = np.repeat(np.arange(len(started)), sizes)
        self.tol = np.array([x for _, _, _, x in started], dtype=float)
        self.floor = np.array([1e-12 * (abs(t[-1]) + abs(t[0]) + 1) for _, t, _, _ in started])
        first = np.ones(len(self.t), bool)
        first[np.cumsum(sizes) - 1] = False
        a = np.flatnonzero(first)  # every vertex but each curve's last
        self._want(
            np.empty(0),
            np.empty((0, 2)),
            np.empty(0, np.int64),
            np.stack([a, a + 1], 1),
            0.5 * (self.uv[a] + self.uv[a + 1]),
        )

    def _want(self, t, hint, curve, ends, mid_hint) -> None:
        """Carry new vertices (t (V,), hint (V, 2), curve (V,)) and the midpoints of the intervals
        between vertices ends (T, 2) (hints mid_hint (T, 2))."""
        self.fresh = len(self.t) + np.arange(len(t))
        self.t = np.concatenate([self.t, t])
        self.uv = np.concatenate([self.uv, hint])  # (a placeholder until carried)
        self.curve = np.concatenate([self.curve, curve])
        self.ends = ends
        ta, tb = self.t[ends[:, 0]], self.t[ends[:, 1]]
        self.want_t = np.concatenate([t, 0.5 * (ta + tb)])
        self.want_curve = np.concatenate([curve, self.curve[ends[:, 0]]])
        self.want_hint = np.concatenate([hint, mid_hint])

    def groups(self):
        """(curve index, selection of the wanted points) per curve with any, in the order of the
        wanted points (each curve's together: new vertices and midpoints apart)."""
        c = self.want_curve
        starts = np.flatnonzero(np.concatenate([[True], c[1:] != c[:-1]]))
        ends = np.append(starts[1:], len(c))
        return [(self.index[c[a]], slice(a, b)) for a, b in zip(starts, ends)]

    def take(self, new: np.ndarray) -> None:
        """The carried points' (u, v) (W, 2): the next round's points chosen."""
        v = len(self.fresh)
        self.uv[self.fresh] = new[:v]
        mid, ends = new[v:], self.ends
        ea, eb = ends[:, 0], ends[:, 1]
        ta, tb, a, b, cid = self.t[ea], self.t[eb], self.uv[ea], self.uv[eb], self.curve[ea]
        tol = self.tol[cid]
        miss = _off_segment(mid, a, b)
        bad = (miss > tol) & (tb - ta > self.floor[cid])
        bad &= np.bincount(self.curve, minlength=len(self.tol))[cid] < _MAX_POINTS
        ta, tb, a, b, mid, ea, eb, cid = ta[bad], tb[bad], a[bad], b[bad], mid[bad], ea[bad], eb[bad], cid[bad]
        m = 2 * np.ceil(np.clip(np.ceil(1.2 * np.sqrt(miss[bad] / tol[bad])), 2, 8) / 2).astype(np.int64)
        centre = len(self.t) + np.arange(len(m))  # the midpoints: vertices now
        self.t = np.concatenate([self.t, 0.5 * (ta + tb)])
        self.uv = np.concatenate([self.uv, mid])
        self.curve = np.concatenate([self.curve, cid])
        k = np.repeat(np.arange(len(m)), m + 1)  # the pieces' ends j / m, j = 0..m, of every cut interval
        j = np.arange(len(k)) - np.repeat(np.cumsum(m + 1) - (m + 1), m + 1)
        f = j / m[k]
        at = ta[k] * (1 - f) + tb[k] * f  # exactly ta, tb and the midpoint at j = 0, m and m / 2
        hint = _parabola(a[k], mid[k], b[k], f)
        vertex = (j > 0) & (j < m[k]) & (2 * j != m[k])
        # each piece end's vertex: the interval's ends, its midpoint, or a new one (numbered next)
        ref = np.where(j == 0, ea[k], np.where(j == m[k], eb[k], centre[k]))
        ref[vertex] = len(self.t) + np.arange(np.count_nonzero(vertex))
        piece = np.flatnonzero(j < m[k])  # a piece starts here
        fm = (f[piece] + f[piece + 1]) / 2
        kp = k[piece]
        ends = np.stack([ref[piece], ref[piece + 1]], 1)
        self._want(at[vertex], hint[vertex], cid[k[vertex]], ends, _parabola(a[kp], mid[kp], b[kp], fm))

    def polylines(self):
        """(curve index, vertices' (u, v) (n, 2) in order along it) per curve."""
        order = np.lexsort((self.t, self.curve))
        cuts = np.searchsorted(self.curve[order], np.arange(1, len(self.tol)))
        return zip(self.index, np.split(self.uv[order], cuts))


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
    if x.size > 1 and np.abs(np.diff(x)).max() >= period / 2:  # (np.unwrap leaves smaller jumps alone)
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
