"""IGES 118 ruled surfaces as NURBS whose rulings join the points the standard pairs (issue 22).

S(u, v) = (1 - v) C1(t1(u)) + v C2(t2(u)), u and v in [0, 1] (IGES 5.3, 4.12; DIRFLG 1 has
reversed C2 already). Form 1 pairs points of equal relative parametric value: t_i runs
affinely over the curve's own IGES parameter (an arc's angle, a line's [0, 1], a spline's
range, a composite's ranges one after the other: the curve's ``pmap``). Form 0 pairs points
of equal relative arc length, the same pairing on a curve of constant speed in its parameter
(lines, circular arcs: checked numerically, not by type).

* When the two pairings are proportional in the two B-splines' own parameters (lines,
  polylines and splines in form 1, arcs of equal span, a constant-speed curve with itself),
  the surface is exact: the curves on one parameter, rational ones brought onto the common
  denominator W1 W2 so that v stays linear.
* Otherwise (an arc paired by angle with a line or a spline, arcs of different spans, arc
  length along a spline or an ellipse) the pairing is not a NURBS. One curve, the master, is
  kept exact: one whose pairing has a closed form (an arc rather than a line), else none (two
  arc-length pairings: the surface's u is the arc length fraction itself). The other curve
  (or both, without a master) is fitted on the master's knots and weights: Bezier pieces of
  degree ``FIT_DEGREE`` (the master raised to it) interpolating the exactly paired points at
  Chebyshev-Lobatto nodes, each piece halved until the fitted curve is within
  ``RULED_TOLERANCE`` x the surface's size (the box diagonal of the two curves' control points)
  of the paired points at ``CHECKS`` points per piece besides the nodes. So every point S(u, v) is within
  that bound of the exact ruled surface's point at the same (u, v), a ruling's ends on the
  curves' exact points. A line or polyline fitted this way stays on its line (its control
  points are affine combinations of the line's points); the surface is C0 at the fitted pieces'
  ends (its tangents continuous there only as nearly as the fit allows).

The u map (the IGES u in [0, 1] to the B-spline's) is the master's pairing (affine, or the
rational arc's closed form), or the identity.

OpenCASCADE pairs differently: a conic by the B-spline parameter of its ``Convert_RationalC1``
form, not its angle, and form 0 like form 1; its surfaces differ from these where an arc is
ruled to a line (up to 1.1e-5 of the part's size on pyIGES nentity.igs).
"""

from __future__ import annotations

from math import comb

import numpy as np

from bsrt.geometry.bspline import BSplineSurface, make_surface
from bsrt.geometry.trim import TrimCurve
from bsrt.io.iges.bspline import (
    bezier_segments,
    clamp,
    common_breaks,
    elevate,
    from_bezier,
    param_map,
    product_segments,
    reparametrised,
    restrict,
)
from bsrt.io.param_map import ParamMap, chebyshev_lobatto

RULED_TOLERANCE = 1e-10  # fitted rulings: the largest deviation, as a fraction of the surface's size
FIT_DEGREE = 8  # the degree of a fitted surface along u: few pieces (the ray hierarchy is slow on many thin ones)
CHECKS = 24  # points per fitted piece where the deviation is measured, besides the interpolated nodes
MAX_PIECES = 4096  # fitted Bezier pieces at most
_SAMPLES = 65  # u values where pairings are compared (proportional? constant speed?)
_GAUSS = np.polynomial.legendre.leggauss(16)  # arc length: Gauss-Legendre per eighth of a Bezier span


class RuledError(Exception):
    """The ruled surface cannot be built within the bound (the message says why)."""


class _Pairing:
    """The B-spline parameter t(u) (N,) -> (N,) of the point the standard pairs with u in [0, 1].

    umap: the same as a ParamMap when it has a closed form (form 1, or a constant-speed curve),
    else None (arc length, numerically). breaks: (K,) the u of the curve's Bezier breakpoints."""

    def __init__(self, c: TrimCurve, form: int):
        self.curve = c
        pm = param_map(c)
        x0, x1 = float(pm.x[0]), float(pm.x[-1])
        self.umap = pm.scaled_x(x1 - x0, x0)
        self.length = None
        if form == 0 and not _constant_speed(c, pm):
            self.umap, self.length = None, _ArcLength(c)
        self.breaks = self.inverse(np.unique(c.knots[c.degree : c.n + 1]))

    def __call__(self, u) -> np.ndarray:
        return self.umap(u) if self.umap is not None else self.length.parameter(u)

    def inverse(self, t) -> np.ndarray:
        return self.umap.inverse(t) if self.umap is not None else self.length.fraction(t)

    @property
    def affine(self) -> bool:
        return self.umap is not None and self.umap.affine_on(0.0, 1.0) is not None


