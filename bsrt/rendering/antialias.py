"""Adaptive anti-aliasing: more samples only where neighbouring pixels disagree.

After a render of one sample per pixel (the pixel-centre rays), a pixel is
*disagreeing* when its 8-bit sRGB colour differs from one of its four
neighbours' by more than CONTRAST levels in some channel (silhouettes, face
borders, shadow borders, texture of the lighting); both pixels of such a
pair are marked. Each marked pixel is then traced again with n samples
(``adaptive_spp``) at the centres of the same stratified columns x rows
grid as uniform ``--spp n`` (pipeline.sample_grid), through the hierarchy,
shaded as every camera ray is, and replaced by their mean (the box filter of
``--spp n``). So a marked pixel gets exactly the samples of ``--spp n``; an
unmarked one keeps its centre sample, within about CONTRAST levels of its
neighbours. ``--stats`` reports ``adaptive_pixels`` and ``adaptive_samples``
(the camera samples added); the render's camera samples in all are
``pixels + adaptive_samples``.
"""

from __future__ import annotations

import numpy as np

from bsrt.rendering.image import srgb_encode
from bsrt.rendering.screen import film_rays

CONTRAST = 4  # 8-bit sRGB levels: neighbours differing by more are anti-aliased


def disagreeing(pixels: np.ndarray) -> np.ndarray:
    """pixels: (H, W, 3) uint8 -> (H, W) bool, True where a 4-neighbour differs by more than CONTRAST
    levels in some channel (both pixels of each such pair)."""
    p = pixels.astype(np.int16)
    marked = np.zeros(p.shape[:2], dtype=bool)
    across = np.abs(p[:, 1:] - p[:, :-1]).max(axis=2) > CONTRAST  # (H, W - 1)
    down = np.abs(p[1:] - p[:-1]).max(axis=2) > CONTRAST  # (H - 1, W)
    marked[:, 1:] |= across
    marked[:, :-1] |= across
    marked[1:] |= down
    marked[:-1] |= down
    return marked


def refine(linear, pixels, grid, shade, trace, options, stats, chunk_samples: int) -> None:
    """Re-render the disagreeing pixels with the samples of ``--spp columns * rows``, in place.

    linear: (H, W, 3) float64 and pixels: (H, W, 3) uint8, the one-sample render, updated where
    marked. grid: (columns, rows) of the sub-pixel grid. trace(directions (K, 3)) -> Hits: the
    camera rays' nearest hits; shade(hits, directions) -> (K, 3) linear RGB. chunk_samples: the
    most samples traced at once."""
    width, height = options.width, options.height
    cols, rows = grid
    n = cols * rows
    marked = np.flatnonzero(disagreeing(pixels).ravel())
    stats.add("adaptive_pixels", marked.size)
    stats.add("adaptive_samples", marked.size * n)
    a, b = np.meshgrid(np.arange(cols), np.arange(rows))  # sample (b, a) of a pixel: row b, column a
    offset = np.stack([(a.ravel() + 0.5) / cols, (b.ravel() + 0.5) / rows], axis=1)  # (n, 2)
    step = max(1, chunk_samples // n)
    flat = linear.reshape(-1, 3)
    for first in range(0, marked.size, step):
        which = marked[first : first + step]
        corner = np.stack([which % width, which // width], axis=1).astype(np.float64)
        xy = (corner[:, None, :] + offset[None, :, :]).reshape(-1, 2)
        directions = film_rays(options.camera, width, height, xy)
        with stats.timer("solve"):
            hits = trace(directions)
        colour = shade(hits, directions)
        flat[which] = colour.reshape(-1, n, 3).mean(axis=1)
    if marked.size:
        pixels.reshape(-1, 3)[marked] = srgb_encode(flat[marked])
