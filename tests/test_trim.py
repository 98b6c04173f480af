"""The trim test "is (u, v) kept?" (bsrt/geometry/trim.py, bsrt/kernels/trim.py), against answers worked out
independently: distances to exact (rational) circles, point-in-polygon in exact rational arithmetic
(fractions), and the sides of a closed cubic B-spline evaluated by the reference Cox-de Boor code.

Points exactly on a curve may go either way; points 1e-9 of the domain's diagonal away must be right,
and are checked here (and closer).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from bsrt.errors import InputError
from bsrt.geometry.bspline import make_surface
from bsrt.geometry.trim import CurveSet, TrimCurve, TrimLoop, check_loops, make_trim_curve
from bsrt.geometry.trim_table import build_trim_table, kept
from bsrt.kernels import trim as K
from bsrt.kernels import trim_pieces as P

W = math.sqrt(0.5)
UNIT = (0.0, 1.0, 0.0, 1.0)


def plate(domain=UNIT):
    u0, u1, v0, v1 = domain
    return make_surface([1, 1], [u0, u0, u1, u1], [v0, v0, v1, v1], [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]])


def circle(cx, cy, r):
    """An exact circle: four rational quadratic quarter arcs (weights 1, 1/sqrt(2), 1), counter-clockwise."""
    curves = []
    for k in range(4):
        a0, a1 = k * math.pi / 2, (k + 1) * math.pi / 2
        p0 = [cx + r * math.cos(a0), cy + r * math.sin(a0)]
        p1 = [cx + r * (math.cos(a0) - math.sin(a0)), cy + r * (math.sin(a0) + math.cos(a0))]
        p2 = [cx + r * math.cos(a1), cy + r * math.sin(a1)]
        curves.append(make_trim_curve(2, [0, 0, 0, 1, 1, 1], [p0, p1, p2], [1.0, W, 1.0]))
    return TrimLoop(tuple(curves))


def circle3(cx, cy, r):
    """An exact circle: three arcs of 120 degrees (middle weight cos 60 = 1/2, middle point at 2 r),
    from -30 degrees, so the arcs hold the turning points at 0, 180 (u) and 270 (v) degrees inside."""
    curves = []
    for k in range(3):
        a0 = math.radians(-30 + 120 * k)
        am, a1 = a0 + math.radians(60), a0 + math.radians(120)
        pts = [
            [cx + r * math.cos(a0), cy + r * math.sin(a0)],
            [cx + 2 * r * math.cos(am), cy + 2 * r * math.sin(am)],
            [cx + r * math.cos(a1), cy + r * math.sin(a1)],
        ]
        curves.append(make_trim_curve(2, [0, 0, 0, 1, 1, 1], pts, [1.0, 0.5, 1.0]))
    return TrimLoop(tuple(curves))


def polygon(points):
    """A loop of segments (degree 1) through the (u, v) points, closed."""
    return TrimLoop(
        tuple(make_trim_curve(1, [0, 0, 1, 1], [list(a), list(b)]) for a, b in zip(points, points[1:] + points[:1]))
    )


def reversed_curve(c: TrimCurve) -> TrimCurve:
    """The same curve run backwards: knots -k reversed, points and weights reversed."""
    return make_trim_curve(c.degree, -c.knots[::-1], c.points[::-1], None if c.weights is None else c.weights[::-1])


def reversed_loop(loop: TrimLoop) -> TrimLoop:
    return TrimLoop(tuple(reversed_curve(c) for c in loop.curves[::-1]))


def closed_cubic(n=24, seed=3):
    """One closed cubic B-spline with n spans (uniform, unclamped knots: n + 6 interior ones), control
    points around (0.5, 0.5) at radii 0.22 .. 0.38 (star-shaped, so the loop does not cross itself)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 0.3 + 0.08 * np.sin(5 * t) * rng.uniform(0.6, 1.0, n)
    pts = np.stack([0.5 + r * np.cos(t), 0.5 + r * np.sin(t)], axis=1)
    pts = np.concatenate([pts, pts[:3]])
    return TrimLoop((make_trim_curve(3, np.arange(pts.shape[0] + 4, dtype=float), pts),))


def ring_points(rng, cx, cy, r, delta, n):
    """n points at distance r + delta from (cx, cy): random angles plus the arcs' joints and the
    turning points (multiples of 30 degrees)."""
    a = np.concatenate([rng.uniform(0, 2 * np.pi, n), np.radians(np.arange(0, 360, 30))])
    return cx + (r + delta) * np.cos(a), cy + (r + delta) * np.sin(a)


def inside_polygon_exact(poly, u, v) -> bool:
    """Even-odd point-in-polygon in rational arithmetic (right for every point not on an edge)."""
    x, y = Fraction(u), Fraction(v)
    inside = False
    for (xa, ya), (xb, yb) in zip(poly, poly[1:] + poly[:1]):
        xa, ya, xb, yb = Fraction(xa), Fraction(ya), Fraction(xb), Fraction(yb)
        if (ya > y) != (yb > y) and xa + (y - ya) * (xb - xa) / (yb - ya) > x:
            inside = not inside
    return inside


