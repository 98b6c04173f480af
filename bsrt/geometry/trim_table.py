"""The trim table the kernels test points against, built from the surfaces' trim loops.

``build_trim_table`` cuts every trim curve into Bezier spans and those into
monotone pieces (``bsrt.kernels.trim_pieces``), converts them to the power
basis and sorts them into bands of v per surface: the layout
:class:`bsrt.kernels.trim.TrimTable` documents. The loops themselves, and why a
point's parity against monotone pieces is exact, are in :mod:`bsrt.geometry.trim`.
"""

from __future__ import annotations

from math import comb
from typing import TYPE_CHECKING

import numpy as np

from bsrt.geometry.trim import _writable

if TYPE_CHECKING:
    from bsrt.kernels.trim import TrimTable

MAX_DEPTH = 48  # cuts of one Bezier span before a piece still turning back becomes its chord
BANDS_PER_PIECE = 2.0  # 1 to 4 measured within 10 % of each other; 2 the best on 200-piece loops
MAX_BANDS = 4096  # per surface


def build_trim_table(surfaces) -> TrimTable:
    """The TrimTable of a list of BSplineSurface (their ``trims``); surface m of the table is surfaces[m]."""
    from bsrt.kernels.trim import TrimTable
    from bsrt.kernels.trim_pieces import bezier_spans, monotone_pieces

    m_count = len(surfaces)
    trimmed = np.zeros(m_count, dtype=bool)
    nets, span_loop, span_surface = [], [], []
    loop_no = 0
    for m, surf in enumerate(surfaces):
        trimmed[m] = bool(surf.trims)
        for loop in surf.trims:
            for curve in loop.curves:
                x = bezier_spans(_writable(curve.knots), _writable(curve.homogeneous()), int(curve.degree))
                nets.append(x)
                span_loop.append(np.full(x.shape[0], loop_no, dtype=np.int64))
                span_surface.append(np.full(x.shape[0], m, dtype=np.int64))
            loop_no += 1
    width = max((x.shape[1] for x in nets), default=2)
    padded = np.zeros((sum(x.shape[0] for x in nets), width, 3))
    span_degree = np.zeros(padded.shape[0], dtype=np.int64)
    at = 0
    for x in nets:
        padded[at : at + x.shape[0], : x.shape[1]] = x
        span_degree[at : at + x.shape[0]] = x.shape[1] - 1
        at += x.shape[0]
    pieces, degree, src = monotone_pieces(padded, span_degree, MAX_DEPTH)
    loop = np.concatenate(span_loop)[src] if nets else np.zeros(0, dtype=np.int64)
    owner = np.concatenate(span_surface)[src] if nets else np.zeros(0, dtype=np.int64)
    k_count = degree.size
    idx = np.arange(k_count)

    # ends, chained: each piece starts exactly where the one before it in its loop ends
    last = pieces[idx, degree]
    end = last[:, :2] / last[:, 2:3]
    prev = idx - 1
    if k_count:
        first_of_loop = np.flatnonzero(np.r_[True, loop[1:] != loop[:-1]])
        prev[first_of_loop] = np.r_[first_of_loop[1:], k_count] - 1
    start = end[prev]
    ends = np.concatenate([start, end], axis=1)

    # control points relative to the start, then the power basis
    local = pieces.copy()
    local[..., 0] -= start[:, 0, None] * pieces[..., 2]
    local[..., 1] -= start[:, 1, None] * pieces[..., 2]
    coef = np.zeros_like(local)
    for d in np.unique(degree):
        sel = degree == d
        coef[sel, : d + 1] = np.einsum("kj,nkc->njc", _bernstein_to_power(int(d)), local[sel, : d + 1])

    used = np.arange(width)[None, :] <= degree[:, None]
    with np.errstate(all="ignore"):  # the padding rows have w = 0
        pts = pieces[..., :2] / pieces[..., 2:3]
    lo = np.minimum(np.where(used[..., None], pts, np.inf).min(axis=1), np.minimum(start, end))
    hi = np.maximum(np.where(used[..., None], pts, -np.inf).max(axis=1), np.maximum(start, end))
    box = np.stack([lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1]], axis=1).reshape(k_count, 4)

    band_first, band_count, band_v0, band_scale, band_start, entry_piece = _bands(owner, box, m_count)
    magnitude = np.zeros(m_count)
    np.maximum.at(magnitude, owner, np.abs(box).max(axis=1, initial=0.0))
    ev = ends[entry_piece][:, [1, 3]]
    entry_box = np.stack(
        [box[entry_piece, 0], box[entry_piece, 1], ev.min(axis=1, initial=np.inf), ev.max(axis=1, initial=-np.inf)],
        axis=1,
    ).reshape(-1, 4)
    c = np.ascontiguousarray
    return TrimTable(
        c(trimmed, dtype=np.bool_),
        c(band_first, dtype=np.int64),
        c(band_count, dtype=np.int64),
        c(band_v0, dtype=np.float64),
        c(band_scale, dtype=np.float64),
        c(magnitude, dtype=np.float64),
        c(degree, dtype=np.int64),
        c(coef, dtype=np.float64),
        c(ends, dtype=np.float64),
        c(box, dtype=np.float64),
        c(band_start, dtype=np.int64),
        c(entry_piece, dtype=np.int64),
        c(entry_box, dtype=np.float64),
    )


