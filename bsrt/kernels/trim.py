"""Is (u, v) kept? The even-odd test on a surface's trim loops, exact at the curve.

The table is :class:`TrimTable` (monotone rational Bezier pieces, banded
over v; its docstring lists the arrays, bsrt/geometry/trim.py's module doc
says why the answer is exact; kernels/trim_pieces.py cuts the curves into
those pieces). A horizontal ray from (u, v) toward +u
crosses a monotone piece at most once. The piece counts when v lies in its
half-open v-range [min(v_a, v_b), max(v_a, v_b)) (v_a, v_b its end points:
a ray through a vertex shared by two pieces then counts it once, or twice
at a turning point, which is the right parity either way; a horizontal
piece never counts) and the crossing lies at u' > u. That is decided

1. by the band entry's box (the band lists its pieces by decreasing u_max,
   so the scan stops at the first piece wholly left of u; a piece wholly
   right of u counts at once),
2. else by the end points (the piece is monotone, so the crossing lies
   between u_a and u_b: both right of u, or both not, decides),
3. else, for a line (degree 1, any weights: still the segment), by the sign
   of one cross product,
4. else on the curve itself: the root s* of V(s) = v is bracketed in [a, b]
   (Newton steps pushed 1 % past the root, so that the bracket closes from
   both ends; bisection whenever it stops halving); as U is monotone too,
   U(s*) lies between U(a) and U(b), and the answer is known as soon as both
   lie on the same side of u (on a circle of radius 0.3, on average after
   2.7 evaluations for points 1e-2 from it, 5.3 at 1e-6, 7 at 1e-9); only
   points within rounding of the curve run the bracket down to neighbouring
   floats.

Every kernel is compiled once (``cache=True``), typed with float64/int64/bool
arrays only, no fastmath; ``point_kept`` and ``rect_state`` are called from
other kernels (the root finders, the hierarchy walk), the ``*_many``
wrappers run on every core through ``threads.run_chunks``. The point test
and its helpers are compiled without numba's reference counting
(``_nrt=False``; they allocate nothing): counting the references of the
table's twelve arrays on every call cost twice the scan itself.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bsrt.kernels.jit import njit
from bsrt.kernels.threads import run_chunks


class TrimTable(NamedTuple):
    """Every trimmed surface's loops as monotone rational Bezier pieces, in flat arrays.

    One argument for the kernels (numba takes a NamedTuple of arrays). M
    surfaces (in the order given to build_trim_table), K pieces, D the
    largest piece degree, B bands in all, E band entries. Every array is
    C-contiguous; float64 unless said otherwise.

    Per surface:
      trimmed: (M,) bool, the surface has loops (False: every (u, v) is kept,
        and the kernels answer at once).
      band_first: (M,) int64, the surface's first band (an index into
        band_start); band_count: (M,) int64, its number of bands (>= 1).
      band_v0: (M,); band_scale: (M,), bands per unit of v: v lies in the
        surface's band int((v - band_v0) * band_scale), clamped to
        [0, band_count - 1] (the end bands reach to -inf and +inf).
      magnitude: (M,), the largest |u| or |v| of the surface's pieces' boxes
        (0 without pieces): rect_state's margin scales with it.
    Per piece (a rational Bezier curve monotone in u and in v; the pieces of
    a loop are consecutive and in order along it):
      degree: (K,) int64, d >= 1.
      coef: (K, D + 1, 3), the piece's (w (u - u_a), w (v - v_a), w) in the
        power basis of its parameter s in [0, 1]: row i multiplies s^i, rows
        above d are 0. (u_a, v_a) is its start (ends[:, :2]).
      ends: (K, 4), (u_a, v_a, u_b, v_b): its start and end, exactly the
        previous piece's end and the next piece's start.
      box: (K, 4), (u_min, u_max, v_min, v_max) of its control points and
        ends: it holds the piece.
    Bands:
      band_start: (B + 1,) int64, band b's entries are
        band_start[b] : band_start[b + 1], sorted by decreasing u_max.
      entry_piece: (E,) int64, the piece of each entry; a piece is listed in
        every band of its surface its box meets.
      entry_box: (E, 4), the entry's piece's (u_min, u_max, min(v_a, v_b),
        max(v_a, v_b)): its u-range and its half-open v-range, copied so a
        band scan reads memory in order.
    """

    trimmed: np.ndarray
    band_first: np.ndarray
    band_count: np.ndarray
    band_v0: np.ndarray
    band_scale: np.ndarray
    magnitude: np.ndarray
    degree: np.ndarray
    coef: np.ndarray
    ends: np.ndarray
    box: np.ndarray
    band_start: np.ndarray
    entry_piece: np.ndarray
    entry_box: np.ndarray


OUTSIDE, INSIDE, MIXED = 0, 1, 2
SOLVE_STEPS = 200  # Newton / bisection steps (the bracket halves at least every third step)
RECT_MARGIN = 1e-12  # rect_state grows the rectangle by this x the coordinates' magnitude
RECT_DEPTH = 60  # halvings of a piece in rect_state before "it may touch" (MIXED)


# ---------------------------------------------------------------------------
# The point test


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True, _nrt=False)
def _eval(coef, k, d, s):
    """(x, y, w): piece k's (degree d) homogeneous point at s, local coordinates (Horner, power basis)."""
    x = coef[k, d, 0]
    y = coef[k, d, 1]
    w = coef[k, d, 2]
    for i in range(d - 1, -1, -1):
        x = x * s + coef[k, i, 0]
        y = y * s + coef[k, i, 1]
        w = w * s + coef[k, i, 2]
    return x, y, w


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True, _nrt=False)
def _solve_right(coef, k, d, ua, va, ub, vb, u, v):
    """Does the curved piece k (degree d, from (ua, va) to (ub, vb), monotone) cross the row v
    right of u? v in its half-open v-range and u strictly between ua and ub assumed.

    F(s) = sigma (V(s) - v) W(s) rises from < 0 at s = 0 to >= 0 at s = 1; its root is kept
    bracketed in [a, b]. As U is monotone, the crossing's u lies between U(a) and U(b): the
    answer is known once both lie on the same side of u. Steps: Newton from the latest point,
    pushed 1 % further so that the points fall on alternate sides of the root and the bracket
    closes from both ends; bisection when a step leaves the bracket or the bracket stops
    halving. The first point is regula falsi's."""
    up = u - ua  # local coordinates: the piece's origin is its start (ua, va)
    vp = v - va
    sigma = 1.0 if vb > va else -1.0
    ga = ua > u
    gb = ub > u
    x, y, w = _eval(coef, k, d, 0.0)
    fa = sigma * (y - vp * w)
    x, y, w = _eval(coef, k, d, 1.0)
    fb = sigma * (y - vp * w)
    if not fa < 0.0:  # rounding right at a vertex: (u, v) is on the curve's level there
        return ga
    if not fb >= 0.0:
        return gb
    a, b = 0.0, 1.0
    s = fa / (fa - fb)
    width = 1.0
    for step in range(SOLVE_STEPS):
        if not (a < s < b):
            s = 0.5 * (a + b)
            if not (a < s < b):  # the bracket is two neighbouring floats: (u, v) is on the curve
                break
        # x, y, w and dy/ds, dw/ds at s (Horner)
        x = coef[k, d, 0]
        y = coef[k, d, 1]
        w = coef[k, d, 2]
        dy = 0.0
        dw = 0.0
        for i in range(d - 1, -1, -1):
            dy = dy * s + y
            dw = dw * s + w
            x = x * s + coef[k, i, 0]
            y = y * s + coef[k, i, 1]
            w = w * s + coef[k, i, 2]
        f = sigma * (y - vp * w)
        g = x - up * w > 0.0
        if f < 0.0:
            a, ga = s, g
        elif f > 0.0:
            b, gb = s, g
        else:
            return g
        if ga == gb:
            return ga
        if step % 3 == 2:  # the bracket must halve every third step at least
            if b - a > 0.5 * width:
                s = 0.5 * (a + b)
                width = b - a
                continue
            width = b - a
        slope = sigma * (dy - vp * dw)
        s = s - 1.01 * f / slope if slope > 0.0 else 0.5 * (a + b)
    return gb


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True, _nrt=False)
def _band(T, m, v):
    """The index (into band_start) of surface m's band holding v (the end bands reach to infinity)."""
    count = T.band_count[m]
    x = (v - T.band_v0[m]) * T.band_scale[m]
    if not x > 0.0:  # also NaN
        return T.band_first[m]
    if x >= count:
        return T.band_first[m] + count - 1
    return T.band_first[m] + int(x)


