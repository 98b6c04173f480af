"""Colour from hits: exact normals and Blinn-Phong lighting. Linear RGB."""

from __future__ import annotations

import numpy as np

from .hits import Hits
from .patches import PatchSet
from .scene import Scene


def surface_frames(patches: PatchSet, hits: Hits, index: np.ndarray):
    """Position and unit normal at the hits ``index`` (K,).

    Returns (position (K, 3), normal (K, 3), speed (K, 2)) float64, speed
    being |S_u|, |S_v| (scene units per unit of u, v). The normal is
    S_u x S_v normalised; where it vanishes (a pole or collapsed edge, a
    repeated control point) the limit normal is taken a step of 1e-7 of the
    patch size toward the patch centre, so no NaN reaches the image.
    """
    patch, u, v = hits.patch[index], hits.u[index], hits.v[index]
    S, Su, Sv = patches.evaluate(patch, u, v)
    speed = np.stack([np.linalg.norm(Su, axis=0), np.linalg.norm(Sv, axis=0)], axis=1)
    n = np.cross(Su.T, Sv.T)
    length = np.linalg.norm(n, axis=1)
    scale = speed[:, 0] * speed[:, 1]
    bad = ~(length > 1e-12 * scale) | ~np.isfinite(length)
    for step in (1e-7, 1e-5, 1e-3):
        if not np.any(bad):
            break
        b = patches.bounds[patch[bad]]
        cu, cv = 0.5 * (b[:, 0] + b[:, 1]), 0.5 * (b[:, 2] + b[:, 3])
        uu = u[bad] + step * (cu - u[bad]) * 2.0
        vv = v[bad] + step * (cv - v[bad]) * 2.0
        _, su, sv = patches.evaluate(patch[bad], uu, vv)
        nb = np.cross(su.T, sv.T)
        n[bad] = nb
        length[bad] = np.linalg.norm(nb, axis=1)
        bad = ~(length > 0) | ~np.isfinite(length)
    length[bad] = 1.0
    n = n / length[:, None]
    n[bad] = 0.0
    return S.T, n, speed


def facing_frames(patches: PatchSet, hits: Hits, directions: np.ndarray):
    """Position and viewer-facing unit normal (K, 3) of each hit, NaN where no hit,
    and |S_u|, |S_v| (K, 2); directions: (K, 3) the rays that found the hits."""
    position = np.full((len(hits), 3), np.nan)
    normal = np.full((len(hits), 3), np.nan)
    speed = np.full((len(hits), 2), np.nan)
    hit = np.flatnonzero(hits.hit)
    if hit.size:
        pos, nrm, speed[hit] = surface_frames(patches, hits, hit)
        flip = np.einsum("ij,ij->i", nrm, directions[hit]) > 0
        nrm[flip] *= -1.0
        position[hit], normal[hit] = pos, nrm
    return position, normal, speed


def light_directions(light, position: np.ndarray):
    """Unit directions (K, 3) from each point toward the light, distances (K,) (inf if directional)."""
    if light.kind == "point":
        to_light = np.array(light.position) - position
        dist = np.linalg.norm(to_light, axis=1)
        return to_light / np.maximum(dist, 1e-300)[:, None], dist
    d = np.array(light.direction)
    return np.broadcast_to(-d / np.linalg.norm(d), position.shape), np.full(position.shape[0], np.inf)


def shade(scene: Scene, position: np.ndarray, normal: np.ndarray, view: np.ndarray, material: np.ndarray,
          visibility: np.ndarray | None = None) -> np.ndarray:
    """Blinn-Phong radiance toward the viewer.

    position, normal: (K, 3) (normal unit, facing the viewer); view: (K, 3)
    unit directions from the viewer to the point; material: (K,) int index
    into scene.materials; visibility: (K, L) float, 1 where light L reaches
    the point (0 in its shadow), None for all lit. Point lights fall off with
    the inverse square of the distance. Returns (K, 3) float64 linear RGB.
    """
    albedo = np.array([m.color for m in scene.materials])[material]
    spec = np.array([m.specular for m in scene.materials])[material][:, None]
    shininess = np.array([m.shininess for m in scene.materials])[material][:, None]
    out = np.zeros_like(position)
    to_eye = -view
    for index, light in enumerate(scene.lights):
        strength = np.array(light.color) * light.intensity
        if light.kind == "ambient":
            out += albedo * strength
            continue
        to_light, dist = light_directions(light, position)
        falloff = 1.0 / (dist * dist) if light.kind == "point" else np.ones(position.shape[0])
        if visibility is not None:
            falloff = falloff * visibility[:, index]
        cos_l = np.einsum("ij,ij->i", normal, to_light)
        lit = cos_l > 0
        half = to_light + to_eye
        half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-300)
        cos_h = np.clip(np.einsum("ij,ij->i", normal, half), 0.0, 1.0)[:, None]
        term = albedo * np.maximum(cos_l, 0.0)[:, None] + spec * cos_h**shininess
        out += np.where(lit[:, None], term, 0.0) * strength * falloff[:, None]
    return out
