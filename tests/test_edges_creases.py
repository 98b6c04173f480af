"""Creases inside one surface (rendering/edges.py, crease_curves), against closed forms.

A surface of degree (2, 1) over u in [0, 1] with the double knot u = 0.5 (C0 there): its control
points along u are (-2, 0), (-0.75, 0), (0.5, 0) (the knot's point), then (1.75, z3), (3, z4) in
(x, z), straight along y in [-3, 4]. Folded (z3 = 0.375, z4 = 0.75): flat for x < 0.5, rising at
slope 0.3 beyond: the normal turns by atan(0.3) = 16.7 degrees across the line x = 0.5, z = 0, a
crease. Bent smoothly (z3 = 0, z4 = 0.75: the three points around the knot in line, G1): the same
knot, no crease. Seen from straight above (0.5, 0.5, 3) on a film of 65 x 65, the line x = 0.5
projects onto the middle of column 32, and the surface's borders fall outside the film.
"""

from __future__ import annotations

import numpy as np
import pytest

from bsrt.rendering.edges import crease_curves
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import parse_scene

pytestmark = pytest.mark.gl

SIZE = 65


def _scene(z3: float, z4: float, trim=None, knots_u=(0, 0, 0, 0.5, 0.5, 1, 1, 1)):
    xs = [(-2.0, 0.0), (-0.75, 0.0), (0.5, 0.0), (1.75, z3), (3.0, z4)]
    if len(knots_u) == 7:  # one simple interior knot: four points
        xs = [(-2.0, 0.0), (0.0, 0.0), (1.5, z3), (3.0, z4)]
    surface = {
        "degree": [2, 1],
        "knots_u": list(knots_u),
        "knots_v": [0, 0, 1, 1],
        "points": [[[x, -3.0, z], [x, 4.0, z]] for x, z in xs],
        "material": "grey",
    }
    if trim is not None:
        (u0, u1), (v0, v1) = trim
        square = [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
        surface["trim"] = [
            {
                "curves": [
                    {"degree": 1, "knots": [0, 0, 1, 1], "points": [list(p), list(q)]}
                    for p, q in zip(square, square[1:] + square[:1])
                ]
            }
        ]
    return parse_scene(
        {
            "film": {"width": SIZE, "height": SIZE, "background": [1.0, 1.0, 1.0]},
            "camera": {"eye": [0.5, 0.5, 3.0], "look_at": [0.5, 0.5, 0.0], "up": [0.0, 1.0, 0.0], "fov": 40.0},
            "render": {"adaptive_spp": 0},
            "material": [{"name": "grey", "color": [0.5, 0.5, 0.5], "specular": 0.0}],
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": [surface],
        }
    )


def _coverage(scene) -> np.ndarray:
    """(H, W) the edges' coverage (width 1, black): 1 - with / without."""
    geometry = Geometry(scene)
    plain = render(scene, RenderOptions.resolve(scene), geometry=geometry).linear[..., 0]
    options = RenderOptions.resolve(scene, edges=True, edge_width=1.0, edge_color=(0.0, 0.0, 0.0))
    return 1.0 - render(scene, options, geometry=geometry).linear[..., 0] / plain


def test_a_fold_at_a_double_knot_is_drawn_on_the_column_it_projects_to_and_nowhere_else():
    cover = _coverage(_scene(0.375, 0.75))
    # a 1-pixel line through the centres of column 32 covers them whole, and no other centre
    assert cover[:, 32].min() > 0.99
    others = np.delete(cover, 32, axis=1)
    assert np.abs(others).max() < 1e-9


def test_a_smooth_surface_has_no_crease_at_its_knots():
    # the same C0 double knot, but the surface is G1 there (its three middle points in line)
    assert np.abs(_coverage(_scene(0.0, 0.75))).max() < 1e-12
    # a simple interior knot (C1 at degree 2): never a crease
    assert np.abs(_coverage(_scene(0.3, 0.75, knots_u=(0, 0, 0, 0.5, 1, 1, 1)))).max() < 1e-12
    # the fold itself is one crease curve, the smooth ones none
    for z3, curves in ((0.375, 1), (0.0, 0)):
        geometry = Geometry(_scene(z3, 0.75))
        assert len(crease_curves(geometry.patches)) == curves


def test_a_crease_is_clipped_by_the_trims():
    # trimmed to v in [0.2, 0.6] (y in [-1.6, 1.2]): above the film's row for y = 1.2 the face is cut
    # away (background), and the crease with it; the trim's own border y = 1.2 is drawn across there
    # (sloping up on the film beyond x = 0.5, where the face rises towards the eye)
    cover = _coverage(_scene(0.375, 0.75, trim=((0.02, 0.98), (0.2, 0.6))))
    half = 3.0 * np.tan(np.radians(20.0))  # film half-height at z = 0, scene units
    border = (1.0 - (1.2 - 0.5) / half) * SIZE / 2.0  # film y of the trim border y = 1.2 (z = 0)
    assert cover[int(border) + 2 :, 32].min() > 0.99
    assert np.abs(cover[: int(border) - 1, 30:35]).max() < 1e-9
