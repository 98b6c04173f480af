"""The scene: what a scene file (or a Python build, or a model file alone) becomes.

- model.py: the frozen dataclasses (``Scene``, ``SceneSurface``, ``Material``,
  ``Light``; ``Film`` and ``RenderSettings`` from the settings registry);
- tables.py: typed access to a TOML table, errors naming file, table and key;
- parse.py: scene files (``load_scene``, ``parse_scene``);
- keyframes.py: ``[[camera.keyframe]]``;
- camera.py: the pinhole camera, pixel rays, orbit / pan / zoom;
- framing.py: the automatic scene of a model file (camera fitting, lights);
- loading.py: a scene or a model file, with the command line's camera overrides;
- document.py, writer.py: Python objects into a scene document, and a scene
  back into a scene file (the one writer).
"""

from bsrt.scene.framing import model_box, scene_for_model
from bsrt.scene.model import (
    DEFAULT_MATERIAL,
    MODEL_MATERIAL,
    Film,
    Light,
    Material,
    RenderSettings,
    Scene,
    SceneSurface,
)
from bsrt.scene.parse import load_scene, parse_scene

__all__ = [
    "DEFAULT_MATERIAL",
    "MODEL_MATERIAL",
    "Film",
    "Light",
    "Material",
    "RenderSettings",
    "Scene",
    "SceneSurface",
    "load_scene",
    "model_box",
    "parse_scene",
    "scene_for_model",
]
