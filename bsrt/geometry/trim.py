"""Trim loops: closed 2-D B-spline curves in a surface's own (u, v) domain.

A trimmed surface shows only the points (u, v) inside its loops by the
even-odd rule: (u, v) is kept where a ray from it in the parameter plane
crosses the loops an odd number of times. So an outer loop with holes,
nested islands and loops of either orientation all work, and a surface with
no loop is whole.

This module holds the data (:class:`TrimCurve`, :class:`TrimLoop`), their
validation (:func:`make_trim_curve`, :func:`check_loops`: every error names
the loop and the curve), and the preparation for the compiled test "is
(u, v) kept?" (:func:`bsrt.geometry.trim_table.build_trim_table`; the tests themselves, ``point_kept``
and ``rect_state``, are in ``kernels/trim.py``; :func:`bsrt.geometry.trim_table.kept` is the
Python-level convenience).

The algorithm
-------------
Preparation (once per scene). Every curve is cut into its rational Bezier
spans (each span's net is the blossom at (a..a, b..b): the same as inserting
every knot to full multiplicity), and each span is cut further (de
Casteljau, in homogeneous coordinates) until its control polygon is monotone
in u and in v: at the turning point of the coordinate that turns back (the
root of its slope, found by bisection) when the end slopes show one, else
at the middle. Steps of the polygon within 64 ulps of the coordinates count
as flat, so the cut at a turning point settles at once. A net that is one
point is dropped (it crosses nothing); a piece still turning back after
MAX_DEPTH cuts (met in none of the test models: their curves give 1.0 to
1.1 pieces per span) is replaced by its chord. Consecutive pieces of a loop share their end
points bit for bit: each piece's start is set to the previous piece's end
(this also closes the gaps, up to 1e-9 of the domain, that check_loops lets
through between curves). Each piece is stored in the power basis of its
parameter s in [0, 1], in coordinates relative to its start (so rounding is
relative to the piece, not to the domain). Per trimmed surface, horizontal
bands over v (two per piece, at most MAX_BANDS) list the pieces whose box
meets them, each band sorted by decreasing u_max: a query reads a few
entries whatever the loops' size.

The query (``kernels/trim.point_kept``): a ray from (u, v) toward +u. A
piece counts when v lies in its half-open v-range
[min(v_a, v_b), max(v_a, v_b)) and its crossing lies right of u. The band
scan stops at the first piece wholly left of u; a piece wholly right of u
counts at once; a piece whose end points lie on one side of u is decided by
them; a segment (degree 1) by one cross product; any other piece by solving
V(s) = v on the curve itself (Newton steps kept in a bracket, with
bisection), only as far as needed to see on which side of u the crossing
lies: the bracket's two ends on one side of u decide, since U is monotone.

Why it is exact at the curve. With positive weights a rational Bezier
curve crosses any line no more often than its control polygon (variation
diminishing: the numerator of X(s) - c has the Bernstein coefficients
w_i (x_i - c)), so a piece with a monotone polygon is itself monotone in u
and v: the line v = const meets it at most once, and its part between two
parameters lies in the box of their two points. Counting a piece when v is
in its half-open end range gives the parity of its crossings with the whole
line exactly (a continuous arc from v_a to v_b crosses v = c an odd number
of times iff c lies between them), with no tolerance, and the shared end
points make the count consistent from piece to piece (a ray through a
vertex counts it once where the loop passes through, and 0 or 2 times at a
turning point). Which side of u the single crossing lies on is decided
with the monotone curve's own values, so the only wrong answers are for
points within rounding (about 1e-15 of the coordinates) of the curve. No
rasterised mask, no polyline.

``rect_state`` (culling): a rectangle that no piece can touch (its box
misses it, or halving the monotone piece shows it passes by; both with a
margin of 1e-12 of the coordinates) holds one state, its centre's;
otherwise it is MIXED.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

from bsrt.errors import InputError
from bsrt.geometry.basis import basis_functions, basis_values, find_span, insert_knot, span_matrices

CLOSE_TOLERANCE = 1e-9  # loop gaps allowed, as a fraction of the domain's size
DOMAIN_TOLERANCE = 1e-5  # how far a curve may stray outside the domain, as a fraction of its size


@dataclass(frozen=True, eq=False)
class TrimCurve:
    """A (rational) B-spline curve: a curve of a trim loop, and the one curve type of the readers.

    degree: p >= 1. knots: (n + p + 1,) float64, non-decreasing.
    points: (n, d) float64: in a trim loop d = 2, (u, v) in the surface's knot
      domain; a reader's model-space curve has d = 3.
    weights: (n,) float64, all > 0, or None (non-rational).
    pmap: how the file's own parameter of the curve maps onto this one's (a
      reader's :class:`bsrt.io.param_map.ParamMap`: an IGES arc's angle), or
      None where they are equal (every curve of a trim loop).
    """

    degree: int
    knots: np.ndarray
    points: np.ndarray
    weights: np.ndarray | None = None
    pmap: object | None = None

    @property
    def n(self) -> int:
        """The number of control points."""
        return self.points.shape[0]

    @property
    def dim(self) -> int:
        """d, the number of coordinates of a point."""
        return self.points.shape[1]

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[self.degree]), float(self.knots[self.points.shape[0]])

    def homogeneous(self) -> np.ndarray:
        """(n, d + 1) float64: (w x, ..., w)."""
        w = np.ones(self.points.shape[0]) if self.weights is None else self.weights
        return np.concatenate([self.points * w[:, None], w[:, None]], axis=1)

    def evaluate(self, s, derivative: bool = False):
        """(N, d) points at curve parameters s (N,); with derivative=True also d/ds (N, d).

        The readers' and the trims' one curve evaluator (outside the domain the end spans extend)."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        p, n = self.degree, self.points.shape[0]
        if not derivative:  # the values alone: the same triangle, without the derivatives' work
            span, basis = basis_values(self.knots, p, n, s)
            index = (span - p)[:, None] + np.arange(p + 1)[None, :]
            if self.weights is None:  # (the basis sums to 1 only to rounding: no division)
                return np.einsum("na,nak->nk", basis, self.points[index])
            h = np.einsum("na,nak->nk", basis, self.homogeneous()[index])
            return h[:, :-1] / h[:, -1:]
        span = find_span(self.knots, p, n, s)
        basis, dbasis = basis_functions(self.knots, p, span, s)
        ctrl = self.homogeneous()[(span - p)[:, None] + np.arange(p + 1)[None, :]]  # (N, p+1, d + 1)
        h = np.einsum("na,nak->nk", basis, ctrl)
        dh = np.einsum("na,nak->nk", dbasis, ctrl)
        pts = h[:, :-1] / h[:, -1:]
        return pts, (dh[:, :-1] - pts * dh[:, -1:]) / h[:, -1:]

    def evaluator(self):
        """s (N,) -> (N, d) points, for many calls on one curve: of degree >= 4 through its Bezier
        pieces (extracted once; then a handful of NumPy calls per call whatever the degree), else
        :meth:`evaluate`. Equal to :meth:`evaluate` to rounding, not bit for bit."""
        p = self.degree
        if p < 4:
            return self.evaluate
        bezier, spans = self.bezier_nets()
        starts, ends = self.knots[spans], self.knots[spans + 1]
        powers = np.arange(p + 1)
        binomials = np.array([comb(p, int(k)) for k in powers], dtype=np.float64)

        def points(s) -> np.ndarray:
            s = np.atleast_1d(np.asarray(s, dtype=np.float64))
            k = np.minimum(np.maximum(np.searchsorted(starts, s, side="right") - 1, 0), starts.size - 1)
            x = ((s - starts[k]) / (ends[k] - starts[k]))[:, None]
            h = np.einsum("nk,nkc->nc", binomials * x**powers * (1.0 - x) ** (p - powers), bezier[k])
            return h[:, :-1] / h[:, -1:]

        return points

    def bezier_nets(self) -> tuple[np.ndarray, np.ndarray]:
        """(nets (S, p + 1, d + 1), spans (S,)): the homogeneous Bezier net of each non-empty span
        [knots[spans[s]], knots[spans[s] + 1]], all at once (Bezier extraction)."""
        p = self.degree
        matrices, spans = span_matrices(self.knots, self.points.shape[0], p)
        window = spans[:, None] - p + np.arange(p + 1)[None, :]
        return np.einsum("skj,sjc->skc", matrices, self.homogeneous()[window]), spans

    def ends(self) -> np.ndarray:
        """(2, d): the curve's first and last point."""
        p, k = self.degree, self.knots
        if k[0] == k[p] and k[-1] == k[-1 - p]:  # clamped: the end control points (n >= 2: a slice)
            return self.points[:: self.points.shape[0] - 1].copy()
        return self.evaluate(np.array(self.domain))


