"""Trimmed surfaces rendered, against closed forms: discs, holes, islands, boxes, shadows.

Every scene here is planar, so the exact hit of every ray is known: the
ray meets the plane at a point whose (u, v) is an affine function of it, and
the point is kept exactly when it lies inside the loops (circles here: a
distance to a centre). All four methods must give the same answers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import parse_scene
from bsrt.scene.camera import pixel_rays
from bsrt.settings import METHODS

W = math.sqrt(0.5)


def circle(cx, cy, r, reverse=False):
    """A loop of four rational quadratic quarter arcs (exact circle) in (u, v)."""
    curves = []
    for k in range(4):
        a0, a1 = k * math.pi / 2, (k + 1) * math.pi / 2
        p0 = [cx + r * math.cos(a0), cy + r * math.sin(a0)]
        p2 = [cx + r * math.cos(a1), cy + r * math.sin(a1)]
        p1 = [cx + r * (math.cos(a0) - math.sin(a0)), cy + r * (math.sin(a0) + math.cos(a0))]
        curves.append({"degree": 2, "knots": [0, 0, 0, 1, 1, 1], "points": [p0, p1, p2], "weights": [1.0, W, 1.0]})
    if reverse:
        curves = [{**c, "points": c["points"][::-1], "weights": c["weights"][::-1]} for c in curves[::-1]]
    return {"curves": curves}


def polygon(points):
    """A loop of line segments through the (u, v) points, closed."""
    return {
        "curves": [
            {"degree": 1, "knots": [0, 0, 1, 1], "points": [list(a), list(b)]}
            for a, b in zip(points, points[1:] + points[:1])
        ]
    }


def plate(x0, x1, y0, y1, z, trims=(), **extra):
    """The square [x0, x1] x [y0, y1] at height z; u, v in [0, 1] along x, y."""
    return {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[x0, y0, z], [x0, y1, z]], [[x1, y0, z], [x1, y1, z]]],
        "trim": list(trims),
        **extra,
    }


def top_view(surfaces, size=64, centre=(0.5, 0.5), height=10.0, half=0.55, lights=None, **render_keys):
    """A camera straight above (x, y) = centre seeing [-half, half] around it at z = 0."""
    fov = 2 * math.degrees(math.atan(half / height))
    return parse_scene(
        {
            "film": {"width": size, "height": size},
            "camera": {
                "eye": [centre[0], centre[1], height],
                "look_at": [centre[0], centre[1], 0.0],
                "up": [0.0, 1.0, 0.0],
                "fov": fov,
            },
            "render": {"adaptive_spp": 0, **render_keys},  # one sample per pixel: the closed forms are per centre ray
            "light": lights or [{"kind": "ambient", "intensity": 1.0}],
            "surface": surfaces,
        }
    )


def ground_points(scene, z=0.0):
    """(N, 2): where each pixel-centre ray meets the plane at height z."""
    cam = scene.camera
    d = pixel_rays(cam, scene.film.width, scene.film.height)
    t = (z - cam.eye[2]) / d[:, 2]
    return (cam.eye + t[:, None] * d)[:, :2], t


def render_all(scene):
    geometry = Geometry(scene)
    return {m: render(scene, RenderOptions.resolve(scene, method=m), geometry=geometry) for m in METHODS}


def check(scene, expected_hit, margin, expected_t=None, expected_surface=None):
    """Every method: hit where expected on every pixel whose margin (distance to the
    nearest trim edge, in scene units) exceeds 1e-9; t and surface as expected."""
    sure = np.abs(margin) > 1e-9
    assert sure.sum() > 0.95 * margin.size
    for method, res in render_all(scene).items():
        hits = res.hits
        bad = np.flatnonzero(sure & (hits.hit != expected_hit))
        assert not bad.size, f"{method}: {bad.size} pixels wrong, e.g. {bad[:5]} margin {margin[bad[:5]]}"
        if expected_t is not None:
            h = hits.hit & sure
            np.testing.assert_allclose(hits.t[h], expected_t[h], atol=1e-8, err_msg=method)
        if expected_surface is not None:
            h = hits.hit & sure
            np.testing.assert_array_equal(hits.surface[h], expected_surface[h], err_msg=method)


@pytest.mark.parametrize("reverse", [False, True])
def test_a_square_trimmed_by_a_circle_shows_an_exact_disc(ctx, reverse):
    scene = top_view([plate(0, 1, 0, 1, 0.0, [circle(0.5, 0.5, 0.3, reverse)])])
    xy, t = ground_points(scene)
    margin = 0.3 - np.hypot(xy[:, 0] - 0.5, xy[:, 1] - 0.5)  # > 0 inside the disc
    check(scene, margin > 0, margin, expected_t=t)


def test_disc_edge_to_a_millionth(ctx):
    """Pixels 1e-6 wide straddling the circle: each side of the edge classified right."""
    size, pixel = 24, 1e-6
    edge = (0.5 + 0.3 * math.cos(0.7), 0.5 + 0.3 * math.sin(0.7))
    scene = top_view(
        [plate(0, 1, 0, 1, 0.0, [circle(0.5, 0.5, 0.3)])], size=size, centre=edge, height=1.0, half=size * pixel / 2
    )
    xy, t = ground_points(scene)
    margin = 0.3 - np.hypot(xy[:, 0] - 0.5, xy[:, 1] - 0.5)
    inside, outside = margin > 1e-9, margin < -1e-9
    assert inside.sum() > 100 and outside.sum() > 100
    assert np.abs(margin).min() < 1e-6
    check(scene, margin > 0, margin, expected_t=t)


def test_a_hole(ctx):
    boundary = polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    scene = top_view([plate(0, 1, 0, 1, 0.0, [boundary, circle(0.4, 0.55, 0.25)])])
    xy, _ = ground_points(scene)
    r = np.hypot(xy[:, 0] - 0.4, xy[:, 1] - 0.55)
    inside_square = np.minimum.reduce([xy[:, 0], 1 - xy[:, 0], xy[:, 1], 1 - xy[:, 1]])
    margin = np.minimum(inside_square, r - 0.25)
    check(scene, margin > 0, np.where(inside_square > 0, margin, inside_square))


def test_nested_islands(ctx):
    scene = top_view(
        [plate(0, 1, 0, 1, 0.0, [circle(0.5, 0.5, 0.45), circle(0.5, 0.5, 0.3, reverse=True), circle(0.5, 0.5, 0.15)])]
    )
    xy, _ = ground_points(scene)
    r = np.hypot(xy[:, 0] - 0.5, xy[:, 1] - 0.5)
    kept = (r < 0.15) | ((r > 0.3) & (r < 0.45))
    margin = np.min(np.abs(r[:, None] - np.array([0.15, 0.3, 0.45])[None, :]), axis=1)
    check(scene, kept, margin)


def test_a_loop_along_the_domain_boundary_keeps_the_whole_surface(ctx):
    whole = top_view([plate(0, 1, 0, 1, 0.0)])
    looped = top_view([plate(0, 1, 0, 1, 0.0, [polygon([(0, 0), (1, 0), (1, 1), (0, 1)])])])
    xy, _ = ground_points(whole)
    margin = np.minimum.reduce([xy[:, 0], 1 - xy[:, 0], xy[:, 1], 1 - xy[:, 1]])
    check(whole, margin > 0, margin)
    check(looped, margin > 0, margin)


def test_a_ray_through_a_hole_hits_the_surface_behind(ctx):
    holed = plate(-1, 2, -1, 2, 1.0, [polygon([(0, 0), (1, 0), (1, 1), (0, 1)]), circle(0.45, 0.5, 0.12)])
    floor = plate(-3, 4, -3, 4, 0.0)
    scene = top_view([holed, floor], height=10.0, half=0.9)
    xy, t_floor = ground_points(scene, z=0.0)
    xy1, t_plate = ground_points(scene, z=1.0)
    # the plate spans [-1, 2]^2 in x, y, so its (u, v) = ((x + 1) / 3, (y + 1) / 3)
    u, v = (xy1[:, 0] + 1) / 3, (xy1[:, 1] + 1) / 3
    r = np.hypot(u - 0.45, v - 0.5)
    through = r < 0.12
    margin = 3 * np.abs(r - 0.12)  # scene units
    expected_t = np.where(through, t_floor, t_plate)
    check(scene, np.ones(r.size, dtype=bool), margin, expected_t=expected_t, expected_surface=np.where(through, 1, 0))


def test_a_shadow_through_a_trimmed_hole_has_the_holes_exact_shape(ctx):
    holed = plate(
        -1, 2, -1, 2, 1.0, [polygon([(0, 0), (1, 0), (1, 1), (0, 1)]), circle(0.5, 0.5, 0.15)], material="white"
    )
    floor = plate(-3, 4, -3, 4, 0.0, material="white")
    light = np.array([0.2, -0.1, -1.0])
    scene = parse_scene(
        {
            "film": {"width": 72, "height": 72},
            # under the plate, looking at the floor from below the plate's height
            "camera": {"eye": [0.5, 0.5, 0.6], "look_at": [0.5, 0.5, 0.0], "up": [0.0, 1.0, 0.0], "fov": 90.0},
            "render": {"adaptive_spp": 0},  # one sample per pixel: the closed form is per centre ray
            "material": [{"name": "white", "color": [1.0, 1.0, 1.0], "specular": 0.0}],
            "light": [{"kind": "directional", "direction": light.tolist(), "intensity": 1.0}],
            "surface": [holed, floor],
        }
    )
    to_light = -light / np.linalg.norm(light)
    for method, res in render_all(scene).items():
        on_floor = res.hits.hit & (res.hits.surface == 1)
        p = res.position[on_floor]
        q = p + (1.0 / to_light[2]) * to_light  # where the light ray crosses z = 1
        u, v = (q[:, 0] + 1) / 3, (q[:, 1] + 1) / 3
        r = np.hypot(u - 0.5, v - 0.5)
        lit, shadowed = r < 0.15 - 1e-9, r > 0.15 + 1e-9
        colour = res.linear.reshape(-1, 3)[on_floor, 0]
        assert lit.sum() > 50 and shadowed.sum() > 500, method
        np.testing.assert_allclose(colour[lit], to_light[2], rtol=1e-9, err_msg=method)
        assert np.all(colour[shadowed] == 0.0), method


def _box_faces():
    """A unit cube [0, 1]^3 made of six planes each 3x larger than its face, trimmed to the face."""
    square = polygon([(1 / 3, 1 / 3), (2 / 3, 1 / 3), (2 / 3, 2 / 3), (1 / 3, 2 / 3)])
    faces = []
    for axis in range(3):
        for value in (0.0, 1.0):
            a, b = [k for k in range(3) if k != axis]

            def point(s, t):
                p = [0.0, 0.0, 0.0]
                p[axis], p[a], p[b] = value, s, t
                return p

            faces.append(
                {
                    "degree": [1, 1],
                    "knots_u": [0, 0, 1, 1],
                    "knots_v": [0, 0, 1, 1],
                    "points": [[point(-1, -1), point(-1, 2)], [point(2, -1), point(2, 2)]],
                    "trim": [square],
                }
            )
    return faces


def test_a_box_of_six_trimmed_faces_has_no_crack(ctx):
    eye = np.array([2.6, -1.9, 2.2])
    scene = parse_scene(
        {
            "film": {"width": 96, "height": 96},
            "camera": {"eye": eye.tolist(), "look_at": [0.5, 0.5, 0.5], "fov": 40.0},
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": _box_faces(),
        }
    )
    d = pixel_rays(scene.camera, 96, 96)
    with np.errstate(divide="ignore", invalid="ignore"):  # slab test against the unit cube
        t1, t2 = (0.0 - eye) / d, (1.0 - eye) / d
        near = np.minimum(t1, t2).max(axis=1)
        far = np.maximum(t1, t2).min(axis=1)
    expected = far > near
    # distance of the entry point to the cube's nearest silhouette edge, roughly: the gap far - near
    margin = np.where(expected, (far - near), (near - far))
    check(scene, expected, margin, expected_t=np.where(expected, near, np.nan))


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda loop: loop["curves"][1]["points"].__setitem__(0, [0.9, 0.2]),
            "scene.toml: surface[0].trim[0].curves[1]: the loop is open: the curve starts at (0.9, 0.2), "
            "not where curves[0] ends (1, 0)",
        ),
        (
            lambda loop: loop["curves"][2]["points"].__setitem__(1, [0.5, 1.5]),
            "scene.toml: surface[0].trim[0].curves[2]: the curve leaves the surface's domain [0, 1] x [0, 1]",
        ),
        (
            lambda loop: loop["curves"][0].__setitem__("knots", [0, 1, 1]),
            "scene.toml: surface[0].trim[0].curves[0].knots: expected 4 values (2 points + degree 1 + 1), got 3",
        ),
        (
            lambda loop: loop["curves"][0].__setitem__("degree", True),
            "scene.toml: surface[0].trim[0].curves[0].degree: expected a whole number >= 1, got True",
        ),
        (
            lambda loop: loop["curves"][0].__setitem__("colour", 1),
            "scene.toml: surface[0].trim[0].curves[0].colour: unknown key",
        ),
    ],
)
def test_bad_trim_loops_name_the_surface_loop_and_curve(edit, message):
    from bsrt.errors import InputError

    loop = polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    edit(loop)
    with pytest.raises(InputError) as err:
        parse_scene(
            {
                "camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0]},
                "surface": [plate(0, 1, 0, 1, 0.0, [loop])],
            },
            "scene.toml",
        )
    assert str(err.value).startswith(message), str(err.value)


def test_info_counts_trimmed_surfaces_and_loops(tmp_path, capsys):
    from bsrt.cli import main
    from bsrt.scene.document import dumps_toml

    doc = {
        "camera": {"eye": [0.5, 0.5, 5.0], "look_at": [0.5, 0.5, 0.0], "up": [0.0, 1.0, 0.0]},
        "surface": [plate(0, 1, 0, 1, 0.0, [circle(0.5, 0.5, 0.3), circle(0.5, 0.5, 0.1)]), plate(0, 1, 0, 1, 1.0)],
    }
    path = tmp_path / "two.toml"
    path.write_text(dumps_toml(doc), encoding="utf-8")
    assert main(["info", str(path)]) == 0
    assert "2 surfaces (1 trimmed, 2 loops)" in capsys.readouterr().out
