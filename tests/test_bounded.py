"""Bounded resources for legal input (issue #16): high degrees, prime spp, films
1 pixel thin or wider than the GL limit, stagnating root finders, large
surfaces. Expected values are closed forms (planes); memory is the peak RSS
of a render in a child process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bsrt
from bsrt import validate
from bsrt.geometry.bspline import evaluate, make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.rendering import prelim
from bsrt.rendering.bvh import padded_nets
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import render, sample_grid
from bsrt.rendering.solve import Rays, find_roots
from bsrt.scene.camera import pixel_rays

ROOT = Path(__file__).resolve().parent.parent
EYE = (0.5, 0.5, 2.0)  # above the plane z = 0, looking straight down
VIEW = dict(camera_eye=EYE, camera_look_at=(0.5, 0.5, 0.0), camera_up=(0.0, 1.0, 0.0))
CLI_VIEW = ["--camera-eye", "0.5,0.5,2", "--camera-look-at", "0.5,0.5,0", "--camera-up", "0,1,0"]


def write_plane(path: Path, degree: int, wavy: float = 0.0) -> Path:
    """One Bezier patch of degree (degree, degree) in a .bpt file: the plane
    z = 0 over x in [-1, 2], y in [-0.5, 1.5] (evenly spaced points are the
    degree-elevated bilinear patch: exactly that plane), or with wavy != 0 a
    bumpy surface of the same degree."""
    lines = ["1", f"{degree} {degree}"]
    for i in range(degree + 1):
        for j in range(degree + 1):
            z = wavy * np.sin(7.0 * i / degree) * np.cos(5.0 * j / degree)
            lines.append(f"{3.0 * i / degree - 1.0!r} {2.0 * j / degree - 0.5!r} {float(z)!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


def plane_t(scene, width: int, height: int):
    """(hit (H, W) bool, t (H, W)) of the pixel-centre rays with the plane patch, in closed form."""
    d = pixel_rays(scene.camera, width, height)
    t = EYE[2] / -d[:, 2]
    x, y = EYE[0] + t * d[:, 0], EYE[1] + t * d[:, 1]
    hit = (x > -1.0) & (x < 2.0) & (y > -0.5) & (y < 1.5)
    return hit.reshape(height, width), t.reshape(height, width)


def run_cli(*args, cwd):
    """bsrt render in a child process: (completed process, its peak RSS in MB).
    A fresh wrapper process runs the render as its only child and reports
    resource.getrusage(RUSAGE_CHILDREN).ru_maxrss: exactly the render's peak."""
    script = (
        "import resource, subprocess, sys\n"
        "p = subprocess.run([sys.executable, '-m', 'bsrt', 'render', *sys.argv[1:]])\n"
        "print('PEAK', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr)\n"
        "sys.exit(p.returncode)\n"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run(
        [sys.executable, "-c", script, *map(str, args)], cwd=cwd, env=env, capture_output=True, text=True, timeout=900
    )
    peak = [line for line in proc.stderr.splitlines() if line.startswith("PEAK ")]
    assert proc.returncode == 0 and peak, proc.stderr
    return proc, int(peak[-1].split()[1]) / 1024.0


# ---------------------------------------------------------------------------
# High degree


@pytest.mark.gl
def test_plane_of_degree_10_hits_every_pixel_at_the_closed_form_depth_in_bounded_memory(tmp_path):
    path = write_plane(tmp_path / "plane.bpt", 10)
    for method in ("newton", "martin"):
        proc, peak = run_cli(
            path,
            "-o",
            tmp_path / "p.png",
            "--width",
            64,
            "--height",
            64,
            *CLI_VIEW,
            "--fov",
            20,
            "--method",
            method,
            "--aov",
            tmp_path / "a.npz",
            cwd=tmp_path,
        )
        aov = np.load(tmp_path / "a.npz")
        scene = bsrt.load(path, width=64, height=64, fov=20, **VIEW)
        hit, t = plane_t(scene, 64, 64)
        assert hit.all()
        assert aov["hit"].all(), method
        np.testing.assert_allclose(aov["t"], t, rtol=0, atol=1e-9)
        assert peak < 700, (method, peak)


@pytest.mark.gl
def test_highest_degree_surface_renders_in_bounded_memory(tmp_path):
    """The highest degree, curved: a wavy degree-25 patch's power-basis evaluation
    is off by about 1e-6 of its size, so the default tolerance is refused, naming
    the surface and the smallest usable value; with that tolerance it renders,
    the hierarchy's leaves keeping (26 x 26) nets, never (rays x net) at once."""
    wavy = write_plane(tmp_path / "wavy.bpt", validate.MAX_DEGREE, wavy=0.3)
    refused = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(wavy), "-o", str(tmp_path / "w.png")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    # the default tolerance (1e-9) is below what this degree's power basis resolves: refused, naming the surface
    message = refused.stderr.strip()
    assert refused.returncode == 2 and "wavy.bpt" in message and "of degree [25, 25]" in message, message
    assert len(message.splitlines()) == 1
    usable = float(message.rsplit("the smallest usable value is ", 1)[1])
    (tmp_path / "s.toml").write_text(
        f"[camera]\neye = [3, -4, 3]\nlook_at = [0.5, 0.5, 0]\nup = [0, 0, 1]\n"
        f'fov = 40\n[render]\ntolerance = {usable * 1.01!r}\n[[import]]\nfile = "wavy.bpt"\n'
    )
    for method in ("newton", "martin"):
        _, peak = run_cli(
            tmp_path / "s.toml",
            "-o",
            tmp_path / "w.png",
            "--width",
            64,
            "--height",
            64,
            "--method",
            method,
            cwd=tmp_path,
        )
        assert peak < 1000, (method, peak)


# ---------------------------------------------------------------------------
# Samples per pixel


def test_prime_spp_is_a_tall_grid_so_a_band_is_one_film_row_of_samples():
    assert sample_grid(251) == (1, 251)
    assert sample_grid(12) == (3, 4)
    assert sample_grid(16) == (4, 4)
    assert sample_grid(1) == (1, 1)


@pytest.mark.gl
def test_spp_251_peaks_as_low_as_spp_64_and_averages_to_the_plane(tmp_path):
    """96 x 96 pixels: 590k samples at spp 64, 2.3M at spp 251, both traced in
    bands of MAX_BAND_SAMPLES (a prime spp was one 251-samples-wide grid row
    per pixel row, which no band could split)."""
    plane = write_plane(tmp_path / "plane1.bpt", 1)
    peaks = {}
    for spp in (64, 251):
        _, peaks[spp] = run_cli(
            plane,
            "-o",
            tmp_path / f"s{spp}.png",
            "--width",
            96,
            "--height",
            96,
            *CLI_VIEW,
            "--fov",
            20,
            "--spp",
            spp,
            cwd=tmp_path,
        )
    assert peaks[251] < peaks[64] + 60, peaks  # bands of samples: memory does not grow with spp
    assert peaks[251] < 1000, peaks
    # spp samples are the pixel centres of a film spp times taller (1 x 251 grid):
    # render that film at spp 1 and box-filter it by hand
    scene = bsrt.load(plane, width=12, height=8, fov=20, **VIEW)
    many = render(scene, RenderOptions.resolve(scene, spp=251))
    tall = render(scene, RenderOptions.resolve(scene, spp=1, adaptive_spp=0, width=12, height=8 * 251)).linear
    np.testing.assert_allclose(many.linear, tall.reshape(8, 251, 12, 3).mean(axis=1), rtol=0, atol=1e-8)
    assert many.hits.hit.all() and many.pixels.shape == (8, 12, 3)
    assert np.ptp(many.linear[..., 0]) > 0.05  # the point light's falloff: a test of where the samples are


@pytest.mark.gl
def test_a_band_ending_inside_a_pixel_row_gives_the_same_image(monkeypatch):
    plane = ROOT / "scenes" / "quad.toml"
    scene = bsrt.load(plane, width=20, height=10)
    whole = render(scene, RenderOptions.resolve(scene, spp=7)).linear
    from bsrt.rendering import pipeline

    monkeypatch.setattr(pipeline, "MAX_BAND_SAMPLES", 20 * 3)  # 3 of each pixel row's 7 sample rows per band
    banded = render(scene, RenderOptions.resolve(scene, spp=7)).linear
    np.testing.assert_allclose(banded, whole, rtol=0, atol=1e-8)  # roots agree to the tolerance


# ---------------------------------------------------------------------------
# Thin and wide films


@pytest.mark.gl
@pytest.mark.parametrize("width,height", [(7, 1), (1, 5), (1, 1)])
def test_films_one_pixel_wide_or_high_hit_the_plane_at_the_closed_form_depth(tmp_path, width, height):
    plane = write_plane(tmp_path / "plane1.bpt", 1)
    scene = bsrt.load(plane, width=width, height=height, fov=1, **VIEW)
    hit, t = plane_t(scene, width, height)
    assert hit.all()
    for method in ("newton", "gradient", "martin"):
        result = bsrt.render(scene, method=method)
        aov = result.aovs()
        assert aov["hit"].all() and result.pixels.shape == (height, width, 3), method
        np.testing.assert_allclose(aov["t"], t, rtol=0, atol=1e-10)


def test_tiles_tile_the_band_exactly():
    assert prelim.tiles(3, 10, 150, 64) == [((3, 10), (0, 64)), ((3, 10), (64, 128)), ((3, 10), (128, 150))]
    assert prelim.tiles(0, 130, 5, 64) == [((0, 64), (0, 5)), ((64, 128), (0, 5)), ((128, 130), (0, 5))]


@pytest.mark.gl
def test_a_map_drawn_in_tiles_is_the_map_drawn_at_once(monkeypatch):
    scene = bsrt.load(ROOT / "scenes" / "water-lily.toml", width=150, height=40)
    patches = PatchSet([s.geometry for s in scene.surfaces])
    once = prelim.render_map(patches, scene.camera, 150, 40)
    tiled = prelim.render_map(patches, scene.camera, 150, 40, tile=64)
    assert (once.surface >= 0).sum() > 1000  # the lily covers much of the film
    np.testing.assert_array_equal(tiled.surface, once.surface)
    # the same fragments (their interpolated values differ in float32's last
    # bits), but for a tie of coverage on an edge here and there
    for name in ("u", "v", "distance"):
        a, b = getattr(tiled, name), getattr(once, name)
        off = ~np.isclose(a, b, rtol=1e-5, atol=1e-5, equal_nan=True)
        assert off.sum() <= 3, (name, np.argwhere(off))
    band = prelim.render_map(patches, scene.camera, 150, 40, rows=(7, 29), tile=16)
    assert (band.surface != once.surface[7:29]).sum() <= 3
    assert (~np.isclose(band.distance, once.distance[7:29], rtol=1e-5)).sum() <= 3
    want = render(scene, RenderOptions.resolve(scene)).pixels
    monkeypatch.setattr(prelim, "TILE", 64)
    np.testing.assert_array_equal(render(scene, RenderOptions.resolve(scene)).pixels, want)


@pytest.mark.gl
def test_a_film_wider_than_the_gl_limit_renders_through_tiles(tmp_path):
    import bsrt.rendering.gl as gl

    limit = gl.max_framebuffer_side(gl.headless_context())
    width = limit + 1
    plane = write_plane(tmp_path / "plane1.bpt", 1)
    run_cli(
        plane,
        "-o",
        tmp_path / "wide.png",
        "--width",
        width,
        "--height",
        1,
        *CLI_VIEW,
        "--fov",
        0.004,
        "--aov",
        tmp_path / "a.npz",
        cwd=tmp_path,
    )
    aov = np.load(tmp_path / "a.npz")
    hit, t = plane_t(bsrt.load(plane, width=width, height=1, fov=0.004, **VIEW), width, 1)
    assert hit.all()  # the film lies on the plane, across the tile seam
    assert aov["hit"].all()
    np.testing.assert_allclose(aov["t"], t, rtol=0, atol=1e-8)  # the tolerance: 1e-9 of the diagonal


# ---------------------------------------------------------------------------
# Stagnation


@pytest.mark.gl
def test_newton_stops_at_float64_resolution_whatever_max_iterations(tmp_path):
    """A degree-8 bumpy patch at the smallest legal tolerance: rounding noise
    keeps w above it, so before the stagnation exit Newton ran all 10,000
    iterations; now each start stops within STALL_STEPS of its last progress."""
    from bsrt.kernels.roots import STALL_STEPS

    path = write_plane(tmp_path / "bumpy8.bpt", 8, wavy=0.3)
    scene = bsrt.load(path, width=32, height=32)
    patches = PatchSet([s.geometry for s in scene.surfaces])
    directions = pixel_rays(scene.camera, 32, 32)
    rays = Rays.from_arrays(scene.camera.eye[None, :], directions)
    item = np.arange(len(rays))
    tolerance = 2.3e-16 * patches.scene_diagonal()
    for method in ("newton", "gradient", "fast"):
        res = find_roots(
            patches,
            rays,
            item,
            np.zeros(item.size, dtype=np.int64),
            np.full(item.size, 0.5),
            np.full(item.size, 0.5),
            method=method,
            tolerance=tolerance,
            max_iterations=10_000,
        )
        assert res.iterations.max() < 10_000, method
        if method == "newton":  # quadratic: a few steps of progress, then at most STALL_STEPS more
            assert res.iterations.max() <= STALL_STEPS + 40
            assert (~res.converged).sum() > 0  # the noise floor is real: some starts cannot reach it
    floor = validate.smallest_tolerance([s.geometry for s in scene.surfaces], scene.camera.eye)
    stats = bsrt.render(scene, method="newton", tolerance=floor, max_iterations=10_000).stats
    assert stats["iterations_max"] < 1000  # own start, up to 9 neighbour starts of 16, the hierarchy


# ---------------------------------------------------------------------------
# Set-up of many patches


def _surface(rng, degree, nu, nv, rational):
    p, q = degree
    ku = np.concatenate([[0.0] * p, np.sort(rng.uniform(0, 1, nu - p + 1)), [1.0] * p])
    ku[p], ku[nu] = 0.0, 1.0
    kv = np.concatenate([[0.0] * q, np.linspace(0.0, 2.0, nv - q + 1), [2.0] * q])
    kv[q + 3] = kv[q + 2]  # a double knot
    pts = np.stack(np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 2, nv), indexing="ij"), axis=-1)
    pts = np.concatenate([pts, rng.normal(0, 0.1, (nu, nv, 1))], axis=-1)
    weights = rng.uniform(0.5, 2.0, (nu, nv)) if rational else None
    return make_surface((p, q), np.sort(ku), kv, pts, weights)


