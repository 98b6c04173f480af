"""Pinhole camera: pixel-centre rays and the matching OpenGL matrix.

Both follow the one formula of the scene format (row 0 at the top, column 0
at the left), so map pixel (i, j) rasterised by OpenGL sees exactly the ray
of pixel (i, j): the GL viewport's pixel centre (j + 0.5, H - 1 - i + 0.5)
maps through ``clip_from_eye`` to the same normalised (x, y) as the ray.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Camera:
    """eye, look_at, up: (3,) float64; fov in degrees (full angle) along fov_axis ("x" or "y")."""

    eye: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float = 40.0
    fov_axis: str = "y"

    def basis(self):
        """(right, up, forward), each (3,) unit float64; right-handed, forward = view direction."""
        f = self.look_at - self.eye
        f = f / np.linalg.norm(f)
        r = np.cross(f, self.up)
        r = r / np.linalg.norm(r)
        return r, np.cross(r, f), f

    def half_extents(self, width: int, height: int) -> tuple[float, float]:
        """(tx, ty): tangents of the half field of view in x and y."""
        aspect = width / height
        ty = np.tan(np.radians(self.fov) / 2.0)
        if self.fov_axis == "x":
            ty /= aspect
        return ty * aspect, ty


def pixel_footprint(camera: Camera, width: int, height: int) -> float:
    """Size of a pixel at unit distance from the eye (scene units per unit distance)."""
    _, ty = camera.half_extents(width, height)
    return 2.0 * ty / height


def pixel_rays(camera: Camera, width: int, height: int, rows=None):
    """Unit directions through the centre of each pixel, row-major.

    rows: (first, stop) to get only the film rows first..stop-1 (a band of a
    tiled render); default all. Returns (n_rows * width, 3) float64; every
    ray starts at camera.eye.
    """
    first, stop = rows if rows is not None else (0, height)
    r, u, f = camera.basis()
    tx, ty = camera.half_extents(width, height)
    x = (2.0 * (np.arange(width) + 0.5) / width - 1.0) * tx
    y = (1.0 - 2.0 * (np.arange(first, stop) + 0.5) / height) * ty
    d = f[None, None, :] + x[None, :, None] * r[None, None, :] + y[:, None, None] * u[None, None, :]
    d = d.reshape(-1, 3)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def clip_from_eye(camera: Camera, width: int, height: int, near: float, far: float, rows=None) -> np.ndarray:
    """(4, 4) float64 projection of eye-relative world points (p - eye) to clip space.

    rows: (first, stop) film rows: the viewport then holds only that band
    (an off-centre projection), so a tiled map sees exactly the rays of
    pixel_rays(..., rows). Vertices are sent eye-relative so float32 keeps
    precision far from the origin. The GL image comes out bottom row first:
    flip it to row 0 = top.
    """
    r, u, f = camera.basis()
    tx, ty = camera.half_extents(width, height)
    camera_from_eye = np.eye(4)
    camera_from_eye[0, :3], camera_from_eye[1, :3], camera_from_eye[2, :3] = r, u, f
    a = (far + near) / (far - near)
    b = -2.0 * far * near / (far - near)
    clip_from_camera = np.array(
        [[1.0 / tx, 0, 0, 0], [0, 1.0 / ty, 0, 0], [0, 0, a, b], [0, 0, 1.0, 0]]
    )
    if rows is not None:
        top, bottom = 1.0 - 2.0 * rows[0] / height, 1.0 - 2.0 * rows[1] / height
        centre, half = (top + bottom) / 2.0, (top - bottom) / 2.0
        clip_from_camera[1] = (clip_from_camera[1] - centre * clip_from_camera[3]) / half
    return clip_from_camera @ camera_from_eye
