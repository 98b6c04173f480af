"""Pcurves: an edge's curve on a face, as OpenCASCADE gives it, and mapped into the B-spline's domain.

``pcurve(edge, face)`` is the edge's 2-D curve in the original surface's
(u, v), converted exactly to a (rational) B-spline by ``Geom2dConvert`` over
the edge's range and reversed for a reversed edge, so the curves of a wire
run end to end. ``map_curve(curve, pmap, tolerance)`` carries it into the
converted B-spline's (x, y) through the face's :class:`~bsrt.io.param_map.FaceMap`:

* where both directions keep their parameter (up to a whole period), the
  control points move by the shift: exact;
* an iso-line (a seam, a cylinder's circle, a pole's degenerate edge) is
  the straight segment between its mapped ends: exact;
* any other curve is fitted, all at once (NumPy over every piece): pieces
  between the curve's knots and the parameters where it crosses the
  B-spline's knot lines (where the map's smoothness breaks), each a
  degree-7 polynomial through Chebyshev-Lobatto points of the mapped curve,
  halved until it is within ``tolerance`` (in (x, y), from the model-space
  tolerance and the B-spline's largest derivative) at 24 check points.
"""

from __future__ import annotations

from math import comb

import numpy as np

from bsrt.errors import InputError
from bsrt.geometry.bspline import BSplineSurface
from bsrt.geometry.trim import TrimCurve, make_trim_curve
from bsrt.io.occt.surfaces import flat_knots
from bsrt.io.param_map import FaceMap

FIT_DEGREE = 7
FIT_TOLERANCE = 1e-10  # fitted pcurves: largest 3-D error, as a fraction of the model's size
_MAX_ROUNDS = 24  # halvings of a fitted piece beyond its breaks (a safeguard)


class TrimError(Exception):
    """The face's wires do not make closed loops in the surface's domain (the reason is the message)."""


def pcurve(edge, face) -> TrimCurve | None:
    """The edge's curve on the face, in the original (u, v), along the edge's direction; None for an empty range."""
    occ = _occ()
    curve = occ.CurveOnSurface(edge, face, 0.0, 0.0)
    if curve is None:
        raise TrimError("an edge has no curve on the face")
    first, last = occ.Range(edge, face)
    if not first < last:
        return None
    reverse = edge.Orientation() == occ.REVERSED
    if type(curve) is occ.Line:
        # Geom2dConvert makes a line from first to last the degree-1 B-spline through its ends (poles
        # Value(first), Value(last), knots first, first, last, last): built here as it would be
        points = np.array([curve.Value(first).Coord(), curve.Value(last).Coord()])
        knots = np.array([first, first, last, last], dtype=np.float64)
        if reverse:
            points, knots = points[::-1].copy(), (knots[0] + knots[-1]) - knots[::-1]
        if np.isfinite(points.sum()):
            points.setflags(write=False)
            knots.setflags(write=False)
            return TrimCurve(1, knots, points)
    Geom2dConvert, Geom2d_TrimmedCurve = occ.Geom2dConvert, occ.TrimmedCurve
    try:
        bc = Geom2dConvert.CurveToBSplineCurve_s(Geom2d_TrimmedCurve(curve, first, last))
    except Exception as e:  # noqa: BLE001 - OCP raises Standard_Failure subclasses
        raise TrimError(f"OpenCASCADE cannot convert a {type(curve).__name__} pcurve ({e})") from None
    if bc.IsPeriodic():
        bc.SetNotPeriodic()
    n = bc.NbPoles()
    pole, weight = bc.Pole, bc.Weight
    points = np.array([pole(i).Coord() for i in range(1, n + 1)], dtype=np.float64).reshape(n, 2)
    weights = np.array(list(map(weight, range(1, n + 1))), dtype=np.float64) if bc.IsRational() else np.ones(n)
    knots = flat_knots(bc.Knot, bc.Multiplicity, bc.NbKnots())
    if reverse:
        points, weights, knots = points[::-1].copy(), weights[::-1].copy(), (knots[0] + knots[-1]) - knots[::-1]
    degree = bc.Degree()
    why = _invalid(degree, knots, points, weights)
    if why:  # make_trim_curve's checks decide (and give the message)
        try:
            return make_trim_curve(degree, knots, points, None if np.all(weights == 1.0) else weights)
        except InputError as e:
            raise TrimError(f"a pcurve is invalid ({e})") from None
    rational = bool(np.any(weights != 1.0))
    for a in (knots, points) + ((weights,) if rational else ()):
        a.setflags(write=False)
    return TrimCurve(degree, knots, points, weights if rational else None)


