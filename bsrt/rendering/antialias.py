"""Adaptive anti-aliasing: more samples only where neighbouring pixels disagree.

After a render of one sample per pixel (the pixel-centre rays), a pixel is
*marked* when its 8-bit sRGB colour is not the mean of its two neighbours
along a row or a column within CONTRAST levels in some channel (the second
difference p[j - 1] - 2 p[j] + p[j + 1]; at the film's border, the first
difference): a step between two pixels marks both of them (silhouettes, face
borders, shadow borders, a thin line), a smooth gradient of shading marks
none. Each marked pixel is traced again with the samples of ``--spp n``
(``adaptive_spp``, default 4: the same stratified columns x rows grid,
pipeline.sample_grid), through the hierarchy, shaded as every camera ray is,
in two rounds: first the grid's four corner samples; a pixel whose corner
samples and centre all agree within CONTRAST levels takes the corners' mean
and stops, the others get the rest of the grid and take the mean of all n
(the box filter of ``--spp n``). Every other sample of the grid lies on a
segment between two of those five points, so a straight edge (a half-plane)
that leaves the five on one side leaves all n there too: such a pixel's
value is exactly ``--spp n``'s where the picture is flat on each side, and a
pixel an edge separates gets exactly the samples of ``--spp n``. The 2 x 2
grid of n = 4 is all corners: one round, every marked pixel gets ``--spp
4``'s value. An odd grid (3 x 3 for n = 9) has the pixel centre as its
middle sample: that one is the centre ray already shaded, not traced again
(a streamed film, which keeps no linear colour, traces it), and a pixel
whose five first samples agree takes their mean. An unmarked pixel keeps its
centre sample.

The cost is the marked pixels' samples, and those are the dear ones: at
silhouettes and borders the hierarchy finds their hits, and their shadow
rays (nearly all of the shading time) cost up to 3 times an average
pixel's (measured on water-lily and column). Seeding the samples with
Newton from the pixel's own hit, accepted where the pixel-centre hits pass
the hard-pixel tests (hard_pixels.suspect_pixels), is not exact: a sliver
of another surface between the centres of a 3 x 3 neighbourhood that all
hit one surface is missed (water-lily at 256 x 256, n = 16: 5 pixels off by
up to 6 levels), and proving a seeded root the nearest with a hierarchy
query bounded by its distance costs 0.7 to 1.2 times the plain query
(measured). So every sample goes through the hierarchy, and the default n
is the one whose cost is a small part of ``--spp 4``'s (docs/design.md,
"Adaptive anti-aliasing").

``--stats`` reports ``adaptive_pixels`` (marked), ``adaptive_full`` (given
all n samples) and ``adaptive_samples`` (the camera samples added); the
render's camera samples in all are ``pixels + adaptive_samples``.
"""

from __future__ import annotations

import numpy as np

from bsrt.rendering.image import srgb_encode
from bsrt.rendering.screen import film_rays

CONTRAST = 6  # 8-bit sRGB levels
BAND_ROWS = 256  # pixel rows whose differences are worked out at once


def disagreeing(pixels: np.ndarray, rows: int = BAND_ROWS) -> np.ndarray:
    """pixels: (H, W, 3) uint8 -> (H, W) bool, True where the second difference along the row or the
    column (the first difference at the film's border) exceeds CONTRAST levels in some channel.
    Worked out ``rows`` pixel rows at a time (each with its neighbours above and below), so the
    temporaries are bounded by the band, not the film."""
    height = pixels.shape[0]
    marked = np.zeros(pixels.shape[:2], dtype=bool)
    for top in range(0, height, rows):
        bottom = min(height, top + rows)
        lo, hi = max(0, top - 1), min(height, bottom + 1)
        marked[top:bottom] = _disagreeing(pixels[lo:hi])[top - lo : bottom - lo]
    return marked


def _disagreeing(pixels: np.ndarray) -> np.ndarray:
    """disagreeing for one slab of rows (its first and last rows taken as the film's border)."""
    p = pixels.astype(np.int32)
    marked = np.zeros(p.shape[:2], dtype=bool)
    for axis in (0, 1):
        q = np.moveaxis(p, axis, 0)  # (n, m, 3): differences along the first axis
        m = np.moveaxis(marked, axis, 0)  # a view: writes go to marked
        if q.shape[0] < 2:
            continue
        m[1:-1] |= np.abs(q[:-2] - 2 * q[1:-1] + q[2:]).max(axis=2) > CONTRAST
        m[0] |= np.abs(q[1] - q[0]).max(axis=1) > CONTRAST
        m[-1] |= np.abs(q[-1] - q[-2]).max(axis=1) > CONTRAST
    return marked