@njit(cache=True, error_model="numpy", _nrt=False)
def point_kept(T, m, u, v):
    """Is (u, v) of surface m inside an odd number of its loops (or is m untrimmed)?

    Compiled without numba's reference counting (_nrt=False: nothing here allocates): counting
    the references of the table's arrays on every call cost twice the scan itself."""
    if not T.trimmed[m]:
        return True
    band = _band(T, m, v)
    start, entry_box, entry_piece, ends = T.band_start, T.entry_box, T.entry_piece, T.ends
    inside = False
    for e in range(start[band], start[band + 1]):
        if not entry_box[e, 1] > u:  # sorted by decreasing u_max: every piece left is left of u
            break
        if not (entry_box[e, 2] <= v < entry_box[e, 3]):
            continue
        if entry_box[e, 0] > u:
            inside = not inside
            continue
        k = entry_piece[e]
        ua, va, ub, vb = ends[k, 0], ends[k, 1], ends[k, 2], ends[k, 3]
        right = ua > u
        if right != (ub > u):  # the ends straddle u (else, monotone in u, they decide)
            d = T.degree[k]
            if d == 1:  # a segment, whatever its weights: which side of it (u, v) lies
                cross = (ub - ua) * (v - va) - (u - ua) * (vb - va)
                right = cross > 0.0 if vb > va else cross < 0.0
            else:
                right = _solve_right(T.coef, k, d, ua, va, ub, vb, u, v)
        if right:
            inside = not inside
    return inside