def _constant_speed(c: TrimCurve, pm: ParamMap) -> bool:
    """Whether |dC/dx| is the same (to 1e-12) along the curve, x its IGES parameter (or it is a point)."""
    x = np.linspace(pm.x[0], pm.x[-1], _SAMPLES)
    speed = np.linalg.norm(c.evaluate(pm(x), derivative=True)[1], axis=1) * pm.derivative(x)
    return bool(np.ptp(speed) <= 1e-12 * speed.max()) or not speed.max() > 0


class _ArcLength:
    """Arc length along a curve: Gauss-Legendre on eighths of its Bezier spans, inverted by Newton."""

    def __init__(self, c: TrimCurve):
        self.curve = c
        b = np.unique(c.knots[c.degree : c.n + 1])
        self.grid = np.concatenate([np.linspace(lo, hi, 9)[:-1] for lo, hi in zip(b[:-1], b[1:])] + [b[-1:]])
        self.cumulative = np.concatenate([[0.0], np.cumsum(self._integral(self.grid[:-1], self.grid[1:]))])
        self.total = self.cumulative[-1]
        if not self.total > 0:
            raise RuledError("a curve of a form 0 ruled surface has no length")

    def _speed(self, t: np.ndarray) -> np.ndarray:
        return np.linalg.norm(self.curve.evaluate(t, derivative=True)[1], axis=1)

    def _integral(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        x, w = _GAUSS
        half = 0.5 * (hi - lo)
        t = (0.5 * (hi + lo))[:, None] + half[:, None] * x[None, :]
        return half * (self._speed(t.ravel()).reshape(t.shape) @ w)

    def _cell(self, t: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self.grid, t, side="right") - 1, 0, len(self.grid) - 2)

    def _length(self, t: np.ndarray) -> np.ndarray:
        j = self._cell(t)
        return self.cumulative[j] + self._integral(self.grid[j], t)

    def fraction(self, t) -> np.ndarray:
        """u (N,): the arc length fraction at curve parameters t (N,)."""
        return self._length(np.atleast_1d(np.asarray(t, float))) / self.total

    def parameter(self, u) -> np.ndarray:
        """t (N,): the curve parameter at arc length fractions u (N,)."""
        target = np.clip(np.atleast_1d(np.asarray(u, float)), 0.0, 1.0) * self.total
        j = np.clip(np.searchsorted(self.cumulative, target, side="right") - 1, 0, len(self.grid) - 2)
        lo, hi = self.grid[j], self.grid[j + 1]
        step = self.cumulative[j + 1] - self.cumulative[j]
        t = lo + (hi - lo) * np.divide(target - self.cumulative[j], step, out=np.zeros_like(target), where=step > 0)
        for _ in range(8):
            speed = self._speed(t)
            t = np.clip(t - (self._length(t) - target) / np.maximum(speed, 1e-300), lo, hi)
        return t


def ruled(c1: TrimCurve, c2: TrimCurve, form: int) -> tuple[BSplineSurface, ParamMap, ParamMap]:
    """The ruled surface from c1 (v = 0) to c2 (v = 1) of an IGES 118 of the given form (0 or 1).

    Returns (surface, map_u, map_v): the maps take the IGES (u, v) in [0, 1] to the B-spline's.
    Raises RuledError where a fit needs more than ``MAX_PIECES`` pieces."""
    pairs = [_Pairing(clamp(c), form) for c in (c1, c2)]
    u = np.linspace(0.0, 1.0, _SAMPLES)
    if all(p.umap is not None for p in pairs):
        t = [p(u) for p in pairs]
        rel = [(x - x[0]) / (x[-1] - x[0]) for x in t]
        if np.abs(rel[0] - rel[1]).max() <= 1e-13:
            return _exact(*(p.curve for p in pairs))
    closed = [k for k, p in enumerate(pairs) if p.umap is not None]
    if len(closed) == 2:  # keep the one that is not affine (the arc): a line fitted stays on its line
        closed = [k for k in closed if not pairs[k].affine] or closed
    master = closed[0] if closed else None
    return _fitted(pairs, master)


def _exact(a: TrimCurve, b: TrimCurve):
    """Both curves on [0, 1] (their parameters scaled: the pairing is proportional in them)."""
    a, b = reparametrised(a, 0.0, 1.0), reparametrised(b, 0.0, 1.0)
    if a.weights is None and b.weights is None:
        p = max(a.degree, b.degree)
        breaks, rows = common_breaks([elevate(a, p), elevate(b, p)])
    else:
        breaks, (sa, sb) = common_breaks([a, b])
        rows = []
        for own, other in ((sa, sb), (sb, sa)):
            rows.append(np.stack([product_segments(own[k], other[k][:, -1]) for k in range(len(breaks) - 1)]))
    return _surface(breaks, rows), _Pairing(a, 1).umap, ParamMap.identity(0.0, 1.0)