def distance_to_polygon(poly, u, v) -> np.ndarray:
    """(N,) distance of the points (u, v) to the polygon's edges (float, for skipping points on them)."""
    p = np.stack([u, v], axis=1)[:, None, :]
    a = np.array(poly)[None]
    b = np.roll(np.array(poly), -1, axis=0)[None]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-300), 0, 1)
    return np.min(np.linalg.norm(p - (a + t[..., None] * ab), axis=2), axis=1)


def star(n, radii, phase=0.1):
    angles = phase + 2 * np.pi * np.arange(n) / n
    return [(0.5 + r * math.cos(a), 0.5 + r * math.sin(a)) for r, a in zip(radii, angles)]


# ---------------------------------------------------------------------------
# Circles: exact at the curve


@pytest.mark.parametrize("make", [circle, circle3], ids=["4-arcs", "3-arcs"])
@pytest.mark.parametrize("domain", [UNIT, (1000.0, 1003.0, -2.0, 0.5)], ids=["unit", "offset"])
def test_points_a_hair_inside_and_outside_a_circle(make, domain):
    u0, u1, v0, v1 = domain
    diag = math.hypot(u1 - u0, v1 - v0)
    cx, cy, r = 0.5 * (u0 + u1), 0.5 * (v0 + v1), 0.3 * min(u1 - u0, v1 - v0)
    surf = plate(domain).with_trims([make(cx, cy, r)])
    rng = np.random.default_rng(7)
    for delta in (1e-6 * diag, 1e-9 * diag) + ((1e-12,) if domain == UNIT else ()):
        u, v = ring_points(rng, cx, cy, r, -delta, 20000)
        assert kept(surf, u, v).all(), delta
        u, v = ring_points(rng, cx, cy, r, delta, 20000)
        assert not kept(surf, u, v).any(), delta
    u, v = rng.uniform(u0, u1, 50000), rng.uniform(v0, v1, 50000)
    assert np.array_equal(kept(surf, u, v), np.hypot(u - cx, v - cy) < r)


