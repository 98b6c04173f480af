"""Rational B-spline curves for the IGES reader: a small exact algebra.

A :class:`TrimCurve` is a (rational) B-spline curve in 2-D or 3-D. The IGES
reader turns every curve entity into one (``iges_curves.py``) and builds
surfaces and trim loops from them. Everything here is exact up to rounding:
knot insertion, reversal, restriction to a sub-range, degree elevation,
joining curves end to end, products of B-spline functions, affine maps, and
conics as rational quadratics.

Each curve may carry a :class:`bsrt.io.param_map.ParamMap` (the one type both
CAD readers use): how the IGES entity's own parameter (an arc's angle, say)
maps onto the B-spline's parameter, affine for polynomial entities and the
closed form of the rational quadratic arc for conics. The maps are monotone
and invertible in closed form, which is what lets trim curves given in an
analytic surface's (angle, height) parameters be placed on its NURBS exactly.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from bsrt.geometry.bspline import insert_knot
from bsrt.geometry.trim import TrimCurve
from bsrt.io.param_map import ParamMap, concat_maps


def param_map(c: TrimCurve) -> ParamMap:
    """The map from the IGES entity's parameter to the curve's (the identity where it has none)."""
    return c.pmap if c.pmap is not None else ParamMap.identity(*c.domain)


def from_homogeneous(degree: int, knots, h: np.ndarray, pmap: ParamMap | None = None) -> TrimCurve:
    """A TrimCurve from homogeneous control points (n, d + 1); equal weights make it non-rational."""
    h = np.asarray(h, float)
    w = h[:, -1]
    pts = h[:, :-1] / w[:, None]
    weights = None if np.all(w == w[0]) else w / np.max(w)
    return TrimCurve(int(degree), np.asarray(knots, float), pts, weights, pmap)


def reverse(c: TrimCurve) -> TrimCurve:
    """The same curve traversed backwards, on the mirrored parameter range."""
    a, b = c.domain
    knots = (a + b) - c.knots[::-1]
    w = None if c.weights is None else c.weights[::-1].copy()
    pmap = None
    if c.pmap is not None:  # x -> -x on the IGES side as well
        m = c.pmap
        pmap = ParamMap(-m.x[::-1], (a + b) - m.s[::-1], m.kinds[::-1], unit=m.unit)
    return TrimCurve(c.degree, knots, c.points[::-1].copy(), w, pmap)


def _restrict_h(knots: np.ndarray, ctrl: np.ndarray, p: int, a: float, b: float):
    """Knots and homogeneous control points of the piece over [a, b] (clamped there)."""
    n = ctrl.shape[0]
    lo, hi = knots[p], knots[n]
    a, b = max(a, lo), min(b, hi)
    for x in (a, b):
        while np.count_nonzero(knots == x) < p:
            knots, ctrl = insert_knot(knots, ctrl, p, x)
    first = int(np.searchsorted(knots, a, side="right")) - 1 - p
    last = int(np.searchsorted(knots, b, side="left"))
    ctrl = ctrl[first:last]
    knots = knots[first : last + p + 1].copy()
    knots[: p + 1] = a
    knots[-(p + 1) :] = b
    return knots, ctrl


def restrict(c: TrimCurve, a: float, b: float) -> TrimCurve:
    """The part over [a, b] (clipped to the domain), clamped: its ends are its end control points."""
    knots, ctrl = _restrict_h(c.knots, c.homogeneous(), c.degree, a, b)
    return from_homogeneous(c.degree, knots, ctrl, c.pmap)


def clamp(c: TrimCurve) -> TrimCurve:
    p = c.degree
    if np.all(c.knots[: p + 1] == c.knots[p]) and np.all(c.knots[-(p + 1) :] == c.knots[-1]):
        return c
    return restrict(c, *c.domain)


def bezier_segments(c: TrimCurve):
    """(breaks (k + 1,), segments (k, p + 1, d + 1) homogeneous Bezier control points)."""
    c = clamp(c)
    p, knots, ctrl = c.degree, c.knots, c.homogeneous()
    for x in np.unique(knots[p + 1 : -(p + 1)]):
        while np.count_nonzero(knots == x) < p:
            knots, ctrl = insert_knot(knots, ctrl, p, x)
    breaks = np.unique(knots)
    k = len(breaks) - 1
    segs = np.stack([ctrl[i * p : i * p + p + 1] for i in range(k)])
    return breaks, segs


def from_bezier(breaks: np.ndarray, segs: np.ndarray, pmap: ParamMap | None = None) -> TrimCurve:
    """Join Bezier segments (k, q + 1, d + 1) over breaks (k + 1,) into one C0 B-spline."""
    k, q1 = segs.shape[:2]
    q = q1 - 1
    ctrl = [segs[0]] + [s[1:] for s in segs[1:]]  # consecutive segments share their end point
    knots = np.concatenate([[breaks[0]] * (q + 1)] + [[x] * q for x in breaks[1:-1]] + [[breaks[-1]] * (q + 1)])
    return from_homogeneous(q, knots, np.concatenate(ctrl), pmap)


def _elevate_bezier(seg: np.ndarray, r: int) -> np.ndarray:
    """A Bezier segment (p + 1, k) raised by r degrees."""
    p = seg.shape[0] - 1
    out = np.zeros((p + r + 1, seg.shape[1]))
    for i in range(p + r + 1):
        for j in range(max(0, i - r), min(p, i) + 1):
            out[i] += math.comb(p, j) * math.comb(r, i - j) / math.comb(p + r, i) * seg[j]
    return out


def elevate(c: TrimCurve, degree: int) -> TrimCurve:
    """The same curve as a B-spline of a higher degree (C0 at its former knots)."""
    if degree == c.degree:
        return c
    breaks, segs = bezier_segments(c)
    up = np.stack([_elevate_bezier(s, degree - c.degree) for s in segs])
    return from_bezier(breaks, up, c.pmap)


def join(curves: list[TrimCurve]) -> TrimCurve:
    """Curves end to end as one curve: each keeps its parameter length, the
    weights are scaled so consecutive pieces share their junction point, whose
    two copies (equal up to the file's gap) are averaged. The parameter map is
    the concatenation of the pieces' maps (an IGES composite curve's parameter)."""
    if len(curves) == 1:
        return curves[0]
    p = max(c.degree for c in curves)
    pieces = [elevate(clamp(c), p) for c in curves]
    knots, ctrl, maps = [], [], []
    offset = pieces[0].domain[0]
    xoffset = param_map(curves[0]).x[0]
    prev_w = None
    for k, c in enumerate(pieces):
        a, b = c.domain
        h = c.homogeneous()
        if prev_w is not None:
            h = h * (prev_w / h[0, -1])
            joint = 0.5 * (ctrl[-1][-1, :-1] / ctrl[-1][-1, -1] + h[0, :-1] / h[0, -1])
            ctrl[-1] = ctrl[-1].copy()
            ctrl[-1][-1, :-1] = joint * prev_w
            h = h[1:]
        ctrl.append(h)
        prev_w = ctrl[-1][-1, -1]
        inner = c.knots[p + 1 : -(p + 1)] - a + offset
        knots.append(([offset] * (p + 1) if k == 0 else [offset] * p) + list(inner))
        m = param_map(curves[k])
        maps.append(m.shifted(xoffset - m.x[0], offset - a))
        xoffset += m.x[-1] - m.x[0]
        offset += b - a
    knots.append([offset] * (p + 1))
    return from_homogeneous(
        p, np.concatenate([np.asarray(k, float) for k in knots]), np.concatenate(ctrl), concat_maps(maps)
    )


def affine(c: TrimCurve, matrix: np.ndarray) -> TrimCurve:
    """Points mapped by an affine (d + 1) x (d + 1) matrix (weights unchanged: exact)."""
    d = c.dim
    m = np.asarray(matrix, float)
    return replace(c, points=c.points @ m[:d, :d].T + m[:d, d])


def with_points(c: TrimCurve, points: np.ndarray) -> TrimCurve:
    return replace(c, points=np.asarray(points, float))


def product_segments(f: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Product of Bezier polynomials: f (p + 1, k) componentwise times g (q + 1,) -> (p + q + 1, k)."""
    p, q = f.shape[0] - 1, g.shape[0] - 1
    out = np.zeros((p + q + 1, f.shape[1]))
    for i in range(p + 1):
        for j in range(q + 1):
            out[i + j] += math.comb(p, i) * math.comb(q, j) / math.comb(p + q, i + j) * f[i] * g[j]
    return out


