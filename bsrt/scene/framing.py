"""A scene for a model file alone: the automatic camera, lights and material."""

from __future__ import annotations

import numpy as np

from bsrt import validate
from bsrt.errors import InputError
from bsrt.scene.camera import Camera
from bsrt.scene.model import MODEL_MATERIAL, Film, Light, RenderSettings, Scene, SceneSurface
from bsrt.scene.parse import _colour_materials, _skipped_notes


def model_box(surfaces) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners (3,) of what the surfaces show.

    An untrimmed surface counts with its control points (its hull holds it);
    a trimmed one with the kept points of a 64 x 64 grid over its domain and
    the points of its trim curves, so a model whose faces are small pieces of
    large surfaces is framed by its faces. The grids are evaluated as tensor
    products and the trims of all surfaces tested in one table (a 2,046-face
    part: 13 s when each point was evaluated and each surface's table built
    alone).
    """
    from bsrt.geometry.bspline import evaluate, grid_points
    from bsrt.geometry.trim import build_trim_table
    from bsrt.kernels.trim import kept_many

    trimmed = [surf for surf in surfaces if surf.is_trimmed]
    parts = [surf.points.reshape(-1, 3) for surf in surfaces if not surf.is_trimmed]
    if trimmed:
        grids = [(np.linspace(*surf.domain_u, 64), np.linspace(*surf.domain_v, 64)) for surf in trimmed]
        u = np.concatenate([np.repeat(gu, gv.size) for gu, gv in grids])
        v = np.concatenate([np.tile(gv, gu.size) for gu, gv in grids])
        sizes = [gu.size * gv.size for gu, gv in grids]
        keep = kept_many(build_trim_table(trimmed), np.repeat(np.arange(len(trimmed)), sizes), u, v)
        starts = np.cumsum([0] + sizes)
        for m, (surf, (gu, gv)) in enumerate(zip(trimmed, grids)):
            parts.append(grid_points(surf, gu, gv).reshape(-1, 3)[keep[starts[m] : starts[m + 1]]])
            uv = np.concatenate([c.evaluate(np.linspace(*c.domain, 33)) for loop in surf.trims for c in loop.curves])
            (u0, u1), (v0, v1) = surf.domain_u, surf.domain_v
            parts.append(evaluate(surf, np.clip(uv[:, 0], u0, u1), np.clip(uv[:, 1], v0, v1))[0])
    pts = np.concatenate(parts)
    return pts.min(axis=0), pts.max(axis=0)


def scene_for_model(model, width=512, height=512, eye=None, look_at=None, fov=None, up=(0.0, 0.0, 1.0)) -> Scene:
    """A scene that shows a model file with no scene file.

    The camera frames the model's box (``model_box``: trimmed surfaces by
    their kept parts) from a three-quarter view above (``up`` is +z unless given): the box's
    bounding sphere fills the narrower field of view. A key point light
    (above and behind the camera, as bright as 1 at the model), a dimmer
    directional fill and a little ambient light; one neutral material.
    eye / look_at / fov override the automatic choice.
    """
    if fov is not None:
        validate.fov(fov, "--fov")
    lo, hi = model_box(model.surfaces)
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-9)
    fov = 35.0 if fov is None else float(fov)
    look = centre if look_at is None else np.asarray(look_at, dtype=np.float64)
    up = np.asarray(up, dtype=np.float64)
    if np.linalg.norm(up) == 0:
        raise InputError("--camera-up: must not be the zero vector")
    automatic = eye is None
    if eye is None:  # three-quarter view from above, relative to "up"
        half = np.radians(fov) / 2.0 * min(1.0, width / height)
        zup = up / np.linalg.norm(up)
        side = np.cross(zup, [1.0, 0.0, 0.0] if abs(zup[0]) < 0.9 else [0.0, 1.0, 0.0])
        side /= np.linalg.norm(side)
        front = np.cross(side, zup)
        direction = 0.55 * side - 0.75 * front + 0.42 * zup
        eye = look + direction / np.linalg.norm(direction) * radius / np.sin(half) * 1.05
    eye = np.asarray(eye, dtype=np.float64)
    view = look - eye
    if np.linalg.norm(view) == 0 or np.linalg.norm(np.cross(view, up)) < 1e-9 * np.linalg.norm(view):
        raise InputError(
            "--camera-eye / --camera-look-at / --camera-up: the view direction must not be zero or parallel to up"
        )
    try:
        validate.camera(Camera(eye, look, up, fov, "y"))
    except InputError as exc:  # the automatic eye of a model near the coordinate limit
        raise InputError(f"{model.path}: {'the automatic ' if automatic else ''}{exc}") from None
    key_pos = centre + (eye - look) / np.linalg.norm(eye - look) * 2.5 * radius + up / np.linalg.norm(up) * 2.0 * radius
    lights = (
        Light("ambient", intensity=0.12),
        Light(
            "point", color=(1.0, 0.97, 0.92), intensity=float(np.sum((key_pos - centre) ** 2)), position=tuple(key_pos)
        ),
        Light("directional", color=(0.8, 0.85, 1.0), intensity=0.35, direction=(-1.0, 0.8, -0.6)),
    )
    materials = [MODEL_MATERIAL]
    colored = _colour_materials(model, materials, MODEL_MATERIAL, "") or [None] * len(model.surfaces)
    flips = model.reversed or [False] * len(model.surfaces)
    surfaces = tuple(
        SceneSurface(g, 0 if c is None else c, n, f) for g, n, c, f in zip(model.surfaces, model.names, colored, flips)
    )
    notes = tuple(f"{model.path}: {w}" for w in model.warnings) + tuple(_skipped_notes(model))
    return Scene(
        Film(width, height),
        Camera(eye, look, up, fov, "y"),
        RenderSettings(),
        tuple(materials),
        lights,
        surfaces,
        str(model.path),
        notes,
        (str(model.path),),
        loads=(model.load,) if getattr(model, "load", None) is not None else (),
    )
