"""``RenderOptions``: the settings of one render, resolved once at the edge.

One field per setting of the registry (bsrt/settings.py) and the camera; the
CLI, the preview, batches and the Python API resolve it (the scene's values,
then the caller's overrides, every value checked) and pass it to
:func:`bsrt.rendering.pipeline.render`.
"""

from __future__ import annotations

from dataclasses import make_dataclass

from bsrt import validate
from bsrt.errors import InputError
from bsrt.methods import MAP_METHODS
from bsrt.scene.camera import Camera
from bsrt.settings import SETTINGS, checked_overrides


def _options_class() -> type:
    cls = make_dataclass(
        "RenderOptions",
        [(s.name, s.python_type) for s in SETTINGS] + [("camera", Camera)],
        frozen=True,
        namespace=dict(_OPTIONS_METHODS),
    )
    cls.__module__ = __name__
    cls.__doc__ = (
        "Everything a render needs besides the scene's geometry, lights and materials: one field per "
        "setting of SETTINGS, and camera (the camera to render from).\n\n"
        + "\n".join(f"{s.name}: {s.describe()}" for s in SETTINGS)
    )
    return cls


def _uses_map(self) -> bool:
    """Whether the method is seeded by the preliminary map (every method but "martin")."""
    return self.method in MAP_METHODS


def _resolve(cls, scene, **overrides):
    """The scene's settings with ``overrides`` (None values are ignored) applied, every value checked.

    Keys: the settings' names, and camera. An explicit width, height or spp of 0 is an error,
    not "the default"."""
    base = {s.name: getattr(getattr(scene, s.table), s.name) for s in SETTINGS}
    camera = overrides.pop("camera", None) or scene.camera
    values = {**base, **checked_overrides(overrides)}
    return cls(**values, camera=camera).checked().check_tolerance(scene)


def _checked(self):
    """Every value's type and range (the docs' Limits), the camera's frame and the film's memory."""
    for s in SETTINGS:
        s.check(getattr(self, s.name))
    validate.camera(self.camera)
    validate.film(self.width, self.height)
    validate.environment()
    return self


def _check_tolerance(self, scene):
    """A tolerance float64 can resolve at the scene's size, seen from the camera (never silently
    degraded): else an InputError naming the key and the smallest usable value."""
    smallest = validate.smallest_tolerance([s.geometry for s in scene.surfaces], self.camera.eye)
    if smallest > 1.0:
        raise InputError(
            f"{scene.path}: camera.eye: float64 cannot resolve this scene from so far away (or so far "
            f"from the origin): even tolerance = 1 is below what it resolves; bring the eye and "
            f"the scene nearer each other and the origin"
        )
    if self.tolerance < smallest:
        raise InputError(
            f"{scene.path}: render.tolerance: {self.tolerance:g} is below what float64 resolves "
            f"at this scene's size and distance; the smallest usable value is {smallest:.2g}"
        )
    geometry = [s.geometry for s in scene.surfaces]
    worst = validate.smallest_tolerance_of_high_degrees(
        geometry, [s.name for s in scene.surfaces], validate.diagonal(geometry)
    )
    if worst is not None and worst[0] > 1.0:
        raise InputError(
            f"{scene.path}: surface {worst[1]!r} of degree {worst[2]}: bsrt's power-basis evaluation "
            f"is off by {worst[0] / 4:.2g} of the scene's size at this degree, so it cannot be "
            f"rendered (see the docs' Limits)"
        )
    if worst is not None and self.tolerance < worst[0]:
        raise InputError(
            f"{scene.path}: render.tolerance: {self.tolerance:g} is below what float64 resolves on "
            f"surface {worst[1]!r} of degree {worst[2]} (its power-basis evaluation is off by "
            f"{worst[0] / 4:.2g} of the scene's size); the smallest usable value is {worst[0]:.2g}"
        )
    return self


_OPTIONS_METHODS = {
    "uses_map": property(_uses_map),
    "resolve": classmethod(_resolve),
    "checked": _checked,
    "check_tolerance": _check_tolerance,
}
RenderOptions = _options_class()
