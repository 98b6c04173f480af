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
edge: where the corners of a triangle that holds it agree within CONTRAST
levels, any straight edge leaves them, and so the sample, on one side, and
it is interpolated from them (in linear RGB: linearly in the first pass,
their mean in the second; it hits where the pixel centre does). A streamed
film keeps only 8-bit colours: it interpolates from those, and traces the
samples next to a centre at 255 in some channel, which may stand for more
than 1 (its picture is the kept film's within a level or two). The marked pixels are refined in two passes, those with
x + y even first: in the first, the triangle is the pixel's centre and the
two neighbouring centres on the sample's side (along the row and along the
column); in the second, the four neighbours are pixels of the first pass,
and a triangle may also take the neighbours' samples as corners (the
pixel's centre one of them, no side longer than a pixel; not across a line
one pixel thin, where the centre differs from both neighbours on a row or
a column). So a straight edge between two pixel centres costs a quarter to
a half of the two pixels' 2n samples: the first pixel's on the edge's side,
and those of the second that the first's do not place. A corner of a shape
inside such a triangle is missed (on the test checker, 6 of 752 marked
pixels, by a quarter). An odd grid's middle sample is the pixel centre,
never traced. An unmarked pixel keeps its centre sample.

The cost is the samples traced, and those are the dear ones: at silhouettes
and borders the hierarchy finds their hits, and their shadow rays cost up to
3 times an average pixel's (docs/design.md, "Adaptive anti-aliasing").

``--stats`` reports ``adaptive_pixels`` (marked), ``adaptive_full`` (those
that traced all n samples) and ``adaptive_samples`` (the camera samples
traced); the render's camera samples in all are ``pixels +
adaptive_samples``.
"""

from __future__ import annotations

import functools
import itertools

import numpy as np

from bsrt.kernels.antialias import SIDES, block_samples, mark_rows
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.film import srgb_bytes
from bsrt.rendering.image import DECODED
from bsrt.rendering.screen import film_rays

CONTRAST = 16  # 8-bit sRGB levels


def disagreeing(pixels: np.ndarray) -> np.ndarray:
    """pixels: (H, W, 3) uint8 -> (H, W) bool, True where the second difference along the row or the
    column (the first difference at the film's border) exceeds CONTRAST levels in some channel
    (kernels/antialias.mark_rows, row by row on every core)."""
    marked = np.empty(pixels.shape[:2], dtype=bool)
    run_chunks(mark_rows, pixels.shape[0], np.ascontiguousarray(pixels), CONTRAST, marked, min_chunk=64)
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


def refine(linear, pixels, coverage, grid, shade, trace, options, stats, chunk_samples: int, centre_hits=None) -> None:
    """Re-render the marked pixels with the n = columns * rows samples of rotated_grid(*grid), in
    place, tracing only the samples that may lie across an edge (the others interpolated).

    linear: (H, W, 3) float64 (or None: a streamed film) and pixels: (H, W, 3) uint8, the one-sample
    render, updated where marked; coverage: (H, W) float64 (or None), the fraction of each pixel's
    samples that hit, updated alike. grid: (columns, rows). trace(directions (K, 3)) -> Hits: the
    camera rays' nearest hits; shade(hits, directions) -> (K, 3) linear RGB. chunk_samples: the
    most samples traced at once (and the marked pixels are taken chunk_samples / n at a time).
    centre_hits: (H, W), non-zero where the pixel-centre ray hit (a streamed film's count, which
    tells its background, exact at 255, from a highlight; None: every centre counts as a hit)."""
    offset = rotated_grid(*grid)  # (n, 2)
    step = max(1, chunk_samples // offset.shape[0])
    centres = _centres(linear, pixels, coverage if coverage is not None else centre_hits)
    marked = np.flatnonzero(disagreeing(pixels).ravel())
    odd = (marked % options.width + marked // options.width) % 2 == 1
    known = _first_pass_none(offset.shape[0])
    results = []
    for second, group in enumerate((marked[~odd], marked[odd])):  # the odd pixels' four neighbours are even
        done = [
            _block(group[a : a + step], offset, grid, known, centres, shade, trace, options, stats)
            for a in range(0, group.size, step)
        ]
        if not done:
            continue
        colour, hit, traced = (np.concatenate([d[k] for d in done]) for k in range(3))
        results.append((group, colour, hit, traced))
        if not second:  # the even pixels' samples, for the odd ones: (indices, colour, levels)
            known = (group, colour, srgb_bytes(colour))
    stats.add("adaptive_pixels", marked.size)
    stats.add("adaptive_full", sum(int(r[3].all(axis=1).sum()) for r in results))
    stats.add("adaptive_samples", sum(int(r[3].sum()) for r in results))
    for group, colour, hit, _ in results:  # written once all are decided (the passes read the centres)
        value = colour.mean(axis=1)
        if coverage is not None:
            coverage.reshape(-1)[group] = hit.mean(axis=1)
        if linear is not None:
            linear.reshape(-1, 3)[group] = value
        pixels.reshape(-1, 3)[group] = srgb_bytes(value)


def _centres(linear, pixels, hits):
    """The one-sample render's pixel centres as block_samples reads them: (linear (H W, 3) float64
    or (0, 3), levels (H W, 3) uint8, hit (H W,) bool or (0,)), views of the film's arrays but for
    hit, one byte a pixel whatever hits' type (hits: (H, W) > 0 where the centre ray hit, or None; a
    streamed 4096 x 4096 film's uint16 counts as float64 took 134 MB more at the render's peak)."""
    return (
        np.empty((0, 3)) if linear is None else linear.reshape(-1, 3),
        pixels.reshape(-1, 3),
        np.empty(0, dtype=bool) if hits is None else (hits > 0).reshape(-1),
    )


def _first_pass_none(n: int):
    """The first pass's samples before there are any: (pixels (0,), colour (0, n, 3), levels (0, n, 3))."""
    return np.empty(0, dtype=np.int64), np.empty((0, n, 3)), np.empty((0, n, 3), dtype=np.uint8)


