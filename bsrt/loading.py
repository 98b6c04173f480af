"""Scene or model file -> Scene, with the camera overrides: one place for the
CLI's render and map, the preview and the batch commands.

A ``.toml`` file is a scene; anything else is a model file read by
``bsrt.io.load_model`` (``format`` picks the reader, "auto" by extension) and
framed by ``scene_for_model`` with the automatic camera and lights.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .errors import InputError
from .files import check_input_file


@dataclass(frozen=True)
class CameraOverrides:
    """What the user asked for on top of the file: any field left None keeps
    the scene's value (or the automatic camera's, for a model). ``eye``,
    ``look_at`` and ``up`` are 3-sequences; ``fov`` is degrees in (0, 180)."""

    eye: tuple | None = None
    look_at: tuple | None = None
    up: tuple | None = None
    fov: float | None = None

    @classmethod
    def from_args(cls, args) -> "CameraOverrides":
        """From argparse's ``--camera-eye --camera-look-at --camera-up --fov``
        (attributes missing on ``args`` count as not given)."""
        return cls(getattr(args, "camera_eye", None), getattr(args, "camera_look_at", None),
                   getattr(args, "camera_up", None), getattr(args, "fov", None))


def load_input(path, format: str = "auto", *, width: int | None = None, height: int | None = None,
               camera: CameraOverrides = CameraOverrides()):
    """A Scene from a scene file, or from a model file with an automatic camera.

    ``width``/``height`` frame a model's automatic camera (default 512); a
    scene keeps its own film (the render options override it later). The
    caller reports ``scene.notes`` (import warnings) once.
    """
    from .scene import load_scene, scene_for_model

    from . import validate

    if camera.fov is not None:
        validate.fov(camera.fov, "--fov")
    for key, value in (("--camera-eye", camera.eye), ("--camera-look-at", camera.look_at), ("--camera-up", camera.up)):
        if value is not None:
            validate.numbers(key, value, validate.MAX_COORDINATE)
    path = check_input_file(path, "scene or model file")
    if path.suffix.lower() == ".toml":
        return _override_camera(load_scene(path), camera)
    from .io import load_model

    model = load_model(path, format)
    return scene_for_model(model, width or 512, height or 512, camera.eye, camera.look_at, camera.fov,
                           camera.up or (0.0, 0.0, 1.0))


def _override_camera(scene, overrides: CameraOverrides):
    cam = scene.camera
    eye = np.array(overrides.eye, float) if overrides.eye else cam.eye
    look = np.array(overrides.look_at, float) if overrides.look_at else cam.look_at
    up = np.array(overrides.up, float) if overrides.up else cam.up
    fov = overrides.fov if overrides.fov is not None else cam.fov
    camera = replace(cam, eye=eye, look_at=look, up=up, fov=fov)
    view = camera.look_at - camera.eye
    if np.linalg.norm(view) == 0 or np.linalg.norm(np.cross(view, camera.up)) < 1e-9 * np.linalg.norm(view):
        raise InputError("--camera-eye / --camera-look-at / --camera-up: the view direction must not be zero "
                         "or parallel to up")
    return replace(scene, camera=camera)
