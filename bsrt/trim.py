"""Trim loops: closed 2-D B-spline curves in a surface's own (u, v) domain.

A trimmed surface shows only the points (u, v) inside its loops by the
even-odd rule: (u, v) is kept where a ray from it in the parameter plane
crosses the loops an odd number of times. So an outer loop with holes,
nested islands and loops of either orientation all work, and a surface with
no loop is whole.

This module holds the data (:class:`TrimCurve`, :class:`TrimLoop`), their
validation (every error names the loop and the curve), and the preparation
for the compiled test "is (u, v) kept?" (:func:`build_trim_table`): every
curve cut into rational Bezier pieces, each cut further until it is monotone
in u and in v, and per surface a band index over v.
"""

from __future__ import annotations

from dataclasses import dataclass

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
