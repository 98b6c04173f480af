"""The preliminary map's triangles: each Bezier patch as a grid fine enough for the map.

The grid's chords stay within half a pixel of the surface (the second-difference
bound of Filip, Magedson & Markot 1986, with the pixel footprint at the patch's
nearest distance), capped at MAX_SEGMENTS x MAX_SEGMENTS quads per patch.
Trimmed surfaces: cells that the trims remove entirely are left out, and the
cells that trim curves cross are cut (in their plane) into pieces whose
fragments the trim test would discard (left out), keep (drawn plainly), or
both (drawn with the trim test per fragment). The test keeps every fragment
within a margin of a trim curve that bounds how far the map's interpolated
(u, v) is from the (u, v) of the point the pixel sees (_param_per_pixel), so
the map never loses a kept part. Drawn by prelim.py; the preview's moving
view draws the same grids.
"""

from __future__ import annotations

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.trim import INSIDE, MIXED, OUTSIDE, classify_grid, rect_states
from bsrt.scene.camera import Camera, pixel_footprint

MAX_SEGMENTS = 64


def segments_per_patch(patches: PatchSet, camera: Camera, width: int, height: int) -> np.ndarray:
    """(P, 2) int64: quads along u and v for each patch (1..MAX_SEGMENTS)."""
    pixel_at_unit_distance = pixel_footprint(camera, width, height)
    lo, hi = patches.box_min, patches.box_max
    nearest = np.linalg.norm(np.maximum(np.maximum(lo - camera.eye, camera.eye - hi), 0.0), axis=1)
    diag = max(patches.scene_diagonal(), 1e-300)
    tolerance = 0.5 * pixel_at_unit_distance * np.maximum(nearest, 1e-3 * diag)
    m_uu, m_vv, m_uv = patches.bend.T
    # chord error <= (m_uu / n_u^2 + 2 m_uv / (n_u n_v) + m_vv / n_v^2) / 8
    n_u = np.sqrt((m_uu + m_uv) / (4.0 * tolerance))
    n_v = np.sqrt((m_vv + m_uv) / (4.0 * tolerance))
    return np.clip(np.ceil(np.stack([n_u, n_v], axis=1)), 1, MAX_SEGMENTS).astype(np.int64)


def tessellate(patches: PatchSet, segments: np.ndarray, eye: np.ndarray):
    """Watertight triangles of every surface.

    Each surface gets one grid whose lines include all its knots, every span
    cut into the largest segment count of that surface's patches, so patches
    share their border vertices exactly (no T-junctions, no cracks).
    segments: (P, 2) quads per patch. Returns (vertices (V, 6) float32 rows
    (x, y, z eye-relative, u_norm, v_norm, surface index + 1), indices (T, 3)
    uint32). Cells of a trimmed surface that its trims remove entirely are
    left out; cells the trim curves cross stay (the map then shows a little
    more than the kept region, and those pixels' roots are refused and
    repaired as hard pixels), so the map never misses a kept part.
    """
    verts, tris, _ = _grids(patches, segments, eye)
    return np.concatenate(verts), np.concatenate([t for t, _ in tris]).astype(np.uint32)


