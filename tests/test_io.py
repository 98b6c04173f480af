"""Tests of the model-file importers in bsrt.io against the real files in
tests/data/models (see its SOURCES.md) and small hand-written files in
tests/data."""

from __future__ import annotations

import math
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from conftest import MODELS as DATA
from conftest import model_files
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bsrt.errors import InputError
from bsrt.geometry.bspline import evaluate, make_surface
from bsrt.io import FORMATS, Model, load_model, restrict
from bsrt.io.bez import newell_from_qt3d
from bsrt.io.info import describe

HERE = Path(__file__).resolve().parent / "data"


def real_files() -> list[Path]:
    # Every file listed in tests/data/models/SOURCES.md; a missing or changed one fails the run.
    return list(model_files())


def grid(a: float, b: float, c: float, d: float, n: int = 9):
    """(n*n,) u and v covering [a, b] x [c, d]."""
    u, v = np.meshgrid(np.linspace(a, b, n), np.linspace(c, d, n), indexing="ij")
    return u.ravel(), v.ravel()


def points(surface, u, v) -> np.ndarray:
    return evaluate(surface, u, v)[0]


def assert_located(err: pytest.ExceptionInfo, path: Path, line: int | None = None) -> str:
    """The message is one sentence that starts 'path:line: '."""
    msg = str(err.value)
    assert "\n" not in msg
    m = re.match(re.escape(str(path)) + r":(\d+): \S", msg)
    assert m, msg
    if line is not None:
        assert int(m.group(1)) == line, msg
    return msg


# ---------------------------------------------------------------------------
# Every real file


@pytest.mark.parametrize("path", real_files(), ids=lambda p: str(p.relative_to(DATA)))
def test_every_real_file_loads_or_is_refused_in_one_sentence(path):
    model = load_model(path)  # STEP too: OpenCASCADE (the cad extra) is installed wherever the tests run
    assert isinstance(model, Model) and len(model.surfaces) >= 1
    assert len(model.names) == len(model.surfaces) == len(set(model.names))
    for s in model.surfaces:
        again = make_surface(s.degree, s.knots_u, s.knots_v, s.points, s.weights)
        assert again.shape == s.shape


# name, surfaces, degree counts, rational count, trimmed count (every IGES trim is read: none is drawn untrimmed)
EXPECTED = [
    ("bezier-teaset/qt3d/teapot.bez", 32, {(3, 3): 32}, 0, 0),
    ("bezier-teaset/qt3d/teapot-body.bez", 24, {(3, 3): 24}, 0, 0),
    ("bezier-teaset/qt3d/teapot-handle.bez", 4, {(3, 3): 4}, 0, 0),
    ("bezier-teaset/qt3d/teapot-spout.bez", 4, {(3, 3): 4}, 0, 0),
    ("bezier-teaset/qt3d/teacup.bez", 26, {(3, 3): 26}, 0, 0),
    ("bezier-teaset/qt3d/teaspoon.bez", 16, {(3, 3): 16}, 0, 0),
    ("bezier-teaset/splipy/teapot.g2", 32, {(3, 3): 32}, 0, 0),
    ("iges/overtureframework/ship_part1.igs", 12, {(3, 3): 12}, 0, 0),
    ("iges/overtureframework/ship_part2.igs", 59, {(3, 3): 59}, 0, 0),
    ("iges/overtureframework/ship_part3.igs", 133, {(3, 3): 133}, 0, 0),
    ("iges/overtureframework/ship_part4.igs", 6, {(3, 3): 6}, 0, 0),
    ("iges/overtureframework/ship_part5.igs", 215, {(3, 3): 215}, 0, 0),
    ("iges/pyIGES-benchmarks/128-000.igs", 1, {(3, 5): 1}, 0, 0),
    ("iges/pyIGES-benchmarks/128-002.igs", 1, {(7, 7): 1}, 0, 0),
    ("iges/pyIGES-benchmarks/128-003.igs", 1, {(7, 7): 1}, 0, 0),
    ("iges/pyIGES-benchmarks/128-004.igs", 1, {(5, 5): 1}, 0, 0),
    ("iges/pyIGES-benchmarks/128-005.igs", 1, {(5, 5): 1}, 0, 0),
    ("iges/pyIGES-benchmarks/128-009.igs", 1, {(3, 2): 1}, 0, 0),
    ("iges/pyIGES-benchmarks/144-000.igs", 1, {(3, 3): 1}, 0, 1),
    (
        "iges/pyIGES-benchmarks/nentity.igs",
        15,  # with the 140 offset surface (a bicubic B-spline: its base is not planar); 3 118s fitted (arc to line)
        {(1, 1): 1, (2, 2): 1, (2, 1): 1, (3, 5): 1, (8, 1): 3, (7, 7): 2, (3, 3): 3, (5, 5): 2, (3, 2): 1},
        5,
        2,
    ),
    ("iges/pyIGES-benchmarks/surf128.igs", 4, {(3, 3): 4}, 0, 0),
    ("iges/pythonocc-core/sunglasses_lens.igs", 9, {(3, 3): 9}, 0, 0),
    (
        "iges/occt/bearing.iges",
        213,
        {(3, 3): 87, (3, 1): 69, (5, 3): 18, (4, 3): 18, (1, 3): 11, (6, 3): 4, (1, 1): 4, (2, 3): 1, (8, 3): 1},
        0,
        213,
    ),
    ("iges/occt/hammer.iges", 45, {(1, 2): 15, (1, 1): 14, (2, 2): 12, (3, 1): 4}, 27, 45),
    ("iges/overtureframework/asmo.igs", 255, {(7, 7): 241, (3, 3): 8, (1, 1): 6}, 0, 8),
    ("iges/overtureframework/marsCapsule.igs", 9, {(3, 3): 8, (1, 1): 1}, 8, 9),
    ("iges/pythonocc-core/example_45_faces.iges", 45, {(1, 1): 21, (5, 1): 10, (5, 4): 8, (4, 1): 4, (5, 5): 2}, 0, 45),
    ("nurbs/glscene/duck1.nurbs", 1, {(3, 3): 1}, 1, 0),
    ("nurbs/glscene/duck2.nurbs", 1, {(3, 3): 1}, 0, 0),
    ("nurbs/glscene/duck3.nurbs", 1, {(3, 3): 1}, 0, 0),
    ("nurbs/splipy/sphere.g2", 1, {(2, 2): 1}, 1, 0),
    ("nurbs/splipy/torus.g2", 1, {(2, 2): 1}, 1, 0),
]


