"""The trim test in GLSL (shaders/trim.glsl, uploaded by bsrt.rendering.trim_gl) and the
preview's moving view that uses it, on a real GL context (EGL, llvmpipe in CI).

- the GLSL test against the float64 kernels (``kernels.trim.kept_many``) on
  random (u, v) of trimmed IGES files: the same answer except within a small
  distance of the curves (float32 in GLSL);
- the fast view (bsrt.preview.view.View, drawn offscreen as the window draws
  while the camera moves) of a disc trimmed out of a square and of a square
  with a hole, seen from straight above: the pixels drawn are the closed-form
  ones, up to two pixels at the edges.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bsrt.geometry.patches import PatchSet
from bsrt.io import load_model
from bsrt.kernels.trim import kept_many
from bsrt.preview.view import View
from bsrt.rendering import gl
from bsrt.rendering.pipeline import Geometry
from bsrt.rendering.trim_gl import kept_gl
from bsrt.scene import parse_scene
from bsrt.scene.camera import pixel_rays

HERE = Path(__file__).parent
IGES = [
    HERE / "data" / "iges" / name
    for name in (  # every file there with trimmed surfaces (curves.igs has none)
        "box_brep.igs",
        "cone_194.igs",
        "cylinder_128_model_space.igs",
        "cylinder_192.igs",
        "cylinder_brep.igs",
        "cylinder_brep_inverted.igs",
        "plane_143.igs",
        "plane_circle_144.igs",
        "sphere_cap_brep.igs",
        "sphere_torus.igs",
        "surfaces_misc.igs",
    )
]
BEARING = HERE / "data" / "models" / "iges" / "occt" / "bearing.iges"
W = math.sqrt(0.5)


def circle(cx, cy, r):
    """A loop of four rational quadratic quarter arcs (an exact circle) in (u, v)."""
    curves = []
    for k in range(4):
        a0, a1 = k * math.pi / 2, (k + 1) * math.pi / 2
        p0 = [cx + r * math.cos(a0), cy + r * math.sin(a0)]
        p2 = [cx + r * math.cos(a1), cy + r * math.sin(a1)]
        p1 = [cx + r * (math.cos(a0) - math.sin(a0)), cy + r * (math.sin(a0) + math.cos(a0))]
        curves.append({"degree": 2, "knots": [0, 0, 0, 1, 1, 1], "points": [p0, p1, p2], "weights": [1.0, W, 1.0]})
    return {"curves": curves}


def square_loop(u0, u1, v0, v1):
    corners = [[u0, v0], [u1, v0], [u1, v1], [u0, v1]]
    return {
        "curves": [
            {"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]} for a, b in zip(corners, corners[1:] + corners[:1])
        ]
    }


def plate(trims):
    """The square [0, 1] x [0, 1] at z = 0; u = x, v = y."""
    return {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]],
        "trim": trims,
    }


def top_view(surface, size, half=0.6, height=10.0):
    """A camera straight above (0.5, 0.5) seeing [-half, half] around it at z = 0."""
    fov = 2 * math.degrees(math.atan(half / height))
    return parse_scene(
        {
            "film": {"width": size, "height": size, "background": [0.0, 0.0, 0.0]},
            "camera": {"eye": [0.5, 0.5, height], "look_at": [0.5, 0.5, 0.0], "up": [0.0, 1.0, 0.0], "fov": fov},
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": [surface],
        }
    )


def fast_view_coverage(ctx, scene, size):
    """(H, W) bool: the pixels the preview's moving view draws, row 0 at the top."""
    with ctx:
        view = View(ctx, scene, Geometry(scene), scene.camera, (size, size))
        try:
            assert view.untested < view.triangles  # the trimmed square's triangles run the test
            picture = view.screenshot((size, size), None, scene.camera)
            assert ctx.error == "GL_NO_ERROR"
        finally:
            view.close()
    assert ctx.error == "GL_NO_ERROR"
    return np.any(picture != 0, axis=2)  # black background, white ambient-lit plate


def ground_uv(scene, size):
    """(H, W) u and v where each pixel-centre ray meets z = 0 (u = x, v = y), row 0 at the top."""
    cam = scene.camera
    d = pixel_rays(cam, size, size)
    t = -cam.eye[2] / d[:, 2]
    p = cam.eye + t[:, None] * d
    return p[:, 0].reshape(size, size), p[:, 1].reshape(size, size)


@pytest.mark.parametrize("hole", [False, True], ids=["disc", "hole"])
def test_fast_view_draws_only_the_trimmed_region(ctx, hole):
    size, r = 96, 0.3
    trims = [square_loop(0.0, 1.0, 0.0, 1.0), circle(0.5, 0.5, r)] if hole else [circle(0.5, 0.5, r)]
    scene = top_view(plate(trims), size)
    drawn = fast_view_coverage(ctx, scene, size)
    u, v = ground_uv(scene, size)
    radius = np.hypot(u - 0.5, v - 0.5)
    in_square = (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1)
    expected = in_square & ((radius > r) if hole else (radius < r))
    pixel = 2 * 0.6 / size  # one pixel on the ground
    edge = np.minimum.reduce([np.abs(radius - r), np.abs(u), np.abs(u - 1), np.abs(v), np.abs(v - 1)])
    sure = edge > 2 * pixel
    assert sure.sum() > 0.7 * size * size
    wrong = (drawn != expected) & sure
    assert not wrong.any(), f"{wrong.sum()} pixels off by more than 2 pixels from the edges"
    assert expected.sum() > 0.15 * size * size and (~expected).sum() > 0.1 * size * size


