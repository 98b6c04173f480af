"""Edges drawn over a render: the model's exact boundary curves and its contours, anti-aliased.

Two sources, both independent of the film's resolution:

- Boundary curves (B-rep edges, trim boundaries, surface borders, creases):
  every trim curve of every surface (the same ``TrimCurve`` objects the trim
  table is built from), the four borders of each untrimmed surface's
  domain, and the creases inside a surface (crease_curves: the iso-curves at
  its interior knots of multiplicity >= the degree, along the spans where
  its normal turns by more than CREASE_DEGREES across the knot, clipped by
  its trims) are sampled in their own parameter, mapped onto the surface in 3-D
  (``PatchSet.evaluate``) and projected onto the film; a span is cut until
  its chord is at most MAX_STEP pixels on the film. A border along which
  the surface closes onto itself (a periodic seam: S at the opposite border
  is the same point) is not an edge and is left out. Each sample is tested
  for visibility exactly: a ray from the eye to the sample through the
  hierarchy (any hit before the sample, by more than 1e-6 of the scene's
  diagonal plus 0.02 of a pixel's footprint at its distance, hides it: a
  ray grazing the edge's own face near a silhouette does not). Consecutive
  samples make segments; a segment with one end hidden is cut at its middle.
- Contours (silhouettes against the background or against a surface further
  back, folds of a surface behind itself): pairs of neighbouring pixels
  whose centre rays hit and miss, or hit at depths differing by more than
  JUMP pixel footprints. The crossing between the two centres is located by
  bisection with rays (BISECTIONS steps: 1/64 pixel), and the crossings of
  each 2 x 2 cell of pixel centres are joined (marching squares).

Segments become coverage by their distance to each pixel centre: a line of
width w covers clip(w / 2 + 1/2 - distance, 0, min(w, 1)) of a pixel (a box
filter across the line), the maximum over the segments (an edge drawn twice,
once by each face, is not darker). The colour is blended in linear RGB:
``linear * (1 - c) + edge_color * c``. Hidden edges (``hidden_edges``) are
drawn dashed at HIDDEN_WEIGHT of the coverage.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.trim import kept_many
from bsrt.rendering.hits import Hits
from bsrt.rendering.screen import film_rays, project

MAX_STEP = 0.4  # pixels: the longest chord between two samples of a curve on the film
SPAN_SAMPLES = 4  # first samples per knot span of a curve, before cutting to MAX_STEP
MAX_SAMPLES = 1 << 22  # samples of all the curves at most (a camera inside the model)
JUMP = 16.0  # pixel footprints: a depth step between neighbouring pixels larger than this is a contour
BISECTIONS = 6
HIDDEN_WEIGHT = 0.45  # coverage of a hidden edge, relative to a visible one
SEAM_TOLERANCE = 1e-7  # of the scene's diagonal: a border meeting its opposite border this closely is a seam
SEGMENT_CHUNK = 1 << 14
MAX_PIECE = 8.0  # pixels: segments are rasterised in pieces at most this long
VISIBILITY_MARGIN = 0.02  # pixels: a surface less than this in front of an edge (a grazing ray) does not hide it
# a knot line of a surface is a crease where its two sides' normals are more than this apart: a C0 knot
# (multiplicity >= degree) along which the surface is still smooth (G1: its control points in line) is no edge
CREASE_DEGREES = 1.0


class _Curve:
    """One boundary curve of surface m: uv(s) -> (N, 2) for s in [a, b]; knots: the span breaks."""

    def __init__(self, m: int, uv, a: float, b: float, knots: np.ndarray, clip: bool = False):
        self.m, self.uv, self.a, self.b, self.clip = m, uv, a, b, clip  # clip: drawn only where the trims keep it
        self.knots = np.unique(np.concatenate([[a, b], knots[(knots > a) & (knots < b)]]))


def _border(u0, u1, v0, v1, which: int):
    """The domain border ``which`` (0: v = v0, 1: u = u1, 2: v = v1, 3: u = u0) as uv(s), s in [0, 1]."""
    ends = ((u0, v0, u1, v0), (u1, v0, u1, v1), (u1, v1, u0, v1), (u0, v1, u0, v0))[which]

    def uv(s):
        s = np.asarray(s, dtype=np.float64)
        return np.stack([ends[0] + (ends[2] - ends[0]) * s, ends[1] + (ends[3] - ends[1]) * s], axis=1)

    return uv


def boundary_curves(patches) -> list[_Curve]:
    """Every surface's trim curves (trimmed surfaces) or its four domain borders (the others)."""
    curves = []
    for m, surface in enumerate(patches.surfaces):
        if surface.is_trimmed:
            for loop in surface.trims:
                for c in loop.curves:
                    a, b = c.domain
                    curves.append(_Curve(m, c.evaluate, a, b, np.asarray(c.knots, dtype=np.float64)))
        else:
            u0, u1, v0, v1 = patches.domain[m]
            for which in range(4):
                curves.append(_Curve(m, _border(u0, u1, v0, v1, which), 0.0, 1.0, np.zeros(0)))
    return curves + crease_curves(patches)


