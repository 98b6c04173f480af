"""Is (u, v) kept? The even-odd test on a surface's trim loops, exact at the curve.

The table is ``bsrt.trim.TrimTable`` (monotone rational Bezier pieces,
banded over v; see bsrt/trim.py for why the answer is exact). A horizontal
ray from (u, v) toward +u crosses a monotone piece at most once: the piece
counts when v lies in its half-open v-range [min(v0, v1), max(v0, v1)) (so a
ray through a vertex shared by two pieces counts it once, or twice at a
turning point: the parity is right either way) and the crossing lies at
u' > u: decided by the piece's box, or else by solving V(s) = v on the piece
(bisection, to machine precision) and comparing U(s) with u.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

OUTSIDE, INSIDE, MIXED = 0, 1, 2
BISECTIONS = 64


@njit(cache=True, inline="always")
def _horner(coef, k, d, c, s):
    a = coef[k, d, c]
    for i in range(d - 1, -1, -1):
        a = a * s + coef[k, i, c]
    return a


@njit(cache=True)
def _crosses_right(T, k, u, v):
    """Does the ray from (u, v) toward +u cross piece k (v in its half-open range assumed)?"""
    box = T.box[k]
    if u < box[0]:
        return True
    if u > box[1]:
        return False
    d = T.degree[k]
    a, b = 0.0, 1.0
    rising = T.ends[k, 1] > T.ends[k, 0]
    for _ in range(BISECTIONS):
        mid = 0.5 * (a + b)
        vm = _horner(T.coef, k, d, 1, mid) / _horner(T.coef, k, d, 2, mid)
        if (vm < v) == rising:
            a = mid
        else:
            b = mid
    s = 0.5 * (a + b)
    return _horner(T.coef, k, d, 0, s) / _horner(T.coef, k, d, 2, s) > u


@njit(cache=True, inline="always")
def _band(T, m, v):
    count = T.band_count[m]
    b = int((v - T.band_v0[m]) / T.band_height[m]) if v > T.band_v0[m] else 0
    return T.band_first[m] + min(max(b, 0), count - 1)


@njit(cache=True)
def point_kept(T, m, u, v):
    """Is (u, v) of surface m inside an odd number of its loops (or is m untrimmed)?"""
    if not T.trimmed[m]:
        return True
    band = _band(T, m, v)
    inside = False
    for e in range(T.band_start[band], T.band_start[band + 1]):
        k = T.band_pieces[e]
        v0, v1 = T.ends[k, 0], T.ends[k, 1]
        if v0 > v1:
            v0, v1 = v1, v0
        if v0 <= v < v1 and _crosses_right(T, k, u, v):
            inside = not inside
    return inside


@njit(cache=True)
def rect_state(T, m, u0, u1, v0, v1):
    """OUTSIDE, INSIDE or MIXED: the rectangle [u0, u1] x [v0, v1] of surface m is
    entirely removed, entirely kept, or (conservatively) crossed by a curve."""
    if not T.trimmed[m]:
        return INSIDE
    first, last = _band(T, m, v0), _band(T, m, v1)
    for band in range(first, last + 1):
        for e in range(T.band_start[band], T.band_start[band + 1]):
            box = T.box[T.band_pieces[e]]
            if box[0] <= u1 and box[1] >= u0 and box[2] <= v1 and box[3] >= v0:
                return MIXED
    return INSIDE if point_kept(T, m, 0.5 * (u0 + u1), 0.5 * (v0 + v1)) else OUTSIDE


@njit(cache=True, parallel=True)
def _kept_many(T, surface, u, v, out):
    for i in prange(surface.shape[0]):
        out[i] = point_kept(T, surface[i], u[i], v[i])


@njit(cache=True, parallel=True)
def _rect_states(T, surface, u0, u1, v0, v1, out):
    for i in prange(surface.shape[0]):
        out[i] = rect_state(T, surface[i], u0[i], u1[i], v0[i], v1[i])


def kept_many(T, surface, u, v):
    """(N,) bool: point_kept for every (surface[i], u[i], v[i])."""
    out = np.empty(len(surface), dtype=np.bool_)
    _kept_many(T, np.ascontiguousarray(surface, dtype=np.int64), np.ascontiguousarray(u, dtype=np.float64),
               np.ascontiguousarray(v, dtype=np.float64), out)
    return out


def rect_states(T, surface, u0, u1, v0, v1):
    """(N,) int64: rect_state for every (surface[i], [u0[i], u1[i]] x [v0[i], v1[i]])."""
    out = np.empty(len(surface), dtype=np.int64)
    f = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    _rect_states(T, np.ascontiguousarray(surface, dtype=np.int64), f(u0), f(u1), f(v0), f(v1), out)
    return out
