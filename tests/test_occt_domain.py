"""bsrt.io.occt.topology._inside_domain on closed forms: a pcurve that only touches the edge of the
surface's domain is kept as it is (a Pro/E part's 145.6-degree arc of radius 85, whose apex lay
1.78e-9 past its plane's v bound, had its middle control point clipped onto the edge: the arc's
middle moved 43 units inward)."""

from __future__ import annotations

import math

import numpy as np
import OCP  # noqa: F401  -- the cad extra (topology imports OpenCASCADE): fail, never skip

from bsrt.geometry.trim import TrimCurve
from bsrt.io.occt.topology import _inside_domain

RADIUS, ANGLE = 85.0, math.radians(145.6)


def _arc() -> TrimCurve:
    """The arc as one rational quadratic, apex (0, RADIUS) on +v, centre the origin."""
    h = ANGLE / 2
    points = np.array(
        [
            [-RADIUS * math.sin(h), RADIUS * math.cos(h)],
            [0.0, RADIUS / math.cos(h)],
            [RADIUS * math.sin(h), RADIUS * math.cos(h)],
        ]
    )
    return TrimCurve(2, np.array([0.0, 0, 0, 1, 1, 1]), points, np.array([1.0, math.cos(h), 1.0]))


def _radii(curve: TrimCurve) -> np.ndarray:
    return np.linalg.norm(curve.evaluate(np.linspace(0.0, 1.0, 101))[:, :2], axis=1)


def test_an_arc_touching_the_domains_edge_keeps_its_shape():
    out = _inside_domain(_arc(), (-100.0, 100.0, -100.0, RADIUS - 1.78e-9))
    np.testing.assert_allclose(_radii(out), RADIUS, rtol=1e-12)


def test_an_arc_far_past_the_edge_is_cut_at_it():
    top = 80.0  # the arc's middle, 5 past it, is cut off along v = 80
    out = _inside_domain(_arc(), (-100.0, 100.0, -100.0, top))
    uv = out.evaluate(np.linspace(*out.domain, 401))[:, :2]
    assert uv[:, 1].max() <= top + 1e-9
    on_arc = uv[:, 1] < top - 1e-6
    np.testing.assert_allclose(np.linalg.norm(uv[on_arc], axis=1), RADIUS, rtol=1e-9)
    assert math.isclose(uv[:, 1].max(), top, abs_tol=1e-9)
