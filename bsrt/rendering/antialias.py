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

from bsrt.rendering.image import srgb_decode, srgb_encode
from bsrt.rendering.screen import film_rays

CONTRAST = 16  # 8-bit sRGB levels
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
    p = pixels.astype(np.int16)  # second differences lie within +-510
    marked = np.zeros(p.shape[:2], dtype=bool)
    for axis in (0, 1):
        q = np.moveaxis(p, axis, 0)  # (n, m, 3): differences along the first axis
        m = np.moveaxis(marked, axis, 0)  # a view: writes go to marked
        if q.shape[0] < 2:
            continue
        m[1:-1] |= _beyond(q[:-2] - 2 * q[1:-1] + q[2:])
        m[0] |= _beyond(q[1] - q[0])
        m[-1] |= _beyond(q[-1] - q[-2])
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
    centres = _Centres(linear, pixels, coverage if coverage is not None else centre_hits, options.width, options.height)
    marked = np.flatnonzero(disagreeing(pixels).ravel())
    odd = (marked % options.width + marked // options.width) % 2 == 1
    known = None
    for group in (marked[~odd], marked[odd]):  # the odd pixels' four neighbours are even
        done = [
            _block(group[a : a + step], offset, grid, known, centres, shade, trace, options, stats)
            for a in range(0, group.size, step)
        ]
        colour, hit, traced = (np.concatenate([d[k] for d in done]) if done else None for k in range(3))
        if known is None:  # the even pixels' samples, for the odd ones: (indices, colour, levels)
            first = (group, colour, hit, traced)
            known = (group, colour, srgb_encode(colour)) if group.size else ()
    results = [r for r in (first, (group, colour, hit, traced)) if r[0].size]
    stats.add("adaptive_pixels", marked.size)
    stats.add("adaptive_full", sum(int(r[3].all(axis=1).sum()) for r in results))
    stats.add("adaptive_samples", sum(int(r[3].sum()) for r in results))
    for group, colour, hit, _ in results:  # written once all are decided (the passes read the centres)
        value = colour.mean(axis=1)
        if coverage is not None:
            coverage.reshape(-1)[group] = hit.mean(axis=1)
        if linear is not None:
            linear.reshape(-1, 3)[group] = value
        pixels.reshape(-1, 3)[group] = srgb_encode(value)


class _Centres:
    """The one-sample render's pixel-centre samples, read by flat pixel index (K,) (row-major)."""

    def __init__(self, linear, pixels, hits, width: int, height: int):
        """hits: (H, W), non-zero where the centre ray hit (the coverage or a hit count), or None."""
        self.linear, self.levels = linear, pixels.reshape(-1, 3)
        self.hits, self.width, self.height = hits, width, height

    def colour(self, index) -> np.ndarray:
        """(K, 3) linear RGB (decoded from the 8-bit pixels where the film keeps no linear RGB)."""
        if self.linear is not None:
            return self.linear.reshape(-1, 3).take(index, axis=0)
        return srgb_decode(self.levels_at(index))

    def levels_at(self, index) -> np.ndarray:
        """(K, 3) uint8 sRGB levels (take: several times faster than fancy indexing of rows)."""
        return self.levels.take(index, axis=0)

    def usable(self, index) -> np.ndarray:
        """(K,) bool: the colour can be interpolated from. A streamed film's 8-bit colour at 255 in
        some channel may stand for more than 1 (a highlight, a light seen directly) where the centre
        ray hit: its samples near such a centre are traced (the background's colour is exact)."""
        if self.linear is not None:
            return np.ones(len(index), bool)
        levels = self.levels_at(index)
        return (levels[:, 0] < 255) & (levels[:, 1] < 255) & (levels[:, 2] < 255) | ~self.hit(index)

    def hit(self, index) -> np.ndarray:
        """(K,) bool: the centre ray hit (True where the film counts none)."""
        return self.hits.reshape(-1)[index] > 0 if self.hits is not None else np.ones(len(index), bool)

    def neighbour(self, index, dx: int, dy: int):
        """The pixels (dx, dy) from index: (flat index (K,), clamped to the film; inside (K,) bool)."""
        y, x = np.divmod(index, self.width)
        inside = (x + dx >= 0) & (x + dx < self.width) & (y + dy >= 0) & (y + dy < self.height)
        return np.where(inside, index + dx + dy * self.width, index), inside


def _apart(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """p, q: (K, 3) 8-bit colours -> (K,) bool, True where they differ by more than CONTRAST in some channel."""
    return _beyond(p.astype(np.int32) - q)


def _beyond(difference: np.ndarray) -> np.ndarray:
    """difference: (..., 3) signed levels -> (...) bool, True where some channel's exceeds CONTRAST
    either way (the channels compared one by one: numpy's reduction over a last axis of 3 is slow)."""
    a = np.abs(difference)
    return (a[..., 0] > CONTRAST) | (a[..., 1] > CONTRAST) | (a[..., 2] > CONTRAST)


def _block(marked, offset, grid, known, centres: _Centres, shade, trace, options, stats):
    """The samples at offset (n, 2) of the marked pixels (K,) (flat indices): (colour (K, n, 3) linear
    RGB, hit (K, n) bool, traced (K, n) bool). known: empty, or the samples of the pixels of the
    first pass (indices (M,) sorted, colour (M, n, 3), 8-bit levels (M, n, 3)), which a
    sample may also be interpolated from (the second pass: the marked pixels' neighbours are there)."""
    n = offset.shape[0]
    centre, levels, centre_usable = centres.colour(marked), centres.levels_at(marked), centres.usable(marked)
    colour, hit = np.empty((marked.size, n, 3)), np.repeat(centres.hit(marked)[:, None], n, axis=1)
    need = np.zeros((marked.size, n), dtype=bool)
    # the pixel itself, then its four neighbours (SIDES), each gathered once:
    # (index (K,), inside the film (K,), levels (K, 3), colour (K, 3), usable (K,))
    near = [(marked, np.ones(marked.size, bool), levels, centre, centre_usable)]
    for dx, dy in SIDES:
        index, inside = centres.neighbour(marked, dx, dy)
        near.append((index, inside, centres.levels_at(index), centres.colour(index), centres.usable(index)))
    apart = [None] + [_apart(levels, m[2]) for m in near[1:]]  # each neighbour apart from the centre
    for s, (dx, dy) in enumerate(offset - 0.5):  # from the pixel centre, in pixels
        # the sample lies in the triangle of the centre and its neighbours on its side along the
        # row (h) and the column (v): where those agree, it is on their side of any straight edge
        h = 1 + SIDES.index((1 if dx > 0 else -1, 0))
        v = 1 + SIDES.index((0, 1 if dy > 0 else -1))
        need[:, s] = ~centre_usable
        if dx != 0:
            need[:, s] |= ~near[h][1] | ~near[h][4] | apart[h]
        if dy != 0:
            need[:, s] |= ~near[v][1] | ~near[v][4] | apart[v]
        if dx != 0 and dy != 0:
            need[:, s] |= _apart(near[h][2], near[v][2])  # (either neighbour outside is needed already)
        colour[:, s] = centre + abs(dx) * (near[h][3] - centre) + abs(dy) * (near[v][3] - centre)
    if known and need.any():  # not across a line one pixel thin (the centre apart from both neighbours)
        wide = ~((apart[1] & apart[2]) | (apart[3] & apart[4]))
        _from_neighbours([tuple(a[wide] for a in m) for m in near], grid, known, colour, need, wide)
    which, sample = np.nonzero(need)
    if which.size:
        xy = np.stack([marked[which] % options.width, marked[which] // options.width], axis=1) + offset[sample]
        directions = film_rays(options.camera, options.width, options.height, xy)
        with stats.timer("solve"):
            found = trace(directions)
        colour[which, sample] = shade(found, directions)
        hit[which, sample] = found.hit
    return colour, hit, need


def _from_neighbours(near, grid, known, colour, need, rows) -> None:
    """Interpolate, in place, the samples still needed of J marked pixels, rows (a (K,) mask, J
    True) of colour (K, n, 3) and need (K, n) (cleared where done) that lie in a triangle of points
    known around their pixel that agree within CONTRAST (the centre, the four neighbours' centres
    and their samples, of the first pass or, for a pixel not marked, its centre's value): the mean
    of the triangle's colours. near: the J pixels themselves, then their neighbours at SIDES, as
    _block gathers them (index (J,), inside the film (J,), levels (J, 3), colour (J, 3), usable (J,))."""
    points, triangles = _triangles(*grid)
    first, first_colour, first_levels = known
    table = {}  # point -> (levels (J, 3), colour (J, 3), inside the film and usable (J,))
    found = {}  # side -> (where the neighbour is a first-pass pixel (J,), its row there)

    def point(p):
        if p not in table:
            side, sample = int(points[p, 2]), int(points[p, 3])
            index, inside, levels, col, usable = near[side + 1]
            lv = levels.astype(np.int32)
            if sample >= 0:  # a neighbour's sample: the first pass's where it was marked
                if side not in found:
                    at = np.minimum(np.searchsorted(first, index), first.size - 1)
                    there = first[at] == index
                    found[side] = there, at[there]
                there, at = found[side]
                col, usable = col.copy(), usable.copy()
                lv[there], col[there] = first_levels[at, sample], first_colour[at, sample]
                usable[there] = True  # traced, or interpolated from usable colours
            table[p] = lv, col, inside & usable
        return table[p]

    rows = np.flatnonzero(rows)
    for s in np.flatnonzero(need[rows].any(axis=0)):
        for a, b, c in triangles[s]:  # smallest first
            (la, ca, ia), (lb, cb, ib), (lc, cc, ic) = point(a), point(b), point(c)
            agree = need[rows, s] & ia & ib & ic & ~_apart(la, lb) & ~_apart(lb, lc) & ~_apart(la, lc)
            done = rows[agree]
            colour[done, s] = ((ca + cb + cc) / 3.0)[agree]
            need[done, s] = False


SIDES = ((1, 0), (-1, 0), (0, 1), (0, -1))  # a pixel's four neighbours (dx, dy)
NEAREST = 16  # the known points nearest a sample whose triangles may hold it


@functools.lru_cache(maxsize=8)
def _triangles(columns: int, rows: int):
    """The points known around a pixel in the second pass, (P, 4): x, y from the pixel centre in
    pixels, the neighbour (index into SIDES, -1: the pixel itself) and its sample (index into
    rotated_grid, -1: the centre); and for each sample s of rotated_grid, the triangles (T_s, 3) of
    those points (among the NEAREST to it) that hold it strictly, no side longer than a pixel,
    smallest first."""
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
        triangles.append(t[keep][np.argsort(area, kind="stable")])
    return points, triangles
