"""IGES boundaries given in model space, on hand-made files whose answers are known (issue 22):
loops along the seam of a surface of revolution, a 142 whose parameter-space curve is bogus,
and surfaces that are part of another entity (not drawn on their own)."""

from __future__ import annotations

import importlib.util
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bsrt.errors import InputError
from bsrt.geometry.bspline import evaluate
from bsrt.geometry.trim_table import kept
from bsrt.io import load_model

HERE = Path(__file__).parent / "data" / "iges"
_spec = importlib.util.spec_from_file_location("iges_generate", HERE / "generate.py")
gen = sys.modules.get("iges_generate")
if gen is None:  # loaded once: a second run of the module would make new classes (E, R) that isinstance misses
    gen = sys.modules["iges_generate"] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(gen)
E, R = gen.E, gen.R
TWO_PI = 2 * math.pi


def write(tmp_path: Path, entities, name: str = "case.igs") -> Path:
    path = tmp_path / name
    path.write_text(gen.iges_text(entities, name))
    return path


def kept_against(s, inside, boundary, n: int = 201) -> None:
    """Over an n x n grid of s's domain: kept by the trims exactly where the closed form says
    inside (points within 1e-6 of the region's boundary, by ``boundary``, excepted)."""
    mid = (np.arange(n) + 0.5) / n
    (u0, u1), (v0, v1) = s.domain_u, s.domain_v
    u, v = np.meshgrid(u0 + (u1 - u0) * mid, v0 + (v1 - v0) * mid, indexing="ij")
    u, v = u.ravel(), v.ravel()
    xyz = evaluate(s, u, v)[0]
    clear = boundary(xyz) > 1e-6
    assert clear.sum() > 0.9 * len(u)
    assert np.array_equal(kept(s, u, v)[clear], inside(xyz)[clear])


# ---------------------------------------------------------------------------
# A cylinder of revolution (120) trimmed by a model-space loop starting on its seam


