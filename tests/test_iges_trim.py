"""IGES trimmed surfaces, bounded surfaces, B-rep faces, analytic surfaces and curves.

Hand-written files in tests/data/iges (made by tests/data/iges/generate.py,
whose entity lists also give the broken variants below) checked against
closed forms, and the shared CAD files in tests/data/models/iges.
"""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from bsrt.cli import main
from bsrt.errors import InputError
from bsrt.geometry.bspline import evaluate
from bsrt.geometry.trim import check_loops
from bsrt.io import load_model
from bsrt.io.iges.bspline import arc_curve, reverse
from bsrt.io.iges.curves import curve
from bsrt.io.iges.records import IgesFile
from bsrt.io.param_map import ParamMap

HERE = Path(__file__).parent / "data" / "iges"
MODELS = Path(__file__).parent / "data" / "models" / "iges"
SHARED = {
    "bearing": MODELS / "occt" / "bearing.iges",
    "hammer": MODELS / "occt" / "hammer.iges",
    "example_45_faces": MODELS / "pythonocc-core" / "example_45_faces.iges",
    "marsCapsule": MODELS / "overtureframework" / "marsCapsule.igs",
    "asmo": MODELS / "overtureframework" / "asmo.igs",
}

_spec = importlib.util.spec_from_file_location("iges_generate", HERE / "generate.py")
gen = sys.modules.get("iges_generate")
if gen is None:  # loaded once: a second run of the module would make new classes (E, R) that isinstance misses
    gen = sys.modules["iges_generate"] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(gen)


def loop_points(loop, n: int = 40) -> np.ndarray:
    """(K, 2) points along every curve of a TrimLoop."""
    return np.concatenate([c.evaluate(np.linspace(*c.domain, n)) for c in loop.curves])


def on_surface(s, uv) -> np.ndarray:
    return evaluate(s, uv[:, 0], uv[:, 1])[0]


def assert_closed(loop, size: float, tol: float = 1e-9) -> None:
    ends = [c.ends() for c in loop.curves]
    for k in range(len(ends)):
        assert np.hypot(*(ends[k - 1][1] - ends[k][0])) <= tol * size


def domain_size(s) -> float:
    return math.hypot(s.domain_u[1] - s.domain_u[0], s.domain_v[1] - s.domain_v[0])


def surface_grid(s, n: int = 17) -> np.ndarray:
    u, v = np.meshgrid(np.linspace(*s.domain_u, n), np.linspace(*s.domain_v, n), indexing="ij")
    return evaluate(s, u.ravel(), v.ravel())[0]


def write(tmp_path: Path, entities, name: str = "case.igs") -> Path:
    path = tmp_path / name
    path.write_text(gen.iges_text(entities, name))
    return path


def replaced(entities, name: str, new) -> list:
    return [new if e.name == name else e for e in entities]


# ---------------------------------------------------------------------------
# The hand-written files


def test_generated_files_are_up_to_date():
    for name, build in gen.FILES.items():
        assert (HERE / name).read_text() == gen.iges_text(build(), name), f"run python {HERE / 'generate.py'}"


def test_written_files_are_80_columns_with_consistent_pointers():
    for name in gen.FILES:
        lines = (HERE / name).read_text().splitlines()
        assert all(len(line) == 80 for line in lines), name
        counts = {c: sum(line[72] == c for line in lines) for c in "SGDP"}
        assert lines[-1][:32] == "S{S:7d}G{G:7d}D{D:7d}P{P:7d}".format(**counts)


def test_144_plane_trimmed_by_a_126_circle_with_a_100_hole_moved_by_a_124():
    model = load_model(HERE / "plane_circle_144.igs")
    assert model.skipped == {} and model.warnings == [] and model.untrimmed == 0
    s, s2 = model.surfaces
    assert s.domain_u == (0.0, 1.0) and s.domain_v == (0.0, 1.0)
    outer, hole = s.trims
    p = loop_points(outer, 200)
    assert np.abs(np.hypot(p[:, 0] - 0.5, p[:, 1] - 0.5) - 0.4).max() < 1e-12
    p = loop_points(hole, 200)
    assert np.abs(np.hypot(p[:, 0] - 0.6, p[:, 1] - 0.45) - 0.1).max() < 1e-12
    for loop in s.trims:
        assert_closed(loop, 1.0)
    # the loop's points are where the plane's points are: x = -1 + 4u, y = -2 + 4v, z = 0
    uv = loop_points(outer)
    assert np.allclose(
        on_surface(s, uv), np.stack([-1 + 4 * uv[:, 0], -2 + 4 * uv[:, 1], 0 * uv[:, 0]], 1), rtol=0, atol=1e-14
    )
    # N1 = 0: the domain's boundary is the outer loop, then the hole
    rect, hole2 = s2.trims
    corners = np.array([c.ends()[0] for c in rect.curves])
    assert sorted(map(tuple, corners)) == [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)]
    assert np.abs(np.hypot(*(loop_points(hole2).T - np.array([[0.6], [0.45]]))) - 0.1).max() < 1e-12


def test_143_bounded_surface_with_a_reversed_141_curve():
    model = load_model(HERE / "plane_143.igs")
    (s,) = model.surfaces
    (loop,) = s.trims
    assert len(loop.curves) == 4
    assert_closed(loop, 1.0, tol=0.0)
    p = loop_points(loop)
    on_square = np.minimum.reduce([abs(p[:, 0] - 0.2), abs(p[:, 0] - 0.8), abs(p[:, 1] - 0.2), abs(p[:, 1] - 0.8)])
    assert on_square.max() < 1e-15 and p.min() == pytest.approx(0.2) and p.max() == pytest.approx(0.8)
    # the reversed side runs from (0.2, 0.8) down to (0.2, 0.2), closing the loop
    assert np.allclose(loop.curves[-1].ends(), [[0.2, 0.8], [0.2, 0.2]])
    assert model.skipped == {} and model.warnings == []