def crease_curves(patches) -> list[_Curve]:
    """The creases inside every surface: at each interior knot of multiplicity >= the degree (in u or
    v), the iso-curve along the spans of the other parameter where the normals of the two patches
    that meet there differ by more than CREASE_DEGREES (checked at SPAN_SAMPLES + 1 points of each
    span); consecutive such spans make one curve. Clipped by the surface's trims when drawn."""
    cos_limit = np.cos(np.radians(CREASE_DEGREES))
    curves = []
    for m, surface in enumerate(patches.surfaces):
        u0, u1, v0, v1 = patches.domain[m]
        for axis, knots, other_knots, degree in (
            (0, surface.knots_u, surface.knots_v, surface.degree[0]),
            (1, surface.knots_v, surface.knots_u, surface.degree[1]),
        ):
            lo, hi = (u0, u1) if axis == 0 else (v0, v1)
            a, b = (v0, v1) if axis == 0 else (u0, u1)
            values, counts = np.unique(knots, return_counts=True)
            breaks = np.unique(np.concatenate([[a, b], other_knots[(other_knots > a) & (other_knots < b)]]))
            for k in values[(values > lo) & (values < hi) & (counts >= degree)]:
                creased = _creased_spans(patches, m, axis, float(k), breaks, cos_limit)
                for first, stop in _runs(creased):
                    uv = _iso(axis, float(k))
                    curves.append(_Curve(m, uv, breaks[first], breaks[stop], breaks, clip=surface.is_trimmed))
    return curves


def _iso(axis: int, k: float):
    """The iso-curve u = k (axis 0) or v = k (axis 1) as uv(s), s the other parameter."""

    def uv(s):
        s = np.asarray(s, dtype=np.float64)
        fixed = np.full(s.shape, k)
        return np.stack([fixed, s] if axis == 0 else [s, fixed], axis=1)

    return uv


def _creased_spans(patches, m: int, axis: int, k: float, breaks: np.ndarray, cos_limit: float) -> np.ndarray:
    """(len(breaks) - 1,) bool: whether the normals on the two sides of the knot line (axis, k) of
    surface m differ by more than the angle of cos_limit somewhere in each span of breaks (a side
    whose normal vanishes there, a degenerate point, decides nothing)."""
    t = np.linspace(0.0, 1.0, SPAN_SAMPLES + 1)
    s = (breaks[:-1, None] + (breaks[1:] - breaks[:-1])[:, None] * t[None, :]).ravel()  # (spans * (n + 1),)
    uv = _iso(axis, k)(s)
    side = np.zeros_like(uv)
    lo, hi = patches.domain[m, 2 * axis : 2 * axis + 2]
    side[:, axis] = max(1e-9 * (hi - lo), 8.0 * np.spacing(abs(k)))  # into the span before / after the knot
    surface = np.full(s.size, m, dtype=np.int64)
    normals = []
    for shift in (-side, side):  # the patch before the knot, then the one after, both evaluated on it
        near = uv + shift
        patch = patches.locate(surface, near[:, 0], near[:, 1])
        _, su, sv = patches.evaluate(patch, uv[:, 0], uv[:, 1])
        normals.append(np.cross(su.T, sv.T))
    na, nb = normals
    size = np.linalg.norm(na, axis=1) * np.linalg.norm(nb, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("ij,ij->i", na, nb) / size
    creased = (size > 0) & (cos < cos_limit)
    return creased.reshape(breaks.size - 1, SPAN_SAMPLES + 1).any(axis=1)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, stop) of each run of True in flags: flags[first:stop] all True."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _points(patches, m: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N, 3) world points S_m(u, v) of surfaces m (N,) at uv (N, 2)."""
    if not m.size:
        return np.zeros((0, 3))
    patch = patches.locate(m, uv[:, 0], uv[:, 1])
    return patches.evaluate(patch, uv[:, 0], uv[:, 1], derivatives=False).T.copy()


