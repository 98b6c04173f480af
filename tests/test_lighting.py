"""Shadows, mirror reflections and anti-aliasing against answers worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import flat_patch
from test_gpu_shadow import ROOT, _look
from test_models import exact_sphere

from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import render
from bsrt.scene import parse_scene
from bsrt.scene.camera import pixel_rays

pytestmark = pytest.mark.gl  # every test here needs it (tests/conftest.py checks)


def _horizontal(x0, x1, y0, y1, z, **extra):
    """A bilinear square in the plane z = const, u along x, v along y."""
    return {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[x0, y0, z], [x0, y1, z]], [[x1, y0, z], [x1, y1, z]]],
        **extra,
    }


def _scene(surfaces, lights, materials, size=96, eye=(0.0, -3.0, 6.0), look_at=(0.0, 0.0, 0.0), **render_keys):
    return parse_scene(
        {
            "film": {"width": size, "height": size, "background": [0.0, 0.0, 0.0]},  # the sky the mirrors show
            "camera": {"eye": list(eye), "look_at": list(look_at), "fov": 50.0},
            "render": {"adaptive_spp": 0, **render_keys},  # one sample per pixel: the closed forms are per centre ray
            "material": materials,
            "light": lights,
            "surface": surfaces,
        }
    )


def test_shadow_of_a_flat_patch_on_a_parallel_plane_has_its_exact_shape():
    light = np.array([0.3, 0.2, -1.0])
    scene = _scene(
        [_horizontal(-3, 3, -3, 3, 0.0, material="ground"), _horizontal(-0.5, 0.7, -0.4, 0.5, 1.0, material="ground")],
        [{"kind": "directional", "direction": light.tolist(), "intensity": 1.0}],
        [{"name": "ground", "color": [1.0, 1.0, 1.0], "specular": 0.0}],
    )
    res = render(scene)
    on_ground = res.hits.hit & (res.hits.surface == 0)
    p = res.position[on_ground]
    # walk from the ground point toward the light up to z = 1: inside the occluder?
    to_light = -light / np.linalg.norm(light)
    q = p + (1.0 / to_light[2]) * to_light
    margin = np.minimum.reduce([q[:, 0] + 0.5, 0.7 - q[:, 0], q[:, 1] + 0.4, 0.5 - q[:, 1]])
    colour = res.linear.reshape(-1, 3)[on_ground, 0]
    shadowed, lit = margin > 1e-6, margin < -1e-6
    assert shadowed.sum() > 50 and lit.sum() > 1000
    assert np.all(colour[shadowed] == 0.0)
    np.testing.assert_allclose(colour[lit], to_light[2], rtol=1e-9)  # Lambert: albedo 1 x cos


def test_mirror_shows_the_surface_geometry_says_it_must():
    scene = _scene(
        [_horizontal(-3, 3, -3, 3, 0.0, material="mirror"), _horizontal(-0.6, 0.4, 0.2, 1.1, 1.5, material="red")],
        [{"kind": "ambient", "intensity": 1.0}],
        [
            {"name": "mirror", "color": [0.0, 0.0, 0.0], "specular": 0.0, "reflectance": 1.0},
            {"name": "red", "color": [1.0, 0.0, 0.0], "specular": 0.0},
        ],
        eye=(0.0, -4.0, 3.0),
        look_at=(0.0, 0.5, 0.0),
    )
    res = render(scene)
    film = scene.film
    d = pixel_rays(scene.camera, film.width, film.height)
    mirror = res.hits.hit & (res.hits.surface == 0)
    p = res.position[mirror]
    r = d[mirror] * [1.0, 1.0, -1.0]  # reflected off z = 0
    q = p + ((1.5 - p[:, 2]) / r[:, 2])[:, None] * r
    margin = np.minimum.reduce([q[:, 0] + 0.6, 0.4 - q[:, 0], q[:, 1] - 0.2, 1.1 - q[:, 1]])
    colour = res.linear.reshape(-1, 3)[mirror]
    sees_red, sees_sky = margin > 1e-6, margin < -1e-6
    assert sees_red.sum() > 100 and sees_sky.sum() > 1000
    np.testing.assert_allclose(colour[sees_red], [[1.0, 0.0, 0.0]] * sees_red.sum(), atol=1e-12)
    np.testing.assert_allclose(colour[sees_sky], [[0.0, 0.0, 0.0]] * sees_sky.sum(), atol=1e-12)


def test_max_depth_bounds_the_bounces_between_two_mirrors():
    """Facing half-mirrors, white (A, in front) and black (B, behind the eye): the centre ray
    sees c_k = 0.5 L_k + 0.5 c_(k+1) for bounces k < max_depth and c = L at the last one."""
    materials = [
        {"name": "white", "color": [1.0, 1.0, 1.0], "specular": 0.0, "reflectance": 0.5},
        {"name": "black", "color": [0.0, 0.0, 0.0], "specular": 0.0, "reflectance": 0.5},
    ]
    surfaces = [
        flat_patch(x0=-5, x1=5, z0=-5, z1=5, y=0.0, material="white"),
        flat_patch(x0=-5, x1=5, z0=-5, z1=5, y=-2.0, material="black"),
    ]
    for depth, expect in ((0, 1.0), (1, 0.5), (2, 0.75), (3, 0.625)):
        scene = parse_scene(
            {
                "film": {"width": 8, "height": 8, "background": [0.0, 0.0, 1.0]},
                "camera": {"eye": [0.0, -1.0, 0.0], "look_at": [0.0, 0.0, 0.0], "fov": 10.0},
                "render": {"max_depth": depth},
                "material": materials,
                "light": [{"kind": "ambient", "intensity": 1.0}],
                "surface": surfaces,
            }
        )
        np.testing.assert_allclose(render(scene).linear[4, 4], [expect] * 3, atol=1e-12)


def test_no_acne_on_a_lit_convex_surface():
    """A sphere under a point light: every point facing the light is lit (no self-shadowing)."""
    s = exact_sphere()
    table = {
        "degree": list(s.degree),
        "knots_u": s.knots_u.tolist(),
        "knots_v": s.knots_v.tolist(),
        "points": s.points.tolist(),
        "weights": s.weights.tolist(),
        "material": "m",
    }
    scene = _scene(
        [table],
        [
            {"kind": "point", "position": [2.0, -3.0, 4.0], "intensity": 29.0},
            {"kind": "directional", "direction": [1.0, 0.2, -0.3], "intensity": 0.5},
        ],
        [{"name": "m", "color": [0.8, 0.8, 0.8], "specular": 0.0}],
        size=128,
        eye=(0.5, -4.0, 2.5),
    )
    res = render(scene)
    hit = res.hits.hit
    p, n = res.position[hit], res.normal[hit]
    to_point = np.array([2.0, -3.0, 4.0]) - p  # Lambert (specular 0): albedo * max(cos, 0) * intensity / r^2
    r2 = np.einsum("ij,ij->i", to_point, to_point)
    cos_point = np.einsum("ij,ij->i", n, to_point) / np.sqrt(r2)
    sun = -np.array([1.0, 0.2, -0.3]) / np.linalg.norm([1.0, 0.2, -0.3])
    unshadowed = 0.8 * (29.0 * np.maximum(cos_point, 0.0) / r2 + 0.5 * np.maximum(n @ sun, 0.0))
    unshadowed = np.repeat(unshadowed[:, None], 3, axis=1)
    got = res.linear.reshape(-1, 3)[hit]
    assert hit.sum() > 2000
    assert res.stats["shadow_rays"] > 1000
    np.testing.assert_allclose(got, unshadowed, rtol=1e-12, atol=1e-15)


def test_spp4_blends_a_high_contrast_edge_only():
    white = flat_patch(x0=-1.0, x1=0.03, material="white")
    base = {
        "film": {"width": 48, "height": 48, "background": [0.0, 0.0, 0.0]},
        "camera": {"eye": [0.0, -4.0, 0.0], "look_at": [0.0, 0.0, 0.0], "fov": 30.0},
        "render": {"adaptive_spp": 0},  # uniform sampling only
        "material": [{"name": "white", "color": [1.0, 1.0, 1.0], "specular": 0.0}],
        "light": [{"kind": "ambient", "intensity": 1.0}],
        "surface": [white],
    }
    one = render(parse_scene(base)).linear[..., 0]
    scene = parse_scene(base)
    four = render(scene, RenderOptions.resolve(scene, spp=4)).linear[..., 0]
    # the edge x = 0.03 crosses column j where the pixel straddles it
    x = (2 * (np.arange(48) + 0.5) / 48 - 1) * np.tan(np.radians(15)) * 4.0
    pixel = 2 * np.tan(np.radians(15)) * 4.0 / 48
    far = (np.abs(x - 0.03) > pixel) & (np.abs(x + 1.0) > pixel)  # both vertical edges
    rows = slice(20, 28)  # well inside the patch vertically
    np.testing.assert_array_equal(four[rows][:, far], one[rows][:, far])
    edge = four[rows][:, ~far]
    assert np.any((edge > 0.05) & (edge < 0.95))  # intermediate values at the edge
    assert set(np.unique(one[rows])) <= {0.0, 1.0}


@pytest.mark.parametrize("name", ["column", "water-lily"])
def test_shadow_packets_of_any_shape_give_each_ray_its_own_answer(name):
    """kernels/lighting.py walks the shadow rays of nearby hits together (packets of up to
    PACKET hits whose points lie within BVH.packet_spread): whatever the packets, each ray's
    answer is its own walk's. Shaded with packets of one hit (spread 0), the default, and
    packets of PACKET consecutive items whatever their spread (across silhouettes and row
    ends, where the packet's interval enters most of the hierarchy): the same colours, shadow
    rays and budgets, bit for bit. The per-ray answers themselves are held to bvh.intersect by
    tests/test_film.py and to the GPU's one-ray walk by tests/test_gpu_shadow.py."""
    import bsrt
    from bsrt.kernels.lighting import PACKET, shade_hits
    from bsrt.rendering.bvh import DEFAULT_RETRY_DEPTH, ray_budget

    size = 80
    path = ROOT / "scenes" / f"{name}.toml"
    scene = bsrt.load(path)
    result = bsrt.render(scene, width=size, height=size, spp=1, adaptive_spp=0, device="cpu")
    geometry, hits, bvh = result.geometry, result.hits, result.geometry.bvh
    directions = np.ascontiguousarray(pixel_rays(result.options.camera, size, size))
    materials, lights, background = _look(scene, result.options)
    tolerance, n = result.options.tolerance * geometry.diagonal, len(hits)
    shaded = []
    for spread in (0.0, bvh.packet_spread, np.inf):
        out = tuple(np.empty(s) for s in ((n, 3), (n, 3), (n, 3), (n, 2))) + (
            np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64),
        )
        shade_hits(
            0, n, geometry.patches.arrays, geometry.patches.trims, bvh.arrays, hits.hit, hits.patch, hits.surface,
            hits.u, hits.v, directions, geometry.material, *materials, *lights, background,
            1e-6 * geometry.diagonal, float(tolerance), 16, DEFAULT_RETRY_DEPTH, bvh.padding + float(tolerance),
            ray_budget(16), spread, *out,
        )  # fmt: skip
        shaded.append(out)
    assert 0.0 < bvh.packet_spread < geometry.diagonal and PACKET > 1
    assert shaded[0][4].sum() > 1000  # shadow rays were traced
    # and many of them blocked: the hits' own shadow rays toward the first casting light, one at a time
    hit = np.flatnonzero(hits.hit)
    kind, position = lights[0], lights[1]
    light = int(np.flatnonzero(kind == 1)[0])
    p, normal, radius = shaded[0][1][hit], shaded[0][2][hit], shaded[0][3][hit]
    towards = position[light] - p
    dist = np.linalg.norm(towards, axis=1)
    towards /= dist[:, None]
    facing = np.einsum("ij,ij->i", normal, towards) > 0
    exclude = (hits.surface[hit], hits.u[hit], hits.v[hit], radius[:, 0], radius[:, 1])
    blocked = geometry.intersect(p, towards, t_max=dist, tolerance=tolerance, any_hit=True, exclude=exclude).hit
    assert (facing & blocked).sum() > 50
    for other in shaded[1:]:
        for want, got in zip(shaded[0], other):
            np.testing.assert_array_equal(got, want)
