"""Trim loops: closed 2-D B-spline curves in a surface's own (u, v) domain.

A trimmed surface shows only the points (u, v) inside its loops by the
even-odd rule: (u, v) is kept where a ray from it in the parameter plane
crosses the loops an odd number of times. So an outer loop with holes,
nested islands and loops of either orientation all work, and a surface with
no loop is whole.

This module holds the data (:class:`TrimCurve`, :class:`TrimLoop`), their
validation (every error names the loop and the curve), and the preparation
for the compiled test "is (u, v) kept?" (:func:`build_trim_table`; the test
itself is ``kernels/trim.py``).

Why the answer is exact at the curve. Every curve is cut into rational
Bezier pieces (knot insertion), and each piece is cut in half (de Casteljau,
homogeneous) until its control polygon is monotone in u and in v. With
positive weights a rational Bezier curve crosses any line no more often than
its control polygon (variation diminishing), so each final piece is itself
monotone: a horizontal line v = const meets it at most once, and whether
that crossing lies right of u is decided either by the piece's box (u left
of the box: it does; right of it: it does not) or, when u falls inside the
box, by solving V(s) = v on the piece itself (bisection to machine
precision) and comparing U(s) with u. No rasterised mask, no polyline. A
piece that is still not monotone after MAX_CUTS halvings (it holds a
tangent parallel to an axis in a stretch shorter than 2^-MAX_CUTS of its
span) is replaced by its chord, an error far below 1e-12 of the domain.
Pieces are indexed per surface in horizontal bands over v, so a query looks
only at the pieces of its band.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb
from typing import NamedTuple

import numpy as np

from .errors import InputError

CLOSE_TOLERANCE = 1e-9  # loop gaps allowed, as a fraction of the domain's size


@dataclass(frozen=True, eq=False)
class TrimCurve:
    """One 2-D B-spline curve of a trim loop.

    degree: p >= 1. knots: (n + p + 1,) float64, non-decreasing.
    points: (n, 2) float64, (u, v) in the surface's knot domain.
    weights: (n,) float64, all > 0, or None (non-rational).
    """

    degree: int
    knots: np.ndarray
    points: np.ndarray
    weights: np.ndarray | None = None

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[self.degree]), float(self.knots[self.points.shape[0]])

    def homogeneous(self) -> np.ndarray:
        """(n, 3) float64: (w u, w v, w)."""
        w = np.ones(self.points.shape[0]) if self.weights is None else self.weights
        return np.concatenate([self.points * w[:, None], w[:, None]], axis=1)

    def evaluate(self, s) -> np.ndarray:
        """(N, 2) points at curve parameters s (N,) (reference Cox-de Boor)."""
        from .bspline import basis_functions, find_span

        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        p, n = self.degree, self.points.shape[0]
        span = find_span(self.knots, p, n, s)
        basis, _ = basis_functions(self.knots, p, span, s)
        ctrl = self.homogeneous()[(span - p)[:, None] + np.arange(p + 1)[None, :]]  # (N, p+1, 3)
        h = np.einsum("na,nak->nk", basis, ctrl)
        return h[:, :2] / h[:, 2:3]

    def ends(self) -> np.ndarray:
        """(2, 2): the curve's first and last point."""
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
    inner = k[(k > k[p]) & (k < k[n])]
    if inner.size and np.unique(inner, return_counts=True)[1].max() > p:
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
    CLOSE_TOLERANCE x the domain's diagonal are allowed. Errors name
    ``trim[i].curves[j]``.
    """
    umin, umax, vmin, vmax = domain
    size = float(np.hypot(umax - umin, vmax - vmin))
    gap = CLOSE_TOLERANCE * size
    slack = CLOSE_TOLERANCE * size
    for i, loop in enumerate(loops):
        if not loop.curves:
            raise InputError(f"trim[{i}].curves: a loop needs at least one curve")
        ends = [c.ends() for c in loop.curves]
        for j, (curve, e) in enumerate(zip(loop.curves, ends)):
            prev = ends[j - 1][1]
            if np.hypot(*(e[0] - prev)) > gap:
                what = "the last curve ends" if len(ends) > 1 else "it ends"
                raise InputError(
                    f"trim[{i}].curves[{j}]: the loop is open: the curve starts at ({e[0][0]:g}, {e[0][1]:g}) "
                    f"but {what} at ({prev[0]:g}, {prev[1]:g})" if j == 0 else
                    f"trim[{i}].curves[{j}]: the loop is open: the curve starts at ({e[0][0]:g}, {e[0][1]:g}), "
                    f"not where curves[{j - 1}] ends ({prev[0]:g}, {prev[1]:g})"
                )
            lo, hi = curve.domain
            pts = curve.evaluate(np.linspace(lo, hi, 16 * (curve.points.shape[0] + 1)))
            out = (pts[:, 0] < umin - slack) | (pts[:, 0] > umax + slack) | (pts[:, 1] < vmin - slack) | (
                pts[:, 1] > vmax + slack)
            if np.any(out):
                k = int(np.argmax(out))
                raise InputError(
                    f"trim[{i}].curves[{j}]: the curve leaves the surface's domain [{umin:g}, {umax:g}] x "
                    f"[{vmin:g}, {vmax:g}] (it passes ({pts[k, 0]:g}, {pts[k, 1]:g}))"
                )
    return tuple(loops)


# ---------------------------------------------------------------------------
# The table for the kernels

MAX_CUTS = 30


class TrimTable(NamedTuple):
    """Every trimmed surface's loops as monotone rational Bezier pieces, flat.

    M surfaces, N pieces, D the largest piece degree, B bands in all:
      trimmed: (M,) bool, the surface has loops (False: everything is kept).
      coef: (N, D + 1, 3) float64, each piece's (w u, w v, w) in the power
        basis of its parameter s in [0, 1] (rows above its degree are 0).
      degree: (N,) int64.
      box: (N, 4) float64, (umin, umax, vmin, vmax) of its control points.
      ends: (N, 2) float64, v at s = 0 and at s = 1.
      band_first: (M,) int64, the surface's first band; band_count: (M,)
        int64; band_v0, band_height: (M,) float64, band b covers
        [band_v0 + b h, band_v0 + (b + 1) h) (the first and last extend to
        infinity).
      band_start: (B + 1,) int64, band k's pieces are
        band_pieces[band_start[k] : band_start[k + 1]].
      band_pieces: (E,) int64.
    """

    trimmed: np.ndarray
    coef: np.ndarray
    degree: np.ndarray
    box: np.ndarray
    ends: np.ndarray
    band_first: np.ndarray
    band_count: np.ndarray
    band_v0: np.ndarray
    band_height: np.ndarray
    band_start: np.ndarray
    band_pieces: np.ndarray


def bezier_pieces(curve: TrimCurve) -> list[np.ndarray]:
    """The curve's rational Bezier pieces: homogeneous nets (p + 1, 3) in curve order."""
    from .bspline import _saturate

    p, n = curve.degree, curve.points.shape[0]
    knots, ctrl = _saturate(curve.knots, curve.homogeneous(), p, n)
    a, b = curve.knots[p], curve.knots[n]
    return [ctrl[i - p : i + 1] for i in range(p, ctrl.shape[0]) if knots[i] < knots[i + 1] and a <= knots[i] < b]