def _invalid(p: int, knots: np.ndarray, points: np.ndarray, weights: np.ndarray) -> str:
    """ "" when the pcurve passes make_trim_curve's checks (done here in a few NumPy calls), else
    roughly why not (make_trim_curve then decides, and says why)."""
    n = points.shape[0]
    if p < 1 or n < p + 1 or knots.size != n + p + 1:
        return "its degree, knots and points do not fit together"
    if not np.isfinite(points.sum() + knots.sum() + weights.sum()):  # (a sum that overflows: checked in full)
        return "a non-finite number"
    if (knots[1:] < knots[:-1]).any() or not knots[p] < knots[n] or weights.min() <= 0:
        return "decreasing knots, an empty domain or a weight <= 0"
    inner = knots[(knots > knots[p]) & (knots < knots[n])]
    if inner.size > p and np.any(inner[p:] == inner[:-p]):  # sorted: p + 1 equal values in a row
        return "an interior knot repeated more than the degree"
    return ""


_OCC = None


def _occ():
    """The OpenCASCADE names pcurve uses (imported once)."""
    global _OCC
    if _OCC is None:
        from types import SimpleNamespace

        from OCP.BRep import BRep_Tool
        from OCP.Geom2d import Geom2d_Line, Geom2d_TrimmedCurve
        from OCP.Geom2dConvert import Geom2dConvert
        from OCP.TopAbs import TopAbs_REVERSED

        _OCC = SimpleNamespace(
            CurveOnSurface=BRep_Tool.CurveOnSurface_s,
            Range=BRep_Tool.Range_s,
            Line=Geom2d_Line,
            TrimmedCurve=Geom2d_TrimmedCurve,
            Geom2dConvert=Geom2dConvert,
            REVERSED=TopAbs_REVERSED,
        )
    return _OCC


def bezier_form(curve: TrimCurve) -> TrimCurve:
    """The curve with every inner knot of multiplicity p, its control points its spans' Bezier nets
    (the same curve, to rounding; the curve itself where it is so already): what
    :func:`~bsrt.geometry.trim.point_outside` works on, made in a few NumPy calls (it would insert
    the knots one at a time)."""
    p, knots = curve.degree, curve.knots
    inner = knots[p + 1 : -p - 1]
    if inner.size % p == 0 and not np.any(inner[::p] != inner[p - 1 :: p]):
        return curve
    nets, spans = curve.bezier_nets()
    h = np.concatenate([nets[:1, 0], nets[:, 1:].reshape(-1, 3)])
    breaks = knots[spans[1:]]
    knots = np.concatenate(
        [np.full(p + 1, knots[spans[0]]), np.repeat(breaks, p), np.full(p + 1, knots[spans[-1] + 1])]
    )
    return TrimCurve(p, knots, h[:, :2] / h[:, 2:3], None if curve.weights is None else h[:, 2].copy())


def shifted(curve: TrimCurve, offset) -> TrimCurve:
    """The curve moved by ``offset`` (2,) in (u, v)."""
    du, dv = offset
    if not (du or dv):
        return curve
    return TrimCurve(curve.degree, curve.knots, curve.points + np.asarray(offset, dtype=np.float64), curve.weights)


_UNIT_KNOTS = np.array([0.0, 0.0, 1.0, 1.0])


def segment(a, b) -> TrimCurve:
    """The straight segment from a (2,) to b (2,)."""
    return TrimCurve(1, _UNIT_KNOTS, np.array([a, b], dtype=np.float64))


def reversed_curve(c: TrimCurve) -> TrimCurve:
    return TrimCurve(
        c.degree,
        (c.knots[0] + c.knots[-1]) - c.knots[::-1],
        c.points[::-1].copy(),
        None if c.weights is None else c.weights[::-1].copy(),
    )