def _block(marked, offset, grid, known, centres, shade, trace, options, stats):
    """The samples at offset (n, 2) of the marked pixels (K,) (flat indices): (colour (K, n, 3) linear
    RGB, hit (K, n) bool, traced (K, n) bool): those _decide leaves needed traced and shaded here."""
    colour, hit, need = _decide(marked, offset, grid, known, centres, options.width, options.height)
    which, sample = np.nonzero(need)
    if which.size:
        xy = np.stack([marked[which] % options.width, marked[which] // options.width], axis=1) + offset[sample]
        directions = film_rays(options.camera, options.width, options.height, xy)
        with stats.timer("solve"):
            found = trace(directions)
        colour[which, sample] = shade(found, directions)
        hit[which, sample] = found.hit
    return colour, hit, need


def _decide(marked, offset, grid, known, centres, width: int, height: int):
    """Which samples at offset (n, 2) of the marked pixels (K,) (flat indices) of a width x height
    film must be traced, and the colour of the others: (colour (K, n, 3) linear RGB, hit (K, n)
    bool, need (K, n) bool) by kernels/antialias.block_samples. known: the samples of the pixels
    of the first pass (indices (M,) sorted, colour (M, n, 3), 8-bit levels (M, n, 3); M = 0 in the
    first pass), which a sample may also be interpolated from (the second pass: the marked pixels'
    neighbours are there). centres: the one-sample render's (linear (H W, 3) or (0, 3), levels (H
    W, 3) uint8, hits (H W,) bool or (0,))."""
    n = offset.shape[0]
    colour, hit, need = (
        np.empty((marked.size, n, 3)),
        np.empty((marked.size, n), bool),
        np.empty((marked.size, n), bool),
    )
    points, starts, triangles = _triangles(*grid)
    run_chunks(
        block_samples,
        marked.size,
        np.ascontiguousarray(marked, dtype=np.int64),
        offset,
        width,
        height,
        *centres,
        DECODED,
        CONTRAST,
        *known,
        points,
        starts,
        triangles,
        colour,
        hit,
        need,
        min_chunk=256,
    )
    return colour, hit, need


NEAREST = 16  # the known points nearest a sample whose triangles may hold it


@functools.lru_cache(maxsize=8)
def _triangles(columns: int, rows: int):
    """The points known around a pixel in the second pass, (P, 4): x, y from the pixel centre in
    pixels, the neighbour (index into SIDES, -1: the pixel itself) and its sample (index into
    rotated_grid, -1: the centre); and the triangles of those points (among the NEAREST to it)
    that hold each sample s of rotated_grid strictly, no side longer than a pixel, smallest first:
    triangles[starts[s] : starts[s + 1]] (T, 3) int64, starts (n + 1,) int64."""
    offset = rotated_grid(columns, rows) - 0.5
    listed = [(0.0, 0.0, -1, -1)]
    for k, (dx, dy) in enumerate(SIDES):
        listed.append((dx, dy, k, -1))
        listed.extend((dx + ox, dy + oy, k, j) for j, (ox, oy) in enumerate(offset))
    points = np.array(listed)
    triangles = []
    for sx, sy in offset:
        near = np.argsort(np.hypot(points[:, 0] - sx, points[:, 1] - sy), kind="stable")[:NEAREST]
        t = np.array(list(itertools.combinations(near, 3)))
        p = points[t][..., :2] - [sx, sy]  # (T, 3, 2) from the sample
        cross = [p[:, i, 0] * p[:, (i + 1) % 3, 1] - p[:, i, 1] * p[:, (i + 1) % 3, 0] for i in range(3)]
        holds = np.all(np.array(cross) > 1e-12, axis=0) | np.all(np.array(cross) < -1e-12, axis=0)
        side = np.max([np.hypot(*(p[:, i] - p[:, (i + 1) % 3]).T) for i in range(3)], axis=0)
        keep = holds & (side <= 1.0 + 1e-9) & (t == 0).any(axis=1)  # the pixel's own centre a corner
        area = np.abs(np.sum(cross, axis=0))[keep]
        triangles.append(t[keep][np.argsort(area, kind="stable")].reshape(-1, 3))
    starts = np.concatenate([[0], np.cumsum([len(t) for t in triangles])]).astype(np.int64)
    return points, starts, np.ascontiguousarray(np.concatenate(triangles), dtype=np.int64)