def test_brep_box_six_planar_faces():
    model = load_model(HERE / "box_brep.igs")
    assert len(model.surfaces) == 6 and model.skipped == {} and model.warnings == []
    corners = set()
    for s in model.surfaces:
        (loop,) = s.trims
        assert len(loop.curves) == 4
        assert_closed(loop, domain_size(s))
        xyz = on_surface(s, loop_points(loop))
        # every point of a loop lies on an edge of the box: two coordinates at their bounds
        at_bound = (np.abs(xyz - 0) < 1e-14) | (np.abs(xyz - [2, 1, 1]) < 1e-14)
        assert np.all(at_bound.sum(axis=1) >= 2)
        corners |= {tuple(np.round(on_surface(s, c.ends()[:1])[0], 12)) for c in loop.curves}
        # the face's plane covers exactly its rectangle
        box = surface_grid(s, 3)
        assert np.ptp(box, axis=0).tolist().count(0.0) == 1
    assert corners == {(x, y, z) for x in (0.0, 2.0) for y in (0.0, 1.0) for z in (0.0, 1.0)}


@pytest.mark.parametrize("name", ["cylinder_brep.igs", "cylinder_brep_inverted.igs"])
def test_brep_cylinder_face_with_a_seam(name):
    model = load_model(HERE / name)
    (s,) = model.surfaces
    assert s.degree == (2, 1)
    assert s.domain_u[0] == pytest.approx(0, abs=1e-12) and s.domain_u[1] == pytest.approx(2 * math.pi)
    assert s.domain_v == (0.0, 2.0)
    (loop,) = s.trims
    assert_closed(loop, domain_size(s))
    xyz = on_surface(s, loop_points(loop, 60))
    assert np.abs(np.hypot(xyz[:, 0], xyz[:, 1]) - 1).max() < 1e-12
    # bottom circle, top circle or the seam x = 1, y = 0
    on = np.minimum.reduce([abs(xyz[:, 2]), abs(xyz[:, 2] - 2), np.hypot(xyz[:, 0] - 1, xyz[:, 1])])
    assert on.max() < 1e-6
    if name == "cylinder_brep.igs":
        assert model.warnings == []
        assert on.max() < 1e-12
    else:
        (w,) = model.warnings
        assert w.startswith("4 trim curves were given only in model space") and "inversion" in w
    assert model.skipped == {}


def test_144_with_only_a_model_space_loop_on_a_128_is_inverted():
    model = load_model(HERE / "cylinder_128_model_space.igs")
    (s,) = model.surfaces
    (w,) = model.warnings
    assert w.startswith("4 trim curves were given only in model space") and "1e-06" in w
    (loop,) = s.trims
    assert len(loop.curves) == 4 and all(c.degree == 1 for c in loop.curves)
    assert_closed(loop, domain_size(s))
    xyz = on_surface(s, loop_points(loop, 300))
    ang = np.arctan2(xyz[:, 1], xyz[:, 0])
    on = np.minimum.reduce([abs(ang - 0.2), abs(ang - 1.2), abs(xyz[:, 2] - 0.5), abs(xyz[:, 2] - 1.5)])
    assert on.max() < 1e-6 * domain_size(s)
    # the surface's v is z / 2: the arcs became the iso-lines v = 0.25 and 0.75
    assert sorted({round(v, 12) for c in loop.curves for v in c.points[:, 1]})[:1] == [0.25]


def test_inverted_loop_through_a_collapsed_edge(tmp_path):
    """A 128 triangle (its edge v = 0 collapsed to the apex) bounded by its three model-space
    edges: at the apex u is undetermined, and the loop crosses the collapsed edge straight."""
    apex, a, b = (0.0, 0.0, 1.0), (2.0, 0.0, 0.0), (0.0, 3.0, 0.0)
    entities = [
        gen.bspline_surface("S", (1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[apex, a], [apex, b]]),
        gen.line("e1", apex, a),
        gen.line("e2", a, b),
        gen.line("e3", b, apex),
        gen.E(102, [3, gen.R("e1"), gen.R("e2"), gen.R("e3")], name="B"),
        gen.E(142, [0, gen.R("S"), 0, gen.R("B"), 2], name="C"),
        gen.E(144, [gen.R("S"), 1, 0, gen.R("C")], name="T"),
    ]
    model = load_model(write(tmp_path, entities))
    (s,) = model.surfaces
    (loop,) = s.trims
    assert_closed(loop, 1.0, tol=0.0)
    p = loop_points(loop, 50)
    on_edge = np.minimum.reduce([abs(p[:, 0]), abs(p[:, 0] - 1), abs(p[:, 1]), abs(p[:, 1] - 1)])
    assert on_edge.max() < 1e-6
    corners = {tuple(np.round(c.ends()[0], 9)) for c in loop.curves}
    assert corners == {(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)}


def test_128_cut_to_u0_u1_unless_its_loops_leave_that_range(tmp_path):
    def plane(u1):
        e = gen.plane_128("S")
        return gen.E(128, e.params[:-4] + [0.0, u1, 0.0, 1.0], name="S")

    # the loop is the circle of radius 0.4 around (0.5, 0.5): inside [0, 0.95] but not [0, 0.8]
    for u1, expected in ((0.95, (0.0, 0.95)), (0.8, (0.0, 1.0))):
        entities = replaced(gen.plane_circle_144()[:7], "S", plane(u1))
        s = load_model(write(tmp_path, entities)).surfaces[0]
        assert s.domain_u == expected
        assert np.abs(np.hypot(*(loop_points(s.trims[0]).T - 0.5)) - 0.4).max() < 1e-12
    # drawn alone, the same surface is cut
    s = load_model(write(tmp_path, [plane(0.8)])).surfaces[0]
    assert s.domain_u == (0.0, 0.8)