def _is_seam(patches, curve: _Curve, uv: np.ndarray, diagonal: float) -> bool:
    """Whether the curve runs along a border of its surface's domain that the surface closes across."""
    u0, u1, v0, v1 = patches.domain[curve.m]
    near_u, near_v = 1e-9 * max(u1 - u0, 1e-300), 1e-9 * max(v1 - v0, 1e-300)
    for axis, lo, hi, near in ((0, u0, u1, near_u), (1, v0, v1, near_v)):
        for at, other in ((lo, hi), (hi, lo)):
            if np.all(np.abs(uv[:, axis] - at) <= near):
                mirrored = uv.copy()
                mirrored[:, axis] = other
                m = np.full(uv.shape[0], curve.m, dtype=np.int64)
                gap = np.linalg.norm(_points(patches, m, uv) - _points(patches, m, mirrored), axis=1)
                return bool(np.all(gap <= SEAM_TOLERANCE * diagonal))
    return False


def sample_curves(patches, camera, width: int, height: int, diagonal: float):
    """The boundary curves sampled to MAX_STEP pixels on the film.

    Returns (curve (N,) int64 index of the curve of each sample, consecutive
    within a curve; m (N,) int64 surface; points (N, 3) float64 world; xy
    (N, 2) float64 film positions; depth (N,) float64 along the view axis,
    NaN where a clipped curve (a crease) lies in a trimmed-away part of its
    surface: no segment ends there)."""
    curves = boundary_curves(patches)
    coarse_s = [
        np.concatenate(
            [np.linspace(k0, k1, SPAN_SAMPLES + 1)[:-1] for k0, k1 in zip(c.knots[:-1], c.knots[1:])] + [[c.b]]
        )
        for c in curves
    ]
    counts = np.array([s.size for s in coarse_s], dtype=np.int64)
    if not counts.size:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0)
    uv = np.concatenate([c.uv(s) for c, s in zip(curves, coarse_s)])
    owner = np.repeat(np.arange(len(curves)), counts)
    m = np.array([c.m for c in curves], dtype=np.int64)[owner]
    xy, depth = project(camera, width, height, _points(patches, m, uv))
    starts = np.concatenate([[0], np.cumsum(counts)])
    out_s, out_curve = [], []
    budget = MAX_SAMPLES
    for k, c in enumerate(curves):
        lo, hi = starts[k], starts[k + 1]
        if _is_seam(patches, c, uv[lo:hi], diagonal):
            continue
        s = coarse_s[k]
        p, z = xy[lo:hi], depth[lo:hi]
        front = (z[:-1] > 0) & (z[1:] > 0)
        step = np.where(front, np.linalg.norm(np.nan_to_num(p[1:] - p[:-1]), axis=1), 0.0)
        margin = 4.0
        off = (
            ((p[:-1, 0] < -margin) & (p[1:, 0] < -margin))
            | ((p[:-1, 0] > width + margin) & (p[1:, 0] > width + margin))
            | ((p[:-1, 1] < -margin) & (p[1:, 1] < -margin))
            | ((p[:-1, 1] > height + margin) & (p[1:, 1] > height + margin))
        )
        cuts = np.where(off, 1, np.clip(np.ceil(step / MAX_STEP), 1, 4096)).astype(np.int64)
        if cuts.sum() > budget:
            break
        budget -= int(cuts.sum())
        frac = np.concatenate([np.arange(n) / n for n in cuts])
        left = np.repeat(s[:-1], cuts)
        fine = np.concatenate([left + frac * (np.repeat(s[1:], cuts) - left), [s[-1]]])
        out_s.append(c.uv(fine))
        out_curve.append(np.full(fine.size, k, dtype=np.int64))
    if not out_s:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0)
    curve = np.concatenate(out_curve)
    uv = np.concatenate(out_s)
    m = np.array([c.m for c in curves], dtype=np.int64)[curve]
    points = _points(patches, m, uv)
    xy, depth = project(camera, width, height, points)
    clip = np.array([c.clip for c in curves])[curve]
    if clip.any():
        clip[clip] = ~kept_many(patches.trims, m[clip], uv[clip, 0], uv[clip, 1])
        depth[clip] = np.nan
    return curve, m, points, xy, depth