@pytest.mark.parametrize("name, count, degrees, rational, trimmed", EXPECTED, ids=[e[0] for e in EXPECTED])
def test_counts_and_degrees_match_sources_md(name, count, degrees, rational, trimmed):
    model = load_model(DATA / name)
    assert len(model.surfaces) == count
    assert Counter(s.degree for s in model.surfaces) == degrees
    assert sum(s.is_rational for s in model.surfaces) == rational
    assert sum(s.is_trimmed for s in model.surfaces) == trimmed
    assert model.untrimmed == 0
    assert not [w for w in model.warnings if "untrimmed" in w]


def test_control_net_shapes_and_skipped_entities():
    shape = lambda name: load_model(DATA / name).surfaces[0].shape  # noqa: E731
    assert shape("nurbs/splipy/sphere.g2") == (5, 9)
    assert shape("nurbs/splipy/torus.g2") == (9, 9)
    assert shape("nurbs/glscene/duck1.nurbs") == (13, 14)
    assert shape("nurbs/glscene/duck2.nurbs") == (10, 9)
    assert shape("nurbs/glscene/duck3.nurbs") == (6, 6)
    duck = load_model(DATA / "nurbs/glscene/duck1.nurbs").surfaces[0]
    # u varies fastest in the file: its first 13 points (v = 0) are one pole
    assert np.all(duck.points[:, 0] == duck.points[0, 0]) and not np.all(duck.points[0, :] == duck.points[0, 0])
    assert sorted(np.unique(duck.weights)) == [0.5, 1.0] and np.count_nonzero(duck.weights == 0.5) == 2
    hammer = load_model(DATA / "iges/occt/hammer.iges")
    # the 144s, their 142s and every curve of theirs are read: only the group is left
    assert hammer.skipped == {"IGES entity 402 (associativity instance)": 1}
    surf = load_model(DATA / "iges/pyIGES-benchmarks/surf128.igs")
    # the four 124s are applied, so only the drawing/view/property entities are skipped
    assert surf.skipped == {
        "IGES entity 404 (drawing)": 1,
        "IGES entity 406 (property)": 3,
        "IGES entity 410 (view)": 1,
    }
    # asmo.igs has 11 124s but no entity points to them
    assert load_model(DATA / "iges/overtureframework/asmo.igs").skipped["IGES entity 124 (transformation matrix)"] == 11


# ---------------------------------------------------------------------------
# Exact shapes: sphere and torus


SQRT_HALF = math.sqrt(0.5)


def snapped(surface, values):
    """The same surface with weights snapped to the nearest of ``values`` and
    Cartesian control points rounded to integers (the exact construction)."""
    values = np.array(values)
    w = values[np.argmin(np.abs(surface.weights[..., None] - values), axis=-1)]
    return make_surface(surface.degree, surface.knots_u, surface.knots_v, np.round(surface.points), w)


def test_sphere_g2_is_the_unit_sphere_to_the_accuracy_of_its_six_decimals():
    s = load_model(DATA / "nurbs/splipy/sphere.g2").surfaces[0]
    u, v = grid(*s.domain_u, *s.domain_v, n=161)  # includes every arc's middle
    err = np.abs(np.linalg.norm(points(s, u, v), axis=1) - 1).max()
    # The file writes 1/sqrt(2) as 0.707107 (the Cartesian points come out exact).
    # On a rational quadratic quarter circle with end weights 1 and middle weight
    # w, the middle point has radius sqrt(2) (1 + 2w) / (2 + 2w); its derivative
    # in w is sqrt(2) * 2 / (2 + 2w)^2, so the weight error moves it by:
    dw = 0.707107 - SQRT_HALF
    bound = math.sqrt(2) * 2 / (2 + 2 * SQRT_HALF) ** 2 * abs(dw)  # 5.31e-8
    assert 5.3e-8 < bound < 5.32e-8
    assert err <= bound * 1.001
    assert err > 1e-9  # so |S| == 1 within 1e-9 is not what this file can give
    # With the weights snapped to their exact values the surface is exact:
    exact = snapped(s, [1.0, SQRT_HALF, 0.5])
    assert np.abs(np.linalg.norm(points(exact, u, v), axis=1) - 1).max() < 1e-14