def test_brep_face_with_a_pole_vertex_edge_and_no_outer_loop_flag(tmp_path):
    (s,) = load_model(HERE / "sphere_cap_brep.igs").surfaces
    assert s.domain_u == (0.0, 2 * math.pi) and s.domain_v == (0.5, math.pi / 2)
    (loop,) = s.trims
    assert len(loop.curves) == 4  # circle, seam, the pole's segment in (u, v), seam
    assert np.allclose(loop.curves[2].ends(), [[2 * math.pi, math.pi / 2], [0, math.pi / 2]])
    assert_closed(loop, domain_size(s), tol=0.0)
    xyz = on_surface(s, loop_points(loop))
    assert np.abs(np.linalg.norm(xyz, axis=1) - 1).max() < 1e-12
    # OF = 0 on a bounded surface: no outer loop, so the loops are holes in the whole sphere
    entities = gen.sphere_cap_brep()
    entities[-1] = gen.E(510, [gen.R("S"), 1, 0, gen.R("loop")], form=1, name="F")
    (s,) = load_model(write(tmp_path, entities)).surfaces
    rect, cap = s.trims
    assert s.domain_u == (0.0, 2 * math.pi) and s.domain_v == (-math.pi / 2, math.pi / 2)
    assert sorted(map(tuple, (c.ends()[0] for c in rect.curves))) == sorted(
        (u, v) for u in (0.0, 2 * math.pi) for v in (-math.pi / 2, math.pi / 2)
    )


def test_unsupported_boundary_curve_draws_the_surface_untrimmed_with_a_warning(tmp_path):
    entities = replaced(gen.plane_circle_144()[:7], "outer", gen.E(130, [0.0] * 10, name="outer"))
    model = load_model(write(tmp_path, entities))
    s = model.surfaces[0]
    assert not s.is_trimmed and model.untrimmed == 1 and s.domain_u == (0.0, 1.0)
    assert model.warnings == [
        "1 surface is drawn untrimmed: its boundaries use entities bsrt does not convert "
        "(1 x IGES entity 130 (offset curve))"
    ]


def test_cylinder_192_trimmed_in_angle_and_height():
    (s,) = load_model(HERE / "cylinder_192.igs").surfaces
    # C + 2 (cos u X + sin u Y) + v Z with C = (1, 2, 3): the NURBS covers exactly the loop's box
    p = surface_grid(s)
    assert np.abs(np.hypot(p[:, 0] - 1, p[:, 1] - 2) - 2).max() < 1e-12
    ang = np.arctan2(p[:, 1] - 2, p[:, 0] - 1)
    assert ang.min() == pytest.approx(0.5, abs=1e-12) and ang.max() == pytest.approx(2.5, abs=1e-12)
    assert p[:, 2].min() == pytest.approx(2.0) and p[:, 2].max() == pytest.approx(5.0)
    (loop,) = s.trims
    xyz = on_surface(s, loop_points(loop))
    ang = np.arctan2(xyz[:, 1] - 2, xyz[:, 0] - 1)
    on = np.minimum.reduce([abs(ang - 0.5), abs(ang - 2.5), abs(xyz[:, 2] - 2), abs(xyz[:, 2] - 5)])
    assert on.max() < 1e-12


def test_cone_194_with_a_general_trim_curve_mapped_to_1e_9():
    model = load_model(HERE / "cone_194.igs")
    (s,) = model.surfaces
    # L + (1 + v tan 30)(cos u X + sin u Y) + v A with A = y, X = z, Y = A x X = x
    p = surface_grid(s)
    v = p[:, 1]
    assert np.abs(np.hypot(p[:, 0], p[:, 2]) - (1 + v * math.tan(math.radians(30)))).max() < 1e-12
    (loop,) = s.trims
    # the 126 pcurve (a quadratic Bezier in (angle, height)) is not a line: its image on the
    # B-spline is approximated; back in (angle, height) it is within 1e-9 of the original
    bez = np.array([(0.2, 0.5), (1.5, -0.5), (2.8, 1.5)])

    def b(t):
        t = np.asarray(t)[..., None]
        return (1 - t) ** 2 * bez[0] + 2 * t * (1 - t) * bez[1] + t**2 * bez[2]

    def db(t):
        t = np.asarray(t)[..., None]
        return 2 * (1 - t) * (bez[1] - bez[0]) + 2 * t * (bez[2] - bez[1])

    def distance(q):  # to the Bezier: the nearest of 2001 samples, then Newton on (B - q) . B' = 0
        ts = np.linspace(0, 1, 2001)
        t = ts[np.argmin(np.hypot(*(b(ts) - q).T))]
        for _ in range(20):
            r, d = b(t) - q, db(t)
            t = float(np.clip(t - r @ d / (d @ d + r @ (2 * (bez[0] - 2 * bez[1] + bez[2]))), 0, 1))
        return float(np.hypot(*(b(t) - q)))

    xyz = on_surface(s, loop_points(loop, 200))
    back = np.stack([np.arctan2(xyz[:, 0], xyz[:, 2]), xyz[:, 1]], 1)
    on_lines = np.minimum(abs(back[:, 1] - 1.5), abs(back[:, 0] - 0.2))
    off = [distance(q) for q, line in zip(back, on_lines) if line > 1e-12]
    assert len(off) > 100 and max(off) < 1e-9 * domain_size(s)
    assert_closed(loop, domain_size(s))


def test_sphere_and_torus_whole_and_a_sphere_trimmed_in_degrees():
    sphere, torus, s2 = load_model(HERE / "sphere_torus.igs").surfaces
    p = surface_grid(sphere, 25)
    assert np.abs(np.linalg.norm(p - 1, axis=1) - 3).max() < 1e-9
    assert sphere.domain_u == (0.0, 2 * math.pi) and sphere.domain_v == (-math.pi / 2, math.pi / 2)
    p = surface_grid(torus, 25)
    z = np.array([0, 1, 1]) / math.sqrt(2)
    h = p @ z
    rho = np.linalg.norm(p - np.outer(h, z), axis=1)
    assert np.abs((rho - 4) ** 2 + h**2 - 1).max() < 1e-9
    (loop,) = s2.trims
    xyz = on_surface(s2, loop_points(loop))
    assert np.abs(np.linalg.norm(xyz, axis=1) - 2).max() < 1e-12
    lon, lat = np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0])), np.degrees(np.arcsin(xyz[:, 2] / 2))
    on = np.minimum.reduce([abs(lon - 30), abs(lon - 120), abs(lat + 45), abs(lat - 60)])
    assert on.max() < 1e-10
    assert s2.domain_u == pytest.approx((math.radians(30), math.radians(120)))
    assert s2.domain_v == pytest.approx((math.radians(-45), math.radians(60)))


