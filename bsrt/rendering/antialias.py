"""Adaptive anti-aliasing: more samples only where neighbouring pixels disagree.

After a render of one sample per pixel (the pixel-centre rays), a pixel is
*marked* when its 8-bit sRGB colour is not the mean of its two neighbours
along a row or a column within CONTRAST levels in some channel (the second
difference p[j - 1] - 2 p[j] + p[j + 1]; at the film's border, the first
difference): a step between two pixels marks both of them (silhouettes, face
borders, shadow borders, a thin line), a smooth gradient of shading marks
none. The threshold is in sRGB, where the eye sees the step.

A marked pixel takes the mean of n = ``adaptive_spp`` samples (default 4) at
the positions of rotated_grid: one in each cell of the columns x rows grid
of ``--spp n`` (pipeline.sample_grid), and in n distinct columns and n
distinct rows of the n x n grid (for n = 4 the rotated grid of 4 of the 16
samples of ``--spp 16``), so a nearly vertical or horizontal edge is
resolved in n steps, not sqrt(n). A sample is traced (through the
hierarchy, shaded as every camera ray is) only where it may lie across an
edge: it lies in the triangle of its pixel's centre and the two neighbouring
centres on its side (along the row and along the column), and where those
three agree within CONTRAST levels any straight edge leaves them, and so the
sample, on one side. Such a sample is interpolated from the three centres
(linearly, in linear RGB), and hits where the pixel's centre does. So a
straight edge between two pixel centres costs the samples of the two pixels
on the edge's side of each, about half of them. An odd grid's middle sample
is the pixel centre, never traced. An unmarked pixel keeps its centre
sample.

The cost is the samples traced, and those are the dear ones: at silhouettes
and borders the hierarchy finds their hits, and their shadow rays cost up to
3 times an average pixel's (docs/design.md, "Adaptive anti-aliasing").

``--stats`` reports ``adaptive_pixels`` (marked), ``adaptive_full`` (those
that traced all n samples) and ``adaptive_samples`` (the camera samples
traced); the render's camera samples in all are ``pixels +
adaptive_samples``.
"""

from __future__ import annotations

import numpy as np

from bsrt.rendering.image import srgb_decode, srgb_encode
from bsrt.rendering.screen import film_rays

CONTRAST = 10  # 8-bit sRGB levels
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


