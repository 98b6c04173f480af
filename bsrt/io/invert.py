"""The closest point of a B-spline surface to given points: (x, y) with S(x, y) nearest each point.

One inverter for every reader that needs one (the OpenCASCADE import's
tabulated parameter maps, the IGES reader's curves on surfaces).
"""

from __future__ import annotations

import numpy as np

from bsrt.geometry.bspline import BSplineSurface, evaluate

_DAMP = 1e-14  # the smallest damping (relative to the normal matrix's diagonal): Gauss-Newton


def invert(surface: BSplineSurface, points: np.ndarray, x, y, size: float, iterations: int = 60):
    """(x, y), each (N,) float64, in the surface's domain with S(x, y) nearest ``points`` (N, 3), from starts x, y (N,).

    Levenberg-Marquardt, clamped to the domain, all points at once. Each
    point's damping starts at Gauss-Newton's (1e-14 of the normal matrix's
    diagonal); a step that leaves the point further from its target than it
    was is undone and retried with 10 times the damping (far from the
    surface the Gauss-Newton step overshoots, and can cycle), an accepted one
    divides it by 10 again. A parameter held at the domain's edge by its step
    leaves the other one a 1-D step (projected Newton: the coupled step would
    converge slowly, and beside the constrained minimum). A point stops when
    its step or its residual reaches rounding level (1e-14 of the domain, of
    ``size``). At a degenerate point (a pole) the free parameter stays at its
    start. Good starts matter: it converges to the nearest local minimum.
    """
    (a0, a1), (b0, b1) = surface.domain_u, surface.domain_v
    x = np.clip(np.array(x, dtype=np.float64), a0, a1)
    y = np.clip(np.array(y, dtype=np.float64), b0, b1)
    points = np.asarray(points, dtype=np.float64)
    n = x.shape[0]
    active = np.ones(n, dtype=bool)
    scale = max(1.0, abs(a0), abs(a1), abs(b0), abs(b1))
    best = np.full(n, np.inf)  # |residual| at the last accepted parameters (bx, by)
    bx, by = x.copy(), y.copy()
    normal = np.zeros((5, n))  # a, b, c, g0, g1 of the normal equations at (bx, by)
    mu = np.full(n, _DAMP)

    def step(ids):
        """Move points ids from their accepted parameters by a damped, projected step; True where it is negligible."""
        a, b, c, g0, g1 = normal[:, ids]
        damp = mu[ids] * (a + c) + 1e-300
        a, c = a + damp, c + damp
        det = a * c - b * b
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        dx, dy = (c * g0 - b * g1) / det, (a * g1 - b * g0) / det
        x0, y0 = bx[ids], by[ids]
        held_x = ((x0 <= a0) & (dx < 0)) | ((x0 >= a1) & (dx > 0))
        held_y = ((y0 <= b0) & (dy < 0)) | ((y0 >= b1) & (dy > 0))
        dx, dy = (
            np.where(held_x, 0.0, np.where(held_y, g0 / a, dx)),
            np.where(held_y, 0.0, np.where(held_x, g1 / c, dy)),
        )
        x[ids] = np.clip(x0 + dx, a0, a1)
        y[ids] = np.clip(y0 + dy, b0, b1)
        return np.hypot(x[ids] - x0, y[ids] - y0) <= 1e-14 * scale

    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        s, su, sv = evaluate(surface, x[idx], y[idx])
        r = points[idx] - s
        dist = np.sqrt(np.einsum("ni,ni->n", r, r))
        worse = dist > best[idx] * (1 + 1e-12) + 1e-15 * size
        w = idx[worse]
        if w.size:  # undone: retried from the accepted parameters with more damping
            mu[w] *= 10.0
            stop = step(w)
            x[w[stop]], y[w[stop]] = bx[w[stop]], by[w[stop]]
            active[w[stop]] = False
        keep = ~worse
        idx, su, sv, r, dist = idx[keep], su[keep], sv[keep], r[keep], dist[keep]
        if idx.size == 0:
            continue
        best[idx], bx[idx], by[idx] = dist, x[idx], y[idx]
        normal[:, idx] = (
            np.einsum("ni,ni->n", su, su),
            np.einsum("ni,ni->n", su, sv),
            np.einsum("ni,ni->n", sv, sv),
            np.einsum("ni,ni->n", su, r),
            np.einsum("ni,ni->n", sv, r),
        )
        done = step(idx) | (dist <= 1e-14 * size)
        mu[idx] = np.maximum(mu[idx] * 0.1, _DAMP)
        active[idx[done]] = False
    return x, y