def test_a_hole_in_the_domain():
    outer = polygon([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
    surf = plate().with_trims([outer, circle(0.4, 0.6, 0.25)])
    rng = np.random.default_rng(1)
    u, v = rng.random(50000), rng.random(50000)
    assert np.array_equal(kept(surf, u, v), np.hypot(u - 0.4, v - 0.6) > 0.25)
    u, v = ring_points(rng, 0.4, 0.6, 0.25, 1e-9, 5000)
    assert kept(surf, u, v).all()
    u, v = ring_points(rng, 0.4, 0.6, 0.25, -1e-9, 5000)
    assert not kept(surf, u, v).any()


def test_nested_islands():
    radii = (0.45, 0.3, 0.12)  # a ring 0.3 < d < 0.45 and an island d < 0.12
    surf = plate().with_trims([circle(0.5, 0.5, r) for r in radii])
    rng = np.random.default_rng(2)
    u, v = rng.random(50000), rng.random(50000)
    d = np.hypot(u - 0.5, v - 0.5)
    assert np.array_equal(kept(surf, u, v), ((d < 0.45) & (d > 0.3)) | (d < 0.12))
    for r, inner_kept in zip(radii, (True, False, True)):
        for delta, expect in ((-1e-9, inner_kept), (1e-9, not inner_kept)):
            u, v = ring_points(rng, 0.5, 0.5, r, delta, 5000)
            assert (kept(surf, u, v) == expect).all(), (r, delta)


def test_a_loop_along_the_domain_boundary_keeps_the_whole_surface():
    surf = plate((0.0, 2.0, 1.0, 2.0)).with_trims([polygon([(0.0, 1.0), (2.0, 1.0), (2.0, 2.0), (0.0, 2.0)])])
    rng = np.random.default_rng(3)
    u, v = rng.uniform(1e-9, 2 - 1e-9, 50000), rng.uniform(1 + 1e-9, 2 - 1e-9, 50000)
    assert kept(surf, u, v).all()
    assert not kept(surf, [-1e-9, 2 + 1e-9, 1.0, 1.0], [1.5, 1.5, 1 - 1e-9, 2 + 1e-9]).any()


def test_both_orientations_give_the_same_answer():
    rng = np.random.default_rng(4)
    u, v = rng.random(30000), rng.random(30000)
    ru, rv = ring_points(rng, 0.5, 0.5, 0.3, 1e-9 * rng.choice([-1, 1], 20012), 20000)
    poly = star(12, rng.uniform(0.1, 0.45, 12))
    su, sv = rng.random(3000), np.array(poly)[rng.integers(0, 12, 3000), 1]  # on the vertices' rows
    loops = [
        [circle(0.5, 0.5, 0.3)],
        [circle3(0.5, 0.5, 0.3), circle(0.5, 0.5, 0.1)],
        [polygon(poly)],
        [closed_cubic()],
    ]
    for loop_set in loops:
        forward = plate().with_trims(loop_set)
        backward = plate().with_trims([reversed_loop(loop) for loop in loop_set])
        for a, b in ((u, v), (ru, rv), (su, sv)):
            assert np.array_equal(kept(forward, a, b), kept(backward, a, b))


# ---------------------------------------------------------------------------
# A closed cubic B-spline, half-open rows, polygons


def test_a_closed_cubic_b_spline_with_interior_knots():
    loop = closed_cubic()
    curve = loop.curves[0]
    surf = plate().with_trims([loop])
    lo, hi = curve.domain
    # the loop's orientation (shoelace on a dense reference polyline): inside is on the left if > 0
    dense = curve.evaluate(np.linspace(lo, hi, 20001))
    area = 0.5 * np.sum(dense[:-1, 0] * dense[1:, 1] - dense[1:, 0] * dense[:-1, 1])
    rng = np.random.default_rng(5)
    s = np.concatenate([rng.uniform(lo, hi, 20000), np.arange(lo, hi)])  # also at every knot
    h = 1e-6
    p = curve.evaluate(s)
    tangent = curve.evaluate(np.minimum(s + h, hi)) - curve.evaluate(np.maximum(s - h, lo))
    left = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1) / np.linalg.norm(tangent, axis=1)[:, None]
    inside = left * np.sign(area)
    for delta in (1e-7, 1e-9 * math.sqrt(2)):
        q = p + delta * inside
        assert kept(surf, q[:, 0], q[:, 1]).all(), delta
        q = p - delta * inside
        assert not kept(surf, q[:, 0], q[:, 1]).any(), delta
    # far from the curve: even-odd against the dense polyline (within 1e-8 of the curve)
    u, v = rng.random(20000), rng.random(20000)
    ref = np.zeros(u.size, dtype=bool)
    a, b = dense[:-1], dense[1:]
    for (xa, ya), (xb, yb) in zip(a, b):
        cross = (ya > v) != (yb > v)
        with np.errstate(divide="ignore", invalid="ignore"):
            ref ^= cross & (xa + (v - ya) * (xb - xa) / (yb - ya) > u)
    near = distance_to_polygon([tuple(x) for x in dense[::40]], u, v) < 1e-3
    assert np.array_equal(kept(surf, u, v)[~near], ref[~near])


def test_rows_through_the_vertices_of_a_diamond():
    diamond = [(0.5, 0.1), (0.9, 0.5), (0.5, 0.9), (0.1, 0.5)]
    surf = plate().with_trims([polygon(diamond)])
    u = np.linspace(0.0, 1.0, 1001)
    for row in (0.1, 0.5, 0.9):
        v = np.full(u.size, row)
        taxi = np.abs(u - 0.5) + np.abs(row - 0.5)
        off = np.abs(taxi - 0.4) > 1e-12  # points on the diamond may go either way
        assert np.array_equal(kept(surf, u, v)[off], (taxi < 0.4)[off]), row
    # a row through two vertices at once, from left of both: two crossings, outside; between: inside
    assert list(kept(surf, [0.05, 0.1 + 1e-9, 0.5, 0.9 - 1e-9, 0.95], [0.5] * 5)) == [False, True, True, True, False]


def test_rows_along_horizontal_edges():
    """A staircase: horizontal edges on the query rows, vertices where the loop turns back in v
    and where it passes through; exact rational point-in-polygon decides."""
    stairs = [
        (0.1, 0.1),
        (0.9, 0.1),
        (0.9, 0.3),
        (0.7, 0.3),
        (0.7, 0.5),
        (0.5, 0.5),
        (0.5, 0.7),
        (0.8, 0.7),
        (0.8, 0.9),
        (0.1, 0.9),
        (0.1, 0.5),
        (0.3, 0.5),
        (0.3, 0.3),
        (0.1, 0.3),
    ]
    surf = plate().with_trims([polygon(stairs)])
    u = np.linspace(0.0, 1.0, 401)
    for row in (0.1, 0.3, 0.5, 0.7, 0.9, 0.2, 0.6):
        v = np.full(u.size, row)
        off = distance_to_polygon(stairs, u, v) > 1e-12
        ref = np.array([inside_polygon_exact(stairs, a, b) for a, b in zip(u, v)])
        assert np.array_equal(kept(surf, u, v)[off], ref[off]), row


@settings(max_examples=40, deadline=None, derandomize=True)
@given(n=st.integers(3, 60), data=st.data())
def test_a_star_polygon_against_exact_point_in_polygon(n, data):
    radii = data.draw(st.lists(st.floats(0.05, 0.45), min_size=n, max_size=n))
    poly = star(n, radii, phase=data.draw(st.floats(0.0, 1.0)))
    surf = plate().with_trims([polygon(poly)])
    rng = np.random.default_rng(n)
    u = np.concatenate([rng.random(300), rng.random(n)])
    v = np.concatenate([rng.random(300), [p[1] for p in poly]])  # also on every vertex's row
    u = np.concatenate([u, data.draw(st.lists(st.floats(0.0, 1.0), min_size=5, max_size=5))])
    v = np.concatenate([v, data.draw(st.lists(st.sampled_from([p[1] for p in poly]), min_size=5, max_size=5))])
    off = distance_to_polygon(poly, u, v) > 1e-12
    ref = np.array([inside_polygon_exact(poly, a, b) for a, b in zip(u[off], v[off])], dtype=bool)
    assert np.array_equal(kept(surf, u[off], v[off]), ref)


def test_a_gap_check_loops_lets_through_is_closed():
    """The right edge in two curves 1e-11 apart (under the 1e-9 allowed): a row through the gap still
    crosses the edge once, so points far from every curve on it are right."""
    loop = TrimLoop(
        (
            make_trim_curve(1, [0, 0, 1, 1], [[0.1, 0.1], [0.9, 0.1]]),
            make_trim_curve(1, [0, 0, 1, 1], [[0.9, 0.1], [0.9, 0.5]]),
            make_trim_curve(2, [0, 0, 0, 1, 1, 1], [[0.9, 0.5 + 1e-11], [0.9, 0.7], [0.9, 0.9]]),
            make_trim_curve(1, [0, 0, 1, 1], [[0.9, 0.9], [0.1, 0.9]]),
            make_trim_curve(1, [0, 0, 1, 1], [[0.1, 0.9], [0.1, 0.1]]),
        )
    )
    surf = plate().with_trims([loop])
    v = 0.5 + np.array([0.0, 2e-12, 5e-12, 9e-12, 1e-11])
    assert kept(surf, np.full(5, 0.5), v).all()
    assert not kept(surf, np.full(5, 0.95), v).any()


def test_degenerate_pieces_a_point_curve_and_a_spike():
    """A curve that is one point (dropped), horizontal edges (never crossed) and a spike out and back
    (its two sides cancel) leave the square's answer unchanged."""
    point = make_trim_curve(2, [0, 0, 0, 1, 1, 1], [[0.8, 0.2]] * 3)
    square = polygon([(0.2, 0.2), (0.8, 0.2), (0.8, 0.5), (0.95, 0.6), (0.8, 0.5), (0.8, 0.8), (0.2, 0.8)])
    loop = TrimLoop(square.curves[:1] + (point,) + square.curves[1:])
    surf = plate().with_trims([loop])
    table = build_trim_table([surf])
    assert table.degree.size == 7  # the point curve left no piece
    rng = np.random.default_rng(6)
    u, v = rng.random(50000), rng.random(50000)
    spike = distance_to_polygon([(0.8, 0.5), (0.95, 0.6)], u, v) < 1e-12
    ref = (u > 0.2) & (u < 0.8) & (v > 0.2) & (v < 0.8)
    assert np.array_equal(kept(surf, u, v)[~spike], ref[~spike])
    assert not kept(surf, [0.9, 0.9, 0.95 + 1e-9], [0.5666, 0.6, 0.6]).any()  # beside and beyond the spike's tip


# ---------------------------------------------------------------------------
# The table


def evaluate_piece(table, k, s):
    """(N, 2) points of piece k at s, from its power-basis coefficients (global coordinates)."""
    d = table.degree[k]
    c = table.coef[k, : d + 1]
    h = np.stack([np.polyval(c[::-1, j], s) for j in range(3)], axis=1)
    return h[:, :2] / h[:, 2:3] + table.ends[k, :2]


def test_the_table_layout():
    surfaces = [
        plate(),
        plate().with_trims([circle3(0.5, 0.5, 0.3)]),
        plate().with_trims([closed_cubic()]),
        plate().with_trims([circle(0.5, 0.5, 0.4), polygon(star(9, [0.2, 0.3] * 4 + [0.25]))]),
    ]
    table = build_trim_table(surfaces)
    for name, dtype in (
        ("trimmed", np.bool_),
        ("band_first", np.int64),
        ("band_count", np.int64),
        ("band_v0", np.float64),
        ("band_scale", np.float64),
        ("magnitude", np.float64),
        ("degree", np.int64),
        ("coef", np.float64),
        ("ends", np.float64),
        ("box", np.float64),
        ("band_start", np.int64),
        ("entry_piece", np.int64),
        ("entry_box", np.float64),
    ):
        a = getattr(table, name)
        assert a.dtype == dtype and a.flags.c_contiguous, name
    k = table.degree.size
    assert table.trimmed.tolist() == [False, True, True, True]
    assert table.coef.shape[0] == k and table.ends.shape == (k, 4) and table.box.shape == (k, 4)
    assert table.band_start[0] == 0 and table.band_start[-1] == table.entry_piece.size == table.entry_box.shape[0]
    assert table.band_start.size == table.band_count.sum() + 1
    # three 120-degree arcs, each cut once at the turning point inside it: six pieces, none a chord
    first = table.entry_piece[table.band_start[table.band_first[1]] : table.band_start[table.band_first[2]]]
    assert sorted(set(first.tolist())) == list(range(6)) and np.all(table.degree[:6] == 2)
    s = np.linspace(0, 1, 257)
    for piece in range(k):
        p = evaluate_piece(table, piece, s)
        assert np.allclose(p[[0, -1]], table.ends[piece].reshape(2, 2), rtol=0, atol=1e-12)
        for c in range(2):  # monotone in u and in v
            step = np.diff(p[:, c])
            assert np.all(step >= -1e-13) or np.all(step <= 1e-13), (piece, c)
        b = table.box[piece]
        assert np.all(
            (p[:, 0] >= b[0] - 1e-13)
            & (p[:, 0] <= b[1] + 1e-13)
            & (p[:, 1] >= b[2] - 1e-13)
            & (p[:, 1] <= b[3] + 1e-13)
        )
    # the pieces of one loop chain exactly, end to start, the last back to the first
    one = build_trim_table([plate().with_trims([closed_cubic()])])
    assert np.array_equal(one.ends[:, 2:], np.roll(one.ends[:, :2], -1, axis=0))
    # every band lists, by decreasing u_max, every piece whose half-open v-range meets it
    for m in range(1, 4):
        for band in range(table.band_first[m], table.band_first[m] + table.band_count[m]):
            e = np.arange(table.band_start[band], table.band_start[band + 1])
            assert np.all(np.diff(table.entry_box[e, 1]) <= 0)
            assert np.array_equal(
                table.entry_box[e],
                np.stack(
                    [
                        table.box[table.entry_piece[e], 0],
                        table.box[table.entry_piece[e], 1],
                        table.ends[table.entry_piece[e]][:, [1, 3]].min(axis=1),
                        table.ends[table.entry_piece[e]][:, [1, 3]].max(axis=1),
                    ],
                    axis=1,
                ).reshape(-1, 4),
            )
    mine = np.concatenate(
        [
            np.arange(
                table.band_start[table.band_first[m]], table.band_start[table.band_first[m] + table.band_count[m]]
            )
            for m in (3,)
        ]
    )
    pieces = np.unique(table.entry_piece[mine])
    for v in np.random.default_rng(8).random(500):
        x = (v - table.band_v0[3]) * table.band_scale[3]
        band = table.band_first[3] + (0 if not x > 0 else min(int(x), table.band_count[3] - 1))
        listed = set(table.entry_piece[table.band_start[band] : table.band_start[band + 1]].tolist())
        lo, hi = np.minimum(table.ends[:, 1], table.ends[:, 3]), np.maximum(table.ends[:, 1], table.ends[:, 3])
        assert set(pieces[(lo[pieces] <= v) & (v < hi[pieces])].tolist()) <= listed


def test_bezier_spans_match_boehm_knot_insertion():
    """The spans' nets (blossoms) are the control points knot insertion to full multiplicity gives."""
    from bsrt.geometry.bspline import insert_knot

    rng = np.random.default_rng(13)
    for p, n in ((1, 5), (2, 7), (3, 9), (4, 8)):
        knots = np.sort(np.concatenate([rng.uniform(0, 1, n + p - 1), [0.5, 0.5]]))[: n + p + 1]  # unclamped
        ctrl = np.concatenate([rng.random((n, 2)) * (w := rng.uniform(0.5, 2.0, n))[:, None], w[:, None]], axis=1)
        nets = P.bezier_spans(knots, ctrl, p)
        k, c = knots, ctrl
        for x in np.unique(knots[p : n + 1]):
            while np.count_nonzero(k == x) < p:
                k, c = insert_knot(k, c, p, x)
        spans = [i for i in range(p, c.shape[0]) if k[i] < k[i + 1]]
        assert nets.shape == (len(spans), p + 1, 3)
        for net, i in zip(nets, spans):
            assert np.allclose(net, c[i - p : i + 1], rtol=0, atol=1e-12)


def test_a_turning_point_is_cut_exactly_and_the_depth_cap_leaves_a_chord():
    arc = np.array([[[1.0, 0.0, 1.0], [2.0, 1.0, 1.0], [-1.0, 1.0, 1.0]]])  # u turns back at s = 1/4
    pieces, degree, src = P.monotone_pieces(arc, np.array([2]), 48)
    assert degree.tolist() == [2, 2] and src.tolist() == [0, 0]
    turn = pieces[0, 2, :2] / pieces[0, 2, 2]  # u(s) = 1 + 2 s - 4 s^2 has its top, 1.25, at s = 1/4
    assert np.array_equal(turn, pieces[1, 0, :2] / pieces[1, 0, 2]) and abs(turn[0] - 1.25) < 1e-15
    assert abs(turn[1] - (2 * 0.25 * 0.75 + 0.25**2)) < 1e-15
    pieces, degree, src = P.monotone_pieces(arc, np.array([2]), 0)
    assert degree.tolist() == [1] and np.array_equal(pieces[0, :2], arc[0, [0, 2]]) and not pieces[0, 2].any()
    # a repeated first point (no slope there) and weights: still one exact cut, u(s) largest there
    cusp = np.array([[[0.0, 0.0, 1.0], [0.0, 0.0, 2.0], [2.0, 1.0, 2.0], [-1.0, 1.0, 1.0]]])
    pieces, degree, src = P.monotone_pieces(cusp, np.array([3]), 48)
    assert degree.tolist() == [3, 3]
    s = np.linspace(0, 1, 100001)
    b = np.stack([(1 - s) ** 3, 3 * s * (1 - s) ** 2, 3 * s**2 * (1 - s), s**3], axis=1) @ cusp[0]
    assert abs(pieces[0, 3, 0] / pieces[0, 3, 2] - np.max(b[:, 0] / b[:, 2])) < 1e-9


def test_untrimmed_and_several_surfaces_in_one_table():
    hole = [polygon([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]), circle(0.5, 0.5, 0.2)]
    surfaces = [plate(), plate().with_trims([circle(0.5, 0.5, 0.2)]), plate().with_trims(hole)]
    table = build_trim_table(surfaces)
    rng = np.random.default_rng(9)
    u, v = rng.uniform(-1, 2, 30000), rng.uniform(-1, 2, 30000)
    m = rng.integers(0, 3, 30000)
    inner = np.hypot(u - 0.5, v - 0.5) < 0.2
    domain = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    expect = np.where(m == 0, True, np.where(m == 1, inner, domain & ~inner))
    assert np.array_equal(K.kept_many(table, m, u, v), expect)
    assert kept(plate(), 5.0, -3.0).tolist() == [True]  # untrimmed: everything, at once
    empty = build_trim_table([])
    assert empty.trimmed.size == 0 and K.kept_many(empty, np.zeros(0, np.int64), [], []).size == 0


def test_point_kept_and_rect_state_are_callable_from_another_kernel():
    @njit
    def count(table, m, u, v):
        n = 0
        for i in range(u.size):
            n += K.point_kept(table, m, u[i], v[i])
        return n, K.rect_state(table, m, 0.45, 0.55, 0.45, 0.55), K.rect_state(table, m, 0.0, 0.1, 0.0, 0.1)

    table = build_trim_table([plate().with_trims([circle(0.5, 0.5, 0.3)])])
    u = np.linspace(0, 1, 100)  # none on the circle (0.2, 0.8)
    assert count(table, 0, u, np.full(100, 0.5)) == (int(np.sum(np.abs(u - 0.5) < 0.3)), K.INSIDE, K.OUTSIDE)


# ---------------------------------------------------------------------------
# Rectangles


def circle_set_reference(circles, u, v):
    """Even-odd over circles (cx, cy, r): kept, and the distance to the nearest circle."""
    inside = np.zeros(np.shape(u), dtype=bool)
    dist = np.full(np.shape(u), np.inf)
    for cx, cy, r in circles:
        d = np.hypot(u - cx, v - cy)
        inside ^= d < r
        dist = np.minimum(dist, np.abs(d - r))
    return inside, dist


def test_rect_state_is_conservative_and_exact_away_from_the_curves():
    circles = [(0.5, 0.5, 0.4), (0.5, 0.5, 0.25), (0.45, 0.55, 0.1)]
    surf = plate().with_trims([circle(*c) if i % 2 else circle3(*c) for i, c in enumerate(circles)])
    table = build_trim_table([surf])
    rng = np.random.default_rng(10)
    n = 3000
    size = 10.0 ** rng.uniform(-6, -0.3, (n, 2))
    u0, v0 = rng.uniform(-0.1, 1.0, n), rng.uniform(-0.1, 1.0, n)
    u1, v1 = u0 + size[:, 0], v0 + size[:, 1]
    states = K.rect_states(table, np.zeros(n, np.int64), u0, u1, v0, v1)
    t = np.linspace(0, 1, 41)
    mixed_needed = 0
    for i in range(n):
        gu, gv = np.meshgrid(u0[i] + t * (u1[i] - u0[i]), v0[i] + t * (v1[i] - v0[i]))
        ref, dist = circle_set_reference(circles, gu.ravel(), gv.ravel())
        ref = ref[dist > 1e-12]
        if states[i] != K.MIXED:
            assert np.all(ref == (states[i] == K.INSIDE)), (i, states[i])
        # exact away from the curves: a rectangle no circle comes within 1e-9 of is never MIXED
        for cx, cy, r in circles:
            dx = np.maximum(np.maximum(u0[i] - cx, cx - u1[i]), 0.0)
            dy = np.maximum(np.maximum(v0[i] - cy, cy - v1[i]), 0.0)
            dmin = math.hypot(dx, dy)
            dmax = math.hypot(max(abs(u0[i] - cx), abs(u1[i] - cx)), max(abs(v0[i] - cy), abs(v1[i] - cy)))
            if dmin - 1e-9 <= r <= dmax + 1e-9:
                mixed_needed += 1
                break
        else:
            assert states[i] != K.MIXED, i
    assert 0 < mixed_needed < n
    assert np.sum(states == K.INSIDE) > 0 and np.sum(states == K.OUTSIDE) > 0


def test_rect_state_beside_a_curve_inside_the_pieces_box():
    """Squares inside a quarter arc's box, 2e-8 or more off the arc on either side: exact, not MIXED."""
    surf = plate().with_trims([circle(0.5, 0.5, 0.3)])
    table = build_trim_table([surf])
    rng = np.random.default_rng(11)
    for a in rng.uniform(0.05, np.pi / 2 - 0.05, 200):
        for side, state in ((-1, K.INSIDE), (1, K.OUTSIDE)):
            d = 0.3 + side * (0.005 + 1e-8)
            c = (0.5 + d * math.cos(a), 0.5 + d * math.sin(a))
            h = (0.005 - 1e-8) / math.sqrt(2)  # every point of the square is 2e-8 or more off the circle
            got = K.rect_states(table, np.zeros(1, np.int64), [c[0] - h], [c[0] + h], [c[1] - h], [c[1] + h])
            assert got[0] == state
    assert K.rect_states(table, np.zeros(1, np.int64), [0.5], [0.9], [0.5], [0.9])[0] == K.MIXED


def test_classify_grid_matches_rect_state_cell_by_cell():
    surf = plate().with_trims([circle(0.5, 0.5, 0.35), polygon(star(7, [0.2, 0.1] * 3 + [0.15]))])
    table = build_trim_table([surf])
    gu = np.concatenate([[0.0], np.sort(np.random.default_rng(12).random(37)), [1.0]])
    gv = np.linspace(0.0, 1.0, 30)
    grid = np.empty((gu.size - 1, gv.size - 1), dtype=np.int64)
    K.classify_grid(table, 0, gu, gv, grid)
    i, j = np.meshgrid(np.arange(gu.size - 1), np.arange(gv.size - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    cells = K.rect_states(table, np.zeros(i.size, np.int64), gu[i], gu[i + 1], gv[j], gv[j + 1])
    assert np.array_equal(grid.ravel(), cells)
    assert set(cells.tolist()) == {K.OUTSIDE, K.INSIDE, K.MIXED}


# ---------------------------------------------------------------------------
# Errors name the loop and the curve


def test_an_open_loop_names_the_loop_and_the_curve():
    square = polygon([(0.1, 0.1), (0.9, 0.1), (0.9, 0.9), (0.1, 0.9)])
    broken = TrimLoop(
        square.curves[:2] + (make_trim_curve(1, [0, 0, 1, 1], [[0.8, 0.9], [0.1, 0.9]]),) + square.curves[3:]
    )
    with pytest.raises(InputError) as err:
        check_loops([circle(0.5, 0.5, 0.05), broken], UNIT)
    assert str(err.value) == (
        "trim[1].curves[2]: the loop is open: the curve starts at (0.8, 0.9), not where curves[1] ends (0.9, 0.9)"
    )
    single = TrimLoop((make_trim_curve(2, [0, 0, 0, 1, 1, 1], [[0.1, 0.1], [0.5, 0.9], [0.9, 0.1]]),))
    with pytest.raises(InputError) as err:
        check_loops([single], UNIT)
    assert str(err.value) == (
        "trim[0].curves[0]: the loop is open: the curve starts at (0.1, 0.1) but it ends at (0.9, 0.1)"
    )
    with pytest.raises(InputError) as err:
        check_loops([TrimLoop(())], UNIT)
    assert str(err.value) == "trim[0].curves: a loop needs at least one curve"
    gap = TrimLoop(
        square.curves[:1] + (make_trim_curve(1, [0, 0, 1, 1], [[0.9 + 1e-11, 0.1], [0.9, 0.9]]),) + square.curves[2:]
    )
    check_loops([gap], UNIT)  # a gap of 1e-11 (under 1e-9 of the diagonal) closes


def test_a_curve_leaving_the_domain_names_the_loop_and_the_curve():
    with pytest.raises(InputError) as err:
        check_loops([circle(0.5, 0.5, 0.1), circle(0.5, 0.5, 0.55)], UNIT)
    assert str(err.value).startswith(
        "trim[1].curves[0]: the curve leaves the surface's domain [0, 1] x [0, 1] (it passes (1.05, "
    ), str(err.value)
    # a dip below v = 0 between the ends: the parabola's lowest point, (0.5, -0.1), is reported
    dip = make_trim_curve(2, [0, 0, 0, 1, 1, 1], [[0.9, 0.1], [0.5, -0.3], [0.1, 0.1]])
    loop = TrimLoop((dip, make_trim_curve(1, [0, 0, 1, 1], [[0.1, 0.1], [0.9, 0.1]])))
    with pytest.raises(InputError) as err:
        check_loops([loop], UNIT)
    assert str(err.value) == (
        "trim[0].curves[0]: the curve leaves the surface's domain [0, 1] x [0, 1] (it passes (0.5, -0.1))"
    )
    # the exact test: control points outside the domain, the curve inside (a 3-arc circle of radius
    # 0.45 has its middle control points 0.9 from the centre), or outside by less than 1e-5
    check_loops([circle3(0.5, 0.5, 0.45)], UNIT)
    check_loops([circle(0.5, 0.5, 0.5 + 1e-6)], UNIT)


def test_trim_curve_messages_name_the_key_and_scenes_add_surface_loop_and_curve():
    cases = [
        ((0, [0, 1], [[0, 0]]), "degree: must be >= 1, got 0"),
        ((1, [0, 0, 1], [[0, 0], [1, 1]]), "knots: expected 4 values (2 points + degree 1 + 1), got 3"),
        ((1, [0, 1, 0, 1], [[0, 0], [1, 1]]), "knots: expected finite, non-decreasing numbers"),
        ((2, [0, 0, 0, 1, 1, 1], [[0, 0], [1, 1]]), "points: degree 2 needs at least 3 points, got 2"),
        (
            (2, [0, 0, 0, 1, 1, 1], [[0, 0], [1, 1], [1, 0]], [1, -1, 1]),
            "weights: every weight must be a finite number > 0",
        ),
        (
            (1, [0, 0, 1, 1], [[0, 0, 0], [1, 1, 1]]),
            "points: expected a list of [u, v] pairs, got an array of shape (2, 3)",
        ),
        (
            (1, [0, 0, 0.5, 0.5, 1, 1], [[0, 0], [1, 1], [0, 1], [1, 0]]),
            "knots: an interior knot is repeated more than the degree 1",
        ),
    ]
    for args, message in cases:
        with pytest.raises(InputError) as err:
            make_trim_curve(*args)
        assert str(err.value) == message
    from bsrt.scene import parse_scene

    square = [
        {"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]}
        for a, b in (
            ([0.2, 0.2], [0.8, 0.2]),
            ([0.8, 0.2], [0.8, 0.8]),
            ([0.8, 0.8], [0.2, 0.8]),
            ([0.2, 0.8], [0.2, 0.2]),
        )
    ]
    bad = [dict(c) for c in square]
    bad[3] = {**bad[3], "weights": [1.0, 0.0]}
    flat = {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]],
    }
    doc = {
        "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0]},
        "surface": [flat, {**flat, "trim": [{"curves": square}, {"curves": bad}]}],
    }
    with pytest.raises(InputError) as err:
        parse_scene(doc, "part.toml")
    assert str(err.value) == "part.toml: surface[1].trim[1].curves[3].weights: every weight must be a finite number > 0"


def test_curve_set_evaluates_as_each_curve_does():
    """CurveSet (the IGES reader's many short curves at once) against TrimCurve.evaluate, bit for
    bit: degrees 1 to 4, rational and not, repeated interior knots, parameters outside the domain
    (the end spans extended) and curves with no points asked for."""
    rng = np.random.default_rng(3)
    curves = []
    for k in range(12):
        p = 1 + k % 4
        n = p + 1 + k % 3
        inner = np.sort(rng.uniform(0.2, 1.8, n - p - 1))
        if k == 7:
            inner[:] = inner[0]  # one knot repeated up to the degree
        knots = np.concatenate([np.full(p + 1, -0.5 + k), inner + k, np.full(p + 1, 2.0 + k)])
        weights = rng.uniform(0.5, 2.0, n) if k % 2 else None
        curves.append(TrimCurve(p, knots, rng.normal(size=(n, 2)), weights))
    which = rng.choice([c for c in range(12) if c != 5], 400)
    lo, hi = np.array([c.domain for c in curves]).T
    s = rng.uniform(lo[which] - 0.1, hi[which] + 0.1)
    got = CurveSet(curves)(s, which)
    for c in range(12):
        assert np.array_equal(got[which == c], curves[c].evaluate(s[which == c]))
