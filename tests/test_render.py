"""The whole pipeline against closed forms: every pixel, silhouettes and borders included."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import flat_patch, scene_dict

from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import render
from bsrt.scene import load_scene, parse_scene
from bsrt.scene.camera import pixel_rays

SCENES = __import__("pathlib").Path(__file__).resolve().parents[1] / "scenes"


def _plane_truth(scene, y=0.0, x0=-1.0, x1=1.0, z0=-1.0, z1=1.0):
    cam, film = scene.camera, scene.film
    d = pixel_rays(cam, film.width, film.height)
    t = (y - cam.eye[1]) / d[:, 1]
    p = cam.eye + t[:, None] * d
    u, v = (p[:, 0] - x0) / (x1 - x0), (p[:, 2] - z0) / (z1 - z0)
    return t, u, v


@pytest.mark.parametrize("method", ["newton", "gradient", "fast"])
def test_flat_patch_every_pixel(ctx, method):
    scene = parse_scene(scene_dict([flat_patch()], width=72, height=56, eye=(0.35, -4.0, 0.25), method=method))
    res = render(scene, ctx=ctx)
    t, u, v = _plane_truth(scene)
    inside = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    edge = np.minimum.reduce([u, 1 - u, v, 1 - v])
    sure = np.abs(edge) > 1e-7  # every pixel whose ray is not within 1e-7 of the border
    np.testing.assert_array_equal(res.hits.hit[sure], inside[sure])
    hit = res.hits.hit
    np.testing.assert_allclose(res.hits.t[hit], t[hit], atol=1e-8)
    np.testing.assert_allclose(res.hits.u[hit], u[hit], atol=1e-8)
    np.testing.assert_allclose(res.hits.v[hit], v[hit], atol=1e-8)
    np.testing.assert_allclose(res.normal[hit], np.tile([0.0, -1.0, 0.0], (hit.sum(), 1)), atol=1e-12)
    assert np.all(np.isnan(res.hits.t[~hit]))
    assert res.stats["hits"] == hit.sum()


def test_no_cracks_between_surfaces_and_knot_spans(ctx):
    """A square cut into two surfaces at x = 0.1, the right one with 5 x 3 knot spans."""
    left = flat_patch(x0=-1.0, x1=0.1)
    right = flat_patch(x0=0.1, x1=1.0, degree=(2, 3))
    right["knots_u"] = [0, 0, 0, 0.2, 0.4, 0.5, 0.9, 1, 1, 1]
    right["knots_v"] = [0, 0, 0, 0, 0.3, 0.31, 1, 1, 1, 1]
    # control points at the Greville abscissae reproduce a linear function exactly
    gu = np.array([(right["knots_u"][i + 1] + right["knots_u"][i + 2]) / 2 for i in range(7)])
    gv = np.array([sum(right["knots_v"][i + 1 : i + 4]) / 3 for i in range(6)])
    right["points"] = [[[0.1 + 0.9 * a, 0.0, -1.0 + 2.0 * b] for b in gv] for a in gu]
    scene = parse_scene(scene_dict([left, right], width=96, height=96, eye=(0.05, -3.0, 0.02)))
    res = render(scene, ctx=ctx)
    t, u, v = _plane_truth(scene)
    edge = np.minimum.reduce([u, 1 - u, v, 1 - v])
    inside = edge > 1e-7
    assert np.all(res.hits.hit[inside]), f"{(~res.hits.hit[inside]).sum()} holes"
    assert not np.any(res.hits.hit[edge < -1e-7])
    x = res.position[:, 0]
    hit = res.hits.hit
    assert np.all(res.hits.surface[hit & (x < 0.1 - 1e-9)] == 0)
    assert np.all(res.hits.surface[hit & (x > 0.1 + 1e-9)] == 1)
    np.testing.assert_allclose(res.hits.t[hit], t[hit], atol=1e-8)


def _paraboloid_table():
    xs, a = [-1.0, 0.0, 1.0], [1.0, -1.0, 1.0]
    return {
        "degree": [2, 2],
        "knots_u": [0, 0, 0, 1, 1, 1],
        "knots_v": [0, 0, 0, 1, 1, 1],
        "points": [[[xs[i], xs[j], a[i] + a[j]] for j in range(3)] for i in range(3)],
    }


def _paraboloid_truth(scene):
    """Nearest positive root of z = x^2 + y^2 with |x|, |y| <= 1, per pixel (NaN if none)."""
    cam, film = scene.camera, scene.film
    d = pixel_rays(cam, film.width, film.height)
    o = cam.eye
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (o[0] * d[:, 0] + o[1] * d[:, 1]) - d[:, 2]
    c = o[0] ** 2 + o[1] ** 2 - o[2]
    disc = b * b - 4 * a * c
    sq = np.sqrt(np.maximum(disc, 0))
    best = np.full(len(d), np.nan)
    margin = np.full(len(d), np.inf)
    for root in ((-b - sq) / (2 * a), (-b + sq) / (2 * a)):
        p = o + root[:, None] * d
        m = 1.0 - np.abs(p[:, :2]).max(axis=1)  # > 0 inside the patch
        ok = (disc >= 0) & (root > 0) & (m > 0) & np.isnan(best)
        best[ok] = root[ok]
        margin = np.minimum(margin, np.where((disc >= 0) & (root > 0), np.abs(m), np.inf))
    margin = np.minimum(margin, np.abs(disc) / (np.abs(b) ** 2 + 1))
    return best, margin


@pytest.mark.parametrize(
    "eye,look_at",
    [
        ((2.5, -3.0, 3.0), (0.0, 0.0, 0.8)),  # from above: silhouette against the rim
        ((2.0, -2.5, -1.5), (0.0, 0.0, 0.7)),  # from below: the ray meets the bowl twice (self-occlusion)
    ],
)
def test_paraboloid_silhouette_and_self_occlusion(ctx, eye, look_at):
    scene = parse_scene(scene_dict([_paraboloid_table()], width=96, height=96, eye=eye, look_at=look_at, fov=45.0))
    res = render(scene, ctx=ctx)
    truth, margin = _paraboloid_truth(scene)
    sure = margin > 1e-6
    expect_hit = ~np.isnan(truth)
    assert expect_hit.sum() > 1000
    np.testing.assert_array_equal(res.hits.hit[sure], expect_hit[sure])
    both = res.hits.hit & expect_hit
    np.testing.assert_allclose(res.hits.t[both], truth[both], atol=1e-8)  # the visible (nearer) root


@pytest.mark.parametrize("name", ["column", "water-lily"])
def test_methods_agree_on_every_pixel(ctx, name):
    scene = load_scene(SCENES / f"{name}.toml")
    results = {
        m: render(scene, RenderOptions.resolve(scene, method=m, width=128, height=128), ctx=ctx)
        for m in ("newton", "gradient", "fast", "martin")
    }
    ref = results["newton"].hits
    tol = scene.render.tolerance * 1e3 * 20  # scene sizes are ~10: distances agree to ~1e-7
    for method, res in results.items():
        hits = res.hits
        np.testing.assert_array_equal(hits.hit, ref.hit, err_msg=method)
        np.testing.assert_array_equal(hits.surface, ref.surface, err_msg=method)
        np.testing.assert_allclose(hits.t[ref.hit], ref.t[ref.hit], atol=tol, err_msg=method)
        # a seed the root finder could not follow to a root is re-solved as a hard pixel
        assert res.stats["non_converged"] <= res.stats["suspect"], method


def test_aovs_follow_the_scene_format(ctx):
    scene = load_scene(SCENES / "quad.toml")
    res = render(scene, ctx=ctx)
    aov = res.aovs()
    h, w = scene.film.height, scene.film.width
    spec = {
        "hit": (bool, (h, w)),
        "t": (np.float64, (h, w)),
        "surface": (np.int32, (h, w)),
        "u": (np.float64, (h, w)),
        "v": (np.float64, (h, w)),
        "position": (np.float64, (h, w, 3)),
        "normal": (np.float64, (h, w, 3)),
        "iterations": (np.int32, (h, w)),
        "residual": (np.float64, (h, w)),
    }
    for key, (dtype, shape) in spec.items():
        assert aov[key].dtype == dtype, key
        assert aov[key].shape == shape, key
    hit = aov["hit"]
    assert hit.sum() == 44 * 44  # pixel centres 10..53 of 64 see |x|, |z| <= 1 (0.25 / tan 20 deg of the half-film)
    assert np.all(aov["surface"][~hit] == -1) and np.all(aov["surface"][hit] == 0)
    for key in ("t", "u", "v", "residual"):
        assert np.all(np.isnan(aov[key][~hit])) and np.all(np.isfinite(aov[key][hit])), key
    n = aov["normal"][hit]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    d = pixel_rays(scene.camera, w, h).reshape(h, w, 3)[hit]
    assert np.all(np.einsum("ij,ij->i", n, d) < 0)  # facing the eye
    tol = scene.render.tolerance * np.sqrt(8.0)
    assert np.all(aov["residual"][hit] <= tol)
    # the position is on the ray at distance t
    p = scene.camera.eye + aov["t"][hit][:, None] * d
    np.testing.assert_allclose(aov["position"][hit], p, atol=1e-8)


def test_bands_and_a_given_map_give_the_same_hits(ctx, monkeypatch):
    """A film traced in bands of 8 rows (each with its own map and a row of margin), or from a
    whole-film map given by the caller (the preview window), hits exactly as in one band."""
    import bsrt.rendering.pipeline as render_module

    scene = load_scene(SCENES / "water-lily.toml")
    one = render(scene, RenderOptions.resolve(scene, width=64, height=48), ctx=ctx)
    monkeypatch.setattr(render_module, "MAX_BAND_SAMPLES", 64 * 8)
    banded = render(scene, RenderOptions.resolve(scene, width=64, height=48), ctx=ctx)
    given = render(scene, RenderOptions.resolve(scene, width=64, height=48), ctx=ctx, prelim=one.prelim)
    assert one.prelim.surface.shape == (48, 64)
    for res in (banded, given):
        np.testing.assert_array_equal(res.hits.hit, one.hits.hit)
        np.testing.assert_array_equal(res.hits.surface, one.hits.surface)
        np.testing.assert_allclose(res.hits.t[one.hits.hit], one.hits.t[one.hits.hit], atol=1e-8)
        np.testing.assert_allclose(res.linear, one.linear, atol=1e-9)


@pytest.mark.parametrize("degree", [1, 5, 10])
@pytest.mark.parametrize("method", ["newton", "martin"])
def test_a_plane_of_the_highest_allowed_degree_is_exact(ctx, degree, method):
    """The square of quad.toml degree-elevated to ``degree`` (its control points a uniform grid,
    which is the same plane): every pixel centre 10..53 of 64 on each axis hits, at t = 4 / cos."""
    grid = np.linspace(-1.0, 1.0, degree + 1)
    knots = [0.0] * (degree + 1) + [1.0] * (degree + 1)
    table = {
        "degree": [degree, degree],
        "knots_u": knots,
        "knots_v": knots,
        "points": [[[x, 0.0, z] for z in grid] for x in grid],
    }
    scene = parse_scene(
        scene_dict([table], width=64, height=64, eye=(0.0, -4.0, 0.0), look_at=(0.0, 0.0, 0.0), fov=40.0)
    )
    res = render(scene, RenderOptions.resolve(scene, method=method), ctx=ctx)
    hit = res.hits.hit.reshape(64, 64)
    assert hit.sum() == 44 * 44 and hit[10:54, 10:54].all()
    d = pixel_rays(scene.camera, 64, 64).reshape(64, 64, 3)
    np.testing.assert_allclose(res.hits.t.reshape(64, 64)[hit], (4.0 / d[..., 1])[hit], rtol=1e-9)


@pytest.mark.parametrize(
    "keys",
    [
        dict(spp=1, adaptive_spp=4),  # the adaptive samples rewrite marked pixels
        dict(spp=1, adaptive_spp=4, edges=True, edge_width=2.0),  # lines drawn over both
        dict(spp=4, adaptive_spp=0),  # the film's sums divided and encoded band by band
    ],
    ids=["adaptive", "edges", "spp4"],
)
def test_an_opaque_pictures_bytes_are_the_linear_images_srgb(ctx, keys):
    """RenderResult.image of an opaque 8-bit picture is the film's pixels, not encoded again: every
    path that writes the linear image writes their sRGB bytes with it, the same bytes as
    srgb_encode of the linear image (the water-lily: mirrors, shadows, petals' edges)."""
    from bsrt.rendering.image import encode_picture, srgb_encode

    scene = load_scene(SCENES / "water-lily.toml")
    res = render(scene, RenderOptions.resolve(scene, width=64, height=48, **keys), ctx=ctx)
    assert res.image is res.pixels
    np.testing.assert_array_equal(res.pixels, srgb_encode(res.linear))
    np.testing.assert_array_equal(res.image, encode_picture(res.linear, res.coverage, res.options.background, False, 8))
    assert (res.pixels > 0).any() and res.stats["hits"] > 0


@pytest.mark.parametrize("scene_name, spp", [("water-lily", 1), ("column", 1), ("column", 4)])
def test_the_aovs_of_a_render_that_kept_the_shadings_frames_are_the_same(ctx, monkeypatch, scene_name, spp):
    """render(aovs=True) keeps the shading's positions and normals of the pixel-centre hits (one
    sample a pixel): aovs() then evaluates no frame (facing_frames is not called) and gives every
    array as a render that evaluates them from its hits; with spp 4 nothing is kept."""
    from bsrt.rendering import pipeline

    scene = load_scene(SCENES / f"{scene_name}.toml")
    options = RenderOptions.resolve(scene, width=48, height=40, spp=spp)
    want = render(scene, options, ctx=ctx).aovs()
    kept = render(scene, options, ctx=ctx, keep=False, aovs=True)
    assert (kept.frames is not None) == (spp == 1) and kept.hits is not None
    if spp == 1:
        monkeypatch.setattr(pipeline, "facing_frames", None)  # calling it would raise
    got = kept.aovs()
    assert list(got) == list(want)
    for name in want:
        np.testing.assert_array_equal(got[name], want[name], err_msg=name)
    assert np.isfinite(got["normal"][got["hit"]]).all() and np.isnan(got["normal"][~got["hit"]]).all()
