"""Cutting trim curves into the trim table's pieces: rational Bezier nets, monotone in u and v.

Called by :func:`bsrt.geometry.trim_table.build_trim_table`; the point and box
tests on the pieces are in kernels/trim.py.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit

MONOTONE_TOL = 64 * 2.220446049250313e-16  # control-polygon steps below this x the magnitude count as flat


@njit(cache=True, error_model="numpy")
def bezier_spans(knots, ctrl, p):
    """The rational Bezier nets (S, p + 1, 3) of a B-spline curve's non-empty spans, in order.

    knots: (n + p + 1,); ctrl: (n, 3) homogeneous (w u, w v, w). Net k of
    the span [a, b] is the blossom at (a, .., a, b, .., b) (k times b),
    computed with de Boor's algorithm (any knot vector, clamped or not): the
    same curve as inserting every knot to full multiplicity (Boehm)."""
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
                for c in range(3):
                    d[j, c] = ctrl[j + i - p, c]
            for r in range(1, p + 1):
                x = a if r <= p - k else b
                for j in range(p, r - 1, -1):
                    lo, hi = knots[j + i - p], knots[j + 1 + i - r]
                    alpha = (x - lo) / (hi - lo) if hi > lo else 0.0
                    for c in range(3):
                        d[j, c] = (1.0 - alpha) * d[j - 1, c] + alpha * d[j, c]
            for c in range(3):
                out[s, k, c] = d[p, c]
        s += 1
    return out


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _magnitude(net, d):
    """The largest |u| or |v| of a net's control points."""
    mag = 0.0
    for i in range(d + 1):
        mag = max(mag, max(abs(net[i, 0] / net[i, 2]), abs(net[i, 1] / net[i, 2])))
    return mag


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _flaws(net, d, floor):
    """Which coordinates' control polygon turns back: 0 none, 1 u, 2 v, 3 both (steps within
    MONOTONE_TOL x max(the coordinates' magnitude, floor) count as flat: rounding, which is
    relative to the span the net was cut from, its magnitude being floor); -1: the net is one
    point."""
    up_u = down_u = up_v = down_v = False
    tol = MONOTONE_TOL * max(_magnitude(net, d), floor)
    point = True
    for i in range(d):
        du = net[i + 1, 0] / net[i + 1, 2] - net[i, 0] / net[i, 2]
        dv = net[i + 1, 1] / net[i + 1, 2] - net[i, 1] / net[i, 2]
        point = point and du == 0.0 and dv == 0.0
        up_u |= du > tol
        down_u |= du < -tol
        up_v |= dv > tol
        down_v |= dv < -tol
    if point:
        return -1
    return (1 if up_u and down_u else 0) + (2 if up_v and down_v else 0)


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _casteljau(src, d, s, lo, hi, tmp):
    """Cut net src (d + 1, 3) at s into lo (the part [0, s]) and hi ([s, 1]); tmp (d + 1, 3) scratch.
    The cut point is written once and copied, so both halves hold the same numbers."""
    for r in range(d + 1):
        for c in range(3):
            tmp[r, c] = src[r, c]
    for r in range(d + 1):
        for c in range(3):
            lo[r, c] = tmp[0, c]
            hi[d - r, c] = tmp[d - r, c]
        for i in range(d - r):
            for c in range(3):
                tmp[i, c] = (1.0 - s) * tmp[i, c] + s * tmp[i + 1, c]


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _slope_sign(net, d, c, s, tmp):
    """Sign of d/ds of coordinate c (0: u, 1: v) of net (d + 1, 3) at s: from the two points of
    de Casteljau's next-to-last level, x1 w0 - x0 w1 (taken about the net's first point)."""
    o = net[0, c] / net[0, 2]
    for r in range(d + 1):
        tmp[r, 0] = net[r, c] - o * net[r, 2]
        tmp[r, 1] = net[r, 2]
    for r in range(1, d):
        for i in range(d - r + 1):
            tmp[i, 0] = (1.0 - s) * tmp[i, 0] + s * tmp[i + 1, 0]
            tmp[i, 1] = (1.0 - s) * tmp[i, 1] + s * tmp[i + 1, 1]
    x = tmp[1, 0] * tmp[0, 1] - tmp[0, 0] * tmp[1, 1]
    return 1 if x > 0.0 else (-1 if x < 0.0 else 0)


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _cut_at(net, d, flaws, tmp):
    """Where to cut a net whose polygon turns back (flaws as _flaws): at the turning point of v
    (else u) when the curve leaves its start and reaches its end in opposite directions in that
    coordinate, found by bisection on the sign of the slope; else at 1/2. The direction at an
    end is that of the first control point differing from the end one (the curve's first
    non-zero term there, weights being positive), so repeated end points do no harm."""
    for c in (1, 0):
        if not flaws & (1 << c):
            continue
        s0 = s1 = 0
        for i in range(1, d + 1):
            x = net[i, c] / net[i, 2] - net[0, c] / net[0, 2]
            if x != 0.0:
                s0 = 1 if x > 0.0 else -1
                break
        for i in range(d - 1, -1, -1):
            x = net[d, c] / net[d, 2] - net[i, c] / net[i, 2]
            if x != 0.0:
                s1 = 1 if x > 0.0 else -1
                break
        if s0 * s1 >= 0:
            continue
        a, b = 0.0, 1.0
        for _ in range(80):
            mid = 0.5 * (a + b)
            if not (a < mid < b):
                break
            if _slope_sign(net, d, c, mid, tmp) == s0:
                a = mid
            else:
                b = mid
        s = 0.5 * (a + b)
        if 1e-9 < s < 1.0 - 1e-9:
            return s
    return 0.5


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _emit(cur, d, ok, out, out_degree, k):
    """Write piece k: net cur (d + 1, 3) if ok, else its chord (degree 1)."""
    for r in range(out.shape[1]):
        for c in range(3):
            out[k, r, c] = 0.0
    if ok:
        for r in range(d + 1):
            for c in range(3):
                out[k, r, c] = cur[r, c]
        out_degree[k] = d
    else:  # a stretch shorter than 2^-max_depth of its span around a turning point: its chord
        for c in range(3):
            out[k, 0, c] = cur[0, c]
            out[k, 1, c] = cur[d, c]
        out_degree[k] = 1


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _split_net(net, d, max_depth, fill, out, out_degree, first):
    """Cut one net (d + 1, 3) until every piece's polygon is monotone in u and v; with fill, write
    the pieces, in order along the curve, to out (C, D + 1, 3) / out_degree from index first.
    Returns the number of pieces. A net that is one point is dropped (it never crosses a ray); a
    piece still turning back after max_depth cuts is replaced by its chord."""
    floor = _magnitude(net, d)
    stack = np.empty((max_depth + 2, d + 1, 3))
    depth = np.empty(max_depth + 2, dtype=np.int64)
    tmp = np.empty((d + 1, 3))
    lo = np.empty((d + 1, 3))
    hi = np.empty((d + 1, 3))
    for r in range(d + 1):
        for c in range(3):
            stack[0, r, c] = net[r, c]
    depth[0] = 0
    top = 1
    count = 0
    while top > 0:
        top -= 1
        cur = stack[top]
        flaws = _flaws(cur, d, floor)
        if flaws == -1:
            continue
        if flaws == 0 or depth[top] >= max_depth:
            if fill:
                _emit(cur, d, flaws == 0, out, out_degree, first + count)
            count += 1
            continue
        s = _cut_at(cur, d, flaws, tmp)
        _casteljau(cur, d, s, lo, hi, tmp)
        for r in range(d + 1):  # the part [0, s] on top: popped first, so the pieces stay in order
            for c in range(3):
                stack[top, r, c] = hi[r, c]
                stack[top + 1, r, c] = lo[r, c]
        depth[top + 1] = depth[top] + 1
        depth[top] += 1
        top += 2
    return count


@njit(cache=True, error_model="numpy")
def monotone_pieces(nets, degree, max_depth):
    """Every net (S, D + 1, 3) of degree (S,) cut until its control polygon is monotone in u and
    in v: (pieces (K, D + 1, 3), their degree (K,), the net each came from (K,)), in order.
    (Two passes, count then fill; element loops rather than array slices, which numba compiles
    far more slowly.)"""
    n = nets.shape[0]
    starts = np.zeros(n + 1, dtype=np.int64)
    out = np.empty((0, nets.shape[1], 3))
    out_degree = np.empty(0, dtype=np.int64)
    for phase in range(2):  # count, then fill (one specialisation of _split_net: fill is no literal)
        fill = phase == 1
        if fill:
            out = np.empty((starts[n], nets.shape[1], 3))
            out_degree = np.empty(starts[n], dtype=np.int64)
        for k in range(n):
            count = _split_net(nets[k], degree[k], max_depth, fill, out, out_degree, starts[k])
            if not fill:
                starts[k + 1] = starts[k] + count
    owner = np.empty(starts[n], dtype=np.int64)
    for k in range(n):
        for i in range(starts[k], starts[k + 1]):
            owner[i] = k
    return out, out_degree, owner