def _grids(
    patches: PatchSet, segments: np.ndarray, eye: np.ndarray, camera: Camera | None = None, footprint: float = 0.0
):
    """tessellate()'s pieces, surface by surface: (vertex blocks [(V_m, 6) float32],
    [(triangles (T_m, 3) int64 indices into the concatenated blocks, mixed (T_m,)
    bool: the triangle's cell is MIXED, trim curves may cross it)], reach).

    With a camera (and footprint = pixel_footprint), reach is (T, 2) float64
    over the concatenated triangles: the trim test's margin along u and v of
    each mixed triangle's cell, TRIM_GROW times the largest _param_per_pixel
    bound of its four corners (NaN where not mixed, or where the view is
    singular at a corner); else None.
    """
    verts, tris, base = [], [], 0  # every surface's grid vertices; the triangles of its kept cells
    at, cells, count, len_at = [], [], 0, 0  # the mixed cells' corners (S, Su, Sv, chord); (cell rows, corner rows)
    for m in range(len(patches.surfaces)):
        mine = patches.surface == m
        n_u, n_v = segments[mine].max(axis=0)
        b = patches.bounds[mine]
        gu = _refined_breaks(np.unique(b[:, :2]), n_u)
        gv = _refined_breaks(np.unique(b[:, 2:]), n_v)
        u, v = np.meshgrid(gu, gv, indexing="ij")
        u, v = u.ravel(), v.ravel()
        sid = np.full(u.size, m)
        i, j = np.meshgrid(np.arange(gu.size - 1), np.arange(gv.size - 1), indexing="ij")
        i, j = i.ravel(), j.ravel()
        mixed = np.zeros(i.size, dtype=bool)
        if patches.surfaces[m].is_trimmed:  # leave out the cells the trims remove entirely
            state = np.empty((gu.size - 1, gv.size - 1), dtype=np.int64)
            classify_grid(patches.trims, m, gu, gv, state)
            keep = state[i, j] != OUTSIDE
            i, j = i[keep], j[keep]
            mixed = state[i, j] == MIXED
        patch = patches.locate(sid, u, v)
        wants_reach = camera is not None and mixed.any()
        if wants_reach:
            S, Su, Sv = patches.evaluate(patch, u, v, derivatives=True)
        else:
            S = patches.evaluate(patch, u, v, derivatives=False)
        d = patches.domain[m]
        block = np.empty((u.size, 6), dtype=np.float32)
        block[:, :3] = (S.T - eye).astype(np.float32)
        block[:, 3] = (u - d[0]) / (d[1] - d[0])
        block[:, 4] = (v - d[2]) / (d[3] - d[2])
        block[:, 5] = m + 1
        verts.append(block)
        corner = i * gv.size + j
        quad = np.stack([corner, corner + gv.size, corner + gv.size + 1, corner + 1], axis=1)
        tris.append((base + np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]), np.concatenate([mixed, mixed])))
        if wants_reach:  # the mixed cells' corners, in one batch below
            corners = np.unique(quad[mixed])
            chord = _chord_bound(patches.bend[mine], n_u, n_v).max()
            at.append((S.T[corners], Su.T[corners], Sv.T[corners], np.full(corners.size, chord)))
            cells.append(
                (
                    count + np.flatnonzero(np.concatenate([mixed, mixed])),
                    len_at + np.searchsorted(corners, np.concatenate([quad[mixed], quad[mixed]])),
                )
            )
            len_at += corners.size
        count += 2 * quad.shape[0]
        base += u.size
    if camera is None:
        return verts, tris, None
    reach = np.full((count, 2), np.nan)
    if at:
        S, Su, Sv, chord = (np.concatenate(a) for a in zip(*at))
        at_vertex = _param_per_pixel(camera, footprint, S, Su, Sv, chord)
        for rows, corner in cells:
            reach[rows] = TRIM_GROW * at_vertex[corner].max(axis=1)  # NaN (any corner) stays NaN
    return verts, tris, reach


# The map's trim test keeps a fragment whose (u, v) lies within this many
# times the first-order parameter error (_param_per_pixel, the largest at the
# cell's corners) of a trim curve: a safety factor for the Jacobian's change
# over a cell and for the linearisation.
TRIM_GROW = 2.0


def _chord_bound(bend: np.ndarray, n_u: int, n_v: int) -> np.ndarray:
    """(K,) the chord error bound of patches with bend (K, 3) cut into n_u x n_v quads
    (segments_per_patch's formula: the distance of a triangle point from S at the
    same interpolated (u, v))."""
    m_uu, m_vv, m_uv = bend.T
    return (m_uu / n_u**2 + 2.0 * m_uv / (n_u * n_v) + m_vv / n_v**2) / 8.0


def _param_per_pixel(
    camera: Camera, footprint: float, S: np.ndarray, Su: np.ndarray, Sv: np.ndarray, chord
) -> np.ndarray:
    """(N, 2) float64: how far (u, v) may be from the true hit's, along u and v, at a map
    fragment drawn near the surface point S (N, 3) with derivatives Su, Sv (N, 3), on a
    tessellation whose chord error is at most chord (scalar or (N,)); NaN where the
    view is singular there (behind the eye, edge-on).

    A fragment at pixel p carries the (u, v) that the triangle interpolates at
    its point P on p's ray (perspective-correct), and S(u, v) lies within the
    chord bound of P (segments_per_patch), so S(u, v) appears within
    E = chord_px + 1 pixels of p (chord_px: that 3-D distance on the film,
    |P| / (z^2 footprint) pixels per unit at depth z; the 1: a line-pass
    fragment lies up to a pixel off its line's point). The true hit at p has
    its own (u, v) on the same surface, so to first order they differ by
    J^-1 e, |e| <= E, with J the 2x2 Jacobian of film pixels by (u, v):
    |du| <= E (|J^-1_ux| + |J^-1_uy|), likewise dv.
    """
    r, up, f = camera.basis()
    P = S - camera.eye
    z = P @ f
    with np.errstate(all="ignore"):
        inv = 1.0 / (z * footprint)
        # d(pixel x)/dS = (r - (P.r / z) f) / (z footprint), likewise y with up
        gx = (r[None, :] - ((P @ r) / z)[:, None] * f[None, :]) * inv[:, None]
        gy = (up[None, :] - ((P @ up) / z)[:, None] * f[None, :]) * inv[:, None]
        a, b = (gx * Su).sum(axis=1), (gx * Sv).sum(axis=1)  # J = [[a, b], [c, d]]
        c, d = (gy * Su).sum(axis=1), (gy * Sv).sum(axis=1)
        det = a * d - b * c
        spread = 1.0 + chord * np.linalg.norm(P, axis=1) * inv / z
        out = np.stack([(np.abs(d) + np.abs(b)), (np.abs(c) + np.abs(a))], axis=1) * (spread / np.abs(det))[:, None]
        scale = np.maximum(np.abs(a) + np.abs(b), np.abs(c) + np.abs(d))
        bad = ~(z > 0) | ~(np.abs(det) > 1e-12 * scale * scale) | ~np.isfinite(out).all(axis=1)
    out[bad] = np.nan
    return out