def test_ruled_revolution_tabulated_spline_and_plane_surfaces():
    model = load_model(HERE / "surfaces_misc.igs")
    ruled, rev, tab, spl, bounded, shown, tri = model.surfaces
    # 118 between radius-1 and radius-2 arcs at z = 0 and 3: a cone frustum r = 1 + z / 3
    p = surface_grid(ruled)
    assert np.abs(np.hypot(p[:, 0], p[:, 1]) - (1 + p[:, 2] / 3)).max() < 1e-12
    assert np.arctan2(p[:, 1], p[:, 0]).min() == pytest.approx(0, abs=1e-12)
    assert np.arctan2(p[:, 1], p[:, 0]).max() == pytest.approx(2.5)
    # 120: a circle of radius 1 around (3, 0, 0) turned about z by [0.5, 4]: a torus
    p = surface_grid(rev)
    assert np.abs((np.hypot(p[:, 0], p[:, 1]) - 3) ** 2 + p[:, 2] ** 2 - 1).max() < 1e-12
    ang = np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * math.pi)
    assert ang.min() == pytest.approx(0.5) and ang.max() == pytest.approx(4.0)
    assert rev.domain_v == (0.5, 4.0)  # v is the angle: its B-spline parameter equals it at the knots
    # 122: an arc of radius 1.5 around (10, 0) swept to z = 4
    p = surface_grid(tab)
    assert np.abs(np.hypot(p[:, 0] - 10, p[:, 1]) - 1.5).max() < 1e-12
    assert (p[:, 2].min(), p[:, 2].max()) == (0.0, 4.0)
    # 114: x = u, y = v, z = u^2 v + 1, on the same parameters
    u, v = np.meshgrid(np.linspace(0, 2, 11), np.linspace(0, 1, 7))
    p = evaluate(spl, u.ravel(), v.ravel())[0]
    assert np.abs(p - np.stack([u.ravel(), v.ravel(), u.ravel() ** 2 * v.ravel() + 1], 1)).max() < 1e-14
    # 108 bounded by a circle of radius 2 at z = 5
    (loop,) = bounded.trims
    xyz = on_surface(bounded, loop_points(loop))
    assert np.abs(np.hypot(xyz[:, 0], xyz[:, 1]) - 2).max() < 1e-12 and np.abs(xyz[:, 2] - 5).max() < 1e-14
    # 108 with a display size: a square of side 3 around (1, 1) at z = -2
    p = surface_grid(shown, 3)
    assert p.min(axis=0).tolist() == [-0.5, -0.5, -2.0] and p.max(axis=0).tolist() == [2.5, 2.5, -2.0]
    # 190 trimmed to a triangle by a 144; the other 190 has no boundary: left out
    (loop,) = tri.trims
    assert len(loop.curves) == 3 and np.allclose(on_surface(tri, loop_points(loop))[:, 2], 7)
    assert model.skipped == {"IGES entity 190 (plane surface)": 1}
    assert model.warnings == ["1 unbounded surface with nothing to bound it is left out (entity 190)"]


def test_curve_entities_against_closed_forms():
    f = IgesFile(str(HERE / "curves.igs"))
    by_label = {}
    for e in f.entities.values():
        by_label.setdefault(e.type, []).append(e)

    def sample(c, n=101):
        return c.evaluate(np.linspace(*c.domain, n))

    # 100 with its 124 (90 degrees about z, then (1, 2, 3)): centre (0, 3, 3.5), radius 2
    arc = curve(f, by_label[100][0])
    p = sample(arc)
    assert np.abs(np.linalg.norm(p - [0, 3, 3.5], axis=1) - 2).max() < 1e-14
    assert np.allclose(p[[0, -1]], [[0, 5, 3.5], [-2, 3, 3.5]], rtol=0, atol=1e-14)
    assert arc.domain == (0.0, math.pi / 2)  # the arc's parameter is its angle at the knots
    # 102: two lines end to end as one curve, parameter [0, 2]
    comp = curve(f, by_label[102][0])
    assert comp.domain == (0.0, 2.0)
    expected = [[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0]]
    assert np.allclose(comp.evaluate([0.0, 0.5, 1.0, 1.5, 2.0]), expected, rtol=0, atol=1e-15)
    ellipse, hyperbola, parabola = (curve(f, e) for e in by_label[104])
    p = sample(ellipse)
    assert np.abs(p[:, 0] ** 2 / 4 + p[:, 1] ** 2 - 1).max() < 1e-14 and np.all(p[:, 2] == 1)
    assert np.allclose(p[[0, -1], :2], [[2, 0], [0, 1]]) and p[:, :2].min() > -1e-15
    p = sample(hyperbola)
    assert np.abs(p[:, 0] ** 2 / 4 - p[:, 1] ** 2 - 1).max() < 1e-12 and p[:, 0].min() > 0
    assert np.allclose(p[[0, -1], 1], [math.sinh(-1), math.sinh(1)])
    p = sample(parabola)
    assert np.abs(p[:, 1] - p[:, 0] ** 2 / 4).max() < 1e-14
    assert np.allclose(p[[0, -1], :2], [[-2, 1], [4, 4]])
    square, poly3 = (curve(f, e) for e in by_label[106])
    assert square.degree == 1
    assert np.array_equal(square.points, [[0, 0, 2], [1, 0, 2], [1, 1, 2], [0, 1, 2], [0, 0, 2]])
    assert np.array_equal(poly3.points, [[0, 0, 0], [1, 1, 1], [2, 0, 3]])
    # 112: (t, t^2, t^3) on T = -1, 0, 2: exactly, on the same parameter
    spline = curve(f, by_label[112][0])
    t = np.linspace(-1, 2, 31)
    assert spline.domain == (-1.0, 2.0)
    assert np.abs(spline.evaluate(t) - np.stack([t, t**2, t**3], 1)).max() < 1e-14
    # 126 restricted to [0.25, 0.75]: the same cubic Bezier there
    bs = curve(f, by_label[126][0])
    assert bs.domain == (0.25, 0.75)
    t = np.linspace(0.25, 0.75, 11)[:, None]
    ctrl = np.array([(0, 0, 0), (1, 2, 0), (2, -1, 1), (3, 0, 0)], float)
    bez = (1 - t) ** 3 * ctrl[0] + 3 * t * (1 - t) ** 2 * ctrl[1] + 3 * t**2 * (1 - t) * ctrl[2] + t**3 * ctrl[3]
    assert np.abs(bs.evaluate(t[:, 0]) - bez).max() < 1e-14


