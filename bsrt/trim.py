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


def build_trim_table(surfaces) -> TrimTable:
    """The TrimTable of a list of BSplineSurface (their ``trims``)."""
    from .kernels.trim import bezier_spans, monotone_pieces

    m_count = len(surfaces)
    trimmed = np.array([bool(s.trims) for s in surfaces], dtype=bool).reshape(m_count)
    spans, span_owner = [], []
    for m, surf in enumerate(surfaces):
        for loop in surf.trims:
            for curve in loop.curves:
                nets = bezier_spans(curve.knots, curve.homogeneous(), curve.degree)
                spans.append(nets)
                span_owner.append(np.full(nets.shape[0], m, dtype=np.int64))
    dmax = max((x.shape[1] for x in spans), default=2)
    padded = np.zeros((sum(x.shape[0] for x in spans), dmax, 3))
    span_degree = np.concatenate([np.full(x.shape[0], x.shape[1] - 1) for x in spans]).astype(np.int64) if spans \
        else np.zeros(0, np.int64)
    at = 0
    for x in spans:
        padded[at : at + x.shape[0], : x.shape[1]] = x
        at += x.shape[0]
    nets, degree, which = monotone_pieces(padded, span_degree, MAX_CUTS)
    owner = np.concatenate(span_owner)[which] if spans else np.zeros(0, np.int64)
    n = nets.shape[0]
    coef = np.zeros((n, dmax, 3))
    used = np.arange(dmax)[None, :] <= degree[:, None]
    with np.errstate(all="ignore"):  # unused rows have w = 0
        pts = np.where(used[..., None], nets[..., :2] / nets[..., 2:3], np.nan)
    for d in np.unique(degree):  # power-basis coefficients, per degree
        sel = degree == d
        coef[sel, : d + 1] = np.einsum("kj,nkc->njc", _bernstein_to_power(d), nets[sel, : d + 1])
    box = np.stack([np.nanmin(pts[..., 0], 1), np.nanmax(pts[..., 0], 1), np.nanmin(pts[..., 1], 1),
                    np.nanmax(pts[..., 1], 1)], axis=1) if n else np.zeros((0, 4))
    ends = np.stack([pts[:, 0, 1], pts[np.arange(n), degree, 1]], axis=1) if n else np.zeros((0, 2))
    return TrimTable(trimmed, coef, degree, box, ends, *_bands(owner, box, m_count))


def _bernstein_to_power(d: int) -> np.ndarray:
    """(d + 1, d + 1) M with sum_k B_k,d(s) c_k = sum_j s^j (M^T c)_j, i.e. M[k, j] = C(d, j) C(j, k) (-1)^(j - k)."""
    return np.array([[comb(d, j) * comb(j, k) * (-1) ** (j - k) if j >= k else 0.0 for j in range(d + 1)]
                     for k in range(d + 1)])


def _bands(owner: np.ndarray, box: np.ndarray, m_count: int):
    """Per surface, horizontal bands over the v-range of its pieces (about 2 sqrt(pieces) of them, at
    most 512), each listing the pieces whose box meets it: the band fields of TrimTable."""
    counts_per = np.bincount(owner, minlength=m_count)
    band_count = np.where(counts_per > 0, np.clip((2 * np.sqrt(counts_per)).astype(np.int64), 1, 512), 1)
    band_first = np.concatenate([[0], np.cumsum(band_count)[:-1]]).astype(np.int64)
    v0 = np.zeros(m_count)
    v1 = np.ones(m_count)
    if owner.size:
        np.minimum.at(v0 := np.full(m_count, np.inf), owner, box[:, 2])
        np.maximum.at(v1 := np.full(m_count, -np.inf), owner, box[:, 3])
        empty = counts_per == 0
        v0[empty], v1[empty] = 0.0, 1.0
    height = np.where(v1 > v0, (v1 - v0) / band_count, 1.0)
    o = owner
    first = np.clip(((box[:, 2] - v0[o]) / height[o]).astype(np.int64), 0, band_count[o] - 1) if o.size else o
    last = np.clip(((box[:, 3] - v0[o]) / height[o]).astype(np.int64), 0, band_count[o] - 1) if o.size else o
    span = last - first + 1
    piece = np.repeat(np.arange(o.size), span)
    band = band_first[np.repeat(o, span)] + np.repeat(first, span) + (np.arange(piece.size) - np.repeat(np.cumsum(span) - span, span))
    order = np.argsort(band, kind="stable")
    total = int(band_count.sum())
    band_start = np.concatenate([[0], np.cumsum(np.bincount(band, minlength=total))]).astype(np.int64)
    return band_first, band_count.astype(np.int64), v0, height, band_start, piece[order].astype(np.int64)


def kept(surface, u, v) -> np.ndarray:
    """(N,) bool: is each (u[i], v[i]) kept by the trims of one BSplineSurface?"""
    from .kernels.trim import kept_many

    u = np.atleast_1d(np.asarray(u, dtype=np.float64))
    v = np.atleast_1d(np.asarray(v, dtype=np.float64))
    return kept_many(build_trim_table([surface]), np.zeros(u.size, dtype=np.int64), u, v)
