"""A scene for a model file alone: the automatic camera, lights and material."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from bsrt import validate
from bsrt.errors import InputError
from bsrt.scene.auto import DEFAULT_FOV, fit_camera, studio_lights, surface_points
from bsrt.scene.camera import Camera
from bsrt.scene.model import MODEL_MATERIAL, Film, RenderSettings, Scene, SceneSurface
from bsrt.scene.parse import _colour_materials, _skipped_notes


def model_box(surfaces) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners (3,) of what the surfaces show (bsrt.scene.auto.surface_points: grids
    over the domains, trimmed surfaces by their kept points and trim curves)."""
    pts = surface_points(surfaces)
    return pts.min(axis=0), pts.max(axis=0)


def scene_for_model(
    model, width=512, height=512, eye=None, look_at=None, fov=None, up=(0.0, 0.0, 1.0), view=None, turntable=False
) -> Scene:
    """A scene that shows a model file with no scene file.

    The camera (bsrt/scene/auto.py) looks along ``view`` ("default": a three-quarter view from
    above; "iso", "front", "back", "left", "right", "top", "bottom") relative to ``up`` (+z
    unless given) and fits what the model shows into 90 % of the frame, centred (turntable:
    centred on the up axis through the model's centre, for ``bsrt animate --orbit``). The
    studio rig lights it (key, fill, rim, ambient); one neutral material. eye / look_at / fov
    override the automatic choice.
    """
    if fov is not None:
        validate.fov(fov, "--fov")
    clock = time.perf_counter()
    points = surface_points(model.surfaces)
    up = np.asarray(up, dtype=np.float64)
    if np.linalg.norm(up) == 0:
        raise InputError("--camera-up: must not be the zero vector")
    fitted = fit_camera(
        points, width, height, view or "default", up, DEFAULT_FOV if fov is None else float(fov), turntable
    )
    fov = fitted.fov
    look = fitted.look_at if look_at is None else np.asarray(look_at, dtype=np.float64)
    automatic = eye is None
    if eye is None:
        eye = look + (fitted.eye - fitted.look_at)
        if view in ("top", "bottom"):
            up = fitted.up
    eye = np.asarray(eye, dtype=np.float64)
    view_dir = look - eye
    if np.linalg.norm(view_dir) == 0 or np.linalg.norm(np.cross(view_dir, up)) < 1e-9 * np.linalg.norm(view_dir):
        raise InputError(
            "--camera-eye / --camera-look-at / --camera-up: the view direction must not be zero or parallel to up"
        )
    try:
        validate.camera(Camera(eye, look, up, fov, "y"))
    except InputError as exc:  # the automatic eye of a model near the coordinate limit
        raise InputError(f"{model.path}: {'the automatic ' if automatic else ''}{exc}") from None
    camera = Camera(eye, look, up, fov, "y")
    lights = studio_lights(points, camera)
    load = getattr(model, "load", None)
    if load is not None:
        load = dataclasses.replace(load, framing_seconds=time.perf_counter() - clock)
    materials = [MODEL_MATERIAL]
    colored = _colour_materials(model, materials, MODEL_MATERIAL, "") or [None] * len(model.surfaces)
    flips = model.reversed or [False] * len(model.surfaces)
    surfaces = tuple(
        SceneSurface(g, 0 if c is None else c, n, f) for g, n, c, f in zip(model.surfaces, model.names, colored, flips)
    )
    notes = tuple(f"{model.path}: {w}" for w in model.warnings) + tuple(_skipped_notes(model))
    return Scene(
        Film(width, height),
        camera,
        RenderSettings(),
        tuple(materials),
        lights,
        surfaces,
        str(model.path),
        notes,
        (str(model.path),),
        loads=(load,) if load is not None else (),
    )
