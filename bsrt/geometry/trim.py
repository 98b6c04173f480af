"""Trim loops: closed 2-D B-spline curves in a surface's own (u, v) domain.

A trimmed surface shows only the points (u, v) inside its loops by the
even-odd rule: (u, v) is kept where a ray from it in the parameter plane
crosses the loops an odd number of times. So an outer loop with holes,
nested islands and loops of either orientation all work, and a surface with
no loop is whole.

This module holds the data (:class:`TrimCurve`, :class:`TrimLoop`), their
validation (:func:`make_trim_curve`, :func:`check_loops`: every error names
the loop and the curve), and the preparation for the compiled test "is
(u, v) kept?" (:func:`build_trim_table`; the tests themselves, ``point_kept``
and ``rect_state``, are in ``kernels/trim.py``; :func:`kept` is the
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
from typing import TYPE_CHECKING

import numpy as np

from bsrt.errors import InputError
from bsrt.geometry.basis import basis_functions, find_span, insert_knot

if TYPE_CHECKING:
    from bsrt.kernels.trim import TrimTable

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

    def evaluate(self, s) -> np.ndarray:
        """(N, d) points at curve parameters s (N,) (reference Cox-de Boor)."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        p, n = self.degree, self.points.shape[0]
        span = find_span(self.knots, p, n, s)
        basis, _ = basis_functions(self.knots, p, span, s)
        ctrl = self.homogeneous()[(span - p)[:, None] + np.arange(p + 1)[None, :]]  # (N, p+1, d + 1)
        h = np.einsum("na,nak->nk", basis, ctrl)
        return h[:, :-1] / h[:, -1:]

    def ends(self) -> np.ndarray:
        """(2, d): the curve's first and last point."""
        p, k = self.degree, self.knots
        if k[0] == k[p] and k[-1] == k[-1 - p]:  # clamped: the end control points (n >= 2: a slice)
            return self.points[:: self.points.shape[0] - 1].copy()
        return self.evaluate(np.array(self.domain))


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


# ---------------------------------------------------------------------------
# The table for the kernels

MAX_DEPTH = 48  # cuts of one Bezier span before a piece still turning back becomes its chord
BANDS_PER_PIECE = 2.0  # 1 to 4 measured within 10 % of each other; 2 the best on 200-piece loops
MAX_BANDS = 4096  # per surface


def build_trim_table(surfaces) -> TrimTable:
    """The TrimTable of a list of BSplineSurface (their ``trims``); surface m of the table is surfaces[m]."""
    from bsrt.kernels.trim import TrimTable
    from bsrt.kernels.trim_pieces import bezier_spans, monotone_pieces

    m_count = len(surfaces)
    trimmed = np.zeros(m_count, dtype=bool)
    nets, span_loop, span_surface = [], [], []
    loop_no = 0
    for m, surf in enumerate(surfaces):
        trimmed[m] = bool(surf.trims)
        for loop in surf.trims:
            for curve in loop.curves:
                x = bezier_spans(_writable(curve.knots), _writable(curve.homogeneous()), int(curve.degree))
                nets.append(x)
                span_loop.append(np.full(x.shape[0], loop_no, dtype=np.int64))
                span_surface.append(np.full(x.shape[0], m, dtype=np.int64))
            loop_no += 1
    width = max((x.shape[1] for x in nets), default=2)
    padded = np.zeros((sum(x.shape[0] for x in nets), width, 3))
    span_degree = np.zeros(padded.shape[0], dtype=np.int64)
    at = 0
    for x in nets:
        padded[at : at + x.shape[0], : x.shape[1]] = x
        span_degree[at : at + x.shape[0]] = x.shape[1] - 1
        at += x.shape[0]
    pieces, degree, src = monotone_pieces(padded, span_degree, MAX_DEPTH)
    loop = np.concatenate(span_loop)[src] if nets else np.zeros(0, dtype=np.int64)
    owner = np.concatenate(span_surface)[src] if nets else np.zeros(0, dtype=np.int64)
    k_count = degree.size
    idx = np.arange(k_count)

    # ends, chained: each piece starts exactly where the one before it in its loop ends
    last = pieces[idx, degree]
    end = last[:, :2] / last[:, 2:3]
    prev = idx - 1
    if k_count:
        first_of_loop = np.flatnonzero(np.r_[True, loop[1:] != loop[:-1]])
        prev[first_of_loop] = np.r_[first_of_loop[1:], k_count] - 1
    start = end[prev]
    ends = np.concatenate([start, end], axis=1)

    # control points relative to the start, then the power basis
    local = pieces.copy()
    local[..., 0] -= start[:, 0, None] * pieces[..., 2]
    local[..., 1] -= start[:, 1, None] * pieces[..., 2]
    coef = np.zeros_like(local)
    for d in np.unique(degree):
        sel = degree == d
        coef[sel, : d + 1] = np.einsum("kj,nkc->njc", _bernstein_to_power(int(d)), local[sel, : d + 1])

    used = np.arange(width)[None, :] <= degree[:, None]
    with np.errstate(all="ignore"):  # the padding rows have w = 0
        pts = pieces[..., :2] / pieces[..., 2:3]
    lo = np.minimum(np.where(used[..., None], pts, np.inf).min(axis=1), np.minimum(start, end))
    hi = np.maximum(np.where(used[..., None], pts, -np.inf).max(axis=1), np.maximum(start, end))
    box = np.stack([lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1]], axis=1).reshape(k_count, 4)

    band_first, band_count, band_v0, band_scale, band_start, entry_piece = _bands(owner, box, m_count)
    magnitude = np.zeros(m_count)
    np.maximum.at(magnitude, owner, np.abs(box).max(axis=1, initial=0.0))
    ev = ends[entry_piece][:, [1, 3]]
    entry_box = np.stack(
        [box[entry_piece, 0], box[entry_piece, 1], ev.min(axis=1, initial=np.inf), ev.max(axis=1, initial=-np.inf)],
        axis=1,
    ).reshape(-1, 4)
    c = np.ascontiguousarray
    return TrimTable(
        c(trimmed, dtype=np.bool_),
        c(band_first, dtype=np.int64),
        c(band_count, dtype=np.int64),
        c(band_v0, dtype=np.float64),
        c(band_scale, dtype=np.float64),
        c(magnitude, dtype=np.float64),
        c(degree, dtype=np.int64),
        c(coef, dtype=np.float64),
        c(ends, dtype=np.float64),
        c(box, dtype=np.float64),
        c(band_start, dtype=np.int64),
        c(entry_piece, dtype=np.int64),
        c(entry_box, dtype=np.float64),
    )


