"""One-direction B-spline basics in NumPy: the knot span, the basis functions
and their derivatives (Cox-de Boor), and knot insertion (Boehm). Shared by the
surfaces (bspline.py) and the trim curves (trim.py); imports nothing of bsrt.
"""

from __future__ import annotations

import numpy as np


def find_span(knots: np.ndarray, p: int, n: int, u: np.ndarray) -> np.ndarray:
    """Knot span index i with knots[i] <= u < knots[i+1], clamped to [p, n-1].

    knots: (n + p + 1,); u: (N,) -> (N,) int64. Parameters outside the domain
    get the first/last span, i.e. the polynomial of that span is extended.
    """
    span = np.searchsorted(knots, u, side="right") - 1
    return np.clip(span, p, n - 1)


def basis_functions(knots: np.ndarray, p: int, span: np.ndarray, u: np.ndarray):
    """The p + 1 non-zero basis functions at u and their first derivatives.

    span, u: (N,). Returns (values, derivatives), each (N, p + 1); column k is
    N_{span - p + k, p}(u). Cox-de Boor's triangular scheme, vectorised over N
    (zero where a denominator is: an empty span, not in a valid knot vector).
    """
    u = np.asarray(u, dtype=np.float64)
    vals = np.empty((u.shape[0], p + 1))
    for guard in (False, True):  # unguarded first: a zero denominator shows as a non-finite value
        vals[:, 0] = 1.0
        if p > 1:
            _triangle(knots, p - 1, span, u, vals[:, :p], guard)
        prev = vals[:, :p].copy()  # the degree p - 1 functions, for the derivatives
        _triangle(knots, p, span, u, vals, guard, first=p)
        if guard or np.isfinite(vals).all():
            break
    # dN_{i,p} = p (N_{i,p-1} / (k[i+p] - k[i]) - N_{i+1,p-1} / (k[i+p+1] - k[i+1])), all k at once:
    # q[:, m] = N_{span-p+m+1,p-1} / (k[span+m+1] - k[span-p+m+1]) (0 where the knots coincide)
    steps = np.arange(1, p + 1)
    d = knots[span[:, None] + steps] - knots[span[:, None] - p + steps]
    q = np.divide(prev, d, out=np.zeros_like(prev), where=d != 0)
    ders = np.zeros((u.shape[0], p + 1))
    ders[:, 1:] += q
    ders[:, :p] -= q
    return vals, p * ders


def insert_knot(knots: np.ndarray, ctrl: np.ndarray, p: int, x: float):
    """Insert the value x once into a knot vector (Boehm's algorithm).

    knots: (n + p + 1,); ctrl: (n, ...) homogeneous control points, the first
    axis being the direction of the knots. Returns (knots', ctrl') with one
    more knot and one more control point; the curve (surface) is unchanged.
    """
    n = ctrl.shape[0]
    k = int(np.clip(np.searchsorted(knots, x, side="right") - 1, p, n - 1))
    new = np.empty((n + 1,) + ctrl.shape[1:])
    new[: k - p + 1] = ctrl[: k - p + 1]
    new[k + 1 :] = ctrl[k:]
    for i in range(k - p + 1, k + 1):
        denom = knots[i + p] - knots[i]
        a = (x - knots[i]) / denom if denom != 0 else 0.0
        new[i] = a * ctrl[i] + (1.0 - a) * ctrl[i - 1]
    return np.insert(knots, k + 1, x), new


