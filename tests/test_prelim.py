"""The preliminary map on a real OpenGL context (Mesa llvmpipe through EGL)."""

from __future__ import annotations

import numpy as np
import pytest

from bsrt.errors import InputError
from bsrt.geometry.bspline import make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.rendering.prelim import render_map
from bsrt.scene.camera import Camera, pixel_rays


def _flat(x0, x1, z0, z1, y=0.0):
    return make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[x0, y, z0], [x0, y, z1]], [[x1, y, z0], [x1, y, z1]]])


CAMERA = Camera(np.array([0.3, -4.0, 0.2]), np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 40.0)


@pytest.mark.parametrize("width,height", [(64, 64), (80, 48)])
def test_map_pixel_sees_the_ray_of_that_pixel(ctx, width, height):
    """At every pixel centre the map's (u, v) is where that pixel's ray meets the plane."""
    surf = _flat(-1.0, 1.0, -1.0, 1.0)
    ps = PatchSet([surf])
    prelim = render_map(ps, CAMERA, width, height, "float", ctx=ctx)
    assert ctx.error == "GL_NO_ERROR"
    d = pixel_rays(CAMERA, width, height)
    t = -CAMERA.eye[1] / d[:, 1]  # plane y = 0
    p = CAMERA.eye + t[:, None] * d
    u_true, v_true = (p[:, 0] + 1) / 2, (p[:, 2] + 1) / 2
    inside = (u_true > 0) & (u_true < 1) & (v_true > 0) & (v_true < 1)
    # pixels whose centre ray is inside (away from the edge by a pixel) are covered, the rest not
    margin = 2.5 / width
    deep = (u_true > margin) & (u_true < 1 - margin) & (v_true > margin) & (v_true < 1 - margin)
    outside = (u_true < -margin) | (u_true > 1 + margin) | (v_true < -margin) | (v_true > 1 + margin)
    surface = prelim.surface.ravel()
    assert np.all(surface[deep] == 0)
    assert np.all(surface[outside] == -1)
    assert deep.sum() > 0.2 * width * height
    # a flat bilinear patch is its own tessellation: the map is exact up to float32
    np.testing.assert_allclose(prelim.u.ravel()[deep], u_true[deep], atol=2e-6)
    np.testing.assert_allclose(prelim.v.ravel()[deep], v_true[deep], atol=2e-6)
    np.testing.assert_allclose(prelim.distance.ravel()[deep], t[deep], rtol=1e-5)
    assert np.all(np.isnan(prelim.u.ravel()[~inside & outside]))


def test_rgba8_map_decodes_with_eq6(ctx):
    """8-bit map: u0 = (umax - umin) g / 255 + umin, on a surface with domain [2, 6] x [-1, 1]."""
    surf = make_surface((1, 1), [2, 2, 6, 6], [-1, -1, 1, 1], [[[-1, 0, -1], [-1, 0, 1]], [[1, 0, -1], [1, 0, 1]]])
    ps = PatchSet([surf])
    width = height = 64
    prelim = render_map(ps, CAMERA, width, height, "rgba8", ctx=ctx)
    d = pixel_rays(CAMERA, width, height)
    t = -CAMERA.eye[1] / d[:, 1]
    p = CAMERA.eye + t[:, None] * d
    u_true, v_true = 2 + 4 * (p[:, 0] + 1) / 2, p[:, 2]
    covered = prelim.surface.ravel() == 0
    deep = covered & (np.abs(p[:, 0]) < 0.9) & (np.abs(p[:, 2]) < 0.9)
    g = prelim.picture[..., 1].ravel().astype(np.float64)
    np.testing.assert_array_equal(prelim.u.ravel()[covered], (6 - 2) * g[covered] / 255 + 2)
    # quantisation: half a step of 1/255 of the domain, plus rasterisation rounding
    assert np.abs(prelim.u.ravel()[deep] - u_true[deep]).max() <= 4 / 255 * 0.5 + 1e-3
    assert np.abs(prelim.v.ravel()[deep] - v_true[deep]).max() <= 2 / 255 * 0.5 + 1e-3
    assert np.all(prelim.picture[..., 0].ravel()[covered] == 1)  # red = index + 1


def test_depth_test_keeps_the_nearer_surface(ctx):
    far = _flat(-1.0, 1.0, -1.0, 1.0, y=1.0)
    near = _flat(-0.5, 0.5, -0.5, 0.5, y=-1.0)
    ps = PatchSet([far, near])
    cam = Camera(np.array([0.0, -4.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]), 40.0)
    prelim = render_map(ps, cam, 64, 64, "float", ctx=ctx)
    assert prelim.surface[32, 32] == 1
    # row 32 looks along z = 0; column 5 at x = -1.51 on the far plane (outside both squares),
    # column 15 at x = -0.94 on the far plane and -0.56 on the near one (outside it)
    assert prelim.surface[32, 5] == -1
    assert prelim.surface[32, 15] == 0
    ids = set(np.unique(prelim.surface).tolist())
    assert ids == {-1, 0, 1}


def test_rgba8_refuses_more_than_255_surfaces(ctx):
    surfaces = [_flat(i, i + 0.5, 0.0, 0.5) for i in range(256)]
    with pytest.raises(InputError, match="at most 255 surfaces"):
        render_map(PatchSet(surfaces), CAMERA, 8, 8, "rgba8", ctx=ctx)


def test_map_leaves_no_gl_error_and_is_repeatable(ctx):
    ps = PatchSet([_flat(-1.0, 1.0, -1.0, 1.0)])
    a = render_map(ps, CAMERA, 32, 32, "float", ctx=ctx)
    b = render_map(ps, CAMERA, 32, 32, "float", ctx=ctx)
    assert ctx.error == "GL_NO_ERROR"
    np.testing.assert_array_equal(a.surface, b.surface)
    np.testing.assert_array_equal(a.u, b.u)
