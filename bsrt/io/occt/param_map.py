"""The map from a face's original (u, v) to its B-spline's parameters, in closed form where it has one.

One :class:`AxisMap` per direction ("identity", "arc": OpenCASCADE's rational
quadratic arcs, x = b_i + h (1 + tan((t - m) / 2) / tan(h / 4)) / 2 between
knots, or "table": Chebyshev-tabulated by inversion); :class:`ParamMap` holds
the two and the period shifts. surfaces.py decides the kinds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_TABLE_NODES = 17  # Chebyshev-Lobatto points per span of a tabulated map


@dataclass
class AxisMap:
    """x = f(t): one direction's increasing map from the original parameter t to the B-spline's x.

    kind: "identity", "arc" or "table" (see the module doc).
    breaks: (K,) float64, the B-spline's distinct knots in this direction
      (before any rotation), the ends of the spans of f.
    period: the B-spline's period in x (0 when it is not periodic); f is
      extended by f(t + period) = f(t) + period.
    shift: added to t before the spans are looked up (a whole number of
      the original surface's periods).
    table: for kind "table", (K - 1, N) t-values and (K - 1, N) x-values of
      the Chebyshev-Lobatto points of each span; else None.
    """

    kind: str
    breaks: np.ndarray
    period: float = 0.0
    shift: float = 0.0
    table: tuple[np.ndarray, np.ndarray] | None = None

    def __call__(self, t) -> np.ndarray:
        """(N,) x of (N,) t."""
        t = np.asarray(t, dtype=np.float64) + self.shift  # (a new array)
        if self.kind == "identity":
            return t
        b = self.breaks
        if self.table is not None:
            ends = self.table[0][:, 0]
            lo = ends[0]
            span_source = np.append(ends, self.table[0][-1, -1])
        else:
            lo = b[0]
            span_source = b
        wraps = None
        if self.period > 0:
            wraps = np.floor((t - lo) / self.period)
            t = t - wraps * self.period
        span = np.minimum(np.maximum(np.searchsorted(span_source, t, side="right") - 1, 0), b.size - 2)
        if self.kind == "arc":
            b0, b1 = b[span], b[span + 1]
            h = b1 - b0
            m = 0.5 * (b0 + b1)
            x = b0 + 0.5 * h * (1.0 + np.tan(0.5 * (t - m)) / np.tan(0.25 * h))
        else:
            x = _barycentric(self.table[0][span], self.table[1][span], t)
        return x if wraps is None else x + wraps * self.period

    def inverse(self, x) -> np.ndarray:
        """(N,) t of (N,) x: f's inverse."""
        x = np.asarray(x, dtype=np.float64)
        if self.kind == "identity":
            return x - self.shift
        b = self.breaks
        wraps = np.zeros_like(x)
        if self.period > 0:
            wraps = np.floor((x - b[0]) / self.period)
            x = x - wraps * self.period
        span = np.clip(np.searchsorted(b, x, side="right") - 1, 0, b.size - 2)
        if self.kind == "arc":
            h = b[span + 1] - b[span]
            m = 0.5 * (b[span] + b[span + 1])
            s = (x - b[span]) / h
            t = m + 2.0 * np.arctan((2.0 * s - 1.0) * np.tan(0.25 * h))
        else:
            t = _barycentric(self.table[1][span], self.table[0][span], x)
        return t + wraps * self.period - self.shift


def _chebyshev_lobatto(a, b, n: int) -> np.ndarray:
    """(..., n) Chebyshev-Lobatto points from a to b (increasing)."""
    s = 0.5 - 0.5 * np.cos(np.pi * np.arange(n) / (n - 1))
    return np.asarray(a)[..., None] + (np.asarray(b) - np.asarray(a))[..., None] * s


def _barycentric(nodes: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Interpolate values (N, n) given at Chebyshev-Lobatto nodes (N, n) at t (N,) (barycentric formula)."""
    n = nodes.shape[1]
    w = (-1.0) ** np.arange(n)
    w[0] *= 0.5
    w[-1] *= 0.5
    d = t[:, None] - nodes
    exact = d == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        c = w / d
        out = (c * values).sum(axis=1) / c.sum(axis=1)
    hit = exact.any(axis=1)
    if hit.any():
        out[hit] = values[hit][exact[hit]]
    return out


# ---------------------------------------------------------------------------
# The whole map


@dataclass
class ParamMap:
    """The map (u, v) -> (x, y) from the original surface's parameters to the B-spline's.

    fu, fv: the two directions' maps. bounds: the face's (umin, umax, vmin,
    vmax) in the original parameters. u_period, v_period: the original
    surface's periods (0 where not periodic). deviation: the largest distance
    (local units) between the original surface at (u, v) and the B-spline at
    the mapped (x, y), on a grid over the bounds (for an approximated offset,
    at least the approximation's own error). approximated: the B-spline
    approximates an offset of a free-form surface. identity: both maps are
    the identity (planes, B-splines): the pcurves are used as they are.
    """

    fu: AxisMap
    fv: AxisMap
    bounds: tuple[float, float, float, float]
    u_period: float
    v_period: float
    deviation: float = 0.0
    approximated: bool = False

    @property
    def identity(self) -> bool:
        return self.fu.kind == "identity" and self.fv.kind == "identity" and not self.fu.shift and not self.fv.shift

    def map(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) original (u, v) -> (N, 2) B-spline (x, y)."""
        out = np.empty((uv.shape[0], 2))
        out[:, 0], out[:, 1] = self.fu(uv[:, 0]), self.fv(uv[:, 1])
        return out