def test_angle_maps_invert_exactly():
    arc = arc_curve([0, 0, 0], [1, 0, 0], [0, 1, 0], 1, 1, 0.3, 5.9)
    x = np.linspace(0.3, 5.9, 57)
    s = arc.pmap(x)
    assert np.abs(arc.pmap.inverse(s) - x).max() < 1e-14
    p = arc.evaluate(s)
    assert np.abs(np.unwrap(np.arctan2(p[:, 1], p[:, 0])) - x).max() < 1e-14
    m = ParamMap.identity(0.0, 2.0)
    assert m.affine_on(0.5, 1.5) == (1.0, 0.0)
    assert np.allclose(reverse(reverse(arc)).knots, arc.knots, rtol=0, atol=1e-15)


# ---------------------------------------------------------------------------
# The shared CAD files


@pytest.mark.parametrize("name", sorted(SHARED))
def test_shared_file_trims_load_closed_and_in_their_domains(name):
    path = SHARED[name]
    model = load_model(path)
    f = IgesFile(str(path))
    n144 = sum(e.type == 144 for e in f.entities.values())
    trimmed = [s for s in model.surfaces if s.is_trimmed]
    assert len(trimmed) == n144 > 0 and model.untrimmed == 0
    for s in trimmed:
        size = domain_size(s)
        for loop in s.trims:
            assert_closed(loop, size)
        check_loops(s.trims, (*s.domain_u, *s.domain_v))
    for text in model.warnings + [" ".join(model.skipped)]:
        for etype in ("144", "142", "102"):
            assert f"entity {etype} " not in text
    if name == "marsCapsule":
        # six arcs and six lines are the model's independent profile curves (in 402 groups)
        assert model.skipped == {
            "IGES entity 100 (circular arc)": 6,
            "IGES entity 110 (line)": 6,
            "IGES entity 402 (associativity instance)": 2,
        }
    else:
        assert not any(key.startswith(("IGES entity 126", "IGES entity 110")) for key in model.skipped)


def test_hammer_loops_lie_on_their_model_space_curves():
    """Each 142's parameter-space curve, on the surface, is its model-space curve."""
    path = SHARED["hammer"]
    model = load_model(path)
    f = IgesFile(str(path))
    by_name = dict(zip(model.names, model.surfaces))
    from bsrt.io.iges.curves import pieces

    worst = 0.0
    for e in f.entities.values():
        if e.type != 144:
            continue
        s = by_name[f.name(e)]
        p = f.params(e)
        p.pointer("PTS")
        p.int("N1")
        p.int("N2")
        q = f.params(f.entities[p.pointer("PTO")])
        q.int("CRTN")
        q.pointer("SPTR")
        q.pointer("BPTR")
        model_pts = np.concatenate(
            [c.evaluate(np.linspace(*c.domain, 3000)) for c in pieces(f, f.entities[q.pointer("CPTR")])]
        )
        size = np.ptp(model_pts, axis=0).max()
        xyz = on_surface(s, np.concatenate([c.ends() for c in s.trims[0].curves]))
        d = np.sqrt(((xyz[:, None] - model_pts[None]) ** 2).sum(-1)).min(axis=1).max()
        worst = max(worst, d / size)
    assert worst < 1e-3


def test_info_reports_trimmed_surfaces_and_loops(capsys):
    assert main(["info", SHARED["hammer"]]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].endswith("hammer.iges: 45 surfaces (45 trimmed, 48 loops)")


# ---------------------------------------------------------------------------
# Bad input: one message naming the file, the line and the entity


