"""bsrt.intersect and bsrt.sensors against closed forms: exact (rational) spheres, tori and trimmed
planes, every expected value worked out by hand (no OpenCASCADE here: tests/test_intersect_cad.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bsrt
from bsrt.errors import InputError
from bsrt.geometry.bspline import evaluate
from bsrt.io.iges.analytic import sphere, torus
from bsrt.parts import Surface
from bsrt.queries import prepared

A = np.array
R = 2.0  # the sphere's radius, centred at the origin
X, Y, Z = A([1.0, 0, 0]), A([0, 1.0, 0]), A([0, 0, 1.0])


def ball():
    s, _, _ = sphere(A([0.0, 0, 0]), X, Y, Z, R, (0.0, 2 * math.pi, -math.pi / 2, math.pi / 2))
    return bsrt.Scene.build([Surface.from_object(s, name="ball")])


def ring():
    """Torus: major radius 3, minor 1, axis z."""
    s, _, _ = torus(A([0.0, 0, 0]), X, Y, Z, 3.0, 1.0, (0.0, 2 * math.pi, 0.0, 2 * math.pi))
    return bsrt.Scene.build([Surface.from_object(s, name="ring")])


W = math.sqrt(0.5)


def circle(cx, cy, r):
    """An exact circle in (u, v): four rational quadratic quarter arcs."""
    curves = []
    for k in range(4):
        a0, a1 = k * math.pi / 2, (k + 1) * math.pi / 2
        p0 = [cx + r * math.cos(a0), cy + r * math.sin(a0)]
        p1 = [cx + r * (math.cos(a0) - math.sin(a0)), cy + r * (math.sin(a0) + math.cos(a0))]
        p2 = [cx + r * math.cos(a1), cy + r * math.sin(a1)]
        curves.append({"degree": 2, "knots": [0, 0, 0, 1, 1, 1], "points": [p0, p1, p2], "weights": [1.0, W, 1.0]})
    return {"curves": curves}


def plate_with_hole():
    """The plane z = 0 over [-1, 1]^2 (u = x, v = y), a round hole of radius 0.5 at the centre."""
    pts = A([[[-1.0, -1, 0], [-1, 1, 0]], [[1, -1, 0], [1, 1, 0]]])
    square = {
        "curves": [
            {"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]}
            for a, b in [([-1, -1], [1, -1]), ([1, -1], [1, 1]), ([1, 1], [-1, 1]), ([-1, 1], [-1, -1])]
        ]
    }
    s = Surface((1, 1), [-1, -1, 1, 1], [-1, -1, 1, 1], pts, trims=[square, circle(0.0, 0.0, 0.5)], name="plate")
    return bsrt.Scene.build([s])


def test_sphere_nearest_hit_point_normal_and_parameters():
    """Rays along -x at height b from x = 5: t = 5 - sqrt(R^2 - b^2), outward normal p / R, front facing;
    (u, v) evaluates (reference evaluator) to the point."""
    scene = ball()
    b = A([0.0, 0.3, 1.0, 1.9])
    origins = np.stack([np.full(4, 5.0), b, np.zeros(4)], axis=1)
    result = bsrt.intersect(scene, origins, np.tile(-X, (4, 1)))
    assert result.hit.all() and result.names == ("ball",) and (result.surface == 0).all()
    assert np.allclose(result.t, 5.0 - np.sqrt(R**2 - b**2), rtol=0, atol=1e-8)
    assert np.allclose(result.point, origins - result.t[:, None] * X, rtol=0, atol=1e-8)
    assert np.allclose(result.normal, result.point / R, rtol=0, atol=1e-7)
    assert result.front_facing.all()
    geometry = scene.surfaces[0].geometry
    for k in range(4):
        assert np.allclose(evaluate(geometry, result.u[k], result.v[k])[0][0], result.point[k], atol=1e-8)
    assert (result.residual <= 1e-9 * 2 * R * math.sqrt(3) * 2).all()
    assert result.surface_names() == ["ball"] * 4


def test_sphere_from_inside_is_back_facing_and_misses_are_nan():
    scene = ball()
    result = bsrt.intersect(scene, A([[0.0, 0, 0], [5, 5, 5]]), A([[0.0, 1, 0], [1.0, 0, 0]]))
    assert result.hit.tolist() == [True, False]
    assert abs(result.t[0] - R) < 1e-8 and np.allclose(result.normal[0], Y, atol=1e-7)
    assert not result.front_facing.any()
    assert np.isnan(result.t[1]) and np.isnan(result.point[1]).all() and result.surface[1] == -1


def test_all_hits_of_a_torus_along_a_line_through_its_hole():
    """x-axis from x = -10 through a torus (R = 3, r = 1): hits at x = -4, -2, 2, 4 -> t = 6, 8, 12, 14;
    the normal is +-(p - tube centre) and front_facing is the normal facing the origin."""
    result = bsrt.intersect(ring(), A([[-10.0, 0, 0], [-10, 0, 5]]), A([[1.0, 0, 0], [1, 0, 0]]), mode="all")
    assert result.offsets.tolist() == [0, 4, 4] and result.count.tolist() == [4, 0]
    assert np.allclose(result.t, [6.0, 8.0, 12.0, 14.0], rtol=0, atol=1e-8) and (result.ray == 0).all()
    tube = A([[-3.0, 0, 0], [-3, 0, 0], [3, 0, 0], [3, 0, 0]])
    radial = result.point - tube
    sign = np.einsum("ij,ij->i", result.normal, radial)
    assert np.allclose(np.abs(sign), 1.0, atol=1e-7) and len(set(np.sign(sign))) == 1  # one orientation
    assert (result.front_facing == (np.einsum("ij,ij->i", result.normal, np.tile(X, (4, 1))) < 0)).all()
    assert result.front_facing.tolist() in ([True, False, True, False], [False, True, False, True])


def test_nearest_and_any_agree_with_the_first_of_all():
    scene = ring()
    rng = np.random.default_rng(3)
    origins = rng.uniform(-6, 6, (400, 3)) + A([0, 0, 8.0])
    directions = rng.uniform(-6, 6, (400, 3)) - origins
    every = bsrt.intersect(scene, origins, directions, mode="all")
    nearest = bsrt.intersect(scene, origins, directions)
    anyhit = bsrt.intersect(scene, origins, directions, mode="any")
    has = every.count > 0
    assert has.sum() > 100 and (nearest.hit == has).all() and (anyhit.hit == has).all()
    first = every.offsets[:-1][has]
    assert np.allclose(nearest.t[has], every.t[first], rtol=0, atol=1e-8)
    assert (every.count[has] % 2 == 0).all()  # a closed surface: in and out (no ray here is tangent)


def test_ray_through_a_trimmed_hole():
    """Rays down onto a plate with a round hole (radius 0.5): through the hole, none; on the plate,
    t = 3; outside the plate, none."""
    xs = A([0.0, 0.3, 0.49, 0.51, 0.8, 1.2])
    origins = np.stack([xs, np.zeros(6), np.full(6, 3.0)], axis=1)
    result = bsrt.intersect(plate_with_hole(), origins, np.tile(-Z, (6, 1)))
    assert result.hit.tolist() == [False, False, False, True, True, False]
    assert np.allclose(result.t[result.hit], 3.0, atol=1e-9)
    assert np.allclose(result.normal[result.hit], Z) and result.front_facing[result.hit].all()


def test_grazing_rays_close_to_a_sphere():
    """Rays along x at distance b = R (1 -+ 1e-6) from the centre: just inside, two hits at
    5 -+ sqrt(R^2 - b^2) (half chord about 2.8e-3); just outside, none."""
    b_in, b_out = R * (1 - 1e-6), R * (1 + 1e-6)
    origins = A([[-5.0, b_in, 0], [-5.0, 0, b_in], [-5.0, b_out, 0], [-5.0, 0, b_out]])
    result = bsrt.intersect(ball(), origins, np.tile(X, (4, 1)), mode="all", tolerance=1e-12)
    half = math.sqrt(R**2 - b_in**2)
    assert result.count.tolist() == [2, 2, 0, 0]
    assert np.allclose(result.t, [5 - half, 5 + half] * 2, rtol=0, atol=1e-9)


def test_rays_starting_on_the_surface_with_t_min():
    """From (R, 0, 0) on the sphere: inward with t_min = 1e-9 the far side at t = 2R; outward, none."""
    on = A([[R, 0.0, 0.0]] * 2)
    result = bsrt.intersect(ball(), on, A([[-1.0, 0, 0], [1.0, 0, 0]]), t_min=1e-9)
    assert result.hit.tolist() == [True, False] and abs(result.t[0] - 2 * R) < 1e-8
    per_ray = bsrt.intersect(ball(), on, A([[-1.0, 0, 0], [-1.0, 0, 0]]), t_min=A([1e-9, 3 * R]))
    assert per_ray.hit.tolist() == [True, False]
    short = bsrt.intersect(ball(), on, A([[-1.0, 0, 0], [-1.0, 0, 0]]), t_min=1e-9, t_max=A([R, 5 * R]))
    assert short.hit.tolist() == [False, True]


def test_tolerance_down_to_1e_13_by_the_polish():
    """At tolerance 1e-13 the residual is below 1e-13 of the diagonal and t is the closed form to that."""
    scene = ball()
    rng = np.random.default_rng(5)
    radius, angle = rng.uniform(0, 1.9, 200), rng.uniform(0, 2 * math.pi, 200)
    b = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    origins = np.concatenate([np.full((200, 1), 5.0), b], axis=1)
    result = bsrt.intersect(scene, origins, np.tile(-X, (200, 1)), tolerance=1e-13)
    diag = result.diagonal
    assert result.hit.all() and (result.residual <= 1e-13 * diag).all()
    exact = 5.0 - np.sqrt(R**2 - (b**2).sum(axis=1))
    assert np.max(np.abs(result.t - exact)) <= 1e-12 * diag
    coarse = bsrt.intersect(scene, origins, np.tile(-X, (200, 1)), tolerance=1e-6)
    assert np.max(np.abs(coarse.t - exact)) > np.max(np.abs(result.t - exact))  # the knob acts
    with pytest.raises(InputError, match="below what float64 can give"):
        bsrt.intersect(scene, origins, np.tile(-X, (200, 1)), tolerance=1e-14)


def test_a_tolerance_float64_cannot_resolve_from_far_origins_is_refused():
    """From x = 1e4 (the sphere's diagonal is about 6.9): 64 float64 steps of 1e4 are 2e-11 of the
    diagonal, so 1e-12 is refused there (and accepted from nearby); 1e-9 finds t = 1e4 - R."""
    far, near = A([[1e4, 0.0, 0.0]]), A([[5.0, 0.0, 0.0]])
    with pytest.raises(InputError, match="for this scene and these origins; the least is 2"):
        bsrt.intersect(ball(), far, [[-1.0, 0, 0]], tolerance=1e-12)
    assert bsrt.intersect(ball(), near, [[-1.0, 0, 0]], tolerance=1e-12).hit.all()
    result = bsrt.intersect(ball(), far, [[-1.0, 0, 0]])
    assert abs(result.t[0] - (1e4 - R)) < 1e-8 * 1e4


def test_the_geometry_is_prepared_once_per_scene():
    scene = ball()
    first = prepared(scene)[1]
    bsrt.intersect(scene, A([0.0, 0, 5]), A([[0.0, 0, -1]]))
    assert prepared(scene)[1] is first
    assert prepared(ball())[1] is not first


def test_long_ray_batches_are_traced_in_chunks(monkeypatch):
    """More rays than one chunk: the same answers as one chunk (the records in ray order)."""
    import bsrt.rendering.raycast as raycast

    scene = ball()
    rng = np.random.default_rng(9)
    origins = np.concatenate([np.full((300, 1), 5.0), rng.uniform(-2.5, 2.5, (300, 2))], axis=1)
    whole = bsrt.intersect(scene, origins, np.tile(-X, (300, 1)), mode="all")
    monkeypatch.setattr(raycast, "CHUNK", 64)
    chunked = bsrt.intersect(scene, origins, np.tile(-X, (300, 1)), mode="all")
    assert np.array_equal(whole.offsets, chunked.offsets) and np.array_equal(whole.t, chunked.t)


@pytest.mark.parametrize(
    "origins, directions, kwargs, message",
    [
        (np.zeros((3, 3)), np.ones((2, 3)), {}, "origins: 3 rows do not match directions: 2 rows"),
        (np.zeros((2, 3)), np.ones((2, 2)), {}, r"directions: expected shape \(N, 3\), got \(2, 2\)"),
        (np.zeros((2, 3)), [["a", "b", "c"]] * 2, {}, "directions: expected an .* got dtype <U1"),
        (np.zeros((2, 3)), A([[1.0, 0, 0], [0, np.nan, 1]]), {}, r"directions: row 1 is not finite"),
        (A([[0.0, 0, 0], [np.inf, 0, 0]]), np.ones((2, 3)), {}, r"origins: row 1 is not finite"),
        (np.zeros((2, 3)), A([[1.0, 0, 0], [0, 0, 0]]), {}, "directions: row 1 is zero"),
        (np.zeros((1, 3)), np.ones((1, 3)), {"mode": "first"}, "mode: expected one of"),
        (np.zeros((1, 3)), np.ones((1, 3)), {"t_min": np.nan}, "t_min: row 0 is NaN"),
        (np.zeros((1, 3)), np.ones((1, 3)), {"t_min": 2.0, "t_max": 1.0}, "t_min 2 >= t_max 1"),
        (np.zeros((1, 3)), np.ones((1, 3)), {"t_max": [1.0, 2.0]}, r"t_max: expected a number or \(1,\)"),
        (np.zeros((1, 3)), np.ones((1, 3)), {"tolerance": "fine"}, "tolerance: expected a number"),
    ],
)
def test_bad_input_is_one_input_error(origins, directions, kwargs, message):
    with pytest.raises(InputError, match=message):
        bsrt.intersect(ball(), origins, directions, **kwargs)
    assert issubclass(InputError, ValueError)


def test_no_rays_give_an_empty_result_and_no_surfaces_an_error():
    for mode in ("nearest", "any", "all"):
        result = bsrt.intersect(ball(), np.zeros((0, 3)), np.zeros((0, 3)), mode=mode)
        assert len(result) == 0 and result.offsets.tolist() == [0] and result.point.shape == (0, 3)
    with pytest.raises(InputError, match="no surfaces"):
        bsrt.intersect([], np.zeros((1, 3)), np.ones((1, 3)))


# ---------------------------------------------------------------------------
# Sensors


def test_lidar_pattern():
    """4 channels over [-30, 30] degrees x 90-degree steps of a full turn: row 0 the highest beam,
    azimuth 0 along forward (made perpendicular to up), counter-clockwise seen from above."""
    rays = bsrt.sensors.lidar(
        (1.0, 2.0, 3.0), up=(0, 0, 1), forward=(1, 0, 1), vertical_fov=(-30, 30), channels=4, horizontal_resolution=90
    )
    assert rays.shape == (4, 4) and len(rays) == 16 and np.allclose(rays.origins, [1.0, 2.0, 3.0])
    d = rays.directions.reshape(4, 4, 3)
    assert np.allclose(np.linalg.norm(d, axis=2), 1.0)
    assert np.allclose(np.degrees(np.arcsin(d[:, 0, 2])), [30, 10, -10, -30])
    c = math.cos(math.radians(30))
    assert np.allclose(d[0, :, :2], [[-c, 0], [0, -c], [c, 0], [0, c]])  # azimuths -180, -90, 0, 90
    beams = bsrt.sensors.lidar((0, 0, 0), elevations=[5.0, -5.0], horizontal_fov=10, horizontal_resolution=5)
    assert beams.shape == (2, 3) and np.allclose(np.degrees(np.arcsin(beams.directions[:, 2])), [5] * 3 + [-5] * 3)


def test_pinhole_depth_image_of_a_plate():
    """A camera 3 above the plate looking down: the centre ray hits at range 3; depth (along the
    axis) is 3 on the plate everywhere, NaN through the hole and beyond the plate."""
    rays = bsrt.sensors.pinhole((0.6, 0.0, 3.0), (0.6, 0.0, 0.0), up=(0, 1, 0), fov=60, width=31, height=21)
    result = bsrt.intersect(plate_with_hole(), rays.origins[:1], rays.directions)
    depth = rays.depth_image(result)
    assert depth.shape == (21, 31) and abs(rays.range_image(result)[10, 15] - 3.0) < 1e-9
    on = np.isfinite(depth)
    assert on.sum() > 100 and np.allclose(depth[on], 3.0, atol=1e-9) and (~on).sum() > 50


def test_bad_sensor_arguments():
    with pytest.raises(InputError, match="up: must not be zero or parallel"):
        bsrt.sensors.lidar((0, 0, 0), up=(0, 0, 1), forward=(0, 0, 2))
    with pytest.raises(InputError, match="position: expected three finite numbers"):
        bsrt.sensors.lidar((0, 0))
    with pytest.raises(InputError, match="vertical_fov"):
        bsrt.sensors.lidar((0, 0, 0), vertical_fov=(10, -10))
    with pytest.raises(InputError, match="look_at: must differ from eye"):
        bsrt.sensors.pinhole((1, 1, 1), (1, 1, 1))


def test_a_ray_grazing_a_sphere_by_its_pole_is_not_cut_short_by_the_work_budget():
    """The ray along x at z = R (1 - 1e-6) passes 1.4e-3 R from the pole, across the pole's many small
    pieces: about 9,000 Newton steps, twice a rendered ray's budget; a query finds both hits and
    says no ray ran out."""
    b_in = R * (1 - 1e-6)
    result = bsrt.intersect(ball(), A([[-5.0, 0, b_in]]), A([X]), mode="all", tolerance=1e-12)
    half = math.sqrt(R**2 - b_in**2)
    assert result.count.tolist() == [2] and not result.exhausted.any()
    assert np.allclose(result.t, [5 - half, 5 + half], rtol=0, atol=1e-9)
