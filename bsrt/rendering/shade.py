"""Colour from hits: exact normals and Blinn-Phong lighting. Linear RGB.

The per-hit loops are compiled (``kernels/shading.py``); this module turns a
scene's materials and lights into the kernels' arrays.
"""

from __future__ import annotations

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.shading import LIGHT_KINDS, blinn_phong, frames_many
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.hits import Hits
from bsrt.scene import Scene


def facing_frames(patches: PatchSet, hits: Hits, directions: np.ndarray):
    """Position and unit normal (K, 3) of each hit, the normal facing the ray's
    origin, NaN where no hit, and |S_u|, |S_v| (K, 2) (scene units per unit of
    u, v). directions: (K, 3) the rays that found the hits. Where S_u x S_v
    vanishes (a pole, a collapsed edge) the limit normal is taken a small
    step toward the patch centre, so no NaN reaches the image."""
    n = len(hits)
    position, normal, speed = np.full((n, 3), np.nan), np.full((n, 3), np.nan), np.full((n, 2), np.nan)
    hit = np.flatnonzero(hits.hit)
    if hit.size:
        pos, nrm, spd = np.empty((hit.size, 3)), np.empty((hit.size, 3)), np.empty((hit.size, 2))
        run_chunks(
            frames_many,
            hit.size,
            patches.arrays,
            hits.patch[hit],
            hits.u[hit],
            hits.v[hit],
            np.ascontiguousarray(directions[hit], dtype=np.float64),
            pos,
            nrm,
            spd,
        )
        position[hit], normal[hit], speed[hit] = pos, nrm, spd
    return position, normal, speed


def light_directions(light, position: np.ndarray):
    """Unit directions (K, 3) from each point toward the light, distances (K,) (inf if directional)."""
    if light.kind == "point":
        to_light = np.array(light.position) - position
        dist = np.linalg.norm(to_light, axis=1)
        return to_light / np.maximum(dist, 1e-300)[:, None], dist
    d = np.array(light.direction)
    return np.broadcast_to(-d / np.linalg.norm(d), position.shape), np.full(position.shape[0], np.inf)


def shade(
    scene: Scene,
    position: np.ndarray,
    normal: np.ndarray,
    view: np.ndarray,
    material: np.ndarray,
    visibility: np.ndarray | None = None,
) -> np.ndarray:
    """Blinn-Phong radiance toward the viewer.

    position, normal: (K, 3) (normal unit, facing the viewer); view: (K, 3)
    unit directions from the viewer to the point; material: (K,) int index
    into scene.materials; visibility: (K, L) float, 1 where light L reaches
    the point (0 in its shadow), None for all lit. Point lights fall off with
    the inverse square of the distance. Returns (K, 3) float64 linear RGB.
    """
    k, lights = position.shape[0], scene.lights
    kind = np.array([LIGHT_KINDS[light.kind] for light in lights], dtype=np.int64)
    light_pos = np.array([light.position or (0.0, 0.0, 0.0) for light in lights], dtype=np.float64).reshape(-1, 3)
    light_dir = np.zeros((len(lights), 3))
    for j, light in enumerate(lights):
        if light.kind == "directional":
            light_dir[j] = -np.array(light.direction) / np.linalg.norm(light.direction)
    strength = np.array([np.array(light.color) * light.intensity for light in lights], dtype=np.float64).reshape(-1, 3)
    if visibility is None:
        visibility = np.ones((k, len(lights)))
    out = np.empty((k, 3))
    mats = scene.materials
    blinn_phong(
        np.ascontiguousarray(position, dtype=np.float64),
        np.ascontiguousarray(normal, dtype=np.float64),
        np.ascontiguousarray(view, dtype=np.float64),
        np.ascontiguousarray(material, dtype=np.int64),
        np.array([m.color for m in mats], dtype=np.float64),
        np.array([m.specular for m in mats], dtype=np.float64),
        np.array([m.shininess for m in mats], dtype=np.float64),
        kind,
        light_pos,
        light_dir,
        strength,
        np.ascontiguousarray(visibility, dtype=np.float64),
        out,
    )
    return out