def loop_points(table: TrimTable, per_piece: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points on the trim loops of a table's surfaces: every piece at s = 0, 1/per_piece, ...
    (its end is the next piece's start). Returns (surface (P,) int64 index into the table's
    surfaces, u (P,), v (P,)), P = per_piece x pieces."""
    surface_of_band = np.repeat(np.arange(table.band_count.size), table.band_count)
    band_of_entry = np.repeat(np.arange(table.band_start.size - 1), np.diff(table.band_start))
    owner = np.zeros(table.degree.size, dtype=np.int64)
    owner[table.entry_piece] = surface_of_band[band_of_entry]  # every piece is in a band of its surface
    s = np.arange(per_piece) / per_piece
    powers = s[:, None] ** np.arange(table.coef.shape[1])  # (per_piece, D + 1)
    h = np.einsum("sj,kjc->ksc", powers, table.coef)  # (K, per_piece, 3): (w (u - u_a), w (v - v_a), w)
    u = table.ends[:, 0, None] + h[..., 0] / h[..., 2]
    v = table.ends[:, 1, None] + h[..., 1] / h[..., 2]
    return np.repeat(owner, per_piece), u.ravel(), v.ravel()


def _bernstein_to_power(d: int) -> np.ndarray:
    """(d + 1, d + 1) M with sum_k B_k,d(s) c_k = sum_j s^j (M^T c)_j, i.e. M[k, j] = C(d, j) C(j, k) (-1)^(j - k)."""
    return np.array(
        [[comb(d, j) * comb(j, k) * (-1) ** (j - k) if j >= k else 0.0 for j in range(d + 1)] for k in range(d + 1)]
    )


def _band_index(v, v0, scale, count):
    """The kernel's ``_band`` (bsrt/kernels/trim.py), elementwise and with the same float operations,
    without the surface's band_first: the band of v, in [0, count - 1]."""
    x = (v - v0) * scale
    inner = np.where(x > 0.0, x, 0.0)
    return np.where(x >= count, count - 1, np.where(x > 0.0, np.minimum(inner, count - 1).astype(np.int64), 0))


def _bands(owner: np.ndarray, box: np.ndarray, m_count: int):
    """Per surface, about BANDS_PER_PIECE bands per piece (at most MAX_BANDS) over the v-range of its
    pieces, each listing the pieces whose box meets it, by decreasing u_max: the band fields of
    TrimTable (band_first, band_count, band_v0, band_scale, band_start, entry_piece)."""
    pieces_per = np.bincount(owner, minlength=m_count)
    v0 = np.full(m_count, np.inf)
    v1 = np.full(m_count, -np.inf)
    np.minimum.at(v0, owner, box[:, 2])
    np.maximum.at(v1, owner, box[:, 3])
    count = np.clip(np.ceil(BANDS_PER_PIECE * pieces_per), 1, MAX_BANDS).astype(np.int64)
    with np.errstate(all="ignore"):
        scale = count / (v1 - v0)
    flat = ~(np.isfinite(scale) & (v1 > v0))  # no pieces, or all at one v: one band
    count[flat] = 1
    scale[flat] = 0.0
    v0[~np.isfinite(v0)] = 0.0
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    o = owner
    lo = _band_index(box[:, 2], v0[o], scale[o], count[o])
    hi = _band_index(box[:, 3], v0[o], scale[o], count[o])
    span = hi - lo + 1
    piece = np.repeat(np.arange(o.size), span)
    offset = np.arange(piece.size) - np.repeat(np.cumsum(span) - span, span)
    band = first[o][piece] + lo[piece] + offset
    order = np.lexsort((-box[piece, 1], band))
    total = int(count.sum())
    band_start = np.concatenate([[0], np.cumsum(np.bincount(band, minlength=total))]).astype(np.int64)
    return first, count, v0, scale, band_start, piece[order].astype(np.int64)


def kept(surface, u, v) -> np.ndarray:
    """(N,) bool: is each (u[i], v[i]) kept by the trims of one BSplineSurface? (u, v: scalars or (N,).)"""
    from bsrt.kernels.trim import kept_many

    u = np.atleast_1d(np.asarray(u, dtype=np.float64)).ravel()
    v = np.atleast_1d(np.asarray(v, dtype=np.float64)).ravel()
    u, v = np.broadcast_arrays(u, v)
    return kept_many(build_trim_table([surface]), np.zeros(u.size, dtype=np.int64), u, v)