def assert_one_error(path: Path, capsys, pattern: str) -> str:
    with pytest.raises(InputError) as err:
        load_model(path)
    msg = str(err.value)
    assert "\n" not in msg and re.match(re.escape(str(path)) + r":\d+: entity \d+ \(DE \d+\): ", msg), msg
    assert re.search(pattern, msg), msg
    assert main(["info", path]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and captured.err.startswith("bsrt: error: ")
    return msg


def test_open_loop_is_one_warning_and_the_surface_is_left_out(tmp_path):
    """A loop that truly does not close is named once (entity, DE, where and how far
    apart) and its surface left out: never drawn with a wrong boundary."""
    entities = gen.plane_circle_144()
    three_quarters = gen.arc("outer", 0.0, (0.5, 0.5), (0.9, 0.5), (0.5, 0.1))
    model = load_model(write(tmp_path, replaced(entities, "outer", three_quarters)))
    assert len(model.surfaces) == 1  # the second plane only
    (msg,) = model.warnings
    assert msg.startswith("entity 144 (DE 13): its outer boundary (DE ") and " is open: " in msg
    assert msg.endswith("the surface is left out")


def test_curve_outside_the_domain(tmp_path, capsys):
    entities = replaced(gen.plane_circle_144(), "outer", gen.circle_126("outer", 0.5, 0.5, 0.7))
    assert_one_error(write(tmp_path, entities), capsys, r"leaves the surface's domain \[0, 1\] x \[0, 1\]")


def test_144_pointing_to_a_missing_entity(tmp_path, capsys):
    entities = gen.plane_circle_144()
    t = next(e for e in entities if e.name == "T")
    entities = replaced(entities, "T", gen.E(144, [99] + t.params[1:], name="T"))
    msg = assert_one_error(write(tmp_path, entities), capsys, r"points to DE 99, which does not exist")
    assert "entity 144 (DE 13)" in msg


def test_508_loop_that_does_not_close(tmp_path, capsys):
    entities = replaced(gen.cylinder_brep(), "p1", gen.line("p1", (2 * math.pi, 0.5), (2 * math.pi, 2.0)))
    msg = assert_one_error(write(tmp_path, entities), capsys, r"its loop 1 \(508 at DE \d+\) is open")
    assert msg.split(": ")[1].startswith("entity 510 (DE")  # the only surface: its error is the file's


# ---------------------------------------------------------------------------
# Periodic surfaces: seams, loops once round, poles


def _kept_against(s, inside, boundary, n: int = 241) -> None:
    """Over an n x n grid of s's domain: kept by the trims exactly where the closed form
    says inside (points within 1e-6 of the region's boundary, by ``boundary``, excepted)."""
    from bsrt.geometry.trim_table import kept

    mid = (np.arange(n) + 0.5) / n  # cell centres: not on the domain's edges (a seam lies there)
    (u0, u1), (v0, v1) = s.domain_u, s.domain_v
    u, v = np.meshgrid(u0 + (u1 - u0) * mid, v0 + (v1 - v0) * mid, indexing="ij")
    u, v = u.ravel(), v.ravel()
    xyz = evaluate(s, u, v)[0]
    keep = kept(s, u, v)
    clear = boundary(xyz) > 1e-6
    assert clear.sum() > 0.9 * len(u)
    assert np.array_equal(keep[clear], inside(xyz)[clear])


def _angle(xyz, start):
    """Angles about z, counterclockwise from ``start`` radians, in [0, 2 pi)."""
    return (np.arctan2(xyz[:, 1], xyz[:, 0]) - start) % (2 * math.pi)


def test_120_loop_across_the_seam_is_closed_and_trims_the_right_region():
    """The issue's case: pieces written in [0, 2 pi] meet only across the seam (2 pi apart in
    (u, v), 0 apart in model space): the loop is closed in one window of the turn."""
    model = load_model(HERE / "revolution_seam_144.igs")
    assert model.warnings == [] and model.untrimmed == 0
    (s,) = model.surfaces
    assert s.domain_v == pytest.approx((5.5, 0.7 + 2 * math.pi))  # one window, across the seam
    (loop,) = s.trims
    assert_closed(loop, domain_size(s))
    span = 0.7 + 2 * math.pi - 5.5

    def inside(xyz):
        return (_angle(xyz, 5.5) < span) & (xyz[:, 2] > 0.6) & (xyz[:, 2] < 2.4)

    def boundary(xyz):
        a = _angle(xyz, 5.5)
        return np.minimum.reduce(
            [np.minimum(a, 2 * math.pi - a) * 2, abs(a - span) * 2, abs(xyz[:, 2] - 0.6), abs(xyz[:, 2] - 2.4)]
        )

    assert np.allclose(np.hypot(*surface_grid(s)[:, :2].T), 2.0, atol=1e-12)
    _kept_against(s, inside, boundary)


def test_closed_128_loop_across_the_seam_splits_the_surface_there():
    model = load_model(HERE / "closed_128_seam_144.igs")
    assert model.warnings == []
    (s,) = model.surfaces
    assert s.domain_u == (3.5, 7.5)  # the seam moved to the loop's start: u = 3.5 (and 7.5)
    (loop,) = s.trims
    assert_closed(loop, domain_size(s))
    # the same cylinder: radius 1, and u = 4.5 (0.5 past the old seam) is 45 degrees
    grid = surface_grid(s)
    assert np.abs(np.hypot(grid[:, 0], grid[:, 1]) - 1).max() < 1e-12
    p = evaluate(s, np.array([4.5, 3.5]), np.array([1.0, 1.0]))[0]
    assert np.allclose(p, [[math.sqrt(0.5), math.sqrt(0.5), 1.0], [math.sqrt(0.5), -math.sqrt(0.5), 1.0]], atol=1e-14)
    q = math.pi / 4

    def inside(xyz):
        return (_angle(xyz, -q) < 2 * q) & (xyz[:, 2] > 0.5) & (xyz[:, 2] < 1.5)

    def boundary(xyz):
        a = _angle(xyz, -q)
        return np.minimum.reduce(
            [np.minimum(a, 2 * math.pi - a), abs(a - 2 * q), abs(xyz[:, 2] - 0.5), abs(xyz[:, 2] - 1.5)]
        )

    _kept_against(s, inside, boundary)


def test_two_loops_once_round_a_cylinder_become_one_band():
    """A 510 with two circles and no seam edge: joined along the domain's edges (the first
    circle's start, 1 radian, is the seam; the second circle is split there)."""
    model = load_model(HERE / "cylinder_band_brep.igs")
    assert model.warnings == []
    (s,) = model.surfaces
    assert s.domain_u == pytest.approx((1.0, 1.0 + 2 * math.pi)) and s.domain_v == (0.0, 2.0)
    (loop,) = s.trims
    assert_closed(loop, domain_size(s))
    _kept_against(
        s, lambda xyz: (xyz[:, 2] > 0) & (xyz[:, 2] < 2), lambda xyz: np.minimum(abs(xyz[:, 2]), abs(xyz[:, 2] - 2))
    )


def test_one_loop_once_round_closes_at_a_pole_or_an_apex():
    """A latitude on a sphere going east: the cap to the north pole; a circle on a cone going
    west: the cone down to its apex (the domain's edge on the loop's left)."""
    model = load_model(HERE / "once_round_144.igs")
    assert model.warnings == []
    sphere, cone = model.surfaces
    assert sphere.domain_v == pytest.approx((0.5, math.pi / 2))
    assert cone.domain_v == pytest.approx((-math.sqrt(3), 1.0))
    for s in (sphere, cone):
        (loop,) = s.trims
        assert_closed(loop, domain_size(s))
    z0 = math.sin(0.5)
    _kept_against(sphere, lambda xyz: xyz[:, 2] > z0, lambda xyz: abs(xyz[:, 2] - z0))
    _kept_against(cone, lambda xyz: xyz[:, 2] < 1.0, lambda xyz: abs(xyz[:, 2] - 1.0))


def test_once_round_loop_with_nothing_to_close_it_is_a_warning(tmp_path):
    """The cone's circle going east: its left is the open end of the cone: not closable."""
    entities = replaced(gen.once_round_144(), "ring", gen.line("ring", (0.0, 1.0), (2 * math.pi, 1.0)))
    model = load_model(write(tmp_path, entities))
    assert len(model.surfaces) == 1
    (msg,) = model.warnings
    assert msg.startswith("entity 144 (DE ") and "goes once round the surface and nothing bounds" in msg


def test_invert_recovers_parameters_from_nearby_starts():
    """bsrt.io.invert.invert (the closest-point inverter both CAD readers share):
    points S(u, v) on a rational surface are carried back to (u, v) from starts 0.05 off."""
    from bsrt.io.invert import invert

    s = load_model(HERE / "closed_128_seam_144.igs").surfaces[0]
    rng = np.random.default_rng(3)
    u = rng.uniform(3.6, 7.4, 200)
    v = rng.uniform(0.1, 1.9, 200)
    pts = evaluate(s, u, v)[0]
    x, y = invert(s, pts, u + 0.05, v - 0.05, 2.0)
    assert np.abs(x - u).max() < 1e-12 and np.abs(y - v).max() < 1e-12


def test_subfigure_instances_place_their_definitions_nested_scaled_moved_and_turned():
    """subfigures.igs (generate.py): a 144 (the square [0.2, 0.8]^2 of the plane z = 0) in a 308,
    placed by a 408 (scale 3, translation (0, 5, 0)) and, through a nested 308 whose 408 scales by
    2 and lifts by 1, by a 408 translated by (10, 0, 0) and then turned 90 degrees about z by its
    124 (IGES 5.3: an instance maps p to M (S p + T)). Worked by hand: (0.2, 0.2) -> 2 p + (0, 0, 1)
    = (0.4, 0.4, 1) -> + (10, 0, 0) -> turned: (-0.4, 10.4, 1)."""
    model = load_model(HERE / "subfigures.igs")
    assert len(model.surfaces) == 2 and model.warnings == []
    assert model.skipped == {"IGES entity 308 (subfigure definition)": 1}  # the definition nobody places
    corners = {
        name.split(" in ")[1]: on_surface(s, np.array([[0.2, 0.2], [0.8, 0.8]]))
        for s, name in zip(model.surfaces, model.names)
    }
    des = sorted(corners)
    assert np.allclose(corners[des[0]], [[-0.4, 10.4, 1.0], [-1.6, 11.6, 1.0]], rtol=0, atol=1e-14)
    assert np.allclose(corners[des[1]], [[0.6, 5.6, 0.0], [2.4, 7.4, 0.0]], rtol=0, atol=1e-14)
    for s in model.surfaces:  # the trim loops are the definition's, in (u, v)
        (loop,) = s.trims
        p = loop_points(loop)
        assert p.min() == pytest.approx(0.2) and p.max() == pytest.approx(0.8)


def test_subfigure_instances_that_contain_each_other_are_an_error(tmp_path, capsys):
    entities = [e for e in gen.subfigures() if e.name not in ("A", "Bi", "D3")]
    entities = replaced(entities, "D1", gen.E(308, [0, "plate", 2, gen.R("T"), gen.R("I2")], name="D1"))
    entities.append(gen.E(408, [gen.R("D2"), 0.0, 0.0, 0.0, 1.0], name="I2"))
    entities.append(gen.E(408, [gen.R("D1"), 0.0, 0.0, 0.0, 1.0], name="top"))
    with pytest.raises(InputError, match="contain each other in a loop"):
        load_model(write(tmp_path, entities))


def test_144_whose_parameter_space_loop_does_not_close_is_trimmed_by_its_model_space_loop():
    """sphere_120_shifted_pcurve.igs (generate.py; the situation of OpenCASCADE's
    bug22566_test_Bad.igs): the 142's parameter-space loop, in the writer's arc parameter (from 0
    at the arc's start), does not close in IGES's; its model-space loop does and bounds the
    quarter of the unit sphere with y <= 0 and z >= 0 (area pi), which is drawn, with a warning."""
    from bsrt.geometry.trim_table import kept

    model = load_model(HERE / "sphere_120_shifted_pcurve.igs")
    (s,) = model.surfaces
    assert model.warnings[0].startswith("entity 144 (DE ") and "model-space boundary does" in model.warnings[0]
    (loop,) = s.trims
    xyz = on_surface(s, loop_points(loop, 200))
    assert np.abs(np.linalg.norm(xyz, axis=1) - 1).max() < 1e-12
    on_boundary = np.minimum(np.abs(xyz[:, 1]), np.abs(xyz[:, 2]))  # the equator, the meridians in z = 0
    assert on_boundary.max() < 1e-5
    (a0, a1), (b0, b1) = s.domain_u, s.domain_v
    u, v = (g.ravel() for g in np.meshgrid(np.linspace(a0, a1, 201), np.linspace(b0, b1, 201), indexing="ij"))
    inside = kept(s, u, v)
    p, su, sv = evaluate(s, u, v)
    assert p[inside, 1].max() < 1e-5 and p[inside, 2].min() > -1e-5
    area = np.linalg.norm(np.cross(su, sv), axis=1)[inside].sum() * (a1 - a0) * (b1 - b0) / 200**2
    assert area == pytest.approx(math.pi, rel=0.03)
    # the seam: the equator arc ending on it and the meridian lying on it are on the side the loop is
    assert not (p[inside, 2] < -1e-3).any()


def test_invert_beyond_the_domain_edge_and_far_from_the_surface():
    """bsrt.io.invert on the closed cylinder (radius 1 about z, z = v in [0, 2]): points 1 above
    its top edge come back to that edge at their own angle (the closest point, with v held at
    the edge: worked by hand), and no point ends further from its target than its start was
    (points inside, near the axis, where the Gauss-Newton step overshoots)."""
    from bsrt.io.invert import invert

    s = load_model(HERE / "closed_128_seam_144.igs").surfaces[0]
    rng = np.random.default_rng(5)
    u = rng.uniform(3.6, 7.4, 100)
    top = evaluate(s, u, np.full(100, 2.0))[0] + [0.0, 0.0, 1.0]
    x, y = invert(s, top, u + 0.1, np.full(100, 1.5), 2.0)
    assert np.abs(y - 2.0).max() == 0.0 and np.abs(x - u).max() < 1e-12
    inside = np.column_stack([rng.uniform(-0.2, 0.2, (100, 2)), rng.uniform(0.2, 1.8, 100)])
    u0, v0 = rng.uniform(*s.domain_u, 100), rng.uniform(*s.domain_v, 100)
    x, y = invert(s, inside, u0, v0, 2.0)
    start = np.linalg.norm(evaluate(s, u0, v0)[0] - inside, axis=1)
    end = np.linalg.norm(evaluate(s, x, y)[0] - inside, axis=1)
    assert np.all(end <= start * (1 + 1e-12))
    # a sheared plane S(u, v) = (u + v, v, 0) on [0, 1]^2 (S_u . S_v != 0): (1.5, 1.5, 0) is
    # nearest (0, 1.5) unconstrained, v beyond the edge; with v held at 1, u + 1 = 1.5
    from bsrt.geometry.bspline import BSplineSurface

    plane = BSplineSurface(
        (1, 1),
        np.array([0.0, 0, 1, 1]),
        np.array([0.0, 0, 1, 1]),
        np.array([[[0.0, 0, 0], [1, 1, 0]], [[1, 0, 0], [2, 1, 0]]]),
    )
    x, y = invert(plane, np.array([[1.5, 1.5, 0.0]]), [0.9], [0.1], 3.0)
    assert (x[0], y[0]) == pytest.approx((0.5, 1.0), abs=1e-14)


def test_revolution_inverse_matches_the_newton_inverter():
    """bsrt.io.invert.RevolutionInverse (closed form, a segment turned about an axis): on a cone
    (apex on the axis) turned 300 degrees, points S(x, y) come back to (x, y) (1e-12), points off
    the surface go where SurfaceInverse's Newton goes (1e-9), the apex's y is NaN, and a segment
    out of the axis's plane (a hyperboloid) gets no closed form."""
    from bsrt.io.iges import analytic
    from bsrt.io.iges.bspline import line_curve
    from bsrt.io.invert import RevolutionInverse, SurfaceInverse

    origin, axis = np.array([1.0, -2.0, 0.5]), np.array([0.0, 0.6, 0.8])
    apex, rim = origin + 0.5 * axis, origin + 2.0 * axis + [3.0, 0.0, 0.0]
    gen = line_curve(apex, rim, 0.25, 1.75)
    a0, a1 = 0.3, 0.3 + math.radians(300)
    s, _, mv = analytic.revolve(gen, origin, axis, a0, a1, angle_first=False)
    inv = RevolutionInverse.of(1, gen.knots, gen.points, None, origin, axis, (a0, a1), mv, mv.inverse)
    assert inv is not None and inv.seams[1][2] is False
    rng = np.random.default_rng(11)
    x, y = rng.uniform(*s.domain_u, 200), rng.uniform(*s.domain_v, 200)
    pts, su, sv = evaluate(s, x, y)
    assert np.abs(inv(pts) - np.stack([x, y], 1)).max() < 1e-12
    normal = np.cross(su, sv)
    off = pts + 0.05 * normal / np.linalg.norm(normal, axis=1)[:, None]
    assert np.abs(inv(off) - SurfaceInverse(s)(off)).max() < 1e-9
    assert np.isnan(inv(apex[None])[0, 1])
    skew = [origin + 0.5 * axis + [1.0, 0.0, 0.0], origin + 2.0 * axis + np.cross(axis, [1.0, 0.0, 0.0])]
    assert RevolutionInverse.of(1, gen.knots, np.array(skew), None, origin, axis, (a0, a1), mv, mv.inverse) is None


def test_one_param_map_for_both_readers():
    """bsrt.io.param_map.ParamMap, the one map type: a circle's rational quadratic B-spline (IGES's
    unit_arc) at s = f(angle) is (cos, sin)(angle), for the IGES map and for the same map made on the
    knots as the OpenCASCADE import does (extended, not clipped, past its ends; periodic:
    f(x + 2 pi) = f(x) + 2 pi); inverse undoes it."""
    from bsrt.geometry.trim import TrimCurve
    from bsrt.io.iges.bspline import unit_arc

    knots, pts, w, iges_map = unit_arc(0.0, 2 * math.pi)
    circle = TrimCurve(2, knots, pts, w)
    on_knots = ParamMap.on_knots("tan", iges_map.x, 2 * math.pi)
    angle = np.linspace(0.0, 2 * math.pi, 101)
    for f in (iges_map, on_knots):
        p = circle.evaluate(f(angle))
        assert np.abs(p - np.stack([np.cos(angle), np.sin(angle)], 1)).max() < 1e-14
        assert np.abs(f.inverse(f(angle)) - angle).max() < 1e-14
    assert np.abs(on_knots(angle + 2 * math.pi) - on_knots(angle) - 2 * math.pi).max() < 1e-13
    ahead = ParamMap.on_knots("tan", iges_map.x)  # not periodic: extended past 2 pi by the arc's formula
    assert ahead(np.array([2 * math.pi + 0.1]))[0] > 2 * math.pi + 0.1 > iges_map(np.array([2 * math.pi + 0.1]))[0]
