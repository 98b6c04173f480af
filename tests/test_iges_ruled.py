"""IGES 118 ruled surfaces (issue 22) on hand-made files with closed-form answers: a quarter arc
of radius 2 at z = 0 ruled to a line at z = 3 (the ruling at angle fraction a joins arc(a theta)
and line(a): not a NURBS pairing, fitted within the stated bound), a cone frustum between two arcs
of equal span (exact), and a parabola (126) paired with a line by arc length (form 0) and by
parameter (form 1). Rays aimed through points worked out by hand hit there at the t they were
aimed at; the u map takes the IGES u to the same points (also for arcs of different spans)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bsrt.geometry.bspline import evaluate
from bsrt.io import load_model
from bsrt.io.iges.bspline import arc_curve, line_curve
from bsrt.io.iges.ruled import RULED_TOLERANCE, ruled
from bsrt.io.param_map import ParamMap
from bsrt.queries import intersect

HERE = Path(__file__).parent / "data" / "iges"
_spec = importlib.util.spec_from_file_location("iges_generate", HERE / "generate.py")
gen = sys.modules.get("iges_generate")
if gen is None:  # loaded once (as tests/test_iges_model_space.py does)
    gen = sys.modules["iges_generate"] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(gen)
E, R = gen.E, gen.R
BOUND = 1e-9  # the brief's bound on the rulings, a fraction of the size (the fit's own is RULED_TOLERANCE)
T0 = 0.05  # the rays start this far from the point they are aimed at

# the quarter arc (radius 2 at z = 0, from (2, 0) to (0, 2)) and the line at z = 3
RADIUS, HEIGHT = 2.0, 3.0
L0, L1 = np.array([3.0, -1.0, HEIGHT]), np.array([-1.0, 3.0, HEIGHT])


def quarter_arc_line(a, v):
    """The exact ruled surface at angle fraction a (N,) and v (N,): (N, 3)."""
    th = 0.5 * math.pi * a
    arc = np.stack([RADIUS * np.cos(th), RADIUS * np.sin(th), np.zeros_like(a)], 1)
    return (1 - v)[:, None] * arc + v[:, None] * (L0 + a[:, None] * (L1 - L0))


def two_arcs(r1, span1, r2, span2, h, a0=0.0):
    """The exact ruled surface between arcs of radius r1 (z = 0) and r2 (z = h) from angle a0 over
    span1 and span2, paired by angle fraction."""

    def s(a, v):
        t1, t2 = a0 + a * span1, a0 + a * span2
        p1 = np.stack([r1 * np.cos(t1), r1 * np.sin(t1), 0 * a], 1)
        p2 = np.stack([r2 * np.cos(t2), r2 * np.sin(t2), 0 * a + h], 1)
        return (1 - v)[:, None] * p1 + v[:, None] * p2

    return s


def parabola_point(a):
    """The point of y = x^2 (0 <= x <= 2, z = 0) at arc length fraction a (N,), by bisection on the
    closed-form length x sqrt(1 + 4 x^2) / 2 + asinh(2 x) / 4."""

    def length(x):
        return x * np.sqrt(1 + 4 * x * x) / 2 + np.arcsinh(2 * x) / 4

    target, lo, hi = a * length(2.0), np.zeros_like(a), np.full_like(a, 2.0)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        low = length(mid) < target
        lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
    x = 0.5 * (lo + hi)
    return np.stack([x, x * x, 0 * x], 1)


PARABOLA_LINE = (np.array([0.0, -1.0, 2.0]), np.array([3.0, 2.0, 2.0]))


def parabola_line(form):
    m0, m1 = PARABOLA_LINE

    def s(a, v):
        # form 1: the 126's parameter t in [0, 1] is x / 2 (control points (0, 0), (1, 0), (2, 4))
        p = parabola_point(a) if form == 0 else np.stack([2 * a, 4 * a * a, 0 * a], 1)
        return (1 - v)[:, None] * p + v[:, None] * (m0 + a[:, None] * (m1 - m0))

    return s


def write(tmp_path: Path, entities, name="ruled.igs") -> Path:
    path = tmp_path / name
    path.write_text(gen.iges_text(entities, name))
    return path


def arc_line_file(form: int, dirflg: int) -> list:
    line = (L0, L1) if dirflg == 0 else (L1, L0)
    return [
        gen.arc("A", 0.0, (0.0, 0.0), (RADIUS, 0.0), (0.0, RADIUS)),
        gen.line("L", *line),
        E(118, [R("A"), R("L"), dirflg, 0], form=form, name="S"),
    ]


def arcs_file(form, r1, span1, r2, span2, h, a0=0.0) -> list:
    def arc(name, r, span, z):
        return gen.arc(
            name,
            z,
            (0.0, 0.0),
            (r * math.cos(a0), r * math.sin(a0)),
            (r * math.cos(a0 + span), r * math.sin(a0 + span)),
        )

    return [arc("A", r1, span1, 0.0), arc("B", r2, span2, h), E(118, [R("A"), R("B"), 0, 0], form=form, name="S")]


def parabola_file(form) -> list:
    m0, m1 = PARABOLA_LINE
    return [
        gen.bspline_curve("P", 2, [0, 0, 0, 1, 1, 1], [[0.0, 0.0], [1.0, 0.0], [2.0, 4.0]]),
        gen.line("L", m0, m1),
        E(118, [R("P"), R("L"), 0, 0], form=form, name="S"),
    ]


def aimed_hits(surfaces, exact, size: float, n: int = 9):
    """Rays aimed at exact(a, v) on an n x n grid inside (0, 1)^2 from T0 along the (finite
    difference) normal: (their hits, the points aimed at (N, 3))."""
    a, v = (x.ravel() for x in np.meshgrid(np.linspace(0.05, 0.95, n), np.linspace(0.05, 0.95, n)))
    x = exact(a, v)
    d = 1e-6
    su = (exact(a + d, v) - exact(a - d, v)) / (2 * d)
    sv = (exact(a, v + d) - exact(a, v - d)) / (2 * d)
    nrm = np.cross(su, sv)
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    return intersect(surfaces, x + T0 * nrm, -nrm, tolerance=1e-12), x


def check_aimed(path: Path, exact):
    (s,) = load_model(path, cache=False).surfaces
    size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
    hits, x = aimed_hits([s], exact, size)
    assert hits.hit.all()
    assert np.abs(hits.t - T0).max() <= BOUND * size
    assert np.linalg.norm(hits.point - x, axis=1).max() <= BOUND * size


@pytest.mark.parametrize("form", [0, 1])
@pytest.mark.parametrize("dirflg", [0, 1])
def test_quarter_arc_to_line_rulings_pair_angle_fraction_with_line_parameter(tmp_path, form, dirflg):
    # forms 0 and 1 pair the same points: arcs and lines have a constant speed in their parameters
    check_aimed(write(tmp_path, arc_line_file(form, dirflg)), quarter_arc_line)


@pytest.mark.parametrize("form", [0, 1])
def test_cone_frustum_between_arcs_of_equal_span_is_hit_at_its_radius(tmp_path, form):
    """Arcs of radius 1 (z = 0) and 2.5 (z = 4) over [0.3, 2.8]: rays from the axis at height z
    along angle phi hit the cone at t = 1 + 1.5 z / 4 (its radius there)."""
    path = write(tmp_path, arcs_file(form, 1.0, 2.5, 2.5, 2.5, 4.0, a0=0.3))
    (s,) = load_model(path, cache=False).surfaces
    z, phi = (x.ravel() for x in np.meshgrid(np.linspace(0.2, 3.8, 7), np.linspace(0.35, 2.75, 9)))
    origins = np.stack([0 * z, 0 * z, z], 1)
    hits = intersect([s], origins, np.stack([np.cos(phi), np.sin(phi), 0 * z], 1), tolerance=1e-12)
    assert hits.hit.all()
    assert np.abs(hits.t - (1 + 1.5 * z / 4)).max() <= 1e-12 * 10
    check_aimed(path, two_arcs(1.0, 2.5, 2.5, 2.5, 4.0, a0=0.3))


@pytest.mark.parametrize("form", [0, 1])
def test_parabola_to_line_pairs_arc_length_in_form_0_and_parameter_in_form_1(tmp_path, form):
    """The line's map is affine and the surface's u is the IGES u: S(a, v) is the exact point.
    (Points, not rays: the ray hierarchy misses some rays on long, thin, twisted patches,
    whoever made them: a fitted surface has more of them.)"""
    (s,) = load_model(write(tmp_path, parabola_file(form)), cache=False).surfaces
    size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
    assert s.domain_u == (0.0, 1.0) and s.domain_v == (0.0, 1.0)
    a, v = (x.ravel() for x in np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 5)))
    p = evaluate(s, a, v)[0]
    assert np.linalg.norm(p - parabola_line(form)(a, v), axis=1).max() <= BOUND * size


def test_the_u_map_takes_the_iges_u_to_the_paired_points():
    """ruled() directly: S(map_u(a), map_v(v)) is the exact point at (a, v) (the arc's map is the
    rational quadratic's closed form in the angle fraction: ParamMap's unit)."""
    th = 0.5 * math.pi
    cases = [
        (arc_curve([0, 0, 0], [1, 0, 0], [0, 1, 0], RADIUS, RADIUS, 0.0, th), line_curve(L0, L1), quarter_arc_line),
        (  # equal spans: exact
            arc_curve([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 1.0, 0.0, 2.5),
            arc_curve([0, 0, 3], [1, 0, 0], [0, 1, 0], 2.0, 2.0, 0.0, 2.5),
            two_arcs(1.0, 2.5, 2.0, 2.5, 3.0),
        ),
        (  # different spans: fitted (rays are not used here: the hierarchy misses some rays on long, thin,
            # twisted patches, whoever made them)
            arc_curve([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 1.0, 0.0, th),
            arc_curve([0, 0, 3], [1, 0, 0], [0, 1, 0], 2.0, 2.0, 0.0, 2 * th),
            two_arcs(1.0, th, 2.0, 2 * th, 3.0),
        ),
    ]
    a, v = (x.ravel() for x in np.meshgrid(np.linspace(0, 1, 41), np.linspace(0, 1, 5)))
    for c1, c2, exact in cases:
        for form in (0, 1):
            s, mu, mv = ruled(c1, c2, form)
            size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
            p = evaluate(s, mu(a), mv(v))[0]
            assert np.linalg.norm(p - exact(a, v), axis=1).max() <= RULED_TOLERANCE * size * 2
            assert np.abs(mu.inverse(mu(a)) - a).max() < 1e-14


def test_a_fitted_line_stays_on_its_line():
    s, _, _ = ruled(
        arc_curve([0, 0, 0], [1, 0, 0], [0, 1, 0], RADIUS, RADIUS, 0.0, 0.5 * math.pi), line_curve(L0, L1), 1
    )
    row = s.points[:, 1]
    off = np.cross(row - L0, L1 - L0)
    assert np.abs(off).max() < 1e-13 * 20
    assert s.degree[0] > 2 and s.points.shape[0] > 3  # fitted, not the rational quadratic alone


def test_a_scaled_angular_map_is_the_same_map():
    """ParamMap.scaled_x on an arc's ("tan") map: the fraction's map equals the angle's, and its
    inverse and derivative agree."""
    c = arc_curve([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 1.0, 0.4, 3.9)
    m = c.pmap
    f = m.scaled_x(3.5, 0.4)
    a = np.linspace(0, 1, 101)
    assert np.abs(f(a) - m(0.4 + 3.5 * a)).max() < 1e-14
    assert np.abs(f.inverse(f(a)) - a).max() < 1e-14
    assert np.abs(f.derivative(a) - 3.5 * m.derivative(0.4 + 3.5 * a)).max() < 1e-12
    assert isinstance(f, ParamMap) and f.unit == 3.5


def test_a_trimmed_118_is_cut_where_its_iges_u_v_say(tmp_path):
    """A 144 on the quarter arc to line surface, trimmed to [0.25, 0.75]^2 in the 118's (u, v): rays
    aimed 0.005 inside the square hit (at T0), 0.005 outside miss (the u map is the angle fraction's,
    not the rational arc's parameter: that one puts u = 0.25 at the angle fraction 0.24)."""
    corners = [(0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)]
    entities = arc_line_file(1, 0)
    entities[-1].status = "00010000"  # the 118: drawn through the 144 only
    entities += [
        *gen.polygon("B", corners),
        E(142, [0, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]
    (s,) = load_model(write(tmp_path, entities), cache=False).surfaces
    assert s.is_trimmed
    near = [0.245, 0.255, 0.5, 0.745, 0.755]
    a, v = (x.ravel() for x in np.meshgrid(near, near))
    inside = (np.abs(a - 0.5) < 0.25) & (np.abs(v - 0.5) < 0.25)
    x = quarter_arc_line(a, v)
    d = 1e-6
    nrm = np.cross(
        quarter_arc_line(a + d, v) - quarter_arc_line(a - d, v), quarter_arc_line(a, v + d) - quarter_arc_line(a, v - d)
    )
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    hits = intersect([s], x + T0 * nrm, -nrm, tolerance=1e-12)
    assert np.array_equal(hits.hit, inside)
    assert np.abs(hits.t[inside] - T0).max() <= 1e-9 * 10


def test_a_trimmed_122_on_an_arc_is_cut_where_its_u_says(tmp_path):
    """The same unit fix on a 122 (its u in [0, 1] runs over the arc's angle): a quarter arc of
    radius 2 swept up by 3, trimmed to [0.25, 0.75]^2: the point at angle fraction 0.255 is drawn,
    0.245 is not (rays from the axis outwards hit the cylinder at t = 2)."""
    corners = [(0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)]
    entities = [
        gen.arc("A", 0.0, (0.0, 0.0), (RADIUS, 0.0), (0.0, RADIUS)),
        E(122, [R("A"), RADIUS, 0.0, HEIGHT], name="S", status="00010000"),
        *gen.polygon("B", corners),
        E(142, [0, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]
    (s,) = load_model(write(tmp_path, entities), cache=False).surfaces
    near = np.array([0.245, 0.255, 0.5, 0.745, 0.755])
    a, v = (x.ravel() for x in np.meshgrid(near, near))
    th = 0.5 * math.pi * a
    hits = intersect([s], np.stack([0 * a, 0 * a, HEIGHT * v], 1), np.stack([np.cos(th), np.sin(th), 0 * a], 1))
    assert np.array_equal(hits.hit, (np.abs(a - 0.5) < 0.25) & (np.abs(v - 0.5) < 0.25))
    assert np.abs(hits.t[hits.hit] - RADIUS).max() <= 1e-9 * 10


def test_a_118_of_another_form_is_left_out_with_one_warning(tmp_path):
    entities = arc_line_file(1, 0)
    entities[-1].form = 2
    entities += [gen.line("X", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), E(118, [R("A"), R("X"), 0, 0], name="S2")]
    model = load_model(write(tmp_path, entities), cache=False)
    assert len(model.surfaces) == 1
    assert model.warnings == ["entity 118 (DE 5) form 2 (forms 0 and 1 are ruled surfaces); the surface is left out"]