def test_torus_g2_has_major_radius_4_and_tube_radius_1_about_z():
    s = load_model(DATA / "nurbs/splipy/torus.g2").surfaces[0]
    u, v = grid(*s.domain_u, *s.domain_v, n=161)
    p = points(s, u, v)
    tube = np.hypot(np.hypot(p[:, 0], p[:, 1]) - 4, p[:, 2])
    err = np.abs(tube - 1).max()
    # Homogeneous values like 3.535534 / 0.707107 = 4.9999986 put the Cartesian
    # control points up to 1.42e-6 from the exact ones (integers); with
    # positive weights the surface stays within that distance plus the
    # weight-only error of the sphere test scaled by the radius (<= 5 * 5.31e-8).
    dev = np.abs(s.points - np.round(s.points)).max()
    assert 1.41e-6 < dev < 1.42e-6
    assert err <= dev + 5 * 5.32e-8
    assert err > 1e-7
    assert p[:, 2].min() > -1 - 1e-6 and p[:, 2].max() < 1 + 1e-6
    exact = snapped(s, [1.0, SQRT_HALF, 0.5])
    pe = points(exact, u, v)
    assert np.abs(np.hypot(np.hypot(pe[:, 0], pe[:, 1]) - 4, pe[:, 2]) - 1).max() < 1e-14


# ---------------------------------------------------------------------------
# The teapot twice: qt3d .bez and Splipy .g2


# g2 patch k (1-based) -> the qt3d .bez patch it reproduces, None for the four
# extra g2 patches; found by matching, then written down.
G2_TO_BEZ = [
    10,
    9,
    6,
    5,
    2,
    1,
    12,
    11,
    8,
    7,
    4,
    3,
    14,
    13,
    16,
    15,
    18,
    17,
    20,
    19,
    None,
    None,
    None,
    None,
    28,
    27,
    26,
    25,
    24,
    23,
    22,
    21,
]


def test_teapot_bez_and_g2_describe_the_same_patches():
    bez = load_model(DATA / "bezier-teaset/qt3d/teapot.bez").surfaces
    g2 = load_model(DATA / "bezier-teaset/splipy/teapot.g2").surfaces
    assert newell_from_qt3d([0.7, 0.45, -0.0]).tolist() == [1.4, 0.0, 2.4]  # Newell's vertex 1
    u, v = grid(0, 1, 0, 1, n=11)
    # g2 = 40 * (Newell - (0, 0, 0.15)): the x40 scale of SOURCES.md plus a shift
    # that puts the bottom of the body (Newell z = 0.15) at z = 0.
    g2_newell = [points(s, u, v) / 40 + [0, 0, 0.15] for s in g2]
    # g2 (u, v) is qt3d (v, 1 - u): a quarter turn of the parameter square,
    # which keeps the orientation (normals point the same way).
    bez_newell = [newell_from_qt3d(points(s, v, 1 - u)) for s in bez]
    worst = 0.0
    for k, j in enumerate(G2_TO_BEZ):
        if j is None:
            continue
        diff = np.abs(g2_newell[k] - bez_newell[j - 1]).max()
        worst = max(worst, diff)
        others = [np.abs(g2_newell[k] - b).max() for i, b in enumerate(bez_newell) if i != j - 1]
        assert min(others) > 0.05  # the match is unique
    assert worst < 1e-14
    # The g2 has no bottom (qt3d patches 29-32) but a flat ring at the rim's
    # lower edge (Newell z = 2.4) between radius 1.25 and 1.4 instead.
    assert sorted(set(range(1, 33)) - set(G2_TO_BEZ)) == [29, 30, 31, 32]
    for k in (20, 21, 22, 23):
        ring = g2_newell[k]
        assert np.allclose(ring[:, 2], 2.4, atol=1e-14)
        r = np.hypot(ring[:, 0], ring[:, 1])
        assert r.min() > 1.24 and r.max() < 1.41


# ---------------------------------------------------------------------------
# IGES transformation matrices


def test_iges_124_matrix_moves_surf128_by_hand_computed_amounts():
    # surf128.igs, DE 3 (the first 128) has field 7 = 1, the 124 at P line 1:
    #   124,1.,0.,0.,-1.516,0.,1.,0.,1.791,0.,0.,1.,2.455;
    # i.e. R = identity, T = (-1.516, 1.791, 2.455). After K1=10, K2=8, M1=M2=3,
    # the 15 + 13 knots and the 99 weights, its control points (u fastest)
    # start at the end of P line 8: (0,0,0), (0,0,0), then on P lines 8-10
    #   P(2,0) = (-3.333333000000000E-007, 0., 0.)
    #   P(3,0) = (0.0072193333333, 0.1227113333333, 0.58341)
    s = load_model(DATA / "iges/pyIGES-benchmarks/surf128.igs").surfaces[0]
    assert s.shape == (11, 9)
    # by hand: x' = x + T
    p00 = [0 - 1.516, 0 + 1.791, 0 + 2.455]
    p20 = [-3.333333e-7 - 1.516, 0 + 1.791, 0 + 2.455]  # (-1.5160003333333, 1.791, 2.455)
    p30 = [
        0.0072193333333 - 1.516,
        0.1227113333333 + 1.791,
        0.58341 + 2.455,
    ]  # (-1.5087806666667, 1.9137113333333, 3.03841)
    assert np.allclose(s.points[[0, 1, 2, 3], 0], [p00, p00, p20, p30], rtol=0, atol=1e-15)
    assert np.allclose(p30, [-1.5087806666667, 1.9137113333333, 3.03841], rtol=0, atol=1e-15)
    # the knots are clamped, so the surface's corner is the first point
    assert np.allclose(points(s, [0.0], [0.0])[0], p00, rtol=0, atol=1e-15)


