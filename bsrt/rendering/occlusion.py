"""Ambient occlusion (``--ao``) and the ground plane (``--ground``), both with exact rays.

* :func:`with_ground`: the scene with one more surface, a flat bilinear B-spline square under
  the model (GROUND_GAP model radii under the lowest point of what it shows along the camera's
  up, GROUND_SIZE model radii across, a light grey material). It is traced, shadowed and
  mirrored like any other surface, so the lights' shadows fall on it.
* :func:`occlusion`: per hit point, the fraction of AO_RAYS cosine-weighted directions over its
  normal's hemisphere that leave without meeting a surface within AO_RANGE model radii
  (any-hit rays through the hierarchy, the secondary rays of shadows; stratified, turned by a
  fixed per-point angle so that neighbours do not share directions).

The shader uses it so: with ``ao``, the ambient lights' part of a point's colour is
multiplied by its openness; the ground's whole colour is multiplied by its openness (the
contact shadow under the model), with or without ``ao``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bsrt.geometry.bspline import make_surface
from bsrt.scene.model import Material, SceneSurface

AO_RAYS = 16  # per hit point (per sample: with spp 4, 64 a pixel)
AO_RANGE = 0.5  # model radii: occluders farther than this do not darken
GROUND_SIZE = 24.0  # model radii across
GROUND_GAP = 1e-4  # model radii under the model's lowest point: a floor of the model's own hides the ground there
GROUND_MATERIAL = Material("ground", color=(0.8, 0.8, 0.8), specular=0.05, shininess=8.0)
GROUND_NAME = "ground"


def with_ground(scene) -> tuple:
    """(the scene with the ground plane as its last surface, the model's radius (its box's
    half diagonal, from points on the surfaces))."""
    from bsrt.scene.auto import surface_points

    points = surface_points([s.geometry for s in scene.surfaces])
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, radius = (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-300)
    up = np.asarray(scene.camera.up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    x = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(up, x)
    base = centre + up * (float(np.min((points - centre) @ up)) - GROUND_GAP * radius)  # under its lowest point
    half = GROUND_SIZE * radius / 2.0
    corners = [[base + sx * half * x + sy * half * y for sy in (-1.0, 1.0)] for sx in (-1.0, 1.0)]
    plane = make_surface((1, 1), [0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0], np.array(corners))
    materials = scene.materials + (GROUND_MATERIAL,)
    surface = SceneSurface(plane, len(materials) - 1, GROUND_NAME)
    return replace(scene, materials=materials, surfaces=scene.surfaces + (surface,)), radius


def hemisphere_directions(normal: np.ndarray, rays: int = AO_RAYS, number=None) -> np.ndarray:
    """(K, rays, 3) unit directions, cosine-weighted over each unit normal's (K, 3) hemisphere:
    a stratified rows x columns grid of the unit square mapped by Malley's method, turned
    about the normal by a fixed angle per point (the golden ratio's multiples of its number:
    number (K,) int, default 0..K-1)."""
    k = normal.shape[0]
    columns = int(np.sqrt(rays))
    rows = rays // columns
    a = (np.arange(rays) % columns + 0.5) / columns
    b = (np.arange(rays) // columns % rows + 0.5) / rows
    r, phi = np.sqrt(a), 2.0 * np.pi * b
    number = np.arange(k) if number is None else np.asarray(number)
    turn = (number * 0.6180339887498949 % 1.0) * 2.0 * np.pi
    angle = phi[None, :] + turn[:, None]  # (K, rays)
    lx, ly, lz = r[None, :] * np.cos(angle), r[None, :] * np.sin(angle), np.sqrt(np.maximum(0.0, 1.0 - a))[None, :]
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(normal, helper)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    s = np.cross(normal, t)
    return lx[..., None] * t[:, None, :] + ly[..., None] * s[:, None, :] + lz[..., None] * normal[:, None, :]


def occlusion(trace, position: np.ndarray, normal: np.ndarray, exclude, reach: float, number=None) -> np.ndarray:
    """(K,) float64 openness in [0, 1] of K points (position, unit normal: (K, 3)): the fraction of
    hemisphere_directions whose any-hit ray meets nothing within ``reach`` (scene units).
    trace(origins, directions, exclude, t_max, any_hit) is the shader's secondary tracer;
    exclude: the points' own parameter boxes (tuples of (K,) arrays), repeated per ray;
    number: (K,) int, each point's number in its render call (its directions' turn), default 0..K-1."""
    k = position.shape[0]
    if not k:
        return np.ones(0)
    directions = hemisphere_directions(normal, number=number).reshape(-1, 3)
    origins = np.repeat(position, AO_RAYS, axis=0)
    repeated = tuple(np.repeat(a, AO_RAYS) for a in exclude)
    blocked = trace(origins, directions, repeated, reach, True).hit.reshape(k, AO_RAYS)
    return 1.0 - blocked.mean(axis=1)
