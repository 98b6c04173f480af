"""The closest point of a B-spline surface to given points: (x, y) with S(x, y) nearest each point.

One inverter for every reader that needs one (the OpenCASCADE import's
tabulated parameter maps, the IGES reader's curves on surfaces).
"""

from __future__ import annotations

import numpy as np

from ..bspline import BSplineSurface, evaluate


def invert(surface: BSplineSurface, points: np.ndarray, x, y, size: float, iterations: int = 60):
    """(x, y), each (N,) float64, in the surface's domain with S(x, y) nearest ``points`` (N, 3), from starts x, y (N,).

    Damped Gauss-Newton (Levenberg-Marquardt), clamped to the domain, all
    points at once; a point stops when its step or its residual reaches
    rounding level (1e-14 of the domain, of ``size``). At a degenerate point
    (a pole) the free parameter stays at its start. Good starts matter: it
    converges to the nearest local minimum.
    """
    (a0, a1), (b0, b1) = surface.domain_u, surface.domain_v
    x = np.clip(np.array(x, dtype=np.float64), a0, a1)
    y = np.clip(np.array(y, dtype=np.float64), b0, b1)
    points = np.asarray(points, dtype=np.float64)
    active = np.ones(x.shape, dtype=bool)
    scale = max(1.0, abs(a0), abs(a1), abs(b0), abs(b1))
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        s, su, sv = evaluate(surface, x[idx], y[idx])
        r = points[idx] - s
        a = np.einsum("ni,ni->n", su, su)
        b = np.einsum("ni,ni->n", su, sv)
        c = np.einsum("ni,ni->n", sv, sv)
        g0 = np.einsum("ni,ni->n", su, r)
        g1 = np.einsum("ni,ni->n", sv, r)
        damp = 1e-14 * (a + c) + 1e-300
        a, c = a + damp, c + damp
        det = a * c - b * b
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        nx = np.clip(x[idx] + (c * g0 - b * g1) / det, a0, a1)
        ny = np.clip(y[idx] + (a * g1 - b * g0) / det, b0, b1)
        step = np.hypot(nx - x[idx], ny - y[idx])
        x[idx], y[idx] = nx, ny
        done = (step <= 1e-14 * scale) | (np.linalg.norm(r, axis=1) <= 1e-14 * size)
        active[idx[done]] = False
    return x, y
