"""Film coordinates: world points to continuous pixel positions and back to camera rays.

A film position (x, y) is measured in pixels from the film's top-left corner,
x to the right and y down, so pixel (i, j) (row i, column j) covers
[j, j + 1) x [i, i + 1) and its centre ray (bsrt.scene.camera.pixel_rays) goes
through (j + 0.5, i + 0.5). The same formula as pixel_rays, for any point.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.threads import run_chunks
from bsrt.scene.camera import Camera


def project(camera: Camera, width: int, height: int, points: np.ndarray):
    """points: (N, 3) float64 world points -> (xy (N, 2) float64 film positions in pixels,
    depth (N,) float64 distance along the view direction; <= 0 behind the eye)."""
    r, u, f = camera.basis()
    tx, ty = camera.half_extents(width, height)
    d = np.asarray(points, dtype=np.float64) - camera.eye
    depth = d @ f
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (d @ r) / depth
        y = (d @ u) / depth
    xy = np.stack([(x / tx + 1.0) * (0.5 * width), (1.0 - y / ty) * (0.5 * height)], axis=1)
    return xy, depth


def film_rays(camera: Camera, width: int, height: int, xy: np.ndarray) -> np.ndarray:
    """xy: (N, 2) float64 film positions in pixels -> (N, 3) float64 unit directions from camera.eye
    (at pixel centres, exactly pixel_rays' directions up to rounding)."""
    from bsrt.kernels.prelim import film_rays_into  # (numba: loaded when rays are made)

    r, u, f = camera.basis()
    tx, ty = camera.half_extents(width, height)
    xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
    directions = np.empty((xy.shape[0], 3))
    run_chunks(film_rays_into, xy.shape[0], xy, float(width), float(height), float(tx), float(ty), r, u, f, directions)
    return directions
