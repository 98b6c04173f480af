"""Render settings, resolved once at the edge.

The one list of methods and map modes lives here. ``RenderOptions`` is built
by the CLI, the preview window and the Python API (scene values, then the
caller's overrides, every override validated) and passed to ``render()``;
nothing downstream re-reads the scene's [render] table or re-checks a name.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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
        return replace(base, **{k: v for k, v in overrides.items() if v is not None}).checked()

    def checked(self) -> "RenderOptions":
        if self.method not in METHODS:
            raise InputError(f"method: expected one of {', '.join(METHODS)}, got {self.method!r}")
        if self.map not in MAP_MODES:
            raise InputError(f"map: expected one of {', '.join(MAP_MODES)}, got {self.map!r}")
        for key in ("width", "height", "spp", "max_iterations"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(f"{key}: expected a whole number >= 1, got {value!r}")
        if isinstance(self.max_depth, bool) or not isinstance(self.max_depth, int) or self.max_depth < 0:
            raise InputError(f"max_depth: expected a whole number >= 0, got {self.max_depth!r}")
        if not 0.0 < self.tolerance <= 1.0:
            raise InputError(f"tolerance: expected a number in (0, 1], got {self.tolerance!r}")
        return self