def common_breaks(curves: list[TrimCurve]):
    """Bezier segments of several curves with equal domains, split at all their breakpoints.

    Returns (breaks (k + 1,), [segments (k, p_i + 1, d_i + 1)])."""
    breaks = np.unique(np.concatenate([np.unique(clamp(c).knots) for c in curves]))
    out = []
    for c in curves:
        cc = clamp(c)
        knots, ctrl = cc.knots, cc.homogeneous()
        p = cc.degree
        for x in breaks[1:-1]:
            while np.count_nonzero(knots == x) < p:
                knots, ctrl = insert_knot(knots, ctrl, p, x)
        out.append(np.stack([ctrl[i * p : i * p + p + 1] for i in range(len(breaks) - 1)]))
    return breaks, out


def reparametrised(c: TrimCurve, a: float, b: float) -> TrimCurve:
    """The same curve on the parameter range [a, b] (an affine change of parameter)."""
    lo, hi = c.domain
    scale = (b - a) / (hi - lo)
    knots = a + (c.knots - lo) * scale
    m = param_map(c)
    pmap = ParamMap(m.x, a + (m.s - lo) * scale, m.kinds, unit=m.unit)
    return TrimCurve(c.degree, knots, c.points, c.weights, pmap)


# ---------------------------------------------------------------------------
# Conics