def visible(geometry, eye: np.ndarray, points: np.ndarray, tolerance: float, footprint: float) -> np.ndarray:
    """(N,) bool: whether each world point (N, 3) is seen from the eye: nothing is hit before it by
    more than 1e-6 of the scene's diagonal plus VISIBILITY_MARGIN pixels (footprint: a pixel's size at
    unit distance) of its distance."""
    if not points.shape[0]:
        return np.zeros(0, dtype=bool)
    to = points - eye
    dist = np.linalg.norm(to, axis=1)
    margin = 1e-6 * geometry.diagonal + VISIBILITY_MARGIN * footprint * dist
    blocked = geometry.intersect(
        eye[None, :], to, t_min=0.0, t_max=np.maximum(dist - margin, 0.0), tolerance=tolerance, any_hit=True
    )
    return ~blocked.hit


def curve_segments(curve, xy, depth, seen, hidden: bool, width_px: float):
    """Segments (K, 4) float64 (x0, y0, x1, y1) in film pixels and their weights (K,):
    consecutive samples of one curve, both in front of the eye; visible parts weight 1,
    hidden parts (only if ``hidden``) HIDDEN_WEIGHT on the dashes, 0 elsewhere."""
    same = (curve[1:] == curve[:-1]) & (depth[1:] > 0) & (depth[:-1] > 0)
    a, b = np.flatnonzero(same), np.flatnonzero(same) + 1
    pa, pb = xy[a], xy[b]
    mid = 0.5 * (pa + pb)
    va, vb = seen[a], seen[b]
    # a segment seen at one end only: the seen half
    segs = [
        np.concatenate([pa[va & vb], pb[va & vb]], axis=1),
        np.concatenate([pa[va & ~vb], mid[va & ~vb]], axis=1),
        np.concatenate([mid[~va & vb], pb[~va & vb]], axis=1),
    ]
    weights = [np.ones(s.shape[0]) for s in segs]
    if hidden:
        along = _dash_phase(curve[a], np.linalg.norm(pb - pa, axis=1), xy, curve)
        period = max(8.0, 6.0 * width_px)  # a gap of half of it, less the round caps (w / 2 + 1/2 each)
        dash = np.mod(along, period) < 0.5 * period
        for keep, p0, p1 in ((~va & ~vb, pa, pb), (va & ~vb, mid, pb), (~va & vb, pa, mid)):
            keep = keep & dash
            segs.append(np.concatenate([p0[keep], p1[keep]], axis=1))
            weights.append(np.full(int(keep.sum()), HIDDEN_WEIGHT))
    return np.concatenate(segs), np.concatenate(weights)