def basis_values(knots: np.ndarray, p: int, n: int, x: np.ndarray, span=None):
    """(span (N,), values (N, p + 1)): the non-zero basis functions at x, values only (Cox-de Boor's
    triangle, as :func:`bsrt.geometry.bspline.basis_functions`, without the derivatives); spans clamped to
    [p, n - 1] as :func:`bsrt.geometry.bspline.find_span` does (outside the domain the end spans extend),
    or the given ``span`` (N,) (indices into ``knots``; n is not used then)."""
    x = np.asarray(x, dtype=np.float64)
    if span is None:
        span = np.minimum(np.maximum(np.searchsorted(knots, x, side="right") - 1, p), n - 1)
    if p == 1:  # (planes, lines): the two hat functions
        a, b = knots[span], knots[span + 1]
        d = b - a
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(d != 0, (x - a) / d, 0.0)
        return span, np.stack([1.0 - s, s], axis=1)
    vals = np.empty((x.shape[0], p + 1))
    vals[:, 0] = 1.0
    vals = _triangle(knots, p, span, x, vals, False)
    if not np.isfinite(vals).all():  # a zero denominator (an empty span: not in a valid clamped knot vector)
        vals[:, 1:] = 0.0
        vals[:, 0] = 1.0
        vals = _triangle(knots, p, span, x, vals, True)  # (0 there, as bsrt.geometry.bspline.basis_functions)
    return span, vals


def _triangle(knots, p, span, x, vals, guard: bool, first: int = 1) -> np.ndarray:
    """Levels first..p of Cox-de Boor's triangle, in place on vals (N, p + 1) holding level first - 1
    (level 0: the column 1.0). guard: zero, not a non-finite value, where a denominator is zero."""
    left = [None] + [x - knots[span + 1 - j] for j in range(1, p + 1)]
    right = [None] + [knots[span + j] - x for j in range(1, p + 1)]
    with np.errstate(divide="ignore", invalid="ignore"):
        for j in range(first, p + 1):
            saved = 0.0
            for r in range(j):
                denom = right[r + 1] + left[j - r]
                temp = vals[:, r] / denom
                if guard:
                    temp = np.where(denom != 0, temp, 0.0)
                vals[:, r] = saved + right[r + 1] * temp
                saved = left[j - r] * temp
            vals[:, j] = saved
    return vals


def basis_matrix(knots: np.ndarray, p: int, n: int, x: np.ndarray) -> np.ndarray:
    """(N, n) float64: all n basis functions at x (zero off their support)."""
    span, vals = basis_values(knots, p, n, x)
    out = np.zeros((vals.shape[0], n))
    out[np.arange(vals.shape[0])[:, None], (span - p)[:, None] + np.arange(p + 1)[None, :]] = vals
    return out


def span_matrices(knots: np.ndarray, n: int, p: int):
    """The Bezier extraction matrices of every non-empty span of a degree-p
    B-spline with n control points along one axis.

    Returns (matrices (S, p + 1, p + 1), spans (S,) int64): span s is
    [knots[i], knots[i + 1]) with i = spans[s], and its Bezier point k is
    sum_j matrices[s, k, j] P[i - p + j]. Bezier point k of span [a, b] is
    the blossom f(a, .., a, b, .., b) (p - k a's): de Boor's triangle with
    argument x_r at level r, run on unit vectors for all spans at once (no
    knot insertion, no per-span Python loop).
    """
    spans = np.flatnonzero(knots[p:n] < knots[p + 1 : n + 1]).astype(np.int64) + p
    a, b = knots[spans, None], knots[spans + 1, None]
    # all p + 1 Bezier points at once (axis 1): at level r, point k's argument is a if r <= p - k else b
    ks = np.arange(p + 1)
    unit = np.eye(p + 1)
    d = [np.broadcast_to(unit[j], (spans.size, p + 1, p + 1)) for j in range(p + 1)]  # d[j] ~ P[i - p + j]
    for r in range(1, p + 1):
        x = np.where(r <= p - ks, a, b)[:, :, None]  # (S, p + 1, 1)
        for j in range(p, r - 1, -1):  # knot index i - p + j
            lo = knots[spans - p + j, None, None]
            hi = knots[spans + j + 1 - r, None, None]
            alpha = (x - lo) / (hi - lo)  # hi > lo on a non-empty span
            d[j] = (1.0 - alpha) * d[j - 1] + alpha * d[j]
    matrices = np.ascontiguousarray(d[p])
    return matrices, spans
