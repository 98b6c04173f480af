"""IGES 140 offset surfaces (issue 22) on hand-made files with closed-form answers: the offset of
a plane is the plane moved by d along S_u x S_v (exactly), the offset of a cylinder of radius 2
(a 120 turning a line about the z axis, S_u x S_v pointing at the axis) is the cylinder of radius
2 - d (within the stated bound); rays hit them at the t worked out by hand."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bsrt.geometry.bspline import evaluate
from bsrt.io import load_model
from bsrt.io.iges.offset import OFFSET_TOLERANCE, offset_bspline
from bsrt.queries import intersect

HERE = Path(__file__).parent / "data" / "iges"
_spec = importlib.util.spec_from_file_location("iges_generate", HERE / "generate.py")
gen = sys.modules.get("iges_generate")
if gen is None:  # loaded once (as tests/test_iges_model_space.py does)
    gen = sys.modules["iges_generate"] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(gen)
E, R = gen.E, gen.R
DEPENDENT = "00010000"  # a base surface: part of the 140, not drawn on its own


def dependent(e):
    e.status = DEPENDENT
    return e


def write(tmp_path: Path, entities) -> Path:
    path = tmp_path / "offset.igs"
    path.write_text(gen.iges_text(entities, path.name))
    return path


def plane_offset(d: float) -> list:
    """The plane z = 0 over [-1, 3] x [-2, 2] (u along x, v along y: S_u x S_v = +z) offset by d."""
    return [
        dependent(gen.plane_128("P")),
        E(140, [0.0, 0.0, 1.0, d, R("P")], name="O"),
    ]


def cylinder_offset(d: float) -> list:
    """The cylinder x^2 + y^2 = 4, 0 <= z <= 3 (a 120: u along the line, v the angle; S_u x S_v
    points at the axis) offset by d: the cylinder of radius 2 - d."""
    return [
        gen.line("axis", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        gen.line("gen", (2.0, 0.0, 0.0), (2.0, 0.0, 3.0)),
        E(120, [R("axis"), R("gen"), 0.0, 2 * math.pi], name="S", status=DEPENDENT),
        E(140, [1.0, 0.0, 0.0, d, R("S")], name="O"),
    ]


@pytest.mark.parametrize("d", [0.75, -0.5])
def test_plane_offset_is_the_moved_plane_exactly(tmp_path, d):
    model = load_model(write(tmp_path, plane_offset(d)), cache=False)
    (s,) = model.surfaces
    assert np.array_equal(s.points[..., 2], np.full(s.points.shape[:2], d))
    rng = np.random.default_rng(1)
    xy = rng.uniform([-0.9, -1.9], [2.9, 1.9], (50, 2))
    origins = np.column_stack([xy, np.full(50, 10.0)])
    hits = intersect([s], origins, np.array([0.0, 0.0, -1.0]) * np.ones((50, 1)))
    assert hits.hit.all()
    assert np.abs(hits.t - (10.0 - d)).max() <= 1e-9 * 10


@pytest.mark.parametrize("d", [0.5, -0.5])
def test_cylinder_offset_has_radius_two_minus_d(tmp_path, d):
    model = load_model(write(tmp_path, cylinder_offset(d)), cache=False)
    (s,) = model.surfaces
    size = 6.0  # the base's control points' box diagonal is below this
    rng = np.random.default_rng(2)
    u = rng.uniform(*s.domain_u, 2000)
    v = rng.uniform(*s.domain_v, 2000)
    p = evaluate(s, u, v)[0]
    assert np.abs(np.hypot(p[:, 0], p[:, 1]) - (2 - d)).max() <= OFFSET_TOLERANCE * size
    assert p[:, 2].min() >= -1e-12 and p[:, 2].max() <= 3 + 1e-12
    # rays from outside at random heights and angles, aimed at the axis: t = 10 - (2 - d)
    angle = rng.uniform(0, 2 * math.pi, 200)
    z = rng.uniform(0.1, 2.9, 200)
    origins = np.column_stack([10 * np.cos(angle), 10 * np.sin(angle), z])
    directions = np.column_stack([-np.cos(angle), -np.sin(angle), np.zeros(200)])
    hits = intersect([s], origins, directions)
    assert hits.hit.all()
    assert np.abs(hits.t - (10 - (2 - d))).max() <= OFFSET_TOLERANCE * size


def test_offset_bspline_states_its_deviation():
    """A free-form offset comes back with its measured deviation (within the tolerance); a plane's is
    exact (0.0) and moved by d along S_u x S_v."""
    from bsrt.geometry.bspline import make_surface

    bump = [[[x, y, 0.3 * math.sin(x) * math.cos(y)] for y in np.linspace(0, 2, 5)] for x in np.linspace(0, 2, 5)]
    s = make_surface((3, 3), [0, 0, 0, 0, 0.5, 1, 1, 1, 1], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], bump)
    fit, deviation = offset_bspline(s, 0.2)
    size = float(np.linalg.norm(np.ptp(np.asarray(bump).reshape(-1, 3), axis=0)))
    assert 0 < deviation <= OFFSET_TOLERANCE * size
    rng = np.random.default_rng(3)
    u, v = rng.random(500), rng.random(500)
    p, su, sv = evaluate(s, u, v)
    n = np.cross(su, sv)
    want = p + 0.2 * n / np.linalg.norm(n, axis=1)[:, None]
    assert np.linalg.norm(evaluate(fit, u, v)[0] - want, axis=1).max() <= 4 * OFFSET_TOLERANCE * size
    flat = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[0, 0, 1], [0, 1, 1]], [[1, 0, 1], [1, 1, 1]]])
    moved, exact = offset_bspline(flat, -0.25)
    assert exact == 0.0 and np.array_equal(moved.points[..., 2], np.full((2, 2), 0.75))


def test_offset_of_a_sphere_pole_is_named(tmp_path):
    """A base whose normal is undefined somewhere (a sphere's poles) is not drawn, and the warning
    names the 140 and why."""
    entities = [
        gen.line("axis", (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)),
        gen.arc("half", 0.0, (0.0, 0.0), (0.0, -1.0), (0.0, 1.0)),
        gen.matrix("xz", [(1, 0, 0), (0, 0, -1), (0, 1, 0)], (0, 0, 0)),
        E(120, [R("axis"), R("half"), 0.0, 2 * math.pi], name="S", status=DEPENDENT),
        E(140, [1.0, 0.0, 0.0, 0.1, R("S")], name="O"),
        gen.plane_128("P"),
    ]
    entities[1].xform = "xz"
    model = load_model(write(tmp_path, entities), cache=False)
    assert len(model.surfaces) == 1  # the plane alone
    assert "IGES entity 140 (offset surface)" in model.skipped
    (note,) = [w for w in model.warnings if "entity 140" in w]
    assert "normal is undefined" in note and "left out" in note