class CurveSet:
    """Many curves evaluated together, bit for bit as :meth:`TrimCurve.evaluate` evaluates each,
    with a few NumPy calls per degree present instead of a dozen per curve (the IGES reader
    carries hundreds of short curves a few points each). Per degree: the curves' knot vectors
    end to end (K,), and beside curve c's knot k0_c + j its homogeneous control point j ((K, d + 1),
    weight 1 where it has none)."""

    def __init__(self, curves):
        self.curves = curves
        self.groups = []  # (degree, curve indices, knots (K,), table (K, d + 1), first knot per curve)
        for p in sorted({c.degree for c in curves}):
            ks = [k for k, c in enumerate(curves) if c.degree == p]
            knots = np.concatenate([curves[k].knots for k in ks])
            table = np.zeros((knots.shape[0], curves[0].points.shape[1] + 1))
            first = np.cumsum([0] + [curves[k].knots.shape[0] for k in ks])
            for k, k0 in zip(ks, first):
                table[k0 : k0 + curves[k].points.shape[0]] = curves[k].homogeneous()
            self.groups.append((p, ks, knots, table, first))
        self.rational = np.array([c.weights is not None for c in curves])

    def __call__(self, s, which) -> np.ndarray:
        """(N, d): curve which[i] at s[i] (s, which (N,))."""
        s = np.asarray(s, dtype=np.float64)
        which = np.asarray(which, dtype=np.int64)
        out = np.empty((s.shape[0], self.groups[0][3].shape[1] - 1))
        order = np.argsort(which, kind="stable")
        cut = np.searchsorted(which[order], np.arange(len(self.curves) + 1))
        for p, ks, knots, table, first in self.groups:
            rows = np.concatenate([order[cut[k] : cut[k + 1]] for k in ks])
            if rows.size == 0:
                continue
            span, at = np.empty(rows.size, np.int64), 0
            for k, k0 in zip(ks, first):  # each curve's spans, as basis_values finds them
                c, m = self.curves[k], cut[k + 1] - cut[k]
                local = np.searchsorted(c.knots, s[rows[at : at + m]], side="right") - 1
                span[at : at + m] = np.minimum(np.maximum(local, p), c.points.shape[0] - 1) + k0
                at += m
            span, vals = basis_values(knots, p, 0, s[rows], span)
            h = np.einsum("na,nak->nk", vals, table[(span - p)[:, None] + np.arange(p + 1)[None, :]])
            pts, rational = h[:, :-1], self.rational[which[rows]]
            pts[rational] /= h[rational, -1:]  # (the basis sums to 1 only to rounding: no division)
            out[rows] = pts
        return out