def _refined_breaks(breaks: np.ndarray, n: int) -> np.ndarray:
    """Every interval of the sorted breaks (K,) cut into n equal parts -> ((K-1) n + 1,)."""
    steps = np.linspace(0.0, 1.0, n + 1)[:-1]
    inner = (breaks[:-1, None] + np.diff(breaks)[:, None] * steps[None, :]).ravel()
    return np.concatenate([inner, breaks[-1:]])


def depth_range(patches: PatchSet, camera: Camera) -> tuple[float, float]:
    """(near, far) planes enclosing every control point in front of the eye."""
    lo, hi = patches.scene_box()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    _, _, f = camera.basis()
    depth = (corners - camera.eye) @ f
    far = max(float(depth.max()), 1e-300) * 1.1 + 1e-9  # generous: depth is tested on linear distance (far_distance)
    near = max(float(depth.min()) * 0.99, far * 1e-5)
    return near, far


def far_distance(patches: PatchSet, camera: Camera) -> float:
    """Beyond the farthest control point from the eye (the linear depth's scale)."""
    lo, hi = patches.scene_box()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return max(float(np.linalg.norm(corners - camera.eye, axis=1).max()), 1e-300) * 1.01


def _tessellation(patches: PatchSet, camera: Camera, width: int, height: int):
    """The map's mesh for this view, cached (one entry on the PatchSet: the
    bands of one map, and repeated renders of one view, share it): the
    _MapMesh of tessellate()'s triangles, the cells that trim curves cross
    split off (with TRIM_MAP) to be drawn with the trim test."""
    key = (
        tuple(camera.eye),
        tuple(camera.look_at),
        tuple(camera.up),
        camera.fov,
        camera.fov_axis,
        width,
        height,
        TRIM_MAP,
        SUB_PIXELS,
    )
    cached = patches.derived.get("tessellation")
    if cached is None or cached[0] != key:
        patches.derived["tessellation"] = cached = (key, _MapMesh(patches, camera, width, height, TRIM_MAP))
    return cached[1]