def test_ten_thousand_patches_set_up_vectorised_match_the_reference_evaluator():
    rng = np.random.default_rng(16)
    surfaces = [
        _surface(rng, (3, 3), 103, 103, False),
        _surface(rng, (2, 3), 20, 12, True),
        _surface(rng, (3, 3), 8, 9, True),
    ]
    patches = PatchSet(surfaces)
    assert (patches.surface == 0).sum() == 100 * 99  # 100 u spans, 99 v spans (one double knot)
    for m, surf in enumerate(surfaces):
        n = 4000
        u = rng.uniform(*surf.domain_u, n)
        v = rng.uniform(*surf.domain_v, n)
        sid = np.full(n, m)
        got = patches.evaluate(patches.locate(sid, u, v), u, v)
        for a, b in zip(got, evaluate(surf, u, v)):
            np.testing.assert_allclose(a.T, b, rtol=0, atol=1e-9)
    nets, degree = padded_nets(patches)
    for k in rng.integers(0, patches.size, 50):
        net = patches.net(k)
        p, q = net.shape[0] - 1, net.shape[1] - 1
        assert tuple(degree[k]) == (p, q)
        np.testing.assert_array_equal(nets[k, : p + 1, : q + 1], net)
        pts = net[..., :3] / net[..., 3:4]
        np.testing.assert_array_equal(patches.box_min[k], pts.min(axis=(0, 1)))
        # the patch's corner is the surface's point at its rectangle's corner
        b = patches.bounds[k]
        corner = evaluate(surfaces[patches.surface[k]], [b[0]], [b[2]])[0][0]
        np.testing.assert_allclose(pts[0, 0], corner, atol=1e-9)


