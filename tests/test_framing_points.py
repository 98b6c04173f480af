"""The automatic camera's points, cut down without changing the fit: the convex hull's vertices
hold every maximum the fit takes (a linear function, or the slope seen from a point in front),
and points on trim loops come from the trim table. Checked against every point by brute force."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MODELS

from bsrt.io import load_model
from bsrt.scene.auto import fit_camera, hull_vertices, surface_points


def _clouds():
    rng = np.random.default_rng(7)
    square = np.stack(np.meshgrid(np.linspace(0, 1, 40), np.linspace(0, 1, 40)), -1).reshape(-1, 2)
    return {
        "normal": rng.normal(size=(20000, 2)),
        "disc": (lambda t, r: np.stack([r * np.cos(t), r * np.sin(t)], 1))(
            rng.uniform(0, 7, 5000), rng.uniform(0, 1, 5000)
        ),
        "grid square (points on the filter's edges)": square,
        "collinear": np.outer(np.linspace(-1, 2, 50), [1.0, 3.0]),
        "three": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        "one": np.array([[2.0, 5.0]]),
    }


@pytest.mark.parametrize("name", list(_clouds()))
def test_the_hull_holds_every_maximum_of_linear_and_projected_functions(name):
    pts = _clouds()[name]
    a, b = pts[:, 0], pts[:, 1]
    keep = hull_vertices(a, b)
    assert keep.size <= max(3, a.size) and np.all(np.diff(keep) > 0)
    rng = np.random.default_rng(1)
    for c in rng.normal(size=(500, 2)):
        assert (c[0] * a[keep] + c[1] * b[keep]).max() == pytest.approx((c[0] * a + c[1] * b).max(), abs=1e-12)
    d = 1.0 - a.min()  # seen from a = -d, every point at least 1 in front
    for s in rng.normal(size=50):
        full, cut = (b - s) / (a + d), (b[keep] - s) / (a[keep] + d)
        assert cut.max() == pytest.approx(full.max(), abs=1e-12) and cut.min() == pytest.approx(full.min(), abs=1e-12)


def test_a_square_keeps_only_its_corners():
    square = np.stack(np.meshgrid(np.linspace(0, 1, 40), np.linspace(0, 1, 40)), -1).reshape(-1, 2)
    keep = hull_vertices(square[:, 0], square[:, 1])
    assert sorted(map(tuple, square[keep])) == [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)]


@pytest.mark.parametrize("view", ["default", "top", "front"])
def test_the_fit_on_the_hull_is_the_fit_on_every_point(view, monkeypatch):
    import bsrt.scene.auto as auto

    pts = surface_points(load_model(MODELS / "iges" / "occt" / "bearing.iges").surfaces)
    fast = fit_camera(pts, 64, 48, view)
    monkeypatch.setattr(auto, "hull_vertices", lambda a, b: np.arange(a.size))
    slow = fit_camera(pts, 64, 48, view)
    size = np.ptp(pts, axis=0).max()
    np.testing.assert_allclose(fast.eye, slow.eye, atol=1e-12 * size)
    np.testing.assert_allclose(fast.look_at, slow.look_at, atol=1e-12 * size)


def test_trim_loop_points_lie_on_the_trimmed_faces_boundaries():
    """Every point surface_points adds for a trim loop lies on one of its surface's trim curves
    (to the spacing of 4001 samples of each curve), and every trimmed surface gets some."""
    from bsrt.geometry.trim_table import build_trim_table, loop_points

    surfaces = [s for s in load_model(MODELS / "iges" / "occt" / "bearing.iges").surfaces if s.is_trimmed]
    table = build_trim_table(surfaces)
    owner, u, v = loop_points(table)
    assert owner.size == u.size == v.size == 4 * table.degree.size
    assert set(np.unique(owner)) == set(range(len(surfaces)))
    for m, surf in enumerate(surfaces):  # each point is on one of its surface's trim curves
        mine = owner == m
        curves = [c for loop in surf.trims for c in loop.curves]
        dense = np.concatenate([c.evaluate(np.linspace(*c.domain, 4001)) for c in curves])
        gap = np.min(np.hypot(u[mine, None] - dense[None, :, 0], v[mine, None] - dense[None, :, 1]), axis=1)
        span = max(np.ptp(dense[:, 0]), np.ptp(dense[:, 1]))
        assert gap.max() <= 2e-3 * span, (m, gap.max() / span)