def cylinder_seam_144(seam_y: float, top_start: float) -> list:
    """A 144 on a 120 turned a full turn (the line x = 2, y = 0, z = 3 u about the z axis: a
    cylinder of radius 2, v the angle) trimmed to angles [0, 1] and z in [0.6, 2.4] by a
    model-space 102 only: the generatrix's own line on the seam (at y = seam_y) first, then
    the arc at z = 2.4 from angle ``top_start``, the line down at angle 1, the arc at z = 0.6
    (written from angle 0 to 1: against the loop)."""
    c1, s1 = 2 * math.cos(1.0), 2 * math.sin(1.0)
    return [
        gen.line("axis", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        gen.line("gen", (2.0, 0.0, 0.0), (2.0, 0.0, 3.0)),
        E(120, [R("axis"), R("gen"), 0.0, TWO_PI], name="S"),
        gen.line("seam", (2.0, seam_y, 0.6), (2.0, seam_y, 2.4)),
        gen.arc("top", 2.4, (0.0, 0.0), (2 * math.cos(top_start), 2 * math.sin(top_start)), (c1, s1)),
        gen.line("side", (c1, s1, 2.4), (c1, s1, 0.6)),
        gen.arc("bottom", 0.6, (0.0, 0.0), (2.0, 0.0), (c1, s1)),
        E(102, [4, R("seam"), R("top"), R("side"), R("bottom")], name="B"),
        E(142, [0, R("S"), 0, R("B"), 2], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


@pytest.mark.parametrize(
    "seam_y, top_start",
    [
        (2 * math.sin(TWO_PI), 0.0),  # the seam line written at angle 2 pi: y = -4.9e-16, inverted to 2 pi
        (0.0, -1e-9),  # the top arc starts just across the seam: its first sample was put at 2 pi
    ],
    ids=["seam-line-at-2pi", "arc-just-across-the-seam"],
)
def test_120_model_space_loop_starting_on_the_seam_trims_the_right_region(tmp_path, seam_y, top_start):
    """gmsh model1.igs's case: 10 such faces were left out as open loops (the first curve, on
    the seam, inverted to v = 2 pi while the rest ran from v = 0; or a sample 1e-10 across the
    seam put a turn away)."""
    model = load_model(write(tmp_path, cylinder_seam_144(seam_y, top_start)))
    assert model.untrimmed == 0 and len(model.warnings) == 1
    assert model.warnings[0].startswith("4 trim curves were given only in model space")
    (s,) = model.surfaces
    assert len(s.trims) == 1

    def angle(xyz):
        return np.arctan2(xyz[:, 1], xyz[:, 0]) % TWO_PI

    def inside(xyz):
        return (angle(xyz) < 1.0) & (xyz[:, 2] > 0.6) & (xyz[:, 2] < 2.4)

    def boundary(xyz):
        a = angle(xyz)
        return np.minimum.reduce(
            [2 * np.minimum(a, TWO_PI - a), 2 * abs(a - 1.0), abs(xyz[:, 2] - 0.6), abs(xyz[:, 2] - 2.4)]
        )

    kept_against(s, inside, boundary)


# ---------------------------------------------------------------------------
# A 142 whose parameter-space curve leaves the domain (PREF = 2: model space preferred)


def plane_bogus_pcurve_144(model_centre) -> list:
    """A 144 on a plane 128 (u in [0, 1] -> x in [-1, 3], v -> y in [-2, 2]) bounded by a 142
    with PREF = 2 whose parameter-space curve is a circle around (6, 7.25) (model x, y, as in
    pyIGES's 144-000.igs: 5.25 outside the domain), and whose model-space curve is the circle
    of radius 1 around ``model_centre``."""
    return [
        gen.plane_128("S"),
        gen.circle_126("bogus", 6.0, 7.25, 0.25),
        gen.circle_126("model", *model_centre, 1.0),
        E(142, [1, R("S"), R("bogus"), R("model"), 2], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


def test_142_parameter_curve_off_the_domain_falls_back_to_the_model_space_curve(tmp_path):
    model = load_model(write(tmp_path, plane_bogus_pcurve_144((1.0, 0.0))))
    assert model.warnings[0] == (
        "entity 144 (DE 9): its parameter-space boundary leaves the surface's domain, its model-space "
        "boundary does not: the surface is trimmed by the model-space curves"
    )
    assert model.warnings[1].startswith("1 trim curve was given only in model space")  # a 128: inverted
    (s,) = model.surfaces

    def dist(xyz):
        return np.hypot(xyz[:, 0] - 1.0, xyz[:, 1])

    kept_against(s, lambda xyz: dist(xyz) < 1.0, lambda xyz: abs(dist(xyz) - 1.0))


def test_142_both_curves_off_the_domain_keep_the_parameter_curve_message(tmp_path):
    """The model-space curve leaves the domain too: the file is refused with the
    parameter-space curve's message, as when it has no model-space curve."""
    with pytest.raises(InputError, match=r"the curve from DE 3 leaves the surface's domain \[0, 1\] x \[0, 1\]"):
        load_model(write(tmp_path, plane_bogus_pcurve_144((20.0, 0.0))))


# ---------------------------------------------------------------------------
# Physically dependent surfaces


@pytest.mark.parametrize("status, drawn", [("00000000", 2), ("00010000", 1), ("00110000", 1)])
def test_physically_dependent_surface_is_not_drawn_on_its_own(tmp_path, status, drawn):
    """A second plane referenced only by a lone 142 (nentity.igs's 114): drawn whole when
    independent, not when physically dependent (subordinate switch 01 or 11), as OpenCASCADE."""
    entities = gen.plane_circle_144()[:7] + [
        replace(gen.plane_128("D", z=1.0), status=status),
        gen.line("seg", (0.2, 0.2), (0.8, 0.8)),
        E(142, [0, R("D"), R("seg"), 0, 1], name="lone"),
    ]
    model = load_model(write(tmp_path, entities))
    assert len(model.surfaces) == drawn
    assert model.names[0].endswith("#D13")  # the trimmed plane is drawn either way


def test_file_of_a_dependent_surface_only_is_refused_saying_so(tmp_path):
    """pyIGES's 142-000.igs: a lone 142 on a dependent surface; OpenCASCADE draws nothing."""
    entities = [
        replace(gen.plane_128("D"), status="00010000"),
        gen.line("seg", (0.2, 0.2), (0.8, 0.8)),
        E(142, [0, R("D"), R("seg"), 0, 1], name="lone"),
    ]
    with pytest.raises(InputError, match="no surfaces bsrt can draw.*; 1 of those surfaces is physically dependent"):
        load_model(write(tmp_path, entities))
