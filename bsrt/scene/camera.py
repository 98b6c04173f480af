"""Pinhole camera: pixel-centre rays and the matching OpenGL matrix.

Both follow the one formula of the scene format (row 0 at the top, column 0
at the left), so map pixel (i, j) rasterised by OpenGL sees exactly the ray
of pixel (i, j): the GL viewport's pixel centre (j + 0.5, H - 1 - i + 0.5)
maps through ``clip_from_eye`` to the same normalised (x, y) as the ray.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bsrt.kernels.prelim import pixel_rays_into
from bsrt.kernels.threads import run_chunks


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
    return _pixel_rays(camera, width, height, rows, origins=False)[1]


def pixel_ray_arrays(camera: Camera, width: int, height: int, rows=None):
    """pixel_rays as the arrays of a ray batch (rendering/solve.Rays): (origins (N, 3), the eye in
    each row; directions (N, 3)), the directions normalised once more as Rays.from_arrays would,
    bit for bit, in the same pass."""
    return _pixel_rays(camera, width, height, rows, origins=True)


def _pixel_rays(camera: Camera, width: int, height: int, rows, origins: bool):
    first, stop = rows if rows is not None else (0, height)
    r, u, f = camera.basis()
    tx, ty = camera.half_extents(width, height)
    x = (2.0 * (np.arange(width) + 0.5) / width - 1.0) * tx
    y = (1.0 - 2.0 * (np.arange(first, stop) + 0.5) / height) * ty
    n = (stop - first) * width
    directions, start = np.empty((n, 3)), np.empty((n if origins else 0, 3))
    eye = np.ascontiguousarray(camera.eye, dtype=np.float64)
    run_chunks(pixel_rays_into, n, f, r, u, x, y, eye, directions, start)  # (f + x r + y u) / |...|
    return start, directions


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
    clip_from_camera = np.array([[1.0 / tx, 0, 0, 0], [0, 1.0 / ty, 0, 0], [0, 0, a, b], [0, 0, 1.0, 0]])
    if rows is not None:
        top, bottom = 1.0 - 2.0 * rows[0] / height, 1.0 - 2.0 * rows[1] / height
        centre, half = (top + bottom) / 2.0, (top - bottom) / 2.0
        clip_from_camera[1] = (clip_from_camera[1] - centre * clip_from_camera[3]) / half
    return clip_from_camera @ camera_from_eye


# ---------------------------------------------------------------- camera moves (the preview's orbit, pan, zoom)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _rotate(v: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """v (3,) rotated about the unit axis (3,) by degrees (right-handed, Rodrigues)."""
    a = np.radians(degrees)
    return v * np.cos(a) + np.cross(axis, v) * np.sin(a) + axis * float(axis @ v) * (1.0 - np.cos(a))


def orbit(camera: Camera, yaw: float, pitch: float) -> Camera:
    """Turn the eye about look_at: yaw degrees about ``up`` (positive turns the
    view to the left, the object to the right: the eye moves clockwise seen
    from above), then pitch degrees about the view's right axis (positive
    raises the eye); a pitch that would bring the eye within 1 degree of
    ``up`` is not applied, so the camera stays valid."""
    up = _unit(camera.up)
    offset = _rotate(camera.eye - camera.look_at, up, -yaw)
    right = _unit(np.cross(-offset, up))
    tilted = _rotate(offset, right, -pitch)
    angle = np.degrees(np.arccos(np.clip(_unit(tilted) @ up, -1.0, 1.0)))
    if 1.0 <= angle <= 179.0:
        offset = tilted
    return replace(camera, eye=camera.look_at + offset)


def pan(camera: Camera, dx: float, dy: float, aspect: float) -> Camera:
    """Move eye and look_at together by (dx, dy) view heights at look_at's
    distance (dx to the right, dy up), opposite to the view's right and up
    axes: the scene follows a dragged cursor. aspect = width / height."""
    right, up, _ = camera.basis()
    _, ty = camera.half_extents(aspect, 1.0)
    scale = 2.0 * ty * float(np.linalg.norm(camera.look_at - camera.eye))
    shift = -(dx * right + dy * up) * scale
    return replace(camera, eye=camera.eye + shift, look_at=camera.look_at + shift)


def zoom(camera: Camera, factor: float) -> Camera:
    """Multiply the eye's distance to look_at by factor (< 1: closer); look_at stays."""
    return replace(camera, eye=camera.look_at + (camera.eye - camera.look_at) * factor)


def rotation_matrix(axis: np.ndarray, degrees: float) -> np.ndarray:
    """(3, 3) right-handed rotation about ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    a = np.radians(degrees)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * kx @ kx
