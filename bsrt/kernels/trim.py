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
from numba import njit

OUTSIDE, INSIDE, MIXED = 0, 1, 2
BISECTIONS = 64


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def _kept_many(T, surface, u, v, out):
    for i in range(surface.shape[0]):
        out[i] = point_kept(T, surface[i], u[i], v[i])


@njit(cache=True)
def _rect_states(T, surface, u0, u1, v0, v1, out):
    for i in range(surface.shape[0]):
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


# ---------------------------------------------------------------------------
# Building the table (called by bsrt.trim.build_trim_table)


@njit(cache=True)
def bezier_spans(knots, ctrl, p):
    """The rational Bezier nets (S, p + 1, 3) of a B-spline curve's spans, in order.

    knots: (n + p + 1,); ctrl: (n, 3) homogeneous (w u, w v, w). Each span's
    net is the blossom at (a, .., a, b, .., b) of the span [a, b], computed
    with de Boor's algorithm (any knot vector, clamped or not).
    """
    n = ctrl.shape[0]
    count = 0
    for i in range(p, n):
        if knots[i] < knots[i + 1]:
            count += 1
    out = np.empty((count, p + 1, 3))
    d = np.empty((p + 1, 3))
    s = 0
    for i in range(p, n):
        a, b = knots[i], knots[i + 1]
        if not a < b:
            continue
        for k in range(p + 1):
            for j in range(p + 1):
                d[j] = ctrl[j + i - p]
            for r in range(1, p + 1):
                x = a if r <= p - k else b
                for j in range(p, r - 1, -1):
                    lo, hi = knots[j + i - p], knots[j + 1 + i - r]
                    alpha = (x - lo) / (hi - lo) if hi > lo else 0.0
                    d[j] = (1.0 - alpha) * d[j - 1] + alpha * d[j]
            out[s, k] = d[p]
        s += 1
    return out


@njit(cache=True)
def _monotone(net, d):
    up_u = down_u = up_v = down_v = False
    for i in range(d):
        du = net[i + 1, 0] / net[i + 1, 2] - net[i, 0] / net[i, 2]
        dv = net[i + 1, 1] / net[i + 1, 2] - net[i, 1] / net[i, 2]
        up_u |= du > 0.0
        down_u |= du < 0.0
        up_v |= dv > 0.0
        down_v |= dv < 0.0
    return not (up_u and down_u) and not (up_v and down_v)


@njit(cache=True)
def _split_monotone(net, d, max_cuts, fill, first, out, out_degree):
    """Halve one net (d + 1, 3) until monotone; with fill, write the pieces from index first.

    (Element loops, not array slices: numba compiles those far faster.)"""
    stack = np.empty((max_cuts + 2, d + 1, 3))
    cuts = np.empty(max_cuts + 2, dtype=np.int64)
    tmp = np.empty((d + 1, 3))
    for r in range(d + 1):
        for c in range(3):
            stack[0, r, c] = net[r, c]
    cuts[0] = 0
    top, count = 1, 0
    while top > 0:
        top -= 1
        ok = _monotone(stack[top], d)
        if ok or cuts[top] >= max_cuts:
            if fill:
                k = first + count
                for r in range(out.shape[1]):
                    for c in range(3):
                        out[k, r, c] = 0.0
                if ok:
                    for r in range(d + 1):
                        for c in range(3):
                            out[k, r, c] = stack[top, r, c]
                    out_degree[k] = d
                else:  # a tiny stretch around an axis-parallel tangent: its chord
                    for c in range(3):
                        out[k, 0, c] = stack[top, 0, c]
                        out[k, 1, c] = stack[top, d, c]
                    out_degree[k] = 1
            count += 1
            continue
        for r in range(d + 1):
            for c in range(3):
                tmp[r, c] = stack[top, r, c]
        hi = top + 1  # de Casteljau at 1/2: the lower half in slot hi (popped first), the upper in slot top
        for r in range(d + 1):
            for c in range(3):
                stack[hi, r, c] = tmp[0, c]
                stack[top, d - r, c] = tmp[d - r, c]
            for i in range(d - r):
                for c in range(3):
                    tmp[i, c] = 0.5 * (tmp[i, c] + tmp[i + 1, c])
        cuts[hi] = cuts[top] = cuts[top] + 1
        top += 2
    return count


@njit(cache=True)
def monotone_pieces(nets, degree, max_cuts):
    """Every net (N, D + 1, 3) of degree (N,) halved until monotone in u and v:
    (pieces (K, D + 1, 3), their degree (K,), the net each came from (K,))."""
    n = nets.shape[0]
    counts = np.zeros(n, dtype=np.int64)
    none, none_d = np.empty((0, nets.shape[1], 3)), np.empty(0, dtype=np.int64)
    for k in range(n):
        counts[k] = _split_monotone(nets[k], degree[k], max_cuts, False, 0, none, none_d)
    starts = np.zeros(n + 1, dtype=np.int64)
    starts[1:] = np.cumsum(counts)
    out = np.zeros((starts[n], nets.shape[1], 3))
    out_degree = np.empty(starts[n], dtype=np.int64)
    owner = np.empty(starts[n], dtype=np.int64)
    for k in range(n):
        _split_monotone(nets[k], degree[k], max_cuts, True, starts[k], out, out_degree)
        owner[starts[k]:starts[k + 1]] = k
    return out, out_degree, owner


@njit(cache=True)
def classify_grid(T, m, gu, gv, out):
    """State of every cell of the grid gu (I + 1,) x gv (J + 1,) of surface m into out (I, J).

    Quadtree over cell ranges: a range the curves miss takes the state of
    its centre at once, so only the cells near a curve are tested one by one.
    """
    stack = np.empty((64 + 4 * 64, 4), dtype=np.int64)
    stack[0] = (0, gu.shape[0] - 1, 0, gv.shape[0] - 1)
    top = 1
    while top > 0:
        top -= 1
        i0, i1, j0, j1 = stack[top]
        state = rect_state(T, m, gu[i0], gu[i1], gv[j0], gv[j1])
        if state != MIXED or (i1 - i0 == 1 and j1 - j0 == 1):
            out[i0:i1, j0:j1] = state
            continue
        if i1 - i0 >= j1 - j0:
            mid = (i0 + i1) // 2
            stack[top] = (i0, mid, j0, j1)
            stack[top + 1] = (mid, i1, j0, j1)
        else:
            mid = (j0 + j1) // 2
            stack[top] = (i0, i1, j0, mid)
            stack[top + 1] = (i0, i1, mid, j1)
        top += 2
