"""Camera keyframes of a scene file, the path of ``bsrt animate``.

Frames are numbered 1..N, as their files (``frame_0001.png`` is frame 1).
The orbit and the animated file: bsrt/batches/animation.py.

* Keyframes: ``[[camera.keyframe]]`` tables (``frame``, and any of ``eye``,
  ``look_at``, ``up``, ``fov``; a key left out takes the ``[camera]``
  table's value). Between two keyframes every value is interpolated
  linearly in the frame number; before the first
  and after the last the nearest keyframe holds.

:func:`parse_keyframes` is what the scene parser calls for the table, so a
bad keyframe is a scene error naming the file and the key.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bsrt.errors import InputError
from bsrt.scene.camera import Camera


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
    from bsrt.scene.tables import _Table

    if not isinstance(raw, list):
        raise InputError(f"{where}: camera.keyframe: expected an array of tables [[camera.keyframe]]")
    out: list[Keyframe] = []
    for i, data in enumerate(raw):
        t = _Table(where, data, f"camera.keyframe[{i}]")
        frame = t.integer("frame", required=True, lo=1)
        if out and frame <= out[-1].frame:
            t.fail("frame", f"must be greater than the previous keyframe's ({out[-1].frame}), got {frame}")
        key = Keyframe(
            frame,
            t.vector("eye", tuple(camera.eye)),
            t.vector("look_at", tuple(camera.look_at)),
            t.vector("up", tuple(camera.up)),
            t.number("fov", camera.fov, lo=0.0, hi=180.0, lo_open=True, hi_open=True),
        )
        t.finish()
        view = np.subtract(key.look_at, key.eye)
        if not np.any(view):
            t.fail("look_at", "must differ from eye")
        if np.linalg.norm(np.cross(view, key.up)) < 1e-9 * np.linalg.norm(view) * np.linalg.norm(key.up) or not np.any(
            key.up
        ):
            t.fail("up", "must not be zero or parallel to the view direction (look_at - eye)")
        out.append(key)
    return tuple(out)


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
        raise InputError(
            f"camera.keyframe: at frame {frame}, between the keyframes of frames {a.frame} and "
            f"{b.frame}, the view direction is zero or parallel to up"
        )
    return replace(camera, eye=eye, look_at=look, up=up, fov=float(mix(a.fov, b.fov)))
