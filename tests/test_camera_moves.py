"""The preview's camera moves (bsrt/scene/camera.py): orbit, pan, zoom, on exact
values worked by hand."""

from __future__ import annotations

import numpy as np

from bsrt.scene.camera import Camera, orbit, pan, zoom


def _camera(eye=(1.0, 0.0, 0.0), look_at=(0.0, 0.0, 0.0), fov=90.0):
    return Camera(np.array(eye), np.array(look_at), np.array([0.0, 0.0, 1.0]), fov, "y")


def test_orbit_by_90_degrees_about_z():
    # yaw -90 degrees (the eye turns counter-clockwise seen from +z) takes (1,0,0) to (0,1,0)
    moved = orbit(_camera(), -90.0, 0.0)
    assert np.allclose(moved.eye, [0.0, 1.0, 0.0], rtol=0, atol=1e-12)
    assert np.array_equal(moved.look_at, [0.0, 0.0, 0.0])
    assert np.allclose(orbit(_camera(), 90.0, 0.0).eye, [0.0, -1.0, 0.0], rtol=0, atol=1e-12)
    # about a look_at away from the origin: the same turn, shifted
    off = orbit(_camera(eye=(3.0, 2.0, 5.0), look_at=(2.0, 2.0, 5.0)), -90.0, 0.0)
    assert np.allclose(off.eye, [2.0, 3.0, 5.0], rtol=0, atol=1e-12)


def test_orbit_pitch_raises_the_eye_and_stops_short_of_up():
    moved = orbit(_camera(), 0.0, 45.0)
    h = np.sqrt(0.5)
    assert np.allclose(moved.eye, [h, 0.0, h], rtol=0, atol=1e-12)
    # 90 degrees would put the eye on the up axis: not applied
    assert np.array_equal(orbit(_camera(), 0.0, 90.0).eye, _camera().eye)
    assert np.allclose(
        orbit(_camera(), 0.0, 88.0).eye, [np.cos(np.radians(88.0)), 0.0, np.sin(np.radians(88.0))], rtol=0, atol=1e-12
    )


def test_zoom_keeps_look_at_and_scales_the_distance():
    cam = _camera(eye=(3.0, 4.0, 0.0), look_at=(1.0, 1.0, 1.0))
    half = zoom(cam, 0.5)
    assert np.array_equal(half.look_at, cam.look_at)
    assert np.allclose(half.eye, [2.0, 2.5, 0.5], rtol=0, atol=1e-12)
    assert np.isclose(np.linalg.norm(half.eye - half.look_at), 0.5 * np.linalg.norm(cam.eye - cam.look_at), rtol=1e-15)


def test_pan_moves_eye_and_look_at_together_in_the_view_plane():
    # eye (1,0,0) looking at the origin, fov 90 (tan 45 = 1), distance 1: one
    # view height is 2 scene units; right = forward x up = (-1,0,0) x (0,0,1) = (0,1,0), up = (0,0,1)
    cam = _camera()
    right, up, _ = cam.basis()
    assert np.allclose(right, [0, 1, 0]) and np.allclose(up, [0, 0, 1])
    moved = pan(cam, 0.25, 0.5, 1.0)
    shift = -(0.25 * 2.0) * right - (0.5 * 2.0) * up  # the scene follows the cursor: the camera goes the other way
    assert np.allclose(moved.eye, cam.eye + shift, rtol=0, atol=1e-12)
    assert np.allclose(moved.look_at, cam.look_at + shift, rtol=0, atol=1e-12)
    assert np.allclose(shift, [0.0, -0.5, -1.0])