def iges_text(entities) -> str:
    """A minimal fixed-format IGES file. entities: [(type, [params], xform DE, form)]."""

    def rec(data: str, letter: str, seq: int) -> str:
        return f"{data:<72}{letter}{seq:7d}"

    s = [rec("bsrt test file", "S", 1)]
    g = [rec("1H,,1H;,4Htest,8Htest.igs;", "G", 1)]
    d, p = [], []
    for k, (etype, params, xform, form) in enumerate(entities):
        de = 2 * k + 1
        tokens = [str(etype)] + [str(x) for x in params]
        chunks, line = [], ""
        for i, t in enumerate(tokens):
            t += ";" if i == len(tokens) - 1 else ","
            if len(line) + len(t) > 64:
                chunks.append(line)
                line = ""
            line += t
        chunks.append(line)
        start = len(p) + 1
        for c in chunks:
            p.append(f"{c:<64}{de:8d}P{len(p) + 1:7d}")
        fields1 = [etype, start, 0, 0, 0, 0, xform, 0]
        d.append("".join(f"{x:8d}" for x in fields1) + "00000000" + f"D{len(d) + 1:7d}")
        fields2 = [etype, 0, 0, len(chunks), form]
        d.append("".join(f"{x:8d}" for x in fields2) + " " * 32 + f"D{len(d) + 1:7d}")
    t = [rec(f"S{len(s):7d}G{len(g):7d}D{len(d):7d}P{len(p):7d}", "T", 1)]
    return "\n".join(s + g + d + p + t) + "\n"


BILINEAR_128 = [
    1,
    1,
    1,
    1,
    0,
    0,
    1,
    0,
    0,
    0,
    0,
    1,
    1,
    0,
    0,
    1,
    1,
    1,
    1,
    1,
    1,
    0,
    0,
    0,
    1,
    0,
    0,
    0,
    1,
    0,
    1,
    1,
    0,
    0,
    1,
    0,
    1,
]  # the unit square z = 0


def test_iges_chained_124_matrices_apply_inner_first(tmp_path):
    rot = [0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0]  # 90 degrees about z, then ...
    move = [1, 0, 0, 10, 0, 1, 0, 20, 0, 0, 1, 30]  # ... a translation
    path = tmp_path / "chain.igs"
    path.write_text(iges_text([(124, move, 0, 0), (124, rot, 1, 0), (128, BILINEAR_128, 3, 0)]))
    model = load_model(path)
    # corner (1, 0, 0): rotated to (0, 1, 0), then moved to (10, 21, 30)
    assert np.allclose(points(model.surfaces[0], [1.0], [0.0])[0], [10, 21, 30])
    assert model.skipped == {}


def test_iges_surface_is_cut_to_u0_u1_v0_v1(tmp_path):
    params = BILINEAR_128[:-4] + [0.25, 0.5, 0, 1]
    path = tmp_path / "cut.igs"
    path.write_text(iges_text([(128, params, 0, 0)]))
    s = load_model(path).surfaces[0]
    assert s.domain_u == (0.25, 0.5) and s.domain_v == (0.0, 1.0)
    assert np.allclose(points(s, [0.25, 0.5], [0.0, 1.0]), [[0.25, 0, 0], [0.5, 1, 0]])


def test_restrict_keeps_the_geometry():
    rng = np.random.default_rng(1)
    ku = [0, 0, 0, 0, 0.3, 0.5, 0.5, 0.8, 1, 1, 1, 1]
    kv = [-1, -1, -1, 0.2, 2, 2, 2]
    s = make_surface((3, 2), ku, kv, rng.normal(size=(8, 4, 3)), rng.uniform(0.5, 2, size=(8, 4)))
    r = restrict(s, (0.1, 0.65), (-0.5, 2))
    assert r.domain_u == (0.1, 0.65) and r.domain_v == (-0.5, 2.0)
    u, v = grid(0.1, 0.65, -0.5, 2, n=13)
    assert np.abs(points(r, u, v) - points(s, u, v)).max() < 1e-12


# ---------------------------------------------------------------------------
# Hand-written OBJ and BPT files