def unit_arc(a0: float, a1: float, hyperbolic: bool = False):
    """The unit circle (cos x, sin x) (or hyperbola (cosh x, sinh x)) for x in [a0, a1].

    Returns (knots, points (n, 2), weights (n,), pmap): rational quadratic
    pieces of span at most pi/2 (hyperbola: at most 1) with knots at the piece
    ends' x values, so the B-spline parameter equals x at every knot.
    """
    span = a1 - a0
    limit = 1.0 if hyperbolic else math.pi / 2
    k = max(1, math.ceil(span / limit - 1e-9))
    xs = a0 + span * np.arange(k + 1) / k
    xs[-1] = a1
    d = span / k
    c, s = (np.cosh, np.sinh) if hyperbolic else (np.cos, np.sin)
    wmid = math.cosh(d / 2) if hyperbolic else math.cos(d / 2)
    pts, w = [], []
    for i in range(k):
        if i == 0:
            pts.append([c(xs[0]), s(xs[0])])
            w.append(1.0)
        m = 0.5 * (xs[i] + xs[i + 1])
        pts.append([c(m) / wmid, s(m) / wmid])
        w.append(wmid)
        pts.append([c(xs[i + 1]), s(xs[i + 1])])
        w.append(1.0)
    knots = np.concatenate([[a0] * 3] + [[x] * 2 for x in xs[1:-1]] + [[a1] * 3])
    pmap = ParamMap(xs.copy(), xs.copy(), ("tanh" if hyperbolic else "tan",) * k)
    return knots, np.array(pts, float), np.array(w, float), pmap


def arc_curve(center, e1, e2, r1: float, r2: float, a0: float, a1: float, hyperbolic: bool = False) -> TrimCurve:
    """center + r1 c(x) e1 + r2 s(x) e2 for x in [a0, a1] (circle, ellipse, hyperbola branch) exactly."""
    knots, uv, w, pmap = unit_arc(a0, a1, hyperbolic)
    center, e1, e2 = (np.asarray(v, float) for v in (center, e1, e2))
    pts = center + (r1 * uv[:, :1]) * e1 + (r2 * uv[:, 1:]) * e2
    return TrimCurve(2, knots, pts, w, pmap)


def line_curve(p0, p1, t0: float = 0.0, t1: float = 1.0) -> TrimCurve:
    """The segment p0 -> p1 on the parameter range [t0, t1]."""
    return TrimCurve(1, np.array([t0, t0, t1, t1], float), np.array([p0, p1], float))


def polyline_curve(points) -> TrimCurve:
    """Degree-1 curve through points (n, d), parameter = point index (consecutive repeats dropped)."""
    pts = np.asarray(points, float)
    keep = np.concatenate([[True], np.any(pts[1:] != pts[:-1], axis=1)])
    pts = pts[keep]
    if len(pts) == 1:
        pts = np.concatenate([pts, pts])
    n = len(pts)
    knots = np.concatenate([[0.0], np.arange(n, dtype=float), [n - 1.0]])
    return TrimCurve(1, knots, pts)