def outline_edges(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The edges that outline the triangles' picture from the eye, for the map's line pass.

    vertices: (V, >= 3) float32 rows, eye-relative positions first; triangles:
    (T, 3) uint32, wound the same way wherever two share an edge (the grids
    are). Returns (E, 2) uint32: each edge that one triangle alone has (a
    surface's or a cut piece's border), that two triangles facing opposite
    ways share (a fold's silhouette), or that a triangle within EDGE_ON of
    edge-on has, once, in the order its first triangle is drawn. An edge two
    triangles facing the same way share lies inside their picture, whose pixel
    centres the triangles cover: drawing it as a line adds nothing a sliver
    needs. On llvmpipe each line costs the drawing thread its set-up; the
    outline is about a tenth of all edges (column: 2,854 of 23,935).
    """
    p = vertices[:, :3]
    a, b, c = (p[triangles[:, k]].astype(np.float64) for k in range(3))
    e1, e2, towards = b - a, c - a, a + b + c
    normal = np.empty_like(e1)  # e1 x e2, component by component
    normal[:, 0] = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    normal[:, 1] = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    normal[:, 2] = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    facing = np.einsum("ij,ij->i", normal, towards)
    margin = EDGE_ON * np.sqrt(np.einsum("ij,ij->i", normal, normal) * np.einsum("ij,ij->i", towards, towards))
    side = np.where(facing > margin, 1, np.where(facing < -margin, -1, 0)).astype(np.int8)
    edges = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    low, high = edges.min(axis=1).astype(np.int64), edges.max(axis=1).astype(np.int64)
    key = low << 32 | high
    order = np.argsort(key, kind="stable")
    key = key[order]
    starts = np.ones(key.size, dtype=bool)
    starts[1:] = key[1:] != key[:-1]
    first = np.flatnonzero(starts)  # each edge's first row in order
    count = np.diff(np.r_[first, key.size])
    sides = side[order // 3]
    keep = count != 2
    pair = np.flatnonzero(count == 2)
    one, other = sides[first[pair]], sides[first[pair] + 1]
    keep[pair] = (one != other) | (one == 0)
    return np.ascontiguousarray(edges[np.sort(order[first[keep]])])


# |cos| between a triangle's normal and the direction to it below this: edge-on,
# its edges drawn whatever its neighbours face (float32 positions leave the sign
# of a tiny triangle's facing uncertain to about this).
EDGE_ON = 1e-3


# Draw the triangles that trim curves cross with the per-fragment trim test
# (shaders/prelim.glsl's TRIM_TEST variant); False: the map of every kept cell
# whole, as before the test (for comparisons).
TRIM_MAP = True


class _MapMesh:
    """The map's triangles as C-ordered arrays for GL buffers.

    vertices (V, 6) float32 (tessellate()'s rows), indices (T, 3) uint32 and
    edges (E, 2) uint32 (outline_edges: the lines of the map's line pass): the triangles drawn
    without the trim test. tested (3 K, 10) float32: the K triangles drawn
    with it, three vertices each, rows (x, y, z, u_norm, v_norm, surface
    index + 1, u, v in the knot domain, reach_u, reach_v: the margin of the
    trim test, _param_per_pixel's bound times TRIM_GROW, the largest over the
    cell's corners); tested_edges (K, 6) uint32 their edges.

    The triangles of the cells that trim curves cross (MIXED; where the view
    is singular at a corner they stay whole and untested) are cut by _cut,
    in their own plane, into pieces that are left out (the trim test would
    discard every fragment), drawn plainly (it would discard none), or, only
    where that stays undecided down to SUB_PIXELS, drawn with the test.
    """

    def __init__(self, patches: PatchSet, camera: Camera, width: int, height: int, trim_map: bool):
        footprint = pixel_footprint(camera, width, height)
        verts, tris, reach = _grids(
            patches,
            segments_per_patch(patches, camera, width, height),
            camera.eye,
            camera if trim_map and patches.trimmed else None,
            footprint,
        )
        vertices = np.concatenate(verts)
        indices = np.concatenate([t for t, _ in tris])
        tested = np.concatenate([mixed for _, mixed in tris])
        if reach is None:
            tested[:] = False
        else:
            tested &= np.isfinite(reach).all(axis=1)
        plain = indices[~tested]
        sub, sub_surface, sub_reach, test = _cut(
            patches.trims,
            camera,
            footprint,
            vertices,
            indices[tested],
            reach[tested] if reach is not None else np.zeros((0, 2)),
            patches.domain,
        )
        keep = sub[~test]  # (I, 3, 7) drawn plainly, three vertices each
        extra = np.empty((keep.shape[0] * 3, 6), dtype=np.float32)
        extra[:, :5] = keep[:, :, :5].reshape(-1, 5)
        extra[:, 5] = np.repeat(sub_surface[~test] + 1, 3)
        plain = np.concatenate([plain, vertices.shape[0] + np.arange(extra.shape[0]).reshape(-1, 3)]).astype(np.uint32)
        self.vertices = np.ascontiguousarray(np.concatenate([vertices, extra]))
        self.indices = np.ascontiguousarray(plain)
        self.edges = outline_edges(self.vertices, self.indices)
        k = int(test.sum())
        rows = np.empty((k, 3, 10), dtype=np.float32)
        rows[:, :, :5] = sub[test][:, :, :5]
        rows[:, :, 5] = (sub_surface[test] + 1)[:, None]
        rows[:, :, 6:8] = sub[test][:, :, 5:7]
        rows[:, :, 8:] = sub_reach[test][:, None, :]
        self.tested = rows.reshape(3 * k, 10)
        first = np.arange(k, dtype=np.uint32) * 3
        self.tested_edges = np.ascontiguousarray(
            np.stack([first, first + 1, first + 1, first + 2, first + 2, first], axis=1)
        )


# The map's triangles that trim curves cross are halved (into 4) until their
# pieces lie inside the trims, outside beyond the reach, or within the reach of
# a curve everywhere; a piece still undecided when it is SUB_PIXELS across on
# the film (or after MAX_HALVINGS) is drawn with the per-fragment trim test.
SUB_PIXELS = 2.0
MAX_HALVINGS = 10
SMALL = 2.0  # a piece near a curve is drawn plainly once its (u, v) box is within SMALL x the reach


def _cut(
    table,
    camera: Camera,
    footprint: float,
    vertices: np.ndarray,
    tris: np.ndarray,
    reach: np.ndarray,
    domain: np.ndarray,
):
    """The pieces of the map's triangles tris (K, 3) (indices into vertices (V, 6),
    tessellate()'s rows) with reach (K, 2): each triangle is cut into four at its
    edges' midpoints, in its plane (the points, positions and (u, v) the GPU
    interpolates there), over and over; a piece is classified by
    kernels.trim.rect_states of its (u, v) box: grown by the reach and OUTSIDE,
    the test would discard every fragment (left out); INSIDE, none (kept, drawn
    without the test); no larger than the reach along u and v, none either
    (every point of the box is within the reach of any curve passing through it,
    and if none does the box is wholly inside or outside: kept, conservatively;
    SMALL = 2 stops a halving sooner, keeping a piece up to twice the reach
    across: fewer pieces, a few more kept fragments off the trims);
    else cut again, or drawn with the per-fragment test once SUB_PIXELS across.

    Returns (pieces (S, 3, 7) float64 rows (x, y, z, u_norm, v_norm, u, v in the
    knot domain) of each piece's vertices, surface (S,) int64, reach (S, 2),
    test (S,) bool: draw with the per-fragment test)."""
    corner = vertices[tris].astype(np.float64)  # (K, 3, 6)
    surface = np.rint(corner[:, 0, 5]).astype(np.int64) - 1
    d = domain[surface]
    data = np.concatenate(
        [
            corner[:, :, :5],
            (d[:, None, 0] + (d[:, None, 1] - d[:, None, 0]) * corner[:, :, 3])[..., None],
            (d[:, None, 2] + (d[:, None, 3] - d[:, None, 2]) * corner[:, :, 4])[..., None],
        ],
        axis=2,
    )
    r, up, f = camera.basis()
    done = []  # (pieces, surface, reach, test)
    for halving in range(MAX_HALVINGS + 1):
        if not data.shape[0]:
            break
        lo, hi = data[:, :, 5:7].min(axis=1), data[:, :, 5:7].max(axis=1)
        grown = rect_states(
            table,
            surface,
            lo[:, 0] - reach[:, 0],
            hi[:, 0] + reach[:, 0],
            lo[:, 1] - reach[:, 1],
            hi[:, 1] + reach[:, 1],
        )
        plain = (grown == INSIDE) | ((grown == MIXED) & ((hi - lo) <= SMALL * reach).all(axis=1))
        ask = np.flatnonzero((grown == MIXED) & ~plain)  # near a curve and larger than the reach: is the box inside?
        plain[ask] = rect_states(table, surface[ask], lo[ask, 0], hi[ask, 0], lo[ask, 1], hi[ask, 1]) == INSIDE
        undecided = (grown != OUTSIDE) & ~plain
        P = data[:, :, :3]
        z = P @ f
        with np.errstate(all="ignore"):
            film = np.stack([P @ r, P @ up], axis=2) / (z * footprint)[..., None]  # (K, 3, 2) pixels
            longest = np.linalg.norm(film - np.roll(film, 1, axis=1), axis=2).max(axis=1)
        final = undecided & ((z > 0).all(axis=1) & (longest <= SUB_PIXELS) | (halving == MAX_HALVINGS))
        done.append((data[plain], surface[plain], reach[plain], np.zeros(int(plain.sum()), dtype=bool)))
        done.append((data[final], surface[final], reach[final], np.ones(int(final.sum()), dtype=bool)))
        split = undecided & ~final
        data = _quarters(data[split])
        surface, reach = np.repeat(surface[split], 4), np.repeat(reach[split], 4, axis=0)
    parts = (
        list(zip(*done))
        if done
        else [[np.zeros((0, 3, 7))], [np.zeros(0, dtype=np.int64)], [np.zeros((0, 2))], [np.zeros(0, dtype=bool)]]
    )
    return tuple(np.concatenate(p) for p in parts)


def _quarters(tris: np.ndarray) -> np.ndarray:
    """(4 K, 3, C): each triangle of tris (K, 3, C) (per-vertex values, linear over
    it) cut into four at its edges' midpoints, a triangle's four in a row."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    return np.stack(
        [np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))], axis=1
    ).reshape(-1, 3, tris.shape[2])