@dataclass(frozen=True, eq=False)
class TrimLoop:
    """A closed loop: curves end to end, the last ending where the first starts."""

    curves: tuple[TrimCurve, ...]


def make_trim_curve(degree, knots, points, weights=None) -> TrimCurve:
    """Validate and build a :class:`TrimCurve`; InputError messages start with the key."""
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
        raise InputError(f"degree: expected a whole number >= 1, got {degree!r}")
    p = int(degree)
    if p < 1:
        raise InputError(f"degree: must be >= 1, got {p}")
    pts = _numbers("points", points, 2)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InputError(f"points: expected a list of [u, v] pairs, got an array of shape {pts.shape}")
    n = pts.shape[0]
    if n < p + 1:
        raise InputError(f"points: degree {p} needs at least {p + 1} points, got {n}")
    if not np.all(np.isfinite(pts)):
        raise InputError(f"points: point {int(np.argwhere(~np.isfinite(pts))[0, 0])} has a non-finite coordinate")
    k = _numbers("knots", knots, 1)
    if k.ndim != 1 or k.size != n + p + 1:
        raise InputError(f"knots: expected {n + p + 1} values ({n} points + degree {p} + 1), got {k.size}")
    if not np.all(np.isfinite(k)) or np.any(np.diff(k) < 0):
        raise InputError("knots: expected finite, non-decreasing numbers")
    if not k[p] < k[n]:
        raise InputError(f"knots: the curve's domain [{k[p]:g}, {k[n]:g}] is empty")
    inner = k[(k > k[p]) & (k < k[n])]  # sorted: a value repeated more than p times equals the one p further on
    if inner.size > p and np.any(inner[p:] == inner[:-p]):
        raise InputError(f"knots: an interior knot is repeated more than the degree {p}")
    w = None
    if weights is not None:
        w = _numbers("weights", weights, 1)
        if w.shape != (n,):
            raise InputError(f"weights: expected {n} values (one per point), got {w.size}")
        if not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise InputError("weights: every weight must be a finite number > 0")
        if np.all(w == 1.0):
            w = None
    for a in (k, pts) + (() if w is None else (w,)):
        a.setflags(write=False)
    return TrimCurve(p, k, pts, w)


