"""Colour from hits: exact normals, and the lights as the shading kernels take them. Linear RGB.

The per-hit loops are compiled: frames (``kernels/shading.py``), and the
whole lighting pass with its shadow rays (``kernels/lighting.py``, driven by
rendering/pipeline.py); this module turns a scene's lights into their arrays.
"""

from __future__ import annotations

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.shading import LIGHT_KINDS, frames_many
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.hits import Hits


def facing_frames(patches: PatchSet, hits: Hits, directions: np.ndarray):
    """Position and unit normal (K, 3) of each hit, the normal facing the ray's
    origin, NaN where no hit, and |S_u|, |S_v| (K, 2) (scene units per unit of
    u, v). directions: (K, 3) the rays that found the hits. Where S_u x S_v
    vanishes (a pole, a collapsed edge) the limit normal is taken a small
    step toward the patch centre, so no NaN reaches the image."""
    n = len(hits)
    position, normal, speed = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2))
    run_chunks(
        frames_many,
        n,
        patches.arrays,
        np.ascontiguousarray(hits.hit),
        np.ascontiguousarray(hits.patch),
        np.ascontiguousarray(hits.u),
        np.ascontiguousarray(hits.v),
        np.ascontiguousarray(directions, dtype=np.float64),
        position,
        normal,
        speed,
    )
    return position, normal, speed


def light_arrays(lights):
    """The kernels' view of a scene's lights (L of them): kind (L,) int64 (LIGHT_KINDS),
    position (L, 3) (point lights; 0 for others), direction (L, 3) (directional lights: the unit
    direction toward the light; 0 for others), strength (L, 3) = colour x intensity."""
    kind = np.array([LIGHT_KINDS[light.kind] for light in lights], dtype=np.int64)
    light_pos = np.array([light.position or (0.0, 0.0, 0.0) for light in lights], dtype=np.float64).reshape(-1, 3)
    light_dir = np.zeros((len(lights), 3))
    for j, light in enumerate(lights):
        if light.kind == "directional":
            light_dir[j] = -np.array(light.direction) / np.linalg.norm(light.direction)
    strength = np.array([np.array(light.color) * light.intensity for light in lights], dtype=np.float64).reshape(-1, 3)
    return kind, light_pos, light_dir, strength
