"""Camera paths for ``bsrt animate``: an orbit, or keyframes from the scene file.

Frames are numbered 1..N, as their files (``frame_0001.png`` is frame 1).

* Orbit by D degrees: frame k (1-based) has its eye rotated about the line
  through ``look_at`` along the camera's ``up`` by D * (k - 1) / N degrees
  (right-handed about up); look_at, up and fov stay. So D = 360 closes the
  loop: frame N + 1 would be frame 1 again, and no frame is shown twice.
* Keyframes: ``[[camera.keyframe]]`` tables (``frame``, and any of ``eye``,
  ``look_at``, ``up``, ``fov``; a key left out takes the ``[camera]``
  table's value). Between two keyframes every value is interpolated
  linearly in the frame number; before the first
  and after the last the nearest keyframe holds.

:func:`parse_keyframes` is what the scene parser calls for the table, so a
bad keyframe is a scene error naming the file and the key.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, replace

import numpy as np

from .camera import Camera
from .errors import InputError


@dataclass(frozen=True)
class Keyframe:
    """The camera at one frame (1-based). eye, look_at, up: (3,) float64 tuples; fov: degrees."""

    frame: int
    eye: tuple
    look_at: tuple
    up: tuple
    fov: float


def parse_keyframes(raw, where: str, camera: Camera) -> tuple[Keyframe, ...]:
    """``[[camera.keyframe]]`` (a list of tables, as tomllib gives it) -> Keyframes in frame order.

    Keys the table leaves out take ``camera``'s values. Frames must be whole
    numbers >= 1 in increasing order. Raises InputError naming ``where`` and
    ``camera.keyframe[i].key``.
    """
    from .scene import _Table

    if not isinstance(raw, list):
        raise InputError(f"{where}: camera.keyframe: expected an array of tables [[camera.keyframe]]")
    out: list[Keyframe] = []
    for i, data in enumerate(raw):
        t = _Table(where, data, f"camera.keyframe[{i}]")
        frame = t.integer("frame", required=True, lo=1)
        if out and frame <= out[-1].frame:
            t.fail("frame", f"must be greater than the previous keyframe's ({out[-1].frame}), got {frame}")
        key = Keyframe(frame, t.vector("eye", tuple(camera.eye)), t.vector("look_at", tuple(camera.look_at)),
                       t.vector("up", tuple(camera.up)),
                       t.number("fov", camera.fov, lo=0.0, hi=180.0, lo_open=True, hi_open=True))
        t.finish()
        view = np.subtract(key.look_at, key.eye)
        if not np.any(view):
            t.fail("look_at", "must differ from eye")
        if np.linalg.norm(np.cross(view, key.up)) < 1e-9 * np.linalg.norm(view) * np.linalg.norm(key.up) or \
                not np.any(key.up):
            t.fail("up", "must not be zero or parallel to the view direction (look_at - eye)")
        out.append(key)
    return tuple(out)


def orbit_camera(camera: Camera, degrees: float, frame: int, frames: int) -> Camera:
    """Frame ``frame`` (1-based) of an orbit of ``degrees`` over ``frames`` frames.

    eye' = look_at + R(up, degrees * (frame - 1) / frames) (eye - look_at),
    R the right-handed rotation about the unit up axis; frame 1 is ``camera``.
    """
    from .scene import rotation_matrix

    angle = degrees * (frame - 1) / frames
    offset = rotation_matrix(np.asarray(camera.up, float), angle) @ (camera.eye - camera.look_at)
    return replace(camera, eye=camera.look_at + offset)


def keyframe_camera(camera: Camera, keys: tuple[Keyframe, ...], frame: int) -> Camera:
    """The camera at ``frame`` (1-based) on the keyframes' path (``camera`` gives fov_axis)."""
    if frame <= keys[0].frame:
        a = b = keys[0]
    elif frame >= keys[-1].frame:
        a = b = keys[-1]
    else:
        b_index = next(i for i, k in enumerate(keys) if k.frame >= frame)
        a, b = keys[b_index - 1], keys[b_index]
    s = 0.0 if a is b else (frame - a.frame) / (b.frame - a.frame)

    def mix(x, y):
        return (1.0 - s) * np.asarray(x, float) + s * np.asarray(y, float)

    eye, look, up = mix(a.eye, b.eye), mix(a.look_at, b.look_at), mix(a.up, b.up)
    view = look - eye
    if not np.any(view) or np.linalg.norm(np.cross(view, up)) < 1e-9 * np.linalg.norm(view) * np.linalg.norm(up):
        raise InputError(f"camera.keyframe: at frame {frame}, between the keyframes of frames {a.frame} and "
                         f"{b.frame}, the view direction is zero or parallel to up")
    return replace(camera, eye=eye, look_at=look, up=up, fov=float(mix(a.fov, b.fov)))


def frame_cameras(scene, frames: int, orbit: float | None) -> list[Camera]:
    """The camera of each frame 1..frames: an orbit of ``orbit`` degrees, else the
    scene's keyframes (InputError if it has none)."""
    if orbit is not None:
        return [orbit_camera(scene.camera, orbit, k, frames) for k in range(1, frames + 1)]
    keys = getattr(scene, "keyframes", ())
    if not keys:
        raise InputError(f"{scene.path}: camera.keyframe: the scene has no [[camera.keyframe]] tables; "
                         "give --orbit DEGREES or add keyframes")
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
            first.save(f, format="WEBP", save_all=True, append_images=rest, duration=duration, loop=0,
                       lossless=True)
        else:
            first.save(f, format="PNG", save_all=True, append_images=rest, duration=duration, loop=0,
                       disposal=0, blend=0)

    return write


def check_fps(fps: float) -> float:
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"--fps: must be a positive number, got {fps:g}")
    return fps
