"""Tensor-product B-spline surfaces (optionally rational) in pure NumPy.

A surface of degree (p, q) has nu x nv control points P[i, j] (i along u, j
along v), knot vectors of length nu + p + 1 and nv + q + 1, and an optional
grid of positive weights. Its parameter domain is
[knots_u[p], knots_u[nu]] x [knots_v[q], knots_v[nv]]; knot vectors need not be
clamped or uniform. Everything is float64.

This module is the reference evaluator (Cox-de Boor, any knot vector) and owns
the surfaces' Bezier extraction; the fast per-pixel evaluator built on the
extracted Bezier patches lives in ``patches.py``. The one-direction basics
(spans, basis functions, knot insertion, a span's Bezier extraction
matrices) are in ``basis.py``, shared with the trim curves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bsrt.errors import InputError
from bsrt.geometry.basis import basis_functions, basis_matrix, find_span, insert_knot, span_matrices  # noqa: F401  (re-exported: the readers')


@dataclass(frozen=True, eq=False)
class BSplineSurface:
    """One B-spline (or NURBS) surface: geometry only, no material.

    degree: (p, q), each >= 1.
    knots_u: (nu + p + 1,) float64, non-decreasing.
    knots_v: (nv + q + 1,) float64, non-decreasing.
    points: (nu, nv, 3) float64, points[i, j] = P(i, j).
    weights: (nu, nv) float64, all > 0, or None for a non-rational surface.
    trims: trim loops (bsrt.geometry.trim.TrimLoop) in the surface's (u, v) domain;
      empty: the surface is whole.

    Construct through :func:`make_surface`, which validates; the messages of
    its :class:`InputError` name the offending key (``knots_u: ...``), and
    callers prefix the file and table.
    """

    degree: tuple[int, int]
    knots_u: np.ndarray
    knots_v: np.ndarray
    points: np.ndarray
    weights: np.ndarray | None = None
    trims: tuple = ()

    @property
    def is_trimmed(self) -> bool:
        return bool(self.trims)

    @property
    def shape(self) -> tuple[int, int]:
        """(nu, nv), the number of control points along u and v."""
        return self.points.shape[0], self.points.shape[1]

    @property
    def domain_u(self) -> tuple[float, float]:
        p, nu = self.degree[0], self.shape[0]
        return float(self.knots_u[p]), float(self.knots_u[nu])

    @property
    def domain_v(self) -> tuple[float, float]:
        q, nv = self.degree[1], self.shape[1]
        return float(self.knots_v[q]), float(self.knots_v[nv])

    @property
    def is_rational(self) -> bool:
        return self.weights is not None

    def homogeneous(self) -> np.ndarray:
        """(nu, nv, 4) float64: (w x, w y, w z, w); w = 1 when non-rational."""
        w = np.ones(self.shape) if self.weights is None else self.weights
        return np.concatenate([self.points * w[..., None], w[..., None]], axis=-1)

    def transformed(self, world_from_local: np.ndarray) -> BSplineSurface:
        """The same surface with its control points mapped by a 4x4 affine matrix.

        Affine maps commute with (rational) B-spline evaluation, so the
        weights and knots are unchanged.
        """
        m = np.asarray(world_from_local, dtype=np.float64)
        pts = self.points @ m[:3, :3].T + m[:3, 3]
        return BSplineSurface(self.degree, self.knots_u, self.knots_v, pts, self.weights, self.trims)

    def with_trims(self, loops) -> BSplineSurface:
        """The same surface trimmed by ``loops`` (TrimLoop, checked to close and lie in the domain)."""
        from bsrt.geometry.trim import check_loops

        domain = (*self.domain_u, *self.domain_v)
        return BSplineSurface(
            self.degree, self.knots_u, self.knots_v, self.points, self.weights, check_loops(tuple(loops), domain)
        )


def _check_knots(key: str, knots: np.ndarray, n: int, p: int) -> None:
    if knots.ndim == 1 and knots.size == n + p + 1 and knots[p] < knots[n]:  # the usual case, in a few calls
        steps = knots[1:] - knots[:-1]
        if steps.min() >= 0:  # (finite, non-decreasing: NaN or inf fail here, or in the sum below)
            inner = knots[(knots > knots[p]) & (knots < knots[n])]  # sorted: p + 1 equal values in a row
            if not (inner.size > p and (inner[p:] == inner[:-p]).any()) and np.isfinite(knots[0] + knots[-1]):
                return
    if knots.ndim != 1 or knots.size != n + p + 1:
        raise InputError(f"{key}: expected {n + p + 1} values ({n} points + degree {p} + 1), got {knots.size}")
    if not np.all(np.isfinite(knots)):
        raise InputError(f"{key}: values must be finite numbers")
    if np.any(np.diff(knots) < 0):
        i = int(np.argmax(np.diff(knots) < 0))
        raise InputError(
            f"{key}: knots must not decrease, but value {i + 1} ({knots[i + 1]:g}) is less than value {i} ({knots[i]:g})"
        )
    a, b = knots[p], knots[n]
    if not a < b:
        raise InputError(f"{key}: the parameter domain [{a:g}, {b:g}] (knots {p} and {n}) is empty")
    inner = knots[(knots > a) & (knots < b)]
    if inner.size:
        values, counts = np.unique(inner, return_counts=True)
        if counts.max() > p:
            x = values[np.argmax(counts)]
            raise InputError(f"{key}: interior knot {x:g} is repeated {counts.max()} times, more than the degree {p}")


def make_surface(degree, knots_u, knots_v, points, weights=None) -> BSplineSurface:
    """Validate and build a :class:`BSplineSurface` from array-likes.

    Raises InputError with a message that starts with the offending key.
    """
    try:
        p, q = (int(d) for d in degree)
        if [p, q] != [d for d in degree]:
            raise ValueError
    except (TypeError, ValueError):
        raise InputError(f"degree: expected two whole numbers [p, q], got {degree!r}") from None
    if p < 1 or q < 1:
        raise InputError(f"degree: each degree must be >= 1, got [{p}, {q}]")
    try:
        pts = np.array(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("points: expected a grid of [x, y, z] numbers (nu rows of nv points)") from None
    if pts.ndim != 3 or pts.shape[2] != 3:
        raise InputError(f"points: expected nu rows of nv [x, y, z] points, got an array of shape {pts.shape}")
    nu, nv = pts.shape[:2]
    if nu < p + 1 or nv < q + 1:
        raise InputError(f"points: degree [{p}, {q}] needs at least {p + 1} x {q + 1} points, got {nu} x {nv}")
    if not np.all(np.isfinite(pts)):
        i, j, _ = np.argwhere(~np.isfinite(pts))[0]
        raise InputError(f"points: point [{i}][{j}] has a non-finite coordinate")
    ku = _as_vector("knots_u", knots_u)
    kv = _as_vector("knots_v", knots_v)
    _check_knots("knots_u", ku, nu, p)
    _check_knots("knots_v", kv, nv, q)
    w = None
    if weights is not None:
        try:
            w = np.array(weights, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("weights: expected nu rows of nv numbers") from None
        if w.shape != (nu, nv):
            raise InputError(f"weights: expected {nu} x {nv} values (one per point), got shape {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise InputError("weights: every weight must be a finite number > 0")
        if np.all(w == 1.0):
            w = None
    for a in (ku, kv, pts) + (() if w is None else (w,)):
        a.setflags(write=False)
    return BSplineSurface((p, q), ku, kv, pts, w)


def _as_vector(key: str, values) -> np.ndarray:
    try:
        knots = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        knots = None
    if knots is None or knots.ndim != 1:
        raise InputError(f"{key}: expected a list of numbers")
    return knots


# ---------------------------------------------------------------------------
# Evaluation


def evaluate(surface: BSplineSurface, u, v):
    """S, S_u, S_v at paired parameters.

    u, v: (N,) float64 in the surface's knot domain (values outside extend the
    end spans). Returns three (N, 3) float64 arrays. Rational surfaces use the
    quotient rule on the homogeneous point.
    """
    u = np.atleast_1d(np.asarray(u, dtype=np.float64))
    v = np.atleast_1d(np.asarray(v, dtype=np.float64))
    (p, q), (nu, nv) = surface.degree, surface.shape
    su = find_span(surface.knots_u, p, nu, u)
    sv = find_span(surface.knots_v, q, nv, v)
    bu, dbu = basis_functions(surface.knots_u, p, su, u)
    bv, dbv = basis_functions(surface.knots_v, q, sv, v)
    ii = (su - p)[:, None, None] + np.arange(p + 1)[None, :, None]
    jj = (sv - q)[:, None, None] + np.arange(q + 1)[None, None, :]
    ctrl = surface.homogeneous()[ii, jj]  # (N, p+1, q+1, 4)
    along_v = (bv[:, None, None, :] @ ctrl)[:, :, 0]  # (N, p+1, 4): batched products, not a 3-operand einsum
    along_dv = (dbv[:, None, None, :] @ ctrl)[:, :, 0]
    h = (bu[:, None, :] @ along_v)[:, 0]
    hu = (dbu[:, None, :] @ along_v)[:, 0]
    hv = (bu[:, None, :] @ along_dv)[:, 0]
    return rational_quotient(h, hu, hv)


def rational_quotient(h, hu, hv):
    """Project homogeneous (N, 4) values and derivatives to (N, 3) S, S_u, S_v."""
    w = h[:, 3:4]
    s = h[:, :3] / w
    su = (hu[:, :3] - s * hu[:, 3:4]) / w
    sv = (hv[:, :3] - s * hv[:, 3:4]) / w
    return s, su, sv


# ---------------------------------------------------------------------------
# Bezier extraction


EXTRACT_CHUNK = 1 << 18  # Bezier points (x 4 floats) gathered at once in the second direction


def bezier_patches(surface: BSplineSurface):
    """Split a surface into its polynomial (rational) Bezier pieces.

    Returns (ctrl, bounds): ctrl (K, p+1, q+1, 4) homogeneous Bezier control
    points; bounds (K, 4) float64 rows (u0, u1, v0, v1), the piece's rectangle
    in the surface's own knot domain. Pieces are ordered u-major. Vectorised
    over the spans (a surface of a million pieces takes seconds).
    """
    (p, q) = surface.degree
    ku, kv = surface.knots_u, surface.knots_v
    nu, nv = surface.shape
    mu, spans_u = span_matrices(ku, nu, p)  # (Su, p+1, p+1)
    mv, spans_v = span_matrices(kv, nv, q)  # (Sv, q+1, q+1)
    window_u = spans_u[:, None] - p + np.arange(p + 1)  # (Su, p+1) control rows of each span
    rows = np.einsum("skj,sjvc->skvc", mu, surface.homogeneous()[window_u])  # (Su, p+1, nv, 4)
    window_v = spans_v[:, None] - q + np.arange(q + 1)  # (Sv, q+1)
    ctrl = np.empty((spans_u.size, spans_v.size, p + 1, q + 1, 4))
    step = max(1, EXTRACT_CHUNK // max(1, spans_v.size * (p + 1) * (q + 1)))
    for first in range(0, spans_u.size, step):  # bounded temporaries: a few u spans at a time
        part = slice(first, first + step)
        ctrl[part] = np.einsum("tlj,cktjx->ctklx", mv, rows[part][:, :, window_v])
    ctrl = ctrl.reshape(-1, p + 1, q + 1, 4)
    if not surface.is_rational:  # weights 1 exactly, not 1 +- rounding: the patches stay polynomial
        ctrl[..., 3] = 1.0
    bounds = np.empty((spans_u.size, spans_v.size, 4))
    bounds[..., 0] = ku[spans_u, None]
    bounds[..., 1] = ku[spans_u + 1, None]
    bounds[..., 2] = kv[spans_v][None, :]
    bounds[..., 3] = kv[spans_v + 1][None, :]
    return ctrl, bounds.reshape(-1, 4)


def restrict(surface: BSplineSurface, range_u, range_v) -> BSplineSurface:
    """The part of ``surface`` over [u0, u1] x [v0, v1], by knot insertion.

    Each range is clipped to the knot domain; one that covers the domain
    leaves that direction as is. Callers check that the clipped ranges are
    non-empty. The result is the same geometry with fewer control points.
    """
    ctrl = surface.homogeneous()  # (nu, nv, 4)
    knots = [surface.knots_u, surface.knots_v]
    for axis, (a, b) in enumerate((range_u, range_v)):
        p = surface.degree[axis]
        k = knots[axis]
        c = np.moveaxis(ctrl, axis, 0)
        lo, hi = k[p], k[c.shape[0]]
        a, b = max(a, lo), min(b, hi)
        if a == lo and b == hi:
            continue
        for x in (a, b):
            if lo < x < hi:
                while np.count_nonzero(k == x) < p:
                    k, c = insert_knot(k, c, p, x)
        # keep the control points whose basis functions are non-zero on [a, b]
        first = int(np.searchsorted(k, a, side="right")) - 1 - p
        last = int(np.searchsorted(k, b, side="left"))
        c = c[first:last]
        k = k[first : last + p + 1]
        # clamp the new ends so the domain is exactly [a, b]
        k = k.copy()
        k[: p + 1] = np.maximum(k[: p + 1], a)
        k[-(p + 1) :] = np.minimum(k[-(p + 1) :], b)
        knots[axis] = k
        ctrl = np.moveaxis(c, 0, axis)
    w = ctrl[..., 3]
    weights = None if surface.weights is None else w
    with np.errstate(all="ignore"):  # extreme weights give non-finite points, which make_surface reports
        pts = ctrl[..., :3] / w[..., None]
    return make_surface(surface.degree, knots[0], knots[1], pts, weights)


def grid_points(surface: BSplineSurface, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(len(x), len(y), 3) float64: the surface's points at the grid x[i], y[j] (values outside the
    domain extend the end spans, as :func:`bsrt.geometry.bspline.evaluate`)."""
    (p, q), (nu, nv) = surface.degree, surface.shape
    bu = basis_matrix(surface.knots_u, p, nu, np.atleast_1d(x))
    bv = basis_matrix(surface.knots_v, q, nv, np.atleast_1d(y))
    if surface.weights is None:
        h = (bu @ surface.points.reshape(nu, nv * 3)).reshape(-1, nv, 3)
        return np.einsum("avk,bv->abk", h, bv)
    h = (bu @ surface.homogeneous().reshape(nu, nv * 4)).reshape(-1, nv, 4)
    h = np.einsum("avk,bv->abk", h, bv)
    return h[..., :3] / h[..., 3:4]