def _dash_phase(owner: np.ndarray, length: np.ndarray, xy: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Film arc length (K,) at the middle of each segment along its curve, measured from the curve's end
    that comes first (by rounded film x, then y), so the two faces' copies of an edge dash alike.
    owner: (K,) the curve of each segment (non-decreasing); length: (K,) the segments' film lengths;
    xy, curve: the samples' film positions (N, 2) and curves (N,)."""
    if not owner.size:
        return np.zeros(0)
    total = np.cumsum(length)
    first = np.concatenate([[True], owner[1:] != owner[:-1]])
    start = np.flatnonzero(first)
    base = np.repeat(total[start] - length[start], np.diff(np.concatenate([start, [owner.size]])))
    mid = total - base - 0.5 * length
    ids, at = np.unique(curve, return_index=True)
    end = np.concatenate([at[1:], [curve.size]]) - 1
    p0, p1 = np.round(xy[at], 3), np.round(xy[end], 3)
    flip = (p0[:, 0] > p1[:, 0]) | ((p0[:, 0] == p1[:, 0]) & (p0[:, 1] > p1[:, 1]))
    curve_length = np.zeros(ids.size)
    np.add.at(curve_length, np.searchsorted(ids, owner), length)
    k = np.searchsorted(ids, owner)
    return np.where(flip[k], curve_length[k] - mid, mid)


def contour_segments(geometry, camera, width: int, height: int, hits: Hits, footprint: float, tolerance: float):
    """Segments (K, 4) float64 along the contours: where neighbouring pixel-centre rays (``hits``,
    H * W row-major) hit and miss, or hit at depths differing by more than JUMP pixel footprints;
    each crossing located by bisection between the two centres."""
    hit = hits.hit.reshape(height, width)
    t = np.where(hit, np.nan_to_num(hits.t.reshape(height, width), nan=np.inf), np.inf)
    crossings = []
    for axis in (1, 0):  # 1: horizontal pairs (i, j)-(i, j + 1); 0: vertical pairs (i, j)-(i + 1, j)
        n = width if axis == 1 else height
        a = (slice(None), slice(0, n - 1)) if axis == 1 else (slice(0, n - 1), slice(None))
        b = (slice(None), slice(1, n)) if axis == 1 else (slice(1, n), slice(None))
        ta, tb = t[a], t[b]
        near_t = np.minimum(ta, tb)
        with np.errstate(invalid="ignore"):  # inf - inf where both miss
            jump = (hit[a] != hit[b]) | (hit[a] & hit[b] & (np.abs(ta - tb) > JUMP * footprint * near_t))
        i, j = np.nonzero(jump)
        centre_a = np.stack([j + 0.5, i + 0.5], axis=1)
        centre_b = centre_a + (np.array([1.0, 0.0]) if axis == 1 else np.array([0.0, 1.0]))
        a_near = ta[i, j] <= tb[i, j]
        lo = np.where(a_near[:, None], centre_a, centre_b)  # the near side
        hi = np.where(a_near[:, None], centre_b, centre_a)
        t_near, t_far = np.minimum(ta[i, j], tb[i, j]), np.maximum(ta[i, j], tb[i, j])
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            seen = geometry.intersect(camera.eye[None, :], film_rays(camera, width, height, mid), tolerance=tolerance)
            ts = np.where(seen.hit, seen.t, np.inf)
            with np.errstate(invalid="ignore"):
                near = seen.hit & (~np.isfinite(t_far) | (np.abs(ts - t_near) < np.abs(ts - t_far)))
            lo = np.where(near[:, None], mid, lo)
            hi = np.where(near[:, None], hi, mid)
        grid = np.full((height, width, 2), np.nan)
        grid[i, j] = 0.5 * (lo + hi)
        crossings.append(grid)
    across, down = crossings  # across[i, j]: between (i, j) and (i, j + 1); down[i, j]: (i, j) and (i + 1, j)
    if height < 2 or width < 2:
        return np.zeros((0, 4))
    sides = np.stack(
        [across[:-1, :-1], across[1:, :-1], down[:-1, :-1], down[:-1, 1:]], axis=2
    )  # (H - 1, W - 1, 4, 2): top, bottom, left, right of each cell of four pixel centres
    has = ~np.isnan(sides[..., 0])
    count = has.sum(axis=2)
    cells = np.flatnonzero(count.ravel() > 0)
    sides, has, count = sides.reshape(-1, 4, 2)[cells], has.reshape(-1, 4)[cells], count.ravel()[cells]
    out = []
    two = count == 2
    pairs = sides[two][has[two]].reshape(-1, 2, 2)
    out.append(pairs.reshape(-1, 4))
    other = ~two  # one crossing: a dot; three or four: each to their centroid
    centre = np.nansum(sides[other], axis=1) / count[other][:, None]
    ends = np.repeat(centre, 4, axis=0).reshape(-1, 4, 2)
    starts = sides[other]
    keep = has[other]
    out.append(np.concatenate([starts[keep], ends[keep]], axis=1))
    return np.concatenate(out)


def _clipped(segments: np.ndarray, weights: np.ndarray, width: int, height: int, reach: float):
    """The parts of segments (K, 4) within the film grown by reach, cut into pieces at most MAX_PIECE
    pixels long (so each piece's box of pixels is small), with their weights; non-finite ones dropped."""
    keep = np.all(np.isfinite(segments), axis=1)
    segments, weights = segments[keep], weights[keep]
    a, d = segments[:, :2], segments[:, 2:] - segments[:, :2]
    t0, t1 = np.zeros(len(segments)), np.ones(len(segments))
    for axis, size in ((0, width), (1, height)):  # Liang-Barsky, one slab per axis
        lo, hi = -reach - a[:, axis], size + reach - a[:, axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = lo / d[:, axis], hi / d[:, axis]
        flat = d[:, axis] == 0
        t0 = np.where(flat, np.where((lo <= 0) & (hi >= 0), t0, 2.0), np.maximum(t0, np.minimum(ta, tb)))
        t1 = np.where(flat, t1, np.minimum(t1, np.maximum(ta, tb)))
    keep = t0 <= t1
    a, d, t0, t1, weights = a[keep], d[keep], t0[keep], t1[keep], weights[keep]
    start, stop = a + t0[:, None] * d, a + t1[:, None] * d
    pieces = np.maximum(1, np.ceil(np.linalg.norm(stop - start, axis=1) / MAX_PIECE)).astype(np.int64)
    k = np.repeat(np.arange(pieces.size), pieces)
    i = np.arange(k.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    f0, f1 = (i / pieces[k])[:, None], ((i + 1) / pieces[k])[:, None]
    step = stop[k] - start[k]
    return np.concatenate([start[k] + f0 * step, start[k] + f1 * step], axis=1), weights[k]


def rasterize(segments: np.ndarray, weights: np.ndarray, width_px: float, width: int, height: int) -> np.ndarray:
    """Coverage (H, W) float64 in [0, 1] of lines of width_px pixels along segments (K, 4)
    (x0, y0, x1, y1 film pixels), each scaled by its weight (K,): the maximum over the segments."""
    cover = np.zeros(height * width)
    reach = 0.5 * width_px + 0.5
    top = min(width_px, 1.0)
    segments, weights = _clipped(segments, weights, width, height, reach)
    for c in range(0, segments.shape[0], SEGMENT_CHUNK):
        seg, wt = segments[c : c + SEGMENT_CHUNK], weights[c : c + SEGMENT_CHUNK]
        x0 = np.floor(np.minimum(seg[:, 0], seg[:, 2]) - reach - 0.5).astype(np.int64)
        x1 = np.ceil(np.maximum(seg[:, 0], seg[:, 2]) + reach - 0.5).astype(np.int64)
        y0 = np.floor(np.minimum(seg[:, 1], seg[:, 3]) - reach - 0.5).astype(np.int64)
        y1 = np.ceil(np.maximum(seg[:, 1], seg[:, 3]) + reach - 0.5).astype(np.int64)
        x0, x1 = np.clip(x0, 0, width - 1), np.clip(x1, 0, width - 1)
        y0, y1 = np.clip(y0, 0, height - 1), np.clip(y1, 0, height - 1)
        nx, ny = np.maximum(x1 - x0 + 1, 0), np.maximum(y1 - y0 + 1, 0)
        inside = (seg[:, [0, 2]].max(axis=1) > -reach) & (seg[:, [0, 2]].min(axis=1) < width + reach)
        inside &= (seg[:, [1, 3]].max(axis=1) > -reach) & (seg[:, [1, 3]].min(axis=1) < height + reach)
        size = np.where(inside, nx * ny, 0)
        k = np.repeat(np.arange(seg.shape[0]), size)
        if not k.size:
            continue
        local = np.arange(k.size) - np.repeat(np.cumsum(size) - size, size)
        px = x0[k] + local % nx[k]
        py = y0[k] + local // nx[k]
        cx, cy = px + 0.5, py + 0.5
        ax, ay, bx, by = seg[k, 0], seg[k, 1], seg[k, 2], seg[k, 3]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(length2 > 0, np.clip(((cx - ax) * dx + (cy - ay) * dy) / length2, 0.0, 1.0), 0.0)
        dist = np.hypot(cx - (ax + s * dx), cy - (ay + s * dy))
        value = np.clip(reach - dist, 0.0, top) * wt[k]
        np.maximum.at(cover, py * width + px, value)
    return cover.reshape(height, width)


def edge_coverage(geometry, options, hits: Hits, stats=None) -> np.ndarray:
    """Coverage (H, W) float64 of the edges options asks for (options.edges, edge_width,
    hidden_edges) on the film of options (camera, width, height); hits: the H * W pixel-centre hits."""
    from bsrt.scene.camera import pixel_footprint

    camera, width, height = options.camera, options.width, options.height
    tolerance = options.tolerance * geometry.diagonal
    curve, _, points, xy, depth = sample_curves(geometry.patches, camera, width, height, geometry.diagonal)
    footprint = pixel_footprint(camera, width, height)
    seen = visible(geometry, camera.eye, points, tolerance, footprint) & (depth > 0)
    segments, weights = curve_segments(curve, xy, depth, seen, options.hidden_edges, options.edge_width)
    contours = contour_segments(geometry, camera, width, height, hits, footprint, tolerance)
    if stats is not None:
        stats.add("edge_samples", points.shape[0])
        stats.add("edge_segments", segments.shape[0])
        stats.add("contour_segments", contours.shape[0])
    all_segments = np.concatenate([segments, contours])
    all_weights = np.concatenate([weights, np.ones(contours.shape[0])])
    return rasterize(all_segments, all_weights, options.edge_width, width, height)


def draw(linear: np.ndarray, coverage: np.ndarray, color) -> np.ndarray:
    """linear: (H, W, 3) float64 linear RGB; coverage: (H, W) in [0, 1] -> the blend, (H, W, 3)."""
    c = coverage[..., None]
    return linear * (1.0 - c) + np.asarray(color, dtype=np.float64) * c


def draw_over(linear, pixels, coverage, hits: Hits, options, geometry, stats):
    """The edges drawn over a render's image, in place: pixels (H, W, 3) uint8 and, when kept,
    linear (H, W, 3) float64 (else the 8-bit pixels under a line are decoded to blend with; both
    get the same bytes, as the film writes them). Returns the coverage (H, W): a line adds to it
    (the alpha) as it covers the pixel, ``a + e (1 - a)``, so a transparent picture keeps the lines
    drawn over the background (None stays None). hits: the H * W pixel-centre hits."""
    from bsrt.rendering.image import srgb_decode, srgb_encode

    with stats.timer("edges"):
        lines = edge_coverage(geometry, options, hits, stats)
        under = lines > 0
        base = linear[under] if linear is not None else srgb_decode(pixels[under])
        blended = draw(base, lines[under], options.edge_color)
        if linear is not None:
            linear[under] = blended
        pixels[under] = srgb_encode(blended)
    return None if coverage is None else coverage + lines * (1.0 - coverage)