# ---------------------------------------------------------------------------
# Rectangles


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def _piece_meets(T, k, u0, u1, v0, v1):
    """May piece k pass through the rectangle [u0, u1] x [v0, v1]? False only when it certainly
    does not: the piece is monotone, so the box of a stretch's two end points holds the stretch;
    a stretch whose box meets the rectangle but whose ends lie outside it is halved, up to
    RECT_DEPTH times. (The caller grows the rectangle to cover rounding and the wobble that
    trim_pieces.MONOTONE_TOL-flat control-polygon steps allow.)"""
    ua, va = T.ends[k, 0], T.ends[k, 1]
    stack = np.empty((RECT_DEPTH + 2, 7))  # per stretch: s0, s1, u(s0), v(s0), u(s1), v(s1), cuts
    for c in range(4):
        stack[0, 2 + c] = T.ends[k, c]
    stack[0, 0], stack[0, 1], stack[0, 6] = 0.0, 1.0, 0.0
    top = 1
    while top > 0:
        top -= 1
        pa_u, pa_v, pb_u, pb_v = stack[top, 2], stack[top, 3], stack[top, 4], stack[top, 5]
        if (u0 <= pa_u <= u1 and v0 <= pa_v <= v1) or (u0 <= pb_u <= u1 and v0 <= pb_v <= v1):
            return True
        if max(pa_u, pb_u) < u0 or min(pa_u, pb_u) > u1 or max(pa_v, pb_v) < v0 or min(pa_v, pb_v) > v1:
            continue
        sa, sb, cuts = stack[top, 0], stack[top, 1], stack[top, 6] + 1.0
        s = 0.5 * (sa + sb)
        if cuts > RECT_DEPTH or not (sa < s < sb):
            return True
        x, y, w = _eval(T.coef, k, T.degree[k], s)
        mu, mv = ua + x / w, va + y / w
        for c, value in enumerate((s, sb, mu, mv, pb_u, pb_v, cuts)):
            stack[top, c] = value
        for c, value in enumerate((sa, s, pa_u, pa_v, mu, mv, cuts)):
            stack[top + 1, c] = value
        top += 2
    return False