def refine(linear, pixels, coverage, grid, shade, trace, options, stats, chunk_samples: int) -> None:
    """Re-render the marked pixels with the samples of ``--spp columns * rows``, in place.

    linear: (H, W, 3) float64 (or None: a streamed film) and pixels: (H, W, 3) uint8, the one-sample
    render, updated where marked; coverage: (H, W) float64 (or None), the fraction of each pixel's samples that hit, updated
    alike. grid: (columns, rows) of the sub-pixel grid. trace(directions (K, 3)) -> Hits: the
    camera rays' nearest hits; shade(hits, directions) -> (K, 3) linear RGB. chunk_samples: the
    most samples traced at once."""
    cols, rows = grid
    a, b = np.meshgrid(np.arange(cols), np.arange(rows))  # sample (b, a) of a pixel: row b, column a
    a, b = a.ravel(), b.ravel()
    offset = np.stack([(a + 0.5) / cols, (b + 0.5) / rows], axis=1)  # (n, 2)
    n = offset.shape[0]
    first = ((a == 0) | (a == cols - 1)) & ((b == 0) | (b == rows - 1))  # the grid's corners
    # an odd grid's middle sample is the pixel-centre ray, already shaded: reused where the film keeps it
    kept = linear is not None and coverage is not None
    middle = (cols % 2 == 1) & (rows % 2 == 1) & (2 * a + 1 == cols) & (2 * b + 1 == rows) & kept
    marked = np.flatnonzero(disagreeing(pixels).ravel())
    centre = pixels.reshape(-1, 3)[marked].astype(np.int32)
    early, early_hit = _samples(marked, offset[first], shade, trace, options, stats, chunk_samples)  # (K, f, 3)
    if middle.any():  # (K, f + 1, 3): the centre sample joins the corners
        early = np.concatenate([early, linear.reshape(-1, 3)[marked][:, None, :]], axis=1)
        early_hit = np.concatenate([early_hit, coverage.reshape(-1)[marked][:, None] > 0], axis=1)
    levels = srgb_encode(early).astype(np.int32)
    spread = np.maximum(levels.max(axis=1), centre) - np.minimum(levels.min(axis=1), centre)
    full = spread.max(axis=1) > CONTRAST
    value = early.mean(axis=1)  # (K, 3): the marked pixels' new linear RGB
    hit_fraction = early_hit.mean(axis=1)  # (K,)
    rest = ~first & ~middle
    full |= not rest.any()  # a grid of corners (2 x 2; 1 x 3 with its middle): every pixel has them all
    if rest.any():
        more, more_hit = _samples(marked[full], offset[rest], shade, trace, options, stats, chunk_samples)
        value[full] = (early[full].sum(axis=1) + more.sum(axis=1)) / n
        hit_fraction[full] = (early_hit[full].sum(axis=1) + more_hit.sum(axis=1)) / n
    stats.add("adaptive_pixels", marked.size)
    stats.add("adaptive_full", int(full.sum()))
    stats.add("adaptive_samples", marked.size * int(first.sum()) + int(full.sum()) * int(rest.sum()))
    if marked.size:
        if coverage is not None:
            coverage.reshape(-1)[marked] = hit_fraction
        if linear is not None:
            linear.reshape(-1, 3)[marked] = value
        pixels.reshape(-1, 3)[marked] = srgb_encode(value)


def _samples(which, offset, shade, trace, options, stats, chunk_samples: int) -> np.ndarray:
    """The samples at offset (n, 2) (fractions of a pixel from its top-left corner) in each pixel
    which (K,) (flat indices, row-major): (colour (K, n, 3) linear RGB, hit (K, n) bool)."""
    width, height = options.width, options.height
    n = offset.shape[0]
    out = np.empty((which.size, n, 3))
    hit = np.zeros((which.size, n), dtype=bool)
    step = max(1, chunk_samples // n)
    for start in range(0, which.size, step):
        part = which[start : start + step]
        corner = np.stack([part % width, part // width], axis=1).astype(np.float64)
        xy = (corner[:, None, :] + offset[None, :, :]).reshape(-1, 2)
        directions = film_rays(options.camera, width, height, xy)
        with stats.timer("solve"):
            hits = trace(directions)
        out[start : start + part.size] = shade(hits, directions).reshape(-1, n, 3)
        hit[start : start + part.size] = hits.hit.reshape(-1, n)
    return out, hit