def rotated_grid(columns: int, rows: int) -> np.ndarray:
    """The n = columns * rows sample positions of a marked pixel: (n, 2) fractions of a pixel from
    its top-left corner, (x, y). Sample (i, j) lies in cell (column i, row j) of the columns x rows
    grid, at x = (i + (j + 1/2) / rows) / columns, y = (j + (columns - i - 1/2) / columns) / rows:
    one in each cell, and in n distinct columns and n distinct rows of an n x n grid (2 x 2: the
    rotated grid (1/8, 3/8), (3/8, 7/8), (5/8, 1/8), (7/8, 5/8))."""
    i, j = np.meshgrid(np.arange(columns), np.arange(rows), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return np.stack([(i + (j + 0.5) / rows) / columns, (j + (columns - i - 0.5) / columns) / rows], axis=1)


def refine(linear, pixels, coverage, grid, shade, trace, options, stats, chunk_samples: int) -> None:
    """Re-render the marked pixels with the n = columns * rows samples of rotated_grid(*grid), in
    place: a sample is traced unless the three pixel centres around it agree (then it is
    interpolated from them).

    linear: (H, W, 3) float64 (or None: a streamed film) and pixels: (H, W, 3) uint8, the one-sample
    render, updated where marked; coverage: (H, W) float64 (or None), the fraction of each pixel's
    samples that hit, updated alike. grid: (columns, rows). trace(directions (K, 3)) -> Hits: the
    camera rays' nearest hits; shade(hits, directions) -> (K, 3) linear RGB. chunk_samples: the
    most samples traced at once (and the marked pixels are taken chunk_samples / n at a time)."""
    offset = rotated_grid(*grid)  # (n, 2)
    marked = np.flatnonzero(disagreeing(pixels).ravel())
    step = max(1, chunk_samples // offset.shape[0])
    value, hit = np.empty((marked.size, 3)), np.empty(marked.size)  # written once all are decided
    traced = full = 0
    for start in range(0, marked.size, step):
        part = slice(start, start + step)
        done = _refine(marked[part], offset, linear, pixels, coverage, shade, trace, options, stats)
        value[part], hit[part] = done[:2]
        traced, full = traced + done[2], full + done[3]
    stats.add("adaptive_pixels", marked.size)
    stats.add("adaptive_full", full)
    stats.add("adaptive_samples", traced)
    if coverage is not None:
        coverage.reshape(-1)[marked] = hit
    if linear is not None:
        linear.reshape(-1, 3)[marked] = value
    pixels.reshape(-1, 3)[marked] = srgb_encode(value)


def _refine(marked, offset, linear, pixels, coverage, shade, trace, options, stats):
    """refine for the marked pixels (K,) (flat indices, row-major) with the samples at offset (n, 2):
    (colour (K, 3) linear RGB, hit fraction (K,) (0 where coverage is None), samples traced, pixels
    that traced all n)."""
    width, height = options.width, options.height
    n = offset.shape[0]
    y, x = np.divmod(marked, width)
    levels = pixels.reshape(-1, 3)

    def colour(index):  # (K,) flat pixel indices -> (K, 3) linear RGB of their centre samples
        return linear.reshape(-1, 3)[index] if linear is not None else srgb_decode(levels[index])

    def apart(p, q):  # (K,) flat indices -> (K,) bool: their 8-bit colours differ by more than CONTRAST
        return np.abs(levels[p].astype(np.int32) - levels[q]).max(axis=1) > CONTRAST

    centre = colour(marked)
    sums = np.zeros((marked.size, 3))  # the samples' colours, summed
    hits = np.zeros(marked.size)  # the samples that hit, counted
    if coverage is not None:  # an interpolated sample hits as the centre does
        centre_hit = coverage.reshape(-1)[marked] > 0
    need = np.zeros((marked.size, n), dtype=bool)  # traced
    neighbour = {}  # (axis, side) -> (flat index, clamped to the film; inside the film)
    for axis, coordinate, size, stride in ((0, x, width, 1), (1, y, height, width)):
        for side in (-1, 1):
            inside = (coordinate + side >= 0) & (coordinate + side < size)
            neighbour[axis, side] = np.where(inside, marked + side * stride, marked), inside
    colours = {key: colour(index) for key, (index, _) in neighbour.items()}
    for s, (dx, dy) in enumerate(offset - 0.5):  # from the pixel centre, in pixels
        # the sample lies in the triangle of the centre and its neighbours on its side along the
        # row (h) and the column (v): where those agree, it is on their side of any straight edge
        key_h, key_v = (0, 1 if dx > 0 else -1), (1, 1 if dy > 0 else -1)
        (h, h_in), (v, v_in) = neighbour[key_h], neighbour[key_v]
        if dx != 0:
            need[:, s] |= ~h_in | apart(marked, h)
        if dy != 0:
            need[:, s] |= ~v_in | apart(marked, v)
        if dx != 0 and dy != 0:
            need[:, s] |= ~h_in | ~v_in | apart(h, v)
        rest = ~need[:, s]
        sums[rest] += (centre + abs(dx) * (colours[key_h] - centre) + abs(dy) * (colours[key_v] - centre))[rest]
        if coverage is not None:
            hits[rest] += centre_hit[rest]
    which, sample = np.nonzero(need)
    if which.size:
        directions = film_rays(options.camera, width, height, np.stack([x[which], y[which]], axis=1) + offset[sample])
        with stats.timer("solve"):
            found = trace(directions)
        np.add.at(sums, which, shade(found, directions))
        np.add.at(hits, which, found.hit)
    return sums / n, hits / n, int(which.size), int(need.all(axis=1).sum())