@njit(cache=True, error_model="numpy")
def rect_state(T, m, u0, u1, v0, v1):
    """OUTSIDE (0), INSIDE (1) or MIXED (2): the rectangle [u0, u1] x [v0, v1] of surface m is
    entirely removed, entirely kept, or (conservatively) may hold both.

    MIXED whenever a piece of a loop may pass within RECT_MARGIN x (the
    coordinates' magnitude) of the rectangle: its box meets the grown
    rectangle, and halving the (monotone) piece does not show it misses.
    Otherwise no curve comes near the rectangle, so one state holds all of
    it: its centre's, which point_kept gets right that far from the curves."""
    if not T.trimmed[m]:
        return INSIDE
    margin = RECT_MARGIN * max(max(max(abs(u0), abs(u1)), max(abs(v0), abs(v1))), T.magnitude[m])
    a0, a1, b0, b1 = u0 - margin, u1 + margin, v0 - margin, v1 + margin
    first, last = _band(T, m, b0), _band(T, m, b1)
    for band in range(first, last + 1):
        for e in range(T.band_start[band], T.band_start[band + 1]):
            k = T.entry_piece[e]
            if T.box[k, 0] > a1 or T.box[k, 1] < a0 or T.box[k, 2] > b1 or T.box[k, 3] < b0:
                continue
            if band != max(first, _band(T, m, T.box[k, 2])):  # listed in several bands: test it once
                continue
            if _piece_meets(T, k, a0, a1, b0, b1):
                return MIXED
    return INSIDE if point_kept(T, m, 0.5 * (u0 + u1), 0.5 * (v0 + v1)) else OUTSIDE


# ---------------------------------------------------------------------------
# Batches


@njit(cache=True, nogil=True, error_model="numpy")
def _kept_many(start, stop, T, surface, u, v, out):
    for i in range(start, stop):
        out[i] = point_kept(T, surface[i], u[i], v[i])


@njit(cache=True, nogil=True, error_model="numpy")
def _rect_states(start, stop, T, surface, u0, u1, v0, v1, out):
    for i in range(start, stop):
        out[i] = rect_state(T, surface[i], u0[i], u1[i], v0[i], v1[i])


def _f64(a):
    return np.ascontiguousarray(a, dtype=np.float64).reshape(-1)


def kept_many(T, surface, u, v):
    """(N,) bool: point_kept(T, surface[i], u[i], v[i]) for every i, on every core.

    surface: (N,) int64 surface indices; u, v: (N,) float64 parameters."""
    s = np.ascontiguousarray(surface, dtype=np.int64).reshape(-1)
    u, v = _f64(u), _f64(v)
    out = np.empty(s.size, dtype=np.bool_)
    run_chunks(_kept_many, s.size, T, s, u, v, out)
    return out


def rect_states(T, surface, u0, u1, v0, v1):
    """(N,) int64: rect_state(T, surface[i], u0[i], u1[i], v0[i], v1[i]) for every i, on every core."""
    s = np.ascontiguousarray(surface, dtype=np.int64).reshape(-1)
    out = np.empty(s.size, dtype=np.int64)
    run_chunks(_rect_states, s.size, T, s, _f64(u0), _f64(u1), _f64(v0), _f64(v1), out)
    return out


@njit(cache=True, error_model="numpy")
def classify_grid(T, m, gu, gv, out):
    """rect_state of every cell of the grid gu (I + 1,) x gv (J + 1,) of surface m into out (I, J) int64.

    Quadtree over cell ranges: a range no curve touches takes its centre's
    state at once, so only the cells near a curve are tested one by one."""
    stack = np.empty((128, 4), dtype=np.int64)
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0, gu.shape[0] - 1, 0, gv.shape[0] - 1
    top = 1
    while top > 0:
        top -= 1
        i0, i1, j0, j1 = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        if i1 <= i0 or j1 <= j0:
            continue
        state = rect_state(T, m, gu[i0], gu[i1], gv[j0], gv[j1])
        if state != MIXED or (i1 - i0 == 1 and j1 - j0 == 1):
            for i in range(i0, i1):
                for j in range(j0, j1):
                    out[i, j] = state
            continue
        if i1 - i0 >= j1 - j0:
            mid = (i0 + i1) // 2
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = i0, mid, j0, j1
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = mid, i1, j0, j1
        else:
            mid = (j0 + j1) // 2
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = i0, i1, j0, mid
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = i0, i1, mid, j1
        top += 2
