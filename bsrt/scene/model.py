"""The scene model: frozen dataclasses, what a scene file or a Python build becomes.

``Film`` and ``RenderSettings`` are generated from the settings registry
(bsrt/settings.py); the rest is declared here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from bsrt.geometry.bspline import BSplineSurface
from bsrt.scene.camera import Camera
from bsrt.settings import Film, RenderSettings

__all__ = ["DEFAULT_MATERIAL", "MODEL_MATERIAL", "Film", "Light", "Material", "RenderSettings", "Scene", "SceneSurface"]


@dataclass(frozen=True)
class Material:
    name: str
    color: tuple[float, float, float] = (0.8, 0.8, 0.8)  # linear RGB albedo
    specular: float = 0.2
    shininess: float = 32.0
    reflectance: float = 0.0


@dataclass(frozen=True)
class Light:
    """kind: "point" (position, inverse-square falloff), "directional"
    (direction the light travels) or "ambient"; color * intensity is the
    light's linear RGB strength."""

    kind: str
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    position: tuple[float, float, float] | None = None
    direction: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class SceneSurface:
    """A surface in world space (transform applied), its material index and name. reversed: its
    outward normal is -(S_u x S_v) (a REVERSED B-rep face: bsrt.io.Model.reversed)."""

    geometry: BSplineSurface
    material: int
    name: str
    reversed: bool = False


@dataclass(frozen=True)
class Scene:
    film: Film
    camera: Camera
    render: RenderSettings
    materials: tuple[Material, ...]
    lights: tuple[Light, ...]
    surfaces: tuple[SceneSurface, ...]
    path: str = "<scene>"
    notes: tuple[str, ...] = field(default=())  # warnings from imports
    inputs: tuple[str, ...] = field(default=())  # the files read: the scene file, then its imports
    keyframes: tuple = field(default=())  # [[camera.keyframe]] for bsrt animate (bsrt/scene/keyframes.py)
    # how each model file was loaded (bsrt.io.LoadRecord: time, cache): --stats' "load"; not part of equality
    loads: tuple = field(default=(), compare=False)


DEFAULT_MATERIAL = Material("default")
MODEL_MATERIAL = Material("model", color=(0.72, 0.70, 0.66), specular=0.3, shininess=48.0)
