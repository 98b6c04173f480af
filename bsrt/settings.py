"""Render settings, resolved once at the edge.

The one list of methods and map modes lives here. ``RenderOptions`` is built
by the CLI, the preview window and the Python API (scene values, then the
caller's overrides, every override validated) and passed to ``render()``;
nothing downstream re-reads the scene's [render] table or re-checks a name.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from . import validate
from .camera import Camera
from .errors import InputError

MAP_METHODS = ("gradient", "fast", "newton")  # seeded by the preliminary map
METHODS = MAP_METHODS + ("martin",)  # "martin": the hierarchy for every ray, no map
MAP_MODES = ("float", "rgba8")


@dataclass(frozen=True)
class RenderOptions:
    """Everything a render needs besides the scene's geometry, lights and materials.

    method: one of METHODS. map: one of MAP_MODES. tolerance: largest
    ray-surface distance of a hit as a fraction of the scene diagonal.
    max_iterations: per pixel and start. spp: samples per pixel.
    max_depth: mirror bounces. width, height: film size in pixels.
    camera: the camera to render from.
    """

    method: str
    map: str
    tolerance: float
    max_iterations: int
    spp: int
    max_depth: int
    width: int
    height: int
    camera: Camera

    @property
    def uses_map(self) -> bool:
        return self.method in MAP_METHODS

    @classmethod
    def resolve(cls, scene, **overrides) -> "RenderOptions":
        """The scene's settings with ``overrides`` (None values are ignored) applied.

        Keys: the field names (``map_mode`` is accepted for ``map``). An
        explicit width, height or spp of 0 is an error, not "the default".
        """
        if "map_mode" in overrides:
            overrides["map"] = overrides.pop("map_mode")
        r = scene.render
        base = cls(method=r.method, map=r.map, tolerance=r.tolerance, max_iterations=r.max_iterations, spp=r.spp,
                   max_depth=r.max_depth, width=scene.film.width, height=scene.film.height, camera=scene.camera)
        unknown = set(overrides) - set(cls.__dataclass_fields__)
        if unknown:
            raise TypeError(f"unknown render option {sorted(unknown)[0]!r}")
        options = replace(base, **{k: v for k, v in overrides.items() if v is not None}).checked()
        return options.check_tolerance(scene)

    def checked(self) -> "RenderOptions":
        """Every value's type and range (the README's Limits), the camera's frame and the film's memory."""
        if self.method not in METHODS:
            raise InputError(f"method: expected one of {', '.join(METHODS)}, got {self.method!r}")
        if self.map not in MAP_MODES:
            raise InputError(f"map: expected one of {', '.join(MAP_MODES)}, got {self.map!r}")
        validate.whole("width", self.width, 1, validate.MAX_FILM_SIDE)
        validate.whole("height", self.height, 1, validate.MAX_FILM_SIDE)
        validate.whole("spp", self.spp, 1, validate.MAX_SPP)
        validate.whole("max_iterations", self.max_iterations, 1, validate.MAX_ITERATIONS)
        validate.whole("max_depth", self.max_depth, 0, validate.MAX_DEPTH)
        validate.real("tolerance", self.tolerance, 0.0, 1.0, lo_open=True, expected="a number in (0, 1]")
        validate.camera(self.camera)
        validate.film(self.width, self.height)
        validate.environment()
        return self

    def check_tolerance(self, scene) -> "RenderOptions":
        """A tolerance float64 can resolve at the scene's size, seen from the camera (never silently
        degraded): else an InputError naming the key and the smallest usable value."""
        smallest = validate.smallest_tolerance([s.geometry for s in scene.surfaces], self.camera.eye)
        if smallest > 1.0:
            raise InputError(f"{scene.path}: camera.eye: float64 cannot resolve this scene from so far away (or so far "
                             f"from the origin): even tolerance = 1 is below what it resolves; bring the eye and "
                             f"the scene nearer each other and the origin")
        if self.tolerance < smallest:
            raise InputError(f"{scene.path}: render.tolerance: {self.tolerance:g} is below what float64 resolves "
                             f"at this scene's size and distance; the smallest usable value is {smallest:.2g}")
        geometry = [s.geometry for s in scene.surfaces]
        worst = validate.smallest_tolerance_of_high_degrees(geometry, [s.name for s in scene.surfaces],
                                                           validate.diagonal(geometry))
        if worst is not None and worst[0] > 1.0:
            raise InputError(f"{scene.path}: surface {worst[1]!r} of degree {worst[2]}: bsrt's power-basis evaluation "
                             f"is off by {worst[0] / 4:.2g} of the scene's size at this degree, so it cannot be "
                             f"rendered (see the README's Limits)")
        if worst is not None and self.tolerance < worst[0]:
            raise InputError(f"{scene.path}: render.tolerance: {self.tolerance:g} is below what float64 resolves on "
                             f"surface {worst[1]!r} of degree {worst[2]} (its power-basis evaluation is off by "
                             f"{worst[0] / 4:.2g} of the scene's size); the smallest usable value is {worst[0]:.2g}")
        return self
