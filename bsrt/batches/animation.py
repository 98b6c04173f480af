"""Camera paths and the animated file of ``bsrt animate``.

* Orbit by D degrees: frame k (1-based) has its eye rotated about the line
  through ``look_at`` along the camera's ``up`` by D * (k - 1) / N degrees
  (right-handed about up); look_at, up and fov stay. So D = 360 closes the
  loop: frame N + 1 would be frame 1 again, and no frame is shown twice.
* Keyframes: the scene's ``[[camera.keyframe]]`` path (bsrt/scene/keyframes.py).
"""

from __future__ import annotations

import io
import math
from dataclasses import replace

import numpy as np

from bsrt.errors import InputError
from bsrt.scene.camera import Camera, rotation_matrix
from bsrt.scene.keyframes import keyframe_camera


def orbit_camera(camera: Camera, degrees: float, frame: int, frames: int) -> Camera:
    """Frame ``frame`` (1-based) of an orbit of ``degrees`` over ``frames`` frames.

    eye' = look_at + R(up, degrees * (frame - 1) / frames) (eye - look_at),
    R the right-handed rotation about the unit up axis; frame 1 is ``camera``.
    """
    angle = degrees * (frame - 1) / frames
    offset = rotation_matrix(np.asarray(camera.up, float), angle) @ (camera.eye - camera.look_at)
    return replace(camera, eye=camera.look_at + offset)


def frame_cameras(scene, frames: int, orbit: float | None) -> list[Camera]:
    """The camera of each frame 1..frames: an orbit of ``orbit`` degrees, else the
    scene's keyframes (InputError if it has none)."""
    if orbit is not None:
        return [orbit_camera(scene.camera, orbit, k, frames) for k in range(1, frames + 1)]
    keys = getattr(scene, "keyframes", ())
    if not keys:
        raise InputError(
            f"{scene.path}: camera.keyframe: the scene has no [[camera.keyframe]] tables; "
            "give --orbit DEGREES or add keyframes"
        )
    try:
        return [keyframe_camera(scene.camera, keys, k) for k in range(1, frames + 1)]
    except InputError as exc:
        raise InputError(f"{scene.path}: {exc}") from None


def animation_writer(frames_png: list[bytes], fps: float, kind: str):
    """PNG-encoded frames -> a function writing an animated ``kind`` ("webp", lossless,
    or "apng") to a binary file, looping forever at ``fps`` frames a second."""
    from PIL import Image

    images = [Image.open(io.BytesIO(data)).convert("RGB") for data in frames_png]
    duration = max(1, int(round(1000.0 / fps)))

    def write(f) -> None:
        first, rest = images[0], images[1:]
        if kind == "webp":
            first.save(f, format="WEBP", save_all=True, append_images=rest, duration=duration, loop=0, lossless=True)
        else:
            first.save(
                f, format="PNG", save_all=True, append_images=rest, duration=duration, loop=0, disposal=0, blend=0
            )

    return write


def check_fps(fps: float) -> float:
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"--fps: must be a positive number, got {fps:g}")
    return fps