def test_obj_bezier_and_rational_bspline_fixture():
    model = load_model(HERE / "freeform.obj")
    bez, cyl = model.surfaces
    assert model.names == ["freeform.obj#1", "freeform.obj#2"]
    assert bez.degree == (2, 1) and bez.shape == (5, 2) and not bez.is_rational
    assert bez.knots_u.tolist() == [0, 0, 0, 1, 1, 3, 3, 3] and bez.knots_v.tolist() == [0, 0, 2, 2]
    assert np.allclose(points(bez, [0.5, 2.0], [1.0, 0.5]), [[0.5, 1, 0.5], [2, 0.5, 0]], rtol=0, atol=1e-15)
    assert cyl.degree == (2, 2) and cyl.is_rational
    assert cyl.domain_u == (0.0, 2.0) and cyl.domain_v == (0.0, 0.5)  # cut by "surf 0 2 0 0.5"
    u, v = grid(0, 2, 0, 0.5, n=21)
    p = points(cyl, u, v)
    assert np.abs(np.hypot(p[:, 0], p[:, 1]) - 1).max() < 1e-15
    assert np.allclose(p[:, 2], 2 * v, rtol=0, atol=1e-15) and p[:, 1].min() > -1e-15
    assert model.skipped == {"OBJ curve (curv2)": 1}
    assert model.untrimmed == 1
    assert model.warnings == ["1 surface has trim/hole/scrv curves, which bsrt ignores: they are rendered untrimmed"]


def test_bpt_fixture():
    model = load_model(HERE / "patches.bpt")
    flat, bump = model.surfaces
    assert flat.degree == (1, 1) and bump.degree == (2, 3) and bump.shape == (3, 4)
    assert np.allclose(points(flat, [0.25], [0.75]), [[0.25, 0.75, 0]], rtol=0, atol=1e-15)
    # z control values i * j give z = (2u)(3v) = 6uv
    assert np.allclose(points(bump, [0.5], [0.25]), [[0.5, 0.25, 0.75]], rtol=0, atol=1e-15)


# ---------------------------------------------------------------------------
# Format selection


def test_formats_table_and_selection(tmp_path):
    assert FORMATS == {
        ".bez": "bez",
        ".bpt": "bpt",
        ".g2": "g2",
        ".igs": "iges",
        ".iges": "iges",
        ".obj": "obj",
        ".nurbs": "nurbs",
        ".step": "step",
        ".stp": "step",
        ".p21": "step",
        ".brep": "brep",
        ".brp": "brep",
    }
    upper = tmp_path / "PATCHES.BPT"
    upper.write_bytes((HERE / "patches.bpt").read_bytes())
    assert len(load_model(upper).surfaces) == 2
    other = tmp_path / "patches.txt"
    other.write_bytes((HERE / "patches.bpt").read_bytes())
    with pytest.raises(InputError, match=r"unknown model file extension '\.txt'; supported extensions are \.bez"):
        load_model(other)
    assert len(load_model(other, format="bpt").surfaces) == 2
    with pytest.raises(
        InputError,
        match="unknown model format 'stl'; supported formats are bez, bpt, brep, g2, iges, nurbs, obj, occt, step",
    ):
        load_model(other, format="stl")
    with pytest.raises(InputError, match=r"missing.bez: no such file$"):
        load_model(tmp_path / "missing.bez")


def test_describe_summarises_a_model():
    text = describe(load_model(HERE / "freeform.obj"))
    assert "2 surfaces" in text and "(2,1) x 1" in text and "(2,2) x 1" in text
    assert "rational:      1" in text and "trimmed in the file" in text
    # the cylinder is cut to z <= 1 by its surf range
    assert "min (-1, 0, 0), max (3, 2, 1)" in text and f"diagonal {math.sqrt(16 + 4 + 1):.6g}" in text
    assert "OBJ curve (curv2)" in text and "rendered untrimmed" in text


def test_describe_iges():
    text = describe(load_model(DATA / "iges/occt/hammer.iges"))
    assert text.splitlines()[0].endswith("hammer.iges: 45 surfaces (45 trimmed, 48 loops)")
    assert "(1,2) x 15, (1,1) x 14, (2,2) x 12, (3,1) x 4" in text
    assert "trim loops:    1 loop x 42, 2 loops x 3" in text
    assert "rational:      27" in text and "1  IGES entity 402 (associativity instance)" in text
    assert "rendered untrimmed although trimmed in the file: 0" in text


# ---------------------------------------------------------------------------
# Malformed files: one sentence naming the file and the line


def write(tmp_path: Path, name: str, text: str | bytes) -> Path:
    path = tmp_path / name
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    return path


BEZ = (
    "2\n1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16\n"
    + "16,15,14,13,12,11,10,9,8,7,6,5,4,3,2,1,4\n"
    + "16\n"
    + "".join(f"{i % 4},{i // 4},{(i * 7) % 5}\n" for i in range(16))
)


@pytest.mark.parametrize(
    "text, line, words",
    [
        (BEZ, None, None),
        (BEZ.replace("\n16\n", "\n17\n"), 20, "the file ends early, expected vertex 17 of 17"),
        (
            BEZ.replace("13,14,15,16\n", "13,14,15\n", 1),
            2,
            "expected 16 vertex indices (and an optional subdivision depth), got 15",
        ),
        (BEZ.replace("1,0,2\n", "1,zero,2\n"), 6, "expected a coordinate (a number), got 'zero'"),
        (BEZ.replace("\n16\n", "\n15\n"), 20, "unexpected text after the 15 vertices"),
        (BEZ.replace("16,15,14", "17,15,14"), 3, "patch 2: vertex index 17 is out of range 1..16"),
        (BEZ.replace("2\n", "3\n", 1), 4, "expected 16 vertex indices"),
        (BEZ[:50], 3, "expected 16 vertex indices (and an optional subdivision depth), got 4"),
        (BEZ.replace("2\n", "-2\n", 1), 1, "the number of patches must be at least 1, got -2"),
    ],
)
def test_bez_errors(tmp_path, text, line, words):
    path = write(tmp_path, "t.bez", text)
    if words is None:
        assert len(load_model(path).surfaces) == 2
        return
    with pytest.raises(InputError) as err:
        load_model(path)
    assert words in assert_located(err, path, line)