def _halves(net: np.ndarray):
    """de Casteljau at s = 1/2 of a homogeneous net (d + 1, 3)."""
    pts, lo, hi = net, [net[0]], [net[-1]]
    for _ in range(net.shape[0] - 1):
        pts = 0.5 * (pts[:-1] + pts[1:])
        lo.append(pts[0])
        hi.append(pts[-1])
    return np.array(lo), np.array(hi[::-1])


def _monotone(net: np.ndarray) -> bool:
    pts = net[:, :2] / net[:, 2:3]
    d = np.diff(pts, axis=0)
    return bool(np.all((np.all(d[:, 0] >= 0) | np.all(d[:, 0] <= 0)) & (np.all(d[:, 1] >= 0) | np.all(d[:, 1] <= 0))))


def monotone_pieces(net: np.ndarray, cuts: int = 0) -> list[np.ndarray]:
    """Cut a homogeneous Bezier net until every piece's control polygon is monotone in u and v."""
    if _monotone(net):
        return [net]
    if cuts >= MAX_CUTS:  # a tiny stretch around an axis-parallel tangent: its chord
        return [net[[0, -1]]]
    lo, hi = _halves(net)
    return monotone_pieces(lo, cuts + 1) + monotone_pieces(hi, cuts + 1)


def _power(net: np.ndarray) -> np.ndarray:
    """Power-basis coefficients (d + 1, 3) of a Bezier net (d + 1, 3) on s in [0, 1]."""
    d = net.shape[0] - 1
    m = np.array([[comb(d, j) * comb(j, k) * (-1) ** (j - k) if j >= k else 0.0 for j in range(d + 1)]
                  for k in range(d + 1)])
    return m.T @ net