def _fitted(pairs: list[_Pairing], master: int | None):
    """Fit the curves other than ``master`` (all without one) on the master's knots and weights."""
    if master is None:
        wmap, exact, n = ParamMap.identity(0.0, 1.0), None, FIT_DEGREE
        breaks = np.array([0.0, 1.0])
    else:
        exact = reparametrised(pairs[master].curve, 0.0, 1.0)
        wmap, n = _Pairing(exact, 1).umap, max(FIT_DEGREE, exact.degree)
        breaks = bezier_segments(exact)[0]
    fit = [k for k in range(2) if k != master]
    for k in fit:  # the fitted curves' own breakpoints (kinks), unless one is as good as there
        for x in wmap(np.clip(pairs[k].breaks, 0.0, 1.0)):
            if np.abs(breaks - x).min() > 1e-12:
                breaks = np.sort(np.append(breaks, x))
    size = float(np.linalg.norm(np.ptp(np.concatenate([p.curve.points for p in pairs]), axis=0)))
    tol = RULED_TOLERANCE * size
    nodes = chebyshev_lobatto(0.0, 1.0, n + 1)
    checks = (np.arange(CHECKS) + 0.5) / CHECKS
    todo, done = list(zip(breaks[:-1], breaks[1:])), []
    while todo:
        if len(done) + len(todo) > MAX_PIECES:
            raise RuledError(f"no fit of up to {MAX_PIECES} pieces is within {RULED_TOLERANCE:g} of its size")
        a, b = todo.pop()
        row = [None, None]
        if exact is not None:
            row[master] = _piece(exact, a, b, n)
        weights = np.ones(n + 1) if exact is None else row[master][:, -1]
        error = 0.0
        for k in fit:
            row[k], e = _fit_piece(pairs[k], wmap, a, b, weights, nodes, checks)
            error = max(error, e)
        if error > tol:
            m = 0.5 * (a + b)
            todo += [(m, b), (a, m)]
        else:
            done.append((a, b, row))
    done.sort(key=lambda x: x[0])
    scale = 1.0
    for k, (_, _, row) in enumerate(done):  # each piece's weights continue the previous one's
        if k:
            scale = done[k - 1][2][0][-1, -1] / row[0][0, -1]
        for r in row:
            r *= scale
    bk = np.array([x[0] for x in done] + [done[-1][1]])
    rows = [np.stack([x[2][k] for x in done]) for k in range(2)]
    return _surface(bk, rows), wmap, ParamMap.identity(0.0, 1.0)


def _piece(c: TrimCurve, a: float, b: float, n: int) -> np.ndarray:
    """(n + 1, 4): c's piece over [a, b] (inside one Bezier span) raised to degree n, homogeneous."""
    return elevate(restrict(c, a, b), n).homogeneous()


def _bernstein(n: int, t: np.ndarray) -> np.ndarray:
    """(N, n + 1): the degree-n Bernstein polynomials at t (N,)."""
    k = np.arange(n + 1)
    return np.array([comb(n, int(i)) for i in k]) * t[:, None] ** k * (1.0 - t[:, None]) ** (n - k)


def _fit_piece(pair: _Pairing, wmap: ParamMap, a, b, weights, nodes, checks):
    """(homogeneous control points (n + 1, 4), the largest deviation at the checks) of the curve's
    paired points over w in [a, b] with the given weights (n + 1,)."""
    n = len(weights) - 1

    def paired(t):
        w = a + (b - a) * t
        return pair.curve.evaluate(pair(wmap.inverse(w)))

    bn = _bernstein(n, nodes)
    wn = bn @ weights
    pts = paired(nodes)
    ctrl = np.linalg.solve(bn, pts * wn[:, None])
    ctrl[0], ctrl[-1] = pts[0] * weights[0], pts[-1] * weights[-1]  # the ends exact
    bc = _bernstein(n, checks)
    got = (bc @ ctrl) / (bc @ weights)[:, None]
    error = float(np.linalg.norm(got - paired(checks), axis=1).max())
    return np.concatenate([ctrl, weights[:, None]], axis=1), error


def _surface(breaks: np.ndarray, rows: list[np.ndarray]) -> BSplineSurface:
    """Degree (q, 1) from two rows of homogeneous Bezier segments (k, q + 1, 4) over breaks (k + 1,)."""
    curves = [from_bezier(breaks, r) for r in rows]  # (the same weights in both rows: the same scaling)
    h = np.stack([c.homogeneous() for c in curves], axis=1)
    w = h[..., 3]
    pts = h[..., :3] / w[..., None]
    return make_surface(
        (curves[0].degree, 1), curves[0].knots, [0, 0, 1, 1], pts, None if np.all(w == w.flat[0]) else w
    )