def test_bez_options(tmp_path):
    plain = load_model(write(tmp_path, "a.bez", BEZ)).surfaces[0]
    rev = load_model(write(tmp_path, "b.bez", BEZ + "# reverse-patches teapot-adjust frob\n"))
    assert rev.warnings == [f"{tmp_path / 'b.bez'}: ignored unknown options frob"]
    expect = plain.points[:, ::-1] * [0.5, 0, 0] + plain.points[:, ::-1] @ [[0, 0, 0], [0, 0, -0.5], [0, 0.5, 0]]
    assert np.allclose(rev.surfaces[0].points, expect + [0, -0.75, 0])
    assert np.allclose(newell_from_qt3d(rev.surfaces[0].points), plain.points[:, ::-1])


BPT = (HERE / "patches.bpt").read_text()


@pytest.mark.parametrize(
    "text, line, words",
    [
        (BPT.replace("2 3\n", "2 4\n"), 19, "the file ends early, expected control point 13 of 15 of patch 2"),
        (BPT.replace("1 1 0\n", "1 1\n"), 6, "expected control point 4 of 4 of patch 1 (3 numbers on the line), got 2"),
        (BPT.replace("0.5 0.0 0\n", "0.5 O.0 0\n"), 12, "expected a coordinate (a number), got 'O.0'"),
        (BPT.replace("2\n", "3\n", 1), 19, "the file ends early, expected the degrees 'du dv' of patch 3 of 3"),
        (BPT.replace("2\n", "1\n", 1), 7, "unexpected text after the last of the 1 patches"),
        (BPT.replace("1 1\n", "0 1\n"), 2, "a patch degree must be at least 1, got 0"),
        (BPT.replace("1 1 0\n", "1 1 1e999\n"), 6, "a coordinate 1e999 is too large"),
    ],
)
def test_bpt_errors(tmp_path, text, line, words):
    path = write(tmp_path, "t.bpt", text)
    with pytest.raises(InputError) as err:
        load_model(path)
    assert words in assert_located(err, path, line)


@pytest.mark.parametrize(
    "edit, line, words",
    [
        (lambda t: t[: t.index("0.500000 0.500000 0.500000")], 14, "the file ends early, expected control point"),
        (
            lambda t: t.replace("5 3\n", "5 3 \n", 1).replace("3.141593 3.141593 3.141593\n", "3.141593 3.141593\n", 1),
            None,
            None,
        ),  # just a different line break: still reads... until the count is off
        (
            lambda t: t.replace("0.707107 0.707107 0.000000 0.707107", "0.707107 0.707107 0.000000 -0.707107"),
            14,
            "control point 8 has weight -0.707107; weights must be > 0",
        ),
        (lambda t: t.replace("3 1\n", "3 one\n"), 2, "expected the rational flag (0 or 1) (a whole number), got 'one'"),
        (
            lambda t: t.replace("3 1\n", "2 1\n"),
            1,
            "surface 1: only 3-D surfaces are supported, this one has dimension 2",
        ),
        # a wrong order shifts every later number: here a homogeneous 0 lands in a weight
        (lambda t: t.replace("9 3\n", "9 4\n"), 10, "control point 4 has weight 0; weights must be > 0"),
        (
            lambda t: t.replace("1.570796 1.570796 3.141593", "1.570796 1.070796 3.141593", 1),
            1,
            "surface 1: knots_u: knots must not decrease",
        ),
        (lambda t: "200 1 0\n", 1, "the file ends early, expected the number of auxiliary header values"),
    ],
)
def test_g2_errors(tmp_path, edit, line, words):
    path = write(tmp_path, "sphere.g2", edit((DATA / "nurbs/splipy/sphere.g2").read_text()))
    if words is None:
        with pytest.raises(InputError) as err:
            load_model(path)
        assert_located(err, path)
        return
    with pytest.raises(InputError) as err:
        load_model(path)
    assert words in assert_located(err, path, line)


def test_g2_skips_other_classes(tmp_path):
    curve = "100 1 0 0\n3 0\n2 2\n0 0 1 1\n0 0 0\n1 1 1\n"
    bounded = "210 1 0 4 255 0 0 255\nsome 1 2\nbody we do not parse\n"
    surf = "200 1 0 0\n3 0\n2 2\n0 0 1 1\n2 2\n0 0 1 1\n0 0 0  1 0 0\n0 1 0  1 1 0\n"
    model = load_model(write(tmp_path, "mix.g2", curve + bounded + surf + curve))
    assert len(model.surfaces) == 1 and model.names == ["mix.g2#1"]
    assert model.skipped == {"GoTools class 100 (spline curve)": 2, "GoTools class 210 (bounded surface)": 1}
    assert np.allclose(points(model.surfaces[0], [0.25], [0.5]), [[0.25, 0.5, 0]])
    with pytest.raises(InputError) as err:
        load_model(write(tmp_path, "curves.g2", curve))
    assert "holds no spline surfaces" in str(err.value)