# ---------------------------------------------------------------------------
# The hierarchy's leaves in a budget


def test_leaf_budget_lowers_the_depth_and_the_retries_keep_the_hits(tmp_path, monkeypatch):
    """A bumpy degree-10 patch cut under a budget of 16 leaf nets: flatten
    lowers max_depth until the leaves fit, and the per-ray retries (quarters
    of a curved leaf) still find the same nearest roots as the full cut."""
    from bsrt.rendering import bvh as bvh_module

    path = write_plane(tmp_path / "bumpy10.bpt", 10, wavy=0.3)
    scene = bsrt.load(path, width=24, height=24, fov=40, **VIEW)
    patches = PatchSet([s.geometry for s in scene.surfaces])
    directions = pixel_rays(scene.camera, 24, 24)
    full = bvh_module.build_bvh(patches)
    per_leaf = full.leaf_net[0].size
    assert full.leaf_total > 16  # the budget below binds
    want = bvh_module.intersect(full, scene.camera.eye[None, :], directions)
    monkeypatch.setattr(bvh_module, "LEAF_NET_FLOATS", 16 * per_leaf)
    monkeypatch.setattr(bvh_module, "LEAVES_PER_PATCH", 1)
    small = bvh_module.build_bvh(patches)
    assert 0 < small.leaf_total <= 16
    assert small.leaf_depth.max() < full.leaf_depth.max()
    got = bvh_module.intersect(small, scene.camera.eye[None, :], directions)
    assert want.hit.all()  # the bumps stay inside the view
    np.testing.assert_array_equal(got.hit, want.hit)
    # both are roots within the tolerance (1e-9 of the diagonal from the ray); t may differ by that over |cos|
    np.testing.assert_allclose(got.t[got.hit], want.t[want.hit], rtol=0, atol=4e-9 * patches.scene_diagonal())


