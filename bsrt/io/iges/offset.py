"""IGES 140 offset surfaces: O(u, v) = S(u, v) + d N(u, v), N = S_u x S_v / |S_u x S_v| (IGES 5.3,
4.20; the offset indicator only tells the sending system's side, d's sign is the offset's side).

The base surface S is read as any surface entity is (:func:`bsrt.io.iges.surfaces.surface`) and
its B-spline offset in its own parameters, so the offset has the base's (u, v), maps and trims:

* a planar base (its control points in one plane, to rounding): its control points moved by
  d N, exactly;
* any other: a bicubic B-spline interpolating O at the Greville points of its knots (the
  base's knots, tripled, and its knot spans cut into equal pieces), the pieces doubled along u, v or both while O is
  further than ``OFFSET_TOLERANCE`` x the base's size from it at the midpoints between the
  interpolated points (u, v and both); the deviation measured there is the stated bound
  (:func:`offset_bspline` returns it), as for the OpenCASCADE import's approximated offsets
  (whose bound is OpenCASCADE's measured error). A base whose normal is undefined somewhere
  (a pole, an apex) or which needs more than ``MAX_POINTS`` points per direction is
  Unsupported.

A trim curve on the offset is carried into (u, v) by the base's closed-form inverse where it
has one (the foot of a point of O on S has the same parameters), else by inversion onto the
offset's B-spline.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bsrt.geometry.basis import basis_matrix
from bsrt.geometry.bspline import BSplineSurface, evaluate, make_surface

OFFSET_TOLERANCE = 1e-8  # approximated offsets: the largest deviation, as a fraction of the base surface's size
MAX_POINTS = 1025  # interpolated points per direction at most


class OffsetError(Exception):
    """The offset cannot be built (the message says why)."""


def _normals(s: BSplineSurface, u: np.ndarray, v: np.ndarray, size: float):
    """(S (N, 3), unit normals (N, 3)) at u, v (N,)."""
    p, su, sv = evaluate(s, u, v)
    n = np.cross(su, sv)
    length = np.linalg.norm(n, axis=1)
    if not np.all(length > 1e-12 * size * size):
        raise OffsetError("the base surface's normal is undefined at some point (a pole or an apex)")
    return p, n / length[:, None]


def _cubic_knots(breaks: np.ndarray, pieces: int) -> np.ndarray:
    """Clamped cubic knots over ``breaks`` (the base's knots: triple, C0 there, as the offset of a
    surface that is only C0 or C1 there is) with every span cut into ``pieces`` equal parts (simple)."""
    spans = [np.concatenate([[a] * 3, np.linspace(a, b, pieces + 1)[1:-1]]) for a, b in zip(breaks[:-1], breaks[1:])]
    return np.concatenate([[breaks[0]]] + spans + [[breaks[-1]] * 4])


def offset_bspline(s: BSplineSurface, d: float) -> tuple[BSplineSurface, float]:
    """(the offset of s by d as a B-spline on the same domain, its measured deviation from the
    true offset in model units: 0.0 where exact)."""
    pts = s.points.reshape(-1, 3)
    size = float(np.linalg.norm(np.ptp(pts, axis=0)))
    (u0, u1), (v0, v1) = s.domain_u, s.domain_v
    centre = pts.mean(axis=0)
    _, sing, vt = np.linalg.svd(pts - centre)
    if sing[2] <= 1e-14 * max(sing[0], 1e-300) * np.sqrt(len(pts)):  # planar: a translation
        _, n = _normals(s, np.array([0.5 * (u0 + u1)]), np.array([0.5 * (v0 + v1)]), size)
        normal = vt[2] if vt[2] @ n[0] > 0 else -vt[2]
        return make_surface(s.degree, s.knots_u, s.knots_v, s.points + d * normal, s.weights), 0.0
    tol = OFFSET_TOLERANCE * size
    breaks = [np.unique(np.clip(k, a, b)) for k, a, b in ((s.knots_u, u0, u1), (s.knots_v, v0, v1))]
    pieces = [1, 1]
    while True:
        knots = [_cubic_knots(b, k) for b, k in zip(breaks, pieces)]
        greville = [(k[1:-3] + k[2:-2] + k[3:-1]) / 3 for k in knots]
        if max(len(g) for g in greville) > MAX_POINTS:
            raise OffsetError(
                f"no bicubic B-spline of up to {MAX_POINTS} points a side is within {OFFSET_TOLERANCE:g} of its size"
            )
        basis = [basis_matrix(k, 3, len(g), g) for k, g in zip(knots, greville)]
        uu, vv = np.meshgrid(*greville, indexing="ij")
        p, n = _normals(s, uu.ravel(), vv.ravel(), size)
        target = (p + d * n).reshape(len(greville[0]), len(greville[1]), 3)
        ctrl = np.linalg.solve(basis[0], target.reshape(len(greville[0]), -1)).reshape(target.shape)
        ctrl = np.linalg.solve(basis[1], ctrl.transpose(1, 0, 2).reshape(len(greville[1]), -1))
        ctrl = ctrl.reshape(len(greville[1]), len(greville[0]), 3).transpose(1, 0, 2)
        fit = make_surface((3, 3), knots[0], knots[1], ctrl)
        mids = [0.5 * (g[:-1] + g[1:]) for g in greville]
        errors = [_deviation(s, fit, x, y, d, size) for x, y in ((mids[0], greville[1]), (greville[0], mids[1]), mids)]
        if max(errors) <= tol:
            return fit, max(errors)
        grow = [
            errors[0] > tol or errors[2] > tol and errors[1] <= tol,
            errors[1] > tol or errors[2] > tol and errors[0] <= tol,
        ]
        pieces = [k * 2 if g else k for k, g in zip(pieces, grow)]


def _deviation(s, fit, x, y, d, size) -> float:
    """The largest distance between the offset and the fit at the grid x x y."""
    uu, vv = np.meshgrid(x, y, indexing="ij")
    p, n = _normals(s, uu.ravel(), vv.ravel(), size)
    q, _, _ = evaluate(fit, uu.ravel(), vv.ravel())
    return float(np.linalg.norm(p + d * n - q, axis=1).max())


def offset_def(base, entity, d: float, m):
    """The SurfaceDef of a 140 (``entity``) offsetting the SurfaceDef ``base`` by d, then mapped by
    the 140's matrix m (or None). Raises OffsetError."""

    def offset(s):
        o, _ = offset_bspline(s, d)
        return o if m is None else o.transformed(m)

    built = {}

    def place(box):
        key = None if box is None else tuple(box)
        if key not in built:
            s, mu, mv = base.place(box)
            built[key] = (offset(s), mu, mv)
        return built[key]

    place(None)  # an error shows now, where the entity is read
    same = m is None  # the base's closed-form inverses hold: a point of O has its foot's parameters
    return replace(
        base,
        entity=entity,
        place=place,
        whole=None if base.whole is None else offset(base.whole),
        plane=base.plane if same else None,
        invert=base.invert if same else None,
        closed_inverse=base.closed_inverse if same else None,
    )