NURBS = (
    "uOrder 2\nvOrder 2\nuDimension 2\nvDimension 3\n"
    "uKnot [ 0, 0, 1, 1 ]\nvKnot [ 0, 0, 0.5, 1, 1 ]\n"
    "controlPoint [\n 0 0 0,\n 1 0 0,\n 0 1 0,\n 1 1 1,\n 0 2 0,\n 1 2 0\n]\n"
    "weight [ 1, 1, 1, 2, 1, 1 ]\nccw FALSE\n"
)


@pytest.mark.parametrize(
    "text, line, words",
    [
        (NURBS, None, None),
        (
            NURBS[: NURBS.index(" 1 1 1")],
            10,
            "the file ends early, expected a number or ']' in controlPoint (opened on line 7)",
        ),
        (NURBS.replace("uDimension 2", "uDimension 3"), 5, "uKnot has 4 values, expected 5 (uDimension + uOrder)"),
        (NURBS.replace(" 1 1 1,", " 1 1 1, 2 2 2,"), 7, "controlPoint has 21 numbers, expected 18"),
        (NURBS.replace("0.5", "half"), 6, "expected a number or ']' in vKnot (a number), got 'half'"),
        (NURBS.replace("ccw FALSE", "colour red"), 16, "unknown field 'colour'"),
        (
            NURBS.replace("weight [ 1, 1, 1, 2,", "weight [ 1, 1, 1, 0,"),
            1,
            "surface: weights: every weight must be a finite number > 0",
        ),
        (NURBS.replace("vOrder 2\n", ""), 15, "the file ends without vOrder"),
        (NURBS.replace("uOrder 2", "uOrder 2\nuOrder 3"), 2, "uOrder is given twice (first on line 1)"),
        (
            NURBS.replace("weight [ 1, 1, 1, 2, 1, 1 ]", "weight [ 1, 1, 2, 1, 1 ]"),
            15,
            "weight has 5 values, expected 6",
        ),
    ],
)
def test_nurbs_errors(tmp_path, text, line, words):
    path = write(tmp_path, "t.nurbs", text)
    if words is None:
        s = load_model(path).surfaces[0]
        assert s.shape == (2, 3) and s.weights[1, 1] == 2 and np.allclose(s.points[1, 1], [1, 1, 1])
        return
    with pytest.raises(InputError) as err:
        load_model(path)
    assert words in assert_located(err, path, line)


OBJ = (HERE / "freeform.obj").read_text()


@pytest.mark.parametrize(
    "text, line, words",
    [
        (
            OBJ.replace("parm u 0 1 3\n", "parm u 0 1 2 3\n"),
            20,
            "surface 1: the surf lists 10 control vertices, but its parm and deg values call for 7 x 2",
        ),
        (OBJ.replace("v 0.5 0 1\n", "v 0.5 0 one\n"), 9, "expected a vertex coordinate (a number), got 'one'"),
        (
            OBJ.replace("     6 7 8 9 10", "     6 7 8 9 99"),
            20,
            "surface 1: control vertex 99 does not exist (10 vertices)",
        ),
        (OBJ.replace("-15 -14", "-99 -14"), 45, "control vertex -99 does not exist (25 vertices so far)"),
        (OBJ[: OBJ.index("trim")], 47, "the file ends inside the element that starts on line 45 (missing 'end')"),
        (OBJ.replace("parm v 0 0 0 1 1 1\n", ""), 45, "surface 2: the bspline surf has no 'parm v' knot vector"),
        (
            OBJ.replace("surf 0 2 0 0.5", "surf 0 2 0 1.5"),
            45,
            "surface 2: the range t0 t1 = [0, 1.5] is not inside the knot domain [0, 1]",
        ),
        (
            OBJ.replace("v 1 1 2 0.7071067811865476", "v 1 1 2 0"),
            45,
            "surface 2: weights: every weight must be a finite number > 0",
        ),
        (OBJ.replace("parm v 0 0 0 1 1 1", "parm v 0 0 0 1 0.5 1"), 45, "surface 2: knots_v: knots must not decrease"),
        (OBJ.replace("deg 2 1\n", ""), 19, "surf needs a preceding 'deg du dv' with two degrees"),
        (OBJ.replace("cstype bezier", "cstype nurbs"), 18, "expected 'cstype [rat] TYPE'"),
        (
            OBJ.replace("end\nv 1 0 0 1", "v 1 0 0 1"),
            44,
            "a new surf starts before the 'end' of the element on line 20",
        ),
    ],
)
def test_obj_errors(tmp_path, text, line, words):
    path = write(tmp_path, "t.obj", text)
    with pytest.raises(InputError) as err:
        load_model(path)
    assert words in assert_located(err, path, line)