@pytest.mark.parametrize("degree", [3, 8, 10])
def test_patch_table_evaluation_within_1e_9_up_to_degree_10(degree):
    """The compiled power-basis evaluation against the reference (de Boor) evaluator
    on a wavy patch of each degree up to 10: within 1e-9 of the diagonal."""
    s = np.linspace(-1.0, 1.0, degree + 1)
    points = np.zeros((degree + 1, degree + 1, 3))
    points[..., 0], points[..., 1] = s[:, None], s[None, :]
    points[..., 2] = 0.2 * np.sin(3 * points[..., 0]) * np.cos(2 * points[..., 1])
    knots = [0.0] * (degree + 1) + [1.0] * (degree + 1)
    surface = make_surface([degree, degree], knots, knots, points.tolist(), None)
    rng = np.random.default_rng(degree)
    u, v = rng.random(400), rng.random(400)
    got = PatchSet([surface]).evaluate(np.zeros(400, dtype=np.int64), u, v, derivatives=False)
    want = evaluate(surface, u, v)
    want = np.asarray(want[0] if isinstance(want, tuple) else want)
    want = want.reshape(-1, 3) if want.shape[-1] == 3 else want.T
    assert np.abs(np.asarray(got).T - want).max() <= 1e-9 * np.sqrt(8.0)