def _numbers(key: str, values, dims: int) -> np.ndarray:
    """float64 array of nested lists of numbers (booleans and strings refused)."""

    def check(x, depth):
        if isinstance(x, (list, tuple, np.ndarray)):
            for y in x:
                check(y, depth + 1)
        elif isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
            raise InputError(f"{key}: expected numbers, got {x!r}")

    if not isinstance(values, np.ndarray):
        check(values, 0)
    try:
        return np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{key}: expected {'a list of numbers' if dims == 1 else 'a list of [u, v] pairs'}") from None


def check_loops(loops, domain) -> tuple[TrimLoop, ...]:
    """Check that every loop closes and lies in the surface's domain.

    loops: sequence of TrimLoop. domain: (umin, umax, vmin, vmax). Gaps up to
    CLOSE_TOLERANCE x the domain's diagonal are allowed. A curve may stray
    outside the domain by up to DOMAIN_TOLERANCE x its diagonal: CAD files'
    trim curves do (hammer.iges by 2e-6), and it is harmless, as the even-odd
    rule reads the loops wherever they run; the check is there for curves
    in the wrong domain. It is exact: a curve whose control points lie in the
    domain lies in it (convex hull); otherwise :func:`point_outside` decides.
    Errors name ``trim[i].curves[j]``.
    """
    umin, umax, vmin, vmax = domain
    size = float(np.hypot(umax - umin, vmax - vmin))
    gap = CLOSE_TOLERANCE * size
    slack = DOMAIN_TOLERANCE * size
    for i, loop in enumerate(loops):
        if not loop.curves:
            raise InputError(f"trim[{i}].curves: a loop needs at least one curve")
        ends = [c.ends() for c in loop.curves]
        if _loop_fine(loop, ends, gap, (umin - slack, umax + slack, vmin - slack, vmax + slack)):
            continue
        for j, (curve, e) in enumerate(zip(loop.curves, ends)):
            prev = ends[j - 1][1]
            if np.hypot(*(e[0] - prev)) > gap:
                if j == 0:
                    what = "the last curve ends" if len(ends) > 1 else "it ends"
                    raise InputError(
                        f"trim[{i}].curves[{j}]: the loop is open: the curve starts at "
                        f"({e[0][0]:g}, {e[0][1]:g}) but {what} at ({prev[0]:g}, {prev[1]:g})"
                    )
                raise InputError(
                    f"trim[{i}].curves[{j}]: the loop is open: the curve starts at "
                    f"({e[0][0]:g}, {e[0][1]:g}), not where curves[{j - 1}] ends "
                    f"({prev[0]:g}, {prev[1]:g})"
                )
            pts = curve.points
            if not _all_within(pts, umin - slack, umax + slack, vmin - slack, vmax + slack):
                far = point_outside(curve, (umin - slack, umax + slack, vmin - slack, vmax + slack))
                if far is not None:
                    raise InputError(
                        f"trim[{i}].curves[{j}]: the curve leaves the surface's domain [{umin:g}, {umax:g}] x "
                        f"[{vmin:g}, {vmax:g}] (it passes ({far[0]:g}, {far[1]:g}))"
                    )
    return tuple(loops)


def _loop_fine(loop: TrimLoop, ends: list[np.ndarray], gap: float, box) -> bool:
    """Whether check_loops' tests pass for the whole loop, tested at once (False: the curve by curve
    tests decide, and name the curve). ends: each curve's (2, 2) ends."""
    e = np.stack(ends)  # (m, 2, 2)
    d = e[:, 0] - np.concatenate([e[-1:, 1], e[:-1, 1]])  # each start minus the previous curve's end
    if (np.hypot(d[:, 0], d[:, 1]) > gap).any():
        return False
    pts = np.concatenate([c.points for c in loop.curves]) if len(loop.curves) > 1 else loop.curves[0].points
    return _all_within(pts, *box) or all(
        _all_within(c.points, *box) or point_outside(c, box) is None for c in loop.curves
    )