@pytest.mark.parametrize(
    "edit, line, words",
    [
        # truncated: the Terminate record is gone
        (lambda ls: ls[:200], 200, "the file has no Terminate (T) record; it may be truncated"),
        # a deleted P line breaks the sequence numbers
        (lambda ls: ls[:40] + ls[41:], 41, "expected sequence number P10 in columns 74-80, got '11'"),
        # header (T record) disagreeing with the body
        (
            lambda ls: ls[:-1] + [ls[-1].replace("P    274", "P    275")],
            306,
            "the Terminate record says 275 P lines but the file has 274",
        ),
        # a non-number in the 128's knots
        (
            lambda ls: ls[:32] + [ls[32].replace("128,10,8,3,3,0,0,1,0,0,0.,", "128,10,8,3,3,0,0,1,0,0,O.,")] + ls[33:],
            33,
            "entity 128 (DE 3): expected a u knot (a number), got 'O.'",
        ),
        # K1 larger than the data: the parameters run out before U0
        (
            lambda ls: ls[:32] + [ls[32].replace("128,10,8,", "128,90,8,")] + ls[33:],
            121,
            "entity 128 (DE 3): its 437 parameters end before a weight",
        ),
        # the 128 points to a matrix that is not a 124
        (
            lambda ls: [
                line.replace(
                    "128       2       0       1       1       0       1",
                    "128       2       0       1       1       0      17",
                )
                for line in ls
            ],
            8,
            "transformation matrix pointer 17 points to entity 406, not to an entity 124",
        ),
        (lambda ls: ls[:5] + [ls[5][:72] + "X" + ls[5][73:]] + ls[6:], 6, "column 73 holds 'X', not a section letter"),
        (
            lambda ls: ls[:5] + [ls[5][:6] + "x" + ls[5][7:]] + ls[6:],
            6,
            "directory entry 1: the entity type (columns 1-8) is '1x4', not a whole number",
        ),
    ],
)
def test_iges_errors(tmp_path, edit, line, words):
    lines = (DATA / "iges/pyIGES-benchmarks/surf128.igs").read_text().splitlines()
    path = write(tmp_path, "surf128.igs", "\n".join(edit(lines)) + "\n")
    with pytest.raises(InputError) as err:
        load_model(path)
    assert words in assert_located(err, path, line)


@pytest.mark.parametrize("name", ["x.bez", "x.bpt", "x.g2", "x.igs", "x.obj", "x.nurbs"])
def test_binary_and_non_utf8_files_are_input_errors(tmp_path, name):
    for data, words in ((b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR", "binary file"), (b"2\n1,2\n\xff\xfe\n", "not valid UTF-8")):
        path = write(tmp_path, name, data)
        with pytest.raises(InputError) as err:
            load_model(path)
        assert words in assert_located(err, path)
    path = write(tmp_path, name, b"")
    with pytest.raises(InputError) as err:
        load_model(path)
    assert str(path) in str(err.value)


# ---------------------------------------------------------------------------
# Property test: mutated real files only ever raise InputError

MUTATION_SOURCES = [
    DATA / "bezier-teaset/qt3d/teapot-handle.bez",
    HERE / "patches.bpt",
    DATA / "nurbs/splipy/sphere.g2",
    DATA / "iges/pyIGES-benchmarks/surf128.igs",
    HERE / "freeform.obj",
    DATA / "nurbs/glscene/duck1.nurbs",
]
GARBAGE = [
    b"",
    b"x",
    b"-1",
    b"0",
    b"-0",
    b"1e999",
    b"nan",
    b"inf",
    b"1.5",
    b"99999999",
    b"1_0",
    b"\x00",
    b"\xff",
    b",",
    b";",
    b"[",
    b"]",
    b"#",
    b"1H",
    b"3H,;",
    b"end",
    b"surf",
    b"200 1 0 0",
    b"124",
    b"/",
    b"\\",
    b"0.0D0",
]


def mutate(data: st.DataObject, raw: bytes) -> bytes:
    kind = data.draw(st.sampled_from(["truncate", "token", "delete_lines", "duplicate_line", "splice"]))
    if kind == "truncate":
        return raw[: data.draw(st.integers(0, len(raw)))]
    if kind == "splice":
        at = data.draw(st.integers(0, len(raw)))
        return raw[:at] + data.draw(st.binary(max_size=8)) + raw[at:]
    lines = raw.split(b"\n")
    if kind == "token":
        tokens = [m.span() for m in re.finditer(rb"[^\s,;\[\]]+", raw)]
        if not tokens:
            return raw
        a, b = tokens[data.draw(st.integers(0, len(tokens) - 1))]
        return raw[:a] + data.draw(st.sampled_from(GARBAGE)) + raw[b:]
    i = data.draw(st.integers(0, len(lines) - 1))
    if kind == "duplicate_line":
        return b"\n".join(lines[: i + 1] + lines[i:])
    n = data.draw(st.integers(1, 3))
    return b"\n".join(lines[:i] + lines[i + n :])


@pytest.mark.parametrize("source", MUTATION_SOURCES, ids=lambda p: p.name)
def test_mutated_files_raise_only_input_error(source, tmp_path_factory):
    raw = source.read_bytes()
    folder = tmp_path_factory.mktemp("mutated")
    path = folder / source.name

    @settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(st.data())
    def check(data):
        path.write_bytes(mutate(data, raw))
        try:
            model = load_model(path)
        except InputError as e:
            msg = str(e)
            assert str(path) in msg and "\n" not in msg
            return
        assert len(model.surfaces) >= 1 and len(model.names) == len(model.surfaces)

    check()