def _bernstein_to_power(d: int) -> np.ndarray:
    """(d + 1, d + 1) M with sum_k B_k,d(s) c_k = sum_j s^j (M^T c)_j, i.e. M[k, j] = C(d, j) C(j, k) (-1)^(j - k)."""
    return np.array(
        [[comb(d, j) * comb(j, k) * (-1) ** (j - k) if j >= k else 0.0 for j in range(d + 1)] for k in range(d + 1)]
    )


def _band_index(v, v0, scale, count):
    """The kernel's ``_band`` (bsrt/kernels/trim.py), elementwise and with the same float operations,
    without the surface's band_first: the band of v, in [0, count - 1]."""
    x = (v - v0) * scale
    inner = np.where(x > 0.0, x, 0.0)
    return np.where(x >= count, count - 1, np.where(x > 0.0, np.minimum(inner, count - 1).astype(np.int64), 0))


def _bands(owner: np.ndarray, box: np.ndarray, m_count: int):
    """Per surface, about BANDS_PER_PIECE bands per piece (at most MAX_BANDS) over the v-range of its
    pieces, each listing the pieces whose box meets it, by decreasing u_max: the band fields of
    TrimTable (band_first, band_count, band_v0, band_scale, band_start, entry_piece)."""
    pieces_per = np.bincount(owner, minlength=m_count)
    v0 = np.full(m_count, np.inf)
    v1 = np.full(m_count, -np.inf)
    np.minimum.at(v0, owner, box[:, 2])
    np.maximum.at(v1, owner, box[:, 3])
    count = np.clip(np.ceil(BANDS_PER_PIECE * pieces_per), 1, MAX_BANDS).astype(np.int64)
    with np.errstate(all="ignore"):
        scale = count / (v1 - v0)
    flat = ~(np.isfinite(scale) & (v1 > v0))  # no pieces, or all at one v: one band
    count[flat] = 1
    scale[flat] = 0.0
    v0[~np.isfinite(v0)] = 0.0
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    o = owner
    lo = _band_index(box[:, 2], v0[o], scale[o], count[o])
    hi = _band_index(box[:, 3], v0[o], scale[o], count[o])
    span = hi - lo + 1
    piece = np.repeat(np.arange(o.size), span)
    offset = np.arange(piece.size) - np.repeat(np.cumsum(span) - span, span)
    band = first[o][piece] + lo[piece] + offset
    order = np.lexsort((-box[piece, 1], band))
    total = int(count.sum())
    band_start = np.concatenate([[0], np.cumsum(np.bincount(band, minlength=total))]).astype(np.int64)
    return first, count, v0, scale, band_start, piece[order].astype(np.int64)


def kept(surface, u, v) -> np.ndarray:
    """(N,) bool: is each (u[i], v[i]) kept by the trims of one BSplineSurface? (u, v: scalars or (N,).)"""
    from bsrt.kernels.trim import kept_many

    u = np.atleast_1d(np.asarray(u, dtype=np.float64)).ravel()
    v = np.atleast_1d(np.asarray(v, dtype=np.float64)).ravel()
    u, v = np.broadcast_arrays(u, v)
    return kept_many(build_trim_table([surface]), np.zeros(u.size, dtype=np.int64), u, v)