def _all_within(pts: np.ndarray, u0: float, u1: float, v0: float, v1: float) -> bool:
    return bool(np.all((pts[:, 0] >= u0) & (pts[:, 0] <= u1) & (pts[:, 1] >= v0) & (pts[:, 1] <= v1)))


def _writable(a) -> np.ndarray:
    """A C-contiguous, writable float64 copy: the kernels see one array type (numba compiles
    read-only arrays, like make_trim_curve's, separately)."""
    return np.array(a, dtype=np.float64, order="C")


def point_outside(curve: TrimCurve, box) -> np.ndarray | None:
    """A point (2,) of the curve outside ``box`` (u0, u1, v0, v1), or None if the curve lies inside it.

    Exact, in NumPy: the curve's rational Bezier spans are halved (de
    Casteljau, all at once) until each control polygon lies inside the box
    (then the span does: convex hull, positive weights) or has a point of the
    curve itself (an end) outside it; a quadratic span (a conic: a circle
    touching the box, which halving would only approach) is decided by its
    own extremes (:func:`_quadratic_inside`); spans still undecided after 30
    halvings (within 1e-9 of their length of the box's edge) count as inside.
    """
    u0, u1, v0, v1 = box
    p = curve.degree
    knots, ctrl = curve.knots, curve.homogeneous()
    inner = knots[p + 1 : -p - 1]
    if inner.size % p or np.any(inner[::p] != inner[p - 1 :: p]):  # not Bezier spans already: made so
        for x in np.unique(inner):
            for _ in range(p - int(np.count_nonzero(knots == x))):
                knots, ctrl = insert_knot(knots, ctrl, p, x)
    nets = ctrl[p * np.arange((ctrl.shape[0] - 1) // p)[:, None] + np.arange(p + 1)[None, :]]  # (S, p + 1, 3)
    low, high = np.array([u0, v0], dtype=np.float64), np.array([u1, v1], dtype=np.float64)
    for _ in range(30):
        xy = nets[..., :2] / nets[..., 2:3]
        out = ((xy < low) | (xy > high)).any(axis=2)  # (S, p + 1): the control point is outside the box
        ends = out[:, ::p]  # (S, 2): the first and the last (points of the curve itself)
        if ends.any():
            span, end = np.argwhere(ends)[0]
            return xy[span, 0 if end == 0 else -1].copy()
        keep = out.any(axis=1)
        if p == 2:  # a conic span: the curve itself may be shown inside at once (a circle touching the box)
            keep &= ~_quadratic_inside(nets, u0, u1, v0, v1)
        if not keep.all():
            nets = nets[keep]
        if nets.shape[0] == 0:
            return None
        halves = np.empty((2, nets.shape[0], p + 1, 3))  # de Casteljau at 1/2: the left and right halves
        halves[0, :, 0], halves[1, :, p] = nets[:, 0], nets[:, -1]
        level = nets
        for r in range(1, p + 1):
            level = 0.5 * (level[:, :-1] + level[:, 1:])
            halves[0, :, r], halves[1, :, p - r] = level[:, 0], level[:, -1]
        nets = halves.reshape(-1, p + 1, 3)
    return None


def _quadratic_inside(nets: np.ndarray, u0: float, u1: float, v0: float, v1: float) -> np.ndarray:
    """(S,) bool: the rational quadratic spans (S, 3, 3) (homogeneous nets) whose ends lie in the box
    that lie wholly in it. Against each edge line x = c the curve's side is the sign of the quadratic
    q(t) = sum a_i B_i(t), a_i = w_i (x_i - c) (positive weights); with a_0, a_2 <= 0 (the ends inside)
    its largest value on [0, 1] is <= 0 exactly when a_1 <= 0 or a_1^2 <= a_0 a_2."""
    inside = np.ones(nets.shape[0], dtype=bool)
    w = nets[:, :, 2]
    for axis, c, sign in ((0, u0, -1.0), (0, u1, 1.0), (1, v0, -1.0), (1, v1, 1.0)):
        a = sign * (nets[:, :, axis] - c * w)  # (S, 3): <= 0 at a point inside, on this edge's side
        inside &= (a[:, 1] <= 0) | (a[:, 1] * a[:, 1] <= a[:, 0] * a[:, 2])
    return inside
