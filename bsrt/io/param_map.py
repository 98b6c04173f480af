"""Parameter maps: how a file's parameter becomes a B-spline's, in closed form where it has one.

One :class:`ParamMap` type for both CAD readers. A map is monotone and
piecewise: piece i takes [x[i], x[i+1]] (the file's parameter: an IGES
entity's, an OpenCASCADE surface's angle or length) onto [s[i], s[i+1]] (the
B-spline's parameter). Each piece has a kind:

- "identity": s = x (OpenCASCADE's planes and B-splines);
- "linear": affine (IGES's polynomial entities);
- "tan": a circular arc of angle span d = x[i+1] - x[i] written as the usual
  rational quadratic (weights 1, cos(d/2), 1): s = s_i + (s_{i+1} - s_i)
  (1 + tan((x - m) / 2) / tan(d / 4)) / 2 about the middle m, and for an
  OpenCASCADE surface (where x = s at the knots) the same formula;
- "tanh": a hyperbolic arc, the same with tanh (angular pieces take x in radians, or
  hyperbolic units, times ``unit``: x may be a fraction of the arc, an IGES 118's or 122's u);
- "table": no closed form (an OpenCASCADE surface of revolution, say): the
  B-spline's parameter at Chebyshev-Lobatto points of x, interpolated
  (barycentric formula; :data:`TABLE_NODES` per piece).

Outside [x[0], x[-1]] the end pieces are extended: linear ones exactly,
angular ones clipped to their ends (an IGES conic ends there) unless
``extend`` (an OpenCASCADE surface's map: a pcurve may run a rounding error
past the face's bounds, and the formula holds there). ``period`` (the B-spline's, in s, and
the original's, in x) extends the map by f(x + period) = f(x) + period;
``shift`` is added to x first (a whole number of periods). :class:`FaceMap`
holds one face's two maps.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from functools import cached_property

import numpy as np

TABLE_NODES = 17  # Chebyshev-Lobatto points per piece of a tabulated map
_ANGULAR = {"tan": (np.tan, np.arctan), "tanh": (np.tanh, np.arctanh)}


@dataclass(frozen=True, eq=False)
class ParamMap:
    """A monotone, piecewise map x (a file's parameter) -> s (a B-spline's parameter); see the module doc.

    x, s: (k + 1,) float64, increasing breakpoints. kinds: k strings, one per
    piece. table: for "table" pieces, (k, n) x and (k, n) s at the
    Chebyshev-Lobatto points of each piece's x range; else None. period: 0
    when the map is not periodic. shift: added to x before the pieces are
    looked up. extend: angular end pieces are extended beyond x[0] and
    x[-1] by their formula, not clipped. unit: radians per unit of x in angular pieces.
    """

    x: np.ndarray
    s: np.ndarray
    kinds: tuple[str, ...]
    table: tuple[np.ndarray, np.ndarray] | None = None
    period: float = 0.0
    shift: float = 0.0
    extend: bool = False
    unit: float = 1.0

    @staticmethod
    def identity(a: float, b: float) -> ParamMap:
        """The affine map of [a, b] onto itself (one "linear" piece)."""
        return ParamMap(np.array([a, b], float), np.array([a, b], float), ("linear",))

    @staticmethod
    def on_knots(kind: str, breaks: np.ndarray, period: float = 0.0, table=None) -> ParamMap:
        """A map whose x equals s at the B-spline's distinct knots ``breaks`` (K,) ("identity" or
        "tan"), or, for "table", the tabulated map whose (t, x) tables (K - 1, n) give x there."""
        x = breaks if table is None else np.append(table[0][:, 0], table[0][-1, -1])
        return ParamMap(x, breaks, (kind,) * (breaks.size - 1), table, period, extend=True)

    @property
    def kind(self) -> str:
        """The first piece's kind (a map made by :meth:`on_knots` has one kind throughout)."""
        return self.kinds[0]

    def with_shift(self, shift: float) -> ParamMap:
        return ParamMap(self.x, self.s, self.kinds, self.table, self.period, shift, self.extend, self.unit)

    def _wrapped(self, v: np.ndarray, breaks: np.ndarray):
        """(v within one period from breaks[0], the whole periods taken off (or None), each v's piece)."""
        wraps = None
        if self.period > 0:
            wraps = np.floor((v - breaks[0]) / self.period)
            v = v - wraps * self.period
        piece = np.minimum(np.maximum(np.searchsorted(breaks, v, side="right") - 1, 0), len(self.kinds) - 1)
        return v, wraps, piece

    def __call__(self, x) -> np.ndarray:
        """s at x: (N,) -> (N,)."""
        x = np.atleast_1d(np.asarray(x, dtype=np.float64)) + self.shift  # (a new array)
        if self.kinds[0] == "identity":
            return x
        x, wraps, i = self._wrapped(x, self.x)
        if self._uniform is not None:
            out = self._local(self._uniform, i, x)
        else:
            out = np.empty_like(x)
            for k in set(self.kinds):
                sel = self._of_kind(k)[i]
                out[sel] = self._local(k, i[sel], x[sel])
        return out if wraps is None else out + wraps * self.period

    @cached_property
    def _uniform(self) -> str | None:
        """The pieces' kind if they all have one, else None."""
        return self.kinds[0] if self.kinds.count(self.kinds[0]) == len(self.kinds) else None

    def _of_kind(self, kind: str) -> np.ndarray:
        """(k,) bool: the pieces of that kind."""
        return np.array([k == kind for k in self.kinds])

    @cached_property
    def _pieces(self) -> dict[str, np.ndarray]:
        """Each piece's constants (k,), computed once for every call: x0, s0, the slope (s1 - s0) / (x1 - x0)
        (a linear piece's), the middle m, the half width d / 2, the half rise (s1 - s0) / 2 and, for an
        angular piece, f(d / 4) (d = x1 - x0)."""
        x0, x1, s0, s1 = self.x[:-1], self.x[1:], self.s[:-1], self.s[1:]
        d = x1 - x0
        out = {"x0": x0, "s0": s0, "slope": (s1 - s0) / d, "m": 0.5 * (x0 + x1), "hd": 0.5 * d, "rise": 0.5 * (s1 - s0)}
        for kind, (f, _) in _ANGULAR.items():
            if kind in self.kinds:
                out[kind] = f(0.25 * d * self.unit)
        return out

    def _local(self, kind: str, i: np.ndarray, x: np.ndarray) -> np.ndarray:
        c = self._pieces
        if kind == "linear":
            return c["s0"][i] + (x - c["x0"][i]) * c["slope"][i]
        if kind == "table":
            return _barycentric(self.table[0][i], self.table[1][i], x)
        f, _ = _ANGULAR[kind]
        y = x - c["m"][i]
        if not self.extend:
            hd = c["hd"][i]
            y = np.clip(y, -hd, hd)
        return c["s0"][i] + c["rise"][i] * (1.0 + f(0.5 * y * self.unit) / c[kind][i])

    def inverse(self, s) -> np.ndarray:
        """x at s (the inverse map): (N,) -> (N,)."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        if self.kinds[0] == "identity":
            return s - self.shift
        s, wraps, i = self._wrapped(s, self.s)
        out = np.empty_like(s)
        for k in (self._uniform,) if self._uniform is not None else set(self.kinds):
            sel = slice(None) if self._uniform is not None else self._of_kind(k)[i]
            j = i[sel]
            x0, x1, s0, s1 = self.x[j], self.x[j + 1], self.s[j], self.s[j + 1]
            if k == "table":
                out[sel] = _barycentric(self.table[1][j], self.table[0][j], s[sel])
                continue
            t = (s[sel] - s0) / (s1 - s0)
            if k == "linear":
                out[sel] = x0 + t * (x1 - x0)
            else:
                f, f_inv = _ANGULAR[k]
                d = x1 - x0
                t = t if self.extend else np.clip(t, 0.0, 1.0)
                out[sel] = 0.5 * (x0 + x1) + 2.0 * f_inv((2.0 * t - 1.0) * f(0.25 * d * self.unit)) / self.unit
        if wraps is not None:
            out = out + wraps * self.period
        return out - self.shift

    def derivative(self, x) -> np.ndarray:
        """ds/dx at x: (N,) -> (N,) (identity, linear, tan and tanh pieces)."""
        if "table" in self.kinds:
            raise ValueError("a tabulated map has no derivative here")
        x = np.atleast_1d(np.asarray(x, dtype=np.float64)) + self.shift
        if self.kinds[0] == "identity":
            return np.ones_like(x)
        x, _, i = self._wrapped(x, self.x)
        x0, x1, s0, s1 = self.x[i], self.x[i + 1], self.s[i], self.s[i + 1]
        d, m = x1 - x0, 0.5 * (x0 + x1)
        out = (s1 - s0) / d  # linear
        for k, (f, _) in _ANGULAR.items():
            sel = self._of_kind(k)[i]
            if sel.any():
                y = x[sel] - m[sel] if self.extend else np.clip(x[sel] - m[sel], -0.5 * d[sel], 0.5 * d[sel])
                c = (np.cos if k == "tan" else np.cosh)(0.5 * y * self.unit)
                out[sel] = (s1 - s0)[sel] * self.unit / (4 * f(0.25 * d[sel] * self.unit) * c * c)
        return out

    def affine_on(self, lo: float, hi: float, tol: float = 0.0):
        """(scale, offset) with s = scale x + offset on [lo, hi] if the map is affine there, else None."""
        last = len(self.kinds) - 1
        if last == 0:
            i = j = 0
        else:
            xs = self.x.tolist()
            i = min(max(bisect.bisect_right(xs, lo + tol) - 1, 0), last)
            j = min(max(bisect.bisect_right(xs, hi - tol) - 1, 0), last)
        if i != j or self.kinds[i] != "linear" or self.period > 0:
            return None
        scale = (self.s[i + 1] - self.s[i]) / (self.x[i + 1] - self.x[i])
        return scale, self.s[i] - scale * self.x[i]

    def shifted(self, dx: float, ds: float) -> ParamMap:
        """The map moved by dx in x and ds in s."""
        return ParamMap(self.x + dx, self.s + ds, self.kinds, unit=self.unit)

    def scaled_x(self, a: float, b: float) -> ParamMap:
        """The map of x' where x = a x' + b (a > 0)."""
        return ParamMap((self.x - b) / a, self.s, self.kinds, unit=self.unit * a)


def concat_maps(maps: list[ParamMap]) -> ParamMap:
    """Maps of consecutive x and s ranges (each starting where the previous ends, all of one unit) as one."""
    x = [maps[0].x[:1]] + [m.x[1:] for m in maps]
    s = [maps[0].s[:1]] + [m.s[1:] for m in maps]
    return ParamMap(np.concatenate(x), np.concatenate(s), sum((m.kinds for m in maps), ()), unit=maps[0].unit)


def chebyshev_lobatto(a, b, n: int) -> np.ndarray:
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


@dataclass
class FaceMap:
    """The map (u, v) -> (x, y) from an OpenCASCADE face's surface parameters to its B-spline's.

    fu, fv: the two directions' maps. bounds: the face's (umin, umax, vmin,
    vmax) in the original parameters. u_period, v_period: the original
    surface's periods (0 where not periodic). deviation: the largest distance
    (local units) between the original surface at (u, v) and the B-spline at
    the mapped (x, y), on a grid over the bounds (for an approximated offset,
    at least the approximation's own error). approximated: the B-spline
    approximates an offset of a free-form surface. identity: both maps are
    the identity (planes, B-splines): the pcurves are used as they are.
    """

    fu: ParamMap
    fv: ParamMap
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