def near_a_curve(table, surface, u, v, delta):
    """(N,) bool: point_kept changes within delta of (u, v) along u or v (so a curve passes that near)."""
    here = kept_many(table, surface, u, v)
    out = np.zeros(u.size, dtype=bool)
    for du, dv in ((delta, 0), (-delta, 0), (0, delta), (0, -delta)):
        out |= kept_many(table, surface, u + du * (np.abs(u) + 1.0), v + dv * (np.abs(v) + 1.0)) != here
    return out


def check_model(ctx, path, points_per_surface=4000):
    surfaces = load_model(path).surfaces
    patches = PatchSet([s for s in surfaces])
    table = patches.trims
    trimmed = np.flatnonzero(table.trimmed)
    assert trimmed.size, f"{path.name}: no trimmed surface"
    rng = np.random.default_rng(7)
    m = np.repeat(trimmed, points_per_surface)
    d = patches.domain[m]
    pad = 0.02 * (d[:, [1, 3]] - d[:, [0, 2]])
    u = d[:, 0] - pad[:, 0] + rng.random(m.size) * (d[:, 1] - d[:, 0] + 2 * pad[:, 0])
    v = d[:, 2] - pad[:, 1] + rng.random(m.size) * (d[:, 3] - d[:, 2] + 2 * pad[:, 1])
    # and as many points 1e-4 of the domain's size (along u and along v) off the curves (the test's hard cases: the
    # piece's ends straddle u, so the crossing is solved for)
    near_m, near_u, near_v = [], [], []
    for k in trimmed:
        curves = [c for loop in surfaces[k].trims for c in loop.curves]
        size = np.hypot(*(patches.domain[k, [1, 3]] - patches.domain[k, [0, 2]]))
        for c in curves:
            count = max(1, points_per_surface // len(curves))
            a, b = c.domain
            on = c.evaluate(a + (b - a) * rng.random(count))
            step = 1e-4 * size * rng.choice([-1.0, 1.0], size=(count, 2))  # diagonal: off lines along u or v too
            near_m.append(np.full(count, k))
            near_u.append(on[:, 0] + step[:, 0])
            near_v.append(on[:, 1] + step[:, 1])
    m = np.concatenate([m] + near_m)
    u = np.concatenate([u] + near_u)
    v = np.concatenate([v] + near_v)
    u, v = u.astype(np.float32).astype(np.float64), v.astype(np.float32).astype(np.float64)  # what GLSL sees
    gpu = kept_gl(table, m, u, v, ctx=ctx)
    cpu = kept_many(table, m.astype(np.int64), u, v)
    assert ctx.error == "GL_NO_ERROR"
    assert 0 < cpu.sum() < cpu.size  # both answers occur
    differ = np.flatnonzero(gpu != cpu)
    near = near_a_curve(table, m[differ].astype(np.int64), u[differ], v[differ], 1e-5)
    assert near.all(), (
        f"{path.name}: {int((~near).sum())} of {m.size} points differ farther than 1e-5 "
        f"(relative) from a curve, e.g. surface {m[differ][~near][:3]}"
    )
    assert differ.size <= 1e-3 * m.size
    return differ.size, m.size


@pytest.mark.parametrize("path", IGES, ids=[p.name for p in IGES])
def test_glsl_trim_test_matches_the_kernels_on_iges_files(ctx, path):
    check_model(ctx, path)


def test_glsl_trim_test_matches_the_kernels_on_bearing(ctx):
    check_model(ctx, BEARING, points_per_surface=500)


def test_glsl_trim_test_on_a_circle_is_exact_away_from_it(ctx):
    scene = top_view(plate([circle(0.5, 0.5, 0.3)]), 8)
    table = Geometry(scene).patches.trims
    rng = np.random.default_rng(3)
    u, v = (rng.random(50000).astype(np.float32).astype(np.float64) for _ in range(2))
    gpu = kept_gl(table, np.zeros(u.size, dtype=np.int64), u, v, ctx=ctx)
    radius = np.hypot(u - 0.5, v - 0.5)
    sure = np.abs(radius - 0.3) > 1e-5
    assert np.array_equal(gpu[sure], radius[sure] < 0.3)


def test_shader_includes_expand_once_with_line_directives():
    source = gl.shader_source("preview")
    assert "#include" not in source.replace("// ", "")
    assert source.count("bool trim_kept(") == 1
    assert source.startswith("#version 330 core\n")
    assert "#line 1 1\n" in source
    probe = gl.shader_source("trim_probe")
    assert probe.count("bool trim_kept(") == 1
