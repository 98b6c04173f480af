"""The IGES reader's closed-form inverses: a 120 turning a circular arc (RevolutionInverse's arc
profile) and a 122 over a segment (a parallelogram, inverted affinely like a plane)."""

from __future__ import annotations

import math

import numpy as np

from bsrt.geometry.bspline import evaluate
from bsrt.io.iges import analytic
from bsrt.io.iges.bspline import arc_curve, reverse
from bsrt.io.invert import CurveInverse, RevolutionInverse, SurfaceInverse

TURN = (0.3, 0.3 + math.radians(300))


def _torus_part(a_start, a_end, turn=TURN):
    """A torus piece: the circle of radius 1 about (3, 0, 0) in the xz-plane, angles a_start..a_end
    (its IGES parameter), turned about the z axis through ``turn``. (generatrix, surface, inverse)."""
    origin, axis = np.zeros(3), np.array([0.0, 0.0, 1.0])
    gen = arc_curve([3.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1.0, 1.0, a_start, a_end)
    s, _, mv = analytic.revolve(gen, origin, axis, *turn, angle_first=False)
    inv = RevolutionInverse.of(
        gen.degree, gen.knots, gen.points, gen.weights, origin, axis, turn, mv, mv.inverse, gen.pmap
    )
    return gen, s, inv


def test_arc_generatrix_inverse_is_exact():
    """On a torus piece (a 200 degree arc turned 300 degrees) points S(x, y) come back to (x, y)
    (1e-12); a point at height z and distance rho from the axis, off the surface, goes to the
    generatrix angle atan2(z, rho - 3) (worked out by hand: the tube's centre circle is at rho = 3)
    and to its own angle about the axis; the reversed arc gives the same points."""
    gen, s, inv = _torus_part(-1.0, -1.0 + math.radians(200))
    assert inv is not None and inv.seams[0][2] is False and inv.seams[1][2] is False
    rng = np.random.default_rng(5)
    x, y = rng.uniform(*s.domain_u, 300), rng.uniform(*s.domain_v, 300)
    pts = evaluate(s, x, y)[0]
    assert np.abs(inv(pts) - np.stack([x, y], 1)).max() < 1e-12
    # off the surface, by hand: rho = 3 + 1.5 cos(0.4), z = 1.5 sin(0.4), at 100 degrees about z
    turn = math.radians(100)
    rho, z = 3 + 1.5 * math.cos(0.4), 1.5 * math.sin(0.4)
    p = np.array([[rho * math.cos(turn), rho * math.sin(turn), z]])
    got = inv(p)[0]
    on = evaluate(s, got[:1], got[1:])[0][0]
    expected = np.array([3 + math.cos(0.4), 0.0, math.sin(0.4)])
    expected[:2] = expected[0] * np.array([math.cos(turn), math.sin(turn)])
    assert np.linalg.norm(on - expected) < 1e-12
    back = reverse(gen)
    _, s2, inv2 = _torus_part(-1.0, -1.0 + math.radians(200))
    flipped = RevolutionInverse.of(
        back.degree,
        back.knots,
        back.points,
        back.weights,
        np.zeros(3),
        np.array([0.0, 0.0, 1.0]),
        TURN,
        inv2.to_y,
        inv2.to_angle,
        back.pmap,
    )
    assert flipped is not None
    assert np.abs(back.evaluate(flipped(pts)[:, 0]) - gen.evaluate(inv(pts)[:, 0])).max() < 1e-12


def test_full_circle_generatrix_is_closed_and_agrees_with_newton():
    """A whole torus (a full circle turned a full turn): closed in both parameters, its seam points
    at the generatrix's start (as the grid's nearest point would give), and off-surface points
    where SurfaceInverse's Newton goes (1e-9)."""
    _, s, inv = _torus_part(0.0, 2 * math.pi, (0.0, 2 * math.pi))
    assert inv.seams[0][2] and inv.seams[1][2]
    seam = evaluate(s, np.array([0.0, s.domain_u[1]]), np.array([1.0, 1.0]))[0]
    assert np.all(inv(seam)[:, 0] == s.domain_u[0])
    rng = np.random.default_rng(6)
    x, y = rng.uniform(0.2, 6.0, 200), rng.uniform(0.2, 6.0, 200)
    pts, su, sv = evaluate(s, x, y)
    normal = np.cross(su, sv)
    off = pts + 0.2 * normal / np.linalg.norm(normal, axis=1)[:, None]
    assert np.abs(inv(off) - SurfaceInverse(s)(off)).max() < 1e-9


def test_curve_inverse_newton_lands_on_the_closed_form():
    """CurveInverse's Newton (which takes its last small step unchecked) against the torus piece's
    closed form: points on the surface and 0.2 off it along the normal (closest point: S(x, y)
    itself, by hand), from the nearest grid point, from hints 1e-3 off and from hints 1e-9 off
    (one step, not confirmed): within 1e-10 of the domain's size everywhere."""
    _, s, closed = _torus_part(-1.0, -1.0 + math.radians(200))
    newton = CurveInverse(s)
    rng = np.random.default_rng(8)
    x, y = rng.uniform(*s.domain_u, 400), rng.uniform(*s.domain_v, 400)
    pts, su, sv = evaluate(s, x, y)
    normal = np.cross(su, sv)
    off = pts + 0.2 * normal / np.linalg.norm(normal, axis=1)[:, None]
    size = math.hypot(np.ptp(s.domain_u), np.ptp(s.domain_v))
    exact = np.stack([x, y], 1)
    for p in (pts, off):
        assert np.abs(closed(p) - exact).max() < 1e-12 * size
        for hint in (None, exact + 1e-3 * size * rng.uniform(-1, 1, exact.shape), exact + 1e-9 * size):
            assert np.abs(newton(p, hint) - exact).max() < 1e-10 * size


def test_no_closed_form_for_an_ellipse_or_a_tilted_arc():
    """An elliptic arc (a 104 conic's "tan" map too) and a circle out of the axis's plane get none."""
    origin, axis, turn = np.zeros(3), np.array([0.0, 0.0, 1.0]), (0.0, 1.0)
    for gen in (
        arc_curve([3.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1.0, 0.5, 0.0, 2.0),
        arc_curve([3.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8], 1.0, 1.0, 0.0, 2.0),
    ):
        _, _, mv = analytic.revolve(gen, origin, axis, *turn, angle_first=False)
        assert (
            RevolutionInverse.of(
                gen.degree, gen.knots, gen.points, gen.weights, origin, axis, turn, mv, mv.inverse, gen.pmap
            )
            is None
        )


def test_tabulated_segment_trims_are_exact(tmp_path):
    """A 122 over a 110 segment (the square x, y in [-2, 2], z = 0: S = (-2, -2, 0) + u (4, 0, 0) +
    v (0, 4, 0)) trimmed by a model-space circle of radius 1 about the origin (a 100): the trim is
    the circle's own rational quadratic carried affinely, the circle of radius 1/4 about (1/2, 1/2)
    in (u, v) (worked out by hand) to rounding at any point, not a polyline, and no warning about
    point inversion."""
    import importlib.util
    import sys
    from pathlib import Path

    here = Path(__file__).parent / "data" / "iges"
    gen = sys.modules.get("iges_generate")
    if gen is None:
        spec = importlib.util.spec_from_file_location("iges_generate", here / "generate.py")
        gen = sys.modules["iges_generate"] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(gen)
    E, R = gen.E, gen.R
    entities = [
        gen.line("directrix", (-2.0, -2.0, 0.0), (2.0, -2.0, 0.0)),
        E(122, [R("directrix"), -2.0, 2.0, 0.0], name="S"),
        gen.arc("circle", 0.0, (0.0, 0.0), (1.0, 0.0), (1.0, 0.0)),
        E(142, [0, R("S"), 0, R("circle"), 2], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]
    path = tmp_path / "tabulated.igs"
    path.write_text(gen.iges_text(entities, "tabulated.igs"))
    from bsrt.io import load_model

    model = load_model(str(path), cache=False)
    (s,) = model.surfaces
    assert not any("point inversion" in w for w in model.warnings)
    (loop,) = s.trims
    assert all(c.degree == 2 and c.weights is not None for c in loop.curves)
    for c in loop.curves:
        uv = c.evaluate(np.linspace(*c.domain, 101))
        assert np.abs(np.hypot(uv[:, 0] - 0.5, uv[:, 1] - 0.5) - 0.25).max() < 1e-14
