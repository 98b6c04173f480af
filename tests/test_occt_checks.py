"""The OpenCASCADE import's faster checks against what they replace: the closed-form points of
elementary surfaces (bsrt.io.occt.surfaces._checker) against OpenCASCADE's own ``Value``, the kinds
known for them (_known_kinds) against the kinds tested on OpenCASCADE's conversion (_kinds), and a
curve's Bezier form (bsrt.io.occt.curves.bezier_form) against the curve, with the same answers from
point_outside on it as on the curve."""

from __future__ import annotations

import numpy as np
import pytest
from OCP.Geom import (  # the cad extra: fail, never skip
    Geom_ConicalSurface,
    Geom_CylindricalSurface,
    Geom_Plane,
    Geom_RectangularTrimmedSurface,
    Geom_SphericalSurface,
    Geom_ToroidalSurface,
)
from OCP.GeomConvert import GeomConvert
from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

from bsrt.geometry.trim import TrimCurve, point_outside
from bsrt.io.occt.curves import bezier_form
from bsrt.io.occt.surfaces import _breaks, _checker, _extract, _kinds, _known_kinds, _points

FRAME = gp_Ax3(gp_Pnt(1.0, -2.0, 3.0), gp_Dir(0.3, 0.4, 0.866), gp_Dir(0.8, -0.6, 0.0))


def _surfaces():
    return {
        "plane": Geom_Plane(FRAME),
        "cylinder": Geom_CylindricalSurface(FRAME, 2.5),
        "cone": Geom_ConicalSurface(FRAME, 0.3, 2.5),
        "sphere": Geom_SphericalSurface(FRAME, 2.5),
        "torus": Geom_ToroidalSurface(FRAME, 5.0, 1.5),
    }


@pytest.mark.parametrize("name", list(_surfaces()))
def test_closed_forms_match_opencascade(name):
    surface = _surfaces()[name]
    rng = np.random.default_rng(7)
    u, v = rng.uniform(-7.0, 7.0, 40), rng.uniform(-1.5, 1.5, 40)
    for s in (surface, Geom_RectangularTrimmedSurface(surface, 0.5, 2.0, -1.0, 1.0)):
        got = _checker(s)(u, v)
        assert got.shape == (40, 3)
        np.testing.assert_allclose(got, _points(s, u, v), rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ["cylinder", "cone", "sphere", "torus"])
def test_known_kinds_are_the_tested_ones(name):
    surface = _surfaces()[name]
    window = (0.0, 2 * np.pi, -1.0, 1.0) if name != "torus" else (0.0, 2 * np.pi, 0.0, 2 * np.pi)
    bs = GeomConvert.SurfaceToBSplineSurface_s(Geom_RectangularTrimmedSurface(surface, *window))
    whole = _extract(bs)
    breaks = (
        _breaks(whole.knots_u, whole.degree[0], whole.shape[0]),
        _breaks(whole.knots_v, whole.degree[1], whole.shape[1]),
    )
    periodic = (surface.IsUPeriodic(), surface.IsVPeriodic())
    assert tuple(_kinds(_checker(surface), whole, breaks, 10.0, periodic)) == _known_kinds(surface)


def test_known_kinds_of_other_surfaces_are_tested():
    assert _known_kinds(_surfaces()["plane"]) == ("identity", "identity")
    from OCP.Geom import Geom_OffsetSurface

    assert _known_kinds(Geom_OffsetSurface(_surfaces()["cylinder"], 0.5)) is None


def test_bezier_form_is_the_same_curve_and_point_outside_agrees():
    rng = np.random.default_rng(11)
    for _ in range(200):
        p = int(rng.integers(1, 6))
        n = int(rng.integers(p + 1, p + 10))
        knots = np.concatenate([np.zeros(p + 1), np.sort(rng.uniform(0.0, 1.0, n - p - 1)), np.ones(p + 1)])
        weights = rng.uniform(0.5, 2.0, n) if rng.random() < 0.5 else None
        curve = TrimCurve(p, knots, rng.uniform(0.0, 1.0, (n, 2)), weights)
        bez = bezier_form(curve)
        inner = bez.knots[p + 1 : -p - 1]
        assert inner.size % p == 0 and np.all(inner[::p] == inner[p - 1 :: p])  # every inner knot p times
        s = np.linspace(0.0, 1.0, 57)
        np.testing.assert_allclose(bez.evaluate(s), curve.evaluate(s), rtol=0, atol=1e-14)
        box = (*np.sort(rng.uniform(-0.1, 1.1, 2)), *np.sort(rng.uniform(-0.1, 1.1, 2)))
        assert (point_outside(bez, box) is None) == (point_outside(curve, box) is None)
    bezier = TrimCurve(2, np.array([0.0, 0, 0, 1, 1, 1]), np.array([[0.0, 0], [1, 1], [2, 0]]))
    assert bezier_form(bezier) is bezier  # a curve in Bezier form already is itself