def derivative_bounds(surface: BSplineSurface) -> tuple[float, float]:
    """Upper bounds of |dS/dx| and |dS/dy| over the surface (from its control net; generous for rational ones)."""
    out = []
    for axis in (0, 1):
        p = surface.degree[axis]
        knots = surface.knots_u if axis == 0 else surface.knots_v
        pts = np.moveaxis(surface.points, axis, 0)
        n = pts.shape[0]
        steps = knots[p + 1 : n + p] - knots[1:n]  # the support lengths of the derivative's control points / p
        diff = np.linalg.norm(np.diff(pts, axis=0), axis=-1).max(axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            rate = np.where(steps > 0, p * diff / np.where(steps > 0, steps, 1.0), 0.0)
        ratio = 1.0
        if surface.weights is not None:
            ratio = (surface.weights.max() / surface.weights.min()) ** 2
        out.append(float(rate.max(initial=0.0)) * ratio)
    return out[0], out[1]


def map_curve(curve: TrimCurve, pmap: FaceMap, tolerance) -> TrimCurve:
    """The pcurve (original (u, v)) as a curve in the B-spline's (x, y).

    tolerance: the largest error allowed in x and in y (a fitted curve's
    3-D error is at most their sum times the derivative bounds' part), as a
    pair of floats or a function of no arguments returning them (called only
    when the curve is fitted).
    """
    fu, fv = pmap.fu, pmap.fv
    if fu.kind == "identity" and fv.kind == "identity":
        return shifted(curve, (fu.shift, fv.shift))
    t0, t1 = curve.domain
    spans = (pmap.bounds[1] - pmap.bounds[0], pmap.bounds[3] - pmap.bounds[2])
    lows, highs = curve.points.min(axis=0).tolist(), curve.points.max(axis=0).tolist()
    for axis in (0, 1):  # an iso-line (axis fixed): a straight segment, exactly
        # read from the control points: a coordinate is constant exactly when all its control values are
        # (positive weights), and a monotone control polygon makes a monotone curve (variation diminishing)
        if highs[axis] - lows[axis] <= 1e-13 * spans[axis]:
            fixed, moving = curve.points[:, axis], curve.points[:, 1 - axis]
            steps = moving[1:] - moving[:-1]
            if (steps >= 0).all() or (steps <= 0).all():
                ends = curve.ends()
                ends[:, axis] = fixed.mean()
                return TrimCurve(1, _UNIT_KNOTS, pmap.map(ends))  # the segment between the mapped ends
    t = np.linspace(t0, t1, 17 + 8 * curve.points.shape[0])
    points = curve.evaluator()
    uv = points(t)
    breaks = [np.array([t0, t1]), np.unique(curve.knots[(curve.knots > t0) & (curve.knots < t1)])]
    for axis, fmap in ((0, fu), (1, fv)):
        if fmap.kind == "identity":
            continue
        values = uv[:, axis]
        lines = _break_lines(fmap, float(values.min()), float(values.max()))
        breaks.append(_crossings(points, axis, lines, t, values))
    return _fit(points, pmap, np.unique(np.concatenate(breaks)), tolerance() if callable(tolerance) else tolerance)


def _break_lines(fmap, lo: float, hi: float) -> np.ndarray:
    """The original parameters in [lo, hi] where f passes one of the B-spline's knots (its smoothness breaks)."""
    b = fmap.s
    if fmap.period > 0:
        first = np.floor((float(fmap(np.array([lo]))[0]) - b[0]) / fmap.period) - 1
        last = np.ceil((float(fmap(np.array([hi]))[0]) - b[0]) / fmap.period) + 1
        b = (b[None, :] + fmap.period * np.arange(first, last + 1)[:, None]).ravel()
    t = fmap.inverse(b)
    return t[(t > lo) & (t < hi)]


def _crossings(points, axis: int, lines: np.ndarray, t: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Curve parameters where coordinate ``axis`` equals one of ``lines`` (``points``: the curve's
    :meth:`TrimCurve.evaluator`; sign changes on the samples, then 24 halvings of each bracket, to 1e-7 of a
    sample step: they only help the fit converge (its error is checked), and the map is C1 at its
    breaks). One evaluation serves several halvings (8 for up to 2 crossings, 4 for up to 16, else
    2: 2^levels - 1 points a crossing): it takes the middles of every bracket they may reach (a
    tree, each middle 0.5 (lo + hi) of its bracket's ends, as one halving at a time would compute
    it), and the signs there choose the way down."""
    if lines.size == 0:
        return np.zeros(0)
    d = samples[:, None] - lines[None, :]  # (S, L)
    k, j = np.nonzero(d[:-1] * d[1:] < 0)
    exact = t[np.nonzero(d == 0)[0]]
    n = k.size
    if n == 0:
        return exact
    a, b, fa = t[k].tolist(), t[k + 1].tolist(), d[k, j].tolist()
    value = lines[j]
    levels = 8 if n <= 2 else 4 if n <= 16 else 2
    for _ in range(24 // levels):
        lo, hi = np.array([a]), np.array([b])  # (nodes of a level, n): the brackets
        middles = []
        for _ in range(levels):  # heap order: a node's halves are nodes 2 i + 1 (left) and 2 i + 2
            m = 0.5 * (lo + hi)
            middles.append(m)
            lo, hi = np.stack([lo, m], axis=1).reshape(-1, n), np.stack([m, hi], axis=1).reshape(-1, n)
        tree = np.concatenate(middles)  # (2^levels - 1, n)
        f = (points(tree.ravel())[:, axis].reshape(tree.shape) - value).T.tolist()  # (n, nodes)
        tree = tree.T.tolist()
        for i in range(n):
            node, ai, bi, fai, fi, ti = 0, a[i], b[i], fa[i], f[i], tree[i]
            for _ in range(levels):
                c, fc = ti[node], fi[node]
                if (fc < 0) == (fai < 0):  # the sign at c is a's: the crossing is in [c, b]
                    ai, fai, node = c, fc, 2 * node + 2
                else:
                    bi, node = c, 2 * node + 1
            a[i], b[i], fa[i] = ai, bi, fai
    return np.concatenate([0.5 * (np.array(a) + np.array(b)), exact])


def _bernstein(d: int, s: np.ndarray) -> np.ndarray:
    k = np.arange(d + 1)
    binom = np.array([comb(d, int(i)) for i in k], dtype=np.float64)
    return binom[None, :] * s[:, None] ** k[None, :] * (1 - s[:, None]) ** (d - k[None, :])


_NODES = 0.5 - 0.5 * np.cos(np.pi * np.arange(FIT_DEGREE + 1) / FIT_DEGREE)  # Chebyshev-Lobatto on [0, 1]
_SOLVE = np.linalg.inv(_bernstein(FIT_DEGREE, _NODES))  # control points from values at the nodes
_CHECKS = (np.arange(24) + 0.5) / 24
_AT_CHECKS = _bernstein(FIT_DEGREE, _CHECKS)


def _fit(points, pmap: FaceMap, breaks: np.ndarray, tolerance) -> TrimCurve:
    """Piecewise polynomial fit (degree 7, C0 at the breaks) of t -> map(curve(t)) (``points``: the
    curve's :meth:`TrimCurve.evaluator`)."""
    d = FIT_DEGREE
    todo = np.stack([breaks[:-1], breaks[1:]], axis=1)
    todo = todo[todo[:, 1] > todo[:, 0]]
    tol = np.asarray(tolerance, dtype=np.float64)
    length = breaks[-1] - breaks[0]
    done_a, done_b, done_ctrl = [], [], []
    for rounds in range(_MAX_ROUNDS + 1):
        if todo.shape[0] == 0:
            break
        a, b = todo[:, :1], todo[:, 1:]
        nodes = (a + (b - a) * _NODES).ravel()
        checks = (a + (b - a) * _CHECKS).ravel()
        mapped = pmap.map(points(np.concatenate([nodes, checks])))  # (one call each: point by point alike)
        values = mapped[: nodes.size].reshape(-1, d + 1, 2)
        ctrl = np.einsum("kn,pnc->pkc", _SOLVE, values)  # (P, d + 1, 2)
        want = mapped[nodes.size :].reshape(-1, _CHECKS.size, 2)
        got = np.einsum("sk,pkc->psc", _AT_CHECKS, ctrl)
        error = (np.abs(got - want) / tol).max(axis=(1, 2))
        good = (error <= 1.0) | (rounds == _MAX_ROUNDS) | ((b - a)[:, 0] <= 1e-12 * length)
        done_a.append(a[good, 0])
        done_b.append(b[good, 0])
        done_ctrl.append(ctrl[good])
        bad = todo[~good]
        mid = 0.5 * (bad[:, 0] + bad[:, 1])
        todo = np.concatenate([np.stack([bad[:, 0], mid], axis=1), np.stack([mid, bad[:, 1]], axis=1)])
    a = np.concatenate(done_a)
    b = np.concatenate(done_b)
    ctrl = np.concatenate(done_ctrl)
    order = np.argsort(a)
    a, b, ctrl = a[order], b[order], ctrl[order]
    ctrl[1:, 0] = ctrl[:-1, -1]  # C0 at the breaks, bit for bit
    points = np.concatenate([ctrl[:1, 0], ctrl[:, 1:].reshape(-1, 2)])
    knots = np.concatenate([np.full(d + 1, a[0]), np.repeat(b[:-1], d), np.full(d + 1, b[-1])])
    return TrimCurve(d, knots, points)