def build_trim_table(surfaces) -> TrimTable:
    """The TrimTable of a list of BSplineSurface (their ``trims``)."""
    m_count = len(surfaces)
    trimmed = np.array([bool(s.trims) for s in surfaces], dtype=bool).reshape(m_count)
    nets, owner = [], []
    for m, surf in enumerate(surfaces):
        for loop in surf.trims:
            for curve in loop.curves:
                for piece in bezier_pieces(curve):
                    for net in monotone_pieces(piece):
                        nets.append(net)
                        owner.append(m)
    n = len(nets)
    dmax = max((x.shape[0] for x in nets), default=1)
    coef = np.zeros((n, dmax, 3))
    degree = np.zeros(n, dtype=np.int64)
    box = np.zeros((n, 4))
    ends = np.zeros((n, 2))
    for k, net in enumerate(nets):
        coef[k, : net.shape[0]] = _power(net)
        degree[k] = net.shape[0] - 1
        pts = net[:, :2] / net[:, 2:3]
        box[k] = pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()
        ends[k] = pts[0, 1], pts[-1, 1]
    owner = np.array(owner, dtype=np.int64)
    band_first = np.zeros(m_count, dtype=np.int64)
    band_count = np.ones(m_count, dtype=np.int64)
    band_v0, band_height = np.zeros(m_count), np.ones(m_count)
    starts, members, total = [0], [], 0
    for m in range(m_count):
        band_first[m] = total
        mine = np.flatnonzero(owner == m)
        if not mine.size:
            starts.append(starts[-1])
            total += 1
            continue
        lo, hi = box[mine, 2].min(), box[mine, 3].max()
        count = int(np.clip(np.sqrt(mine.size) * 2, 1, 512))
        height = (hi - lo) / count if hi > lo else 1.0
        band_count[m], band_v0[m], band_height[m] = count, lo, height
        first = np.clip(((box[mine, 2] - lo) / height).astype(np.int64), 0, count - 1)
        last = np.clip(((box[mine, 3] - lo) / height).astype(np.int64), 0, count - 1)
        for b in range(count):
            inside = mine[(first <= b) & (last >= b)]
            members.append(inside)
            starts.append(starts[-1] + inside.size)
        total += count
    return TrimTable(trimmed, coef, degree, box, ends, band_first, band_count, band_v0, band_height,
                     np.array(starts, dtype=np.int64),
                     np.concatenate(members).astype(np.int64) if members else np.zeros(0, dtype=np.int64))


def kept(surface, u, v) -> np.ndarray:
    """(N,) bool: is each (u[i], v[i]) kept by the trims of one BSplineSurface?"""
    from .kernels.trim import kept_many

    u = np.atleast_1d(np.asarray(u, dtype=np.float64))
    v = np.atleast_1d(np.asarray(v, dtype=np.float64))
    return kept_many(build_trim_table([surface]), np.zeros(u.size, dtype=np.int64), u, v)
