"""Flattened Bezier pieces in a bounding volume hierarchy (Martin et al. 2000).

The baseline ray tracer of Martin, Cohen, Fish & Shirley, "Practical Ray
Tracing of Trimmed NURBS Surfaces" (JGT 5(1), 2000), without trimming:

1. **Flattening** (their section 3). Every Bezier patch of a PatchSet is cut
   by de Casteljau subdivision of its homogeneous control net at the
   parameter midpoint, in u or in v, until each piece is flat enough. Each
   final piece is a *leaf*: it keeps its patch id, its parameter rectangle
   (u0, u1, v0, v1) in the surface's own knot domain, an axis-aligned box of
   its projected control points (with positive weights the piece lies in
   their convex hull) padded by the solver tolerance, and the start of
   Newton's iteration, the centre of its rectangle.

   Flatness criterion (ours; Martin's is a curvature and size bound). With
   P_ij the projected control points of a piece of degree (p, q) and
   B(s, t) the bilinear interpolant of its four corner points,

       dev   = max_ij |P_ij - B(i/p, j/q)|
       dev_u = max_ij |P_ij - ((1 - i/p) P_0j + (i/p) P_pj)|     (rows)
       dev_v = max_ij |P_ij - ((1 - j/q) P_i0 + (j/q) P_iq)|     (columns)

   For a rational piece, the spread of its weights adds
   ``(max w / min w - 1) * diag`` (diag = diagonal of the piece's box; per
   row/column for the directional measures), since uneven weights bend the
   parametrisation even of a flat piece. A piece is a leaf when
   ``dev <= flatness * scene_diagonal`` or it has been cut ``max_depth``
   times; otherwise it is cut across the direction with the larger
   directional measure. dev is zero exactly when the piece *is* the bilinear
   patch of its corners with the uniform parametrisation; it bounds both the
   piece's departure from a plane and the non-linearity of its
   parametrisation, which is what limits Newton's basin from the centre.
   A second, relative bound (curvature-based, like Martin's) also splits a
   piece while ``dev > BEND * size`` or its corners' bilinear patch is
   twisted by more than that (``|P00 - Pp0 - P0q + Ppq| / 4``; size = its box
   diagonal, BEND = 0.02): the piece is then within 2% of its size of a
   plane, its normals turn by only about 9 degrees, so a ray can cross a
   leaf twice only within about 9 degrees of its tangent plane, i.e. with
   |cos(normal, ray)| < 0.16, which the grazing retries below (threshold
   0.3) cover. Without it, small strongly curved features (the column's
   mouldings) made leaves that a ray at cos 0.3-0.5 crosses twice, and
   Newton from the centre found the far root.
   Default ``flatness = 2e-3`` (``DEFAULT_FLATNESS``), ``max_depth = 12``
   (at most 4096 leaves per Bezier patch). Finer values cost little at
   render time (the water-lily renders as fast at 1e-3 as at 1e-2) but
   make Newton from the centre fail less often.

2. **BVH** over the leaves, arrays only, built top-down level by level
   (vectorised over all nodes of a level): a node's leaves are split at the
   median of their box centroids along the longest axis of the centroids'
   box, until a node holds at most ``leaf_size`` leaves (default 2).

3. **Intersection** (:func:`intersect`), vectorised over rays: a frontier of
   (ray, node) pairs goes down the tree with slab tests; each (ray, leaf)
   pair whose leaf box (the oriented one) the ray enters within
   [t_min, t_max] is a candidate. Candidates are sorted per ray by entry
   distance and solved in rounds: each round runs Newton
   (``find_roots(..., stop_on_growth=True)``) from the leaf's centre on the
   next few candidates of every unfinished ray; a root counts if it
   converged, its t is in (t_min, t_max) and its (u, v) lies in the leaf's
   rectangle grown by 1e-9 of its size. A ray is finished once its nearest
   root so far is closer than its next candidate's entry distance.

   Robustness: Newton from a leaf's centre can miss a root of a curved leaf
   or, for a grazing ray that crosses the leaf twice, find the far root. So
   (``retry_depth``, default 4) a pair whose centre start finds no root in
   the leaf, or whose root is grazing (|cos(normal, ray)| < 0.3), has its
   leaf net cut into quarters by de Casteljau; quarters whose control points
   do not straddle the ray in the ray's frame (or lie beyond the root found)
   are culled and Newton restarts from the survivors' centres, recursively;
   quarters whose root is again grazing are cut further too (the nearer of
   two crossings may be in the same quarter).
   Measured against an exhaustive search (Newton from 10 x 10 starts on
   every Bezier patch whose box the ray enters): 30,000 random rays at
   three non-uniform surfaces (degrees 3, 2 and a rational bowl, a third of
   the rays starting inside the bowl), 12,493 hits: centre start only
   misses or mis-orders 10 rays at flatness 2e-3 (76 at 1e-2); with the
   retries, 0 (2 at 1e-2). Water-lily camera rays (20,000 of 512 x 512,
   5,630 hits): 6 vs. 0.

Leaf boxes: an axis-aligned box (for the tree) and an oriented box (axes
from the corners' u direction and normal) tested per (ray, leaf) pair.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hits import Hits
from .patches import PatchSet
from .solve import Rays, find_roots

DEFAULT_FLATNESS = 2e-3
DEFAULT_MAX_DEPTH = 12
DEFAULT_LEAF_SIZE = 2
RECT_SLACK = 1e-9
DEFAULT_RETRY_DEPTH = 4
GRAZING_COSINE = 0.3
BEND = 0.02  # a leaf deviates from its bilinear patch by at most this fraction of its size
PAIR_CHUNK = 1 << 20


@dataclass(eq=False)
class BVH:
    """Leaves (flat Bezier pieces) and the tree over them.

    L leaves, stored in tree order (each node's leaves are contiguous), C the
    largest control-point count (p + 1)(q + 1) of any patch, K nodes (node 0
    is the root):

      patches: the PatchSet the leaves were cut from.
      leaf_patch: (L,) int64, PatchSet patch id.
      leaf_surface: (L,) int64, surface index.
      leaf_rect: (L, 4) float64, (u0, u1, v0, v1) in the surface's knot domain.
      leaf_start: (L, 2) float64, Newton's start (u, v): the rectangle's centre.
      leaf_min, leaf_max: (L, 3) float64, box of the piece's projected
        control points, padded by ``padding``.
      leaf_obb: (L, 15) float64, a tighter oriented box of the same points
        (padded likewise): centre (3), three orthonormal axes (3 x 3, row
        k = axis k; axis 0 ~ u, axis 1 ~ v, axis 2 ~ the corners' normal),
        half extents (3).
      leaf_points: (L, C, 3) float64, the piece's projected control points
        (pieces with fewer points repeat their first one).
      leaf_net: (L, P, Q, 4) float64, the piece's homogeneous Bezier net
        (P, Q the largest p + 1, q + 1; a net of degree leaf_degree fills
        the [:p + 1, :q + 1] corner, the rest is zero).
      leaf_degree: (L, 2) int64, (p, q) of the piece.
      leaf_depth: (L,) int64, number of cuts from the Bezier patch.
      leaf_planar: (L,) bool, the piece's control points lie in one plane
        (its oriented box has no thickness beyond the padding).
      node_min, node_max: (K, 3) float64, node boxes (union of their leaves).
      node_bounds: (6, K) float64, the same, component-major
        (min x, min y, min z, max x, max y, max z), for traversal.
      node_left, node_right: (K,) int64, children, -1 for a tree leaf.
      node_first, node_count: (K,) int64, the node's leaves are
        first .. first + count - 1 (every node, inner ones included).
      flatness: the criterion's constant (fraction of the scene diagonal).
      padding: absolute box padding (scene units).
    """

    patches: PatchSet
    leaf_patch: np.ndarray
    leaf_surface: np.ndarray
    leaf_rect: np.ndarray
    leaf_start: np.ndarray
    leaf_min: np.ndarray
    leaf_max: np.ndarray
    leaf_obb: np.ndarray
    leaf_points: np.ndarray
    leaf_net: np.ndarray
    leaf_degree: np.ndarray
    leaf_depth: np.ndarray
    leaf_planar: np.ndarray
    node_min: np.ndarray
    node_max: np.ndarray
    node_bounds: np.ndarray
    node_left: np.ndarray
    node_right: np.ndarray
    node_first: np.ndarray
    node_count: np.ndarray
    flatness: float
    padding: float

    @property
    def leaf_total(self) -> int:
        return int(self.leaf_patch.shape[0])

    @property
    def node_total(self) -> int:
        return int(self.node_min.shape[0])


# ---------------------------------------------------------------------------
# Flattening


def split_half(ctrl: np.ndarray, axis: int):
    """de Casteljau at the midpoint of a stack of homogeneous Bezier nets.

    ctrl: (K, p + 1, q + 1, 4); axis 1 splits in u, 2 in v. Returns the two
    halves (lower parameters first), each shaped like ctrl.
    """
    pts = np.moveaxis(ctrl, axis, 1)
    n = pts.shape[1] - 1
    left, right = [pts[:, 0]], [pts[:, n]]
    for _ in range(n):
        pts = 0.5 * (pts[:, :-1] + pts[:, 1:])
        left.append(pts[:, 0])
        right.append(pts[:, -1])
    lo = np.moveaxis(np.stack(left, axis=1), 1, axis)
    hi = np.moveaxis(np.stack(right[::-1], axis=1), 1, axis)
    return lo, hi


def flatness_measures(ctrl: np.ndarray):
    """(dev, dev_u, dev_v), each (K,), of a stack of nets (K, p+1, q+1, 4); see the module doc."""
    w = ctrl[..., 3]
    pts = ctrl[..., :3] / w[..., None]
    p, q = pts.shape[1] - 1, pts.shape[2] - 1
    s = (np.arange(p + 1) / p)[None, :, None, None]
    t = (np.arange(q + 1) / q)[None, None, :, None]
    c00, c10 = pts[:, :1, :1], pts[:, -1:, :1]
    c01, c11 = pts[:, :1, -1:], pts[:, -1:, -1:]
    bil = (1 - s) * ((1 - t) * c00 + t * c01) + s * ((1 - t) * c10 + t * c11)
    dev = np.linalg.norm(pts - bil, axis=-1).max(axis=(1, 2))
    row = (1 - s) * pts[:, :1] + s * pts[:, -1:]
    col = (1 - t) * pts[:, :, :1] + t * pts[:, :, -1:]
    dev_u = np.linalg.norm(pts - row, axis=-1).max(axis=(1, 2))
    dev_v = np.linalg.norm(pts - col, axis=-1).max(axis=(1, 2))
    if not np.all(w == w[:, :1, :1]):
        diag = np.linalg.norm(pts.max(axis=(1, 2)) - pts.min(axis=(1, 2)), axis=-1)
        spread_u = (w.max(axis=1) / w.min(axis=1)).max(axis=1) - 1.0
        spread_v = (w.max(axis=2) / w.min(axis=2)).max(axis=1) - 1.0
        dev_u = dev_u + spread_u * diag
        dev_v = dev_v + spread_v * diag
        dev = dev + np.maximum(spread_u, spread_v) * diag
    return dev, dev_u, dev_v


def flatten(patches: PatchSet, flatness: float = DEFAULT_FLATNESS, max_depth: int = DEFAULT_MAX_DEPTH):
    """Cut every Bezier patch into flat pieces.

    Returns (patch (L,) int64, rect (L, 4), depth (L,) int64, nets): nets is
    a list of (indices into the L leaves, (n, p+1, q+1, 4) homogeneous nets),
    one entry per patch shape.
    """
    eps = flatness * patches.scene_diagonal()
    shapes: dict[tuple[int, int], list[int]] = {}
    for k, b in enumerate(patches.bezier):
        shapes.setdefault(b.shape[:2], []).append(k)
    out_patch, out_rect, out_depth, out_nets = [], [], [], []
    for ids in shapes.values():
        ids = np.array(ids, dtype=np.int64)
        ctrl = np.array([patches.bezier[k] for k in ids])
        patch, rect, depth = ids, patches.bounds[ids].copy(), np.zeros(ids.size, np.int64)
        while patch.size:
            dev, dev_u, dev_v = flatness_measures(ctrl)
            pts = ctrl[..., :3] / ctrl[..., 3:4]
            size = np.linalg.norm(pts.max(axis=(1, 2)) - pts.min(axis=(1, 2)), axis=-1)
            # the twist of the corners' bilinear patch (zero when they are coplanar)
            twist = 0.25 * np.linalg.norm(pts[:, 0, 0] - pts[:, -1, 0] - pts[:, 0, -1] + pts[:, -1, -1], axis=-1)
            bent = np.maximum(dev, twist) > BEND * size
            split = ((dev > eps) | bent) & (depth < max_depth)
            done = ~split
            if np.any(done):
                out_patch.append(patch[done])
                out_rect.append(rect[done])
                out_depth.append(depth[done])
                out_nets.append(ctrl[done])
            pieces = []
            for axis, sel in ((1, split & (dev_u >= dev_v)), (2, split & (dev_u < dev_v))):
                if not np.any(sel):
                    continue
                lo, hi = split_half(ctrl[sel], axis)
                r = rect[sel]
                a, b = (0, 1) if axis == 1 else (2, 3)
                mid = 0.5 * (r[:, a] + r[:, b])
                r_lo, r_hi = r.copy(), r.copy()
                r_lo[:, b] = mid
                r_hi[:, a] = mid
                pieces.append((np.concatenate([lo, hi]), np.tile(patch[sel], 2),
                               np.concatenate([r_lo, r_hi]), np.tile(depth[sel] + 1, 2)))
            if not pieces:
                break
            ctrl = np.concatenate([x[0] for x in pieces])
            patch = np.concatenate([x[1] for x in pieces])
            rect = np.concatenate([x[2] for x in pieces])
            depth = np.concatenate([x[3] for x in pieces])
    counts = [x.shape[0] for x in out_patch]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    nets = [(np.arange(starts[i], starts[i + 1]), out_nets[i]) for i in range(len(counts))]
    return np.concatenate(out_patch), np.concatenate(out_rect), np.concatenate(out_depth), nets


# ---------------------------------------------------------------------------
# Tree


def _ranges(first: np.ndarray, count: np.ndarray):
    """Concatenation of the ranges first[i] .. first[i] + count[i] - 1, and their owner i."""
    owner = np.repeat(np.arange(first.size), count)
    offs = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    return np.repeat(first - offs, count) + np.arange(owner.size), owner


def _build_tree(box_min: np.ndarray, box_max: np.ndarray, leaf_size: int):
    """Median-split tree over L boxes. Returns (order, node arrays...)."""
    n = box_min.shape[0]
    centre = 0.5 * (box_min + box_max)
    order = np.arange(n)
    n_min, n_max, n_left, n_right, n_first, n_count = [], [], [], [], [], []
    level_first = np.array([0], dtype=np.int64)
    level_count = np.array([n], dtype=np.int64)
    next_id = 1
    while level_first.size:
        idx, owner = _ranges(level_first, level_count)
        offs = np.concatenate([[0], np.cumsum(level_count)[:-1]]).astype(np.int64)
        members = order[idx]
        c = centre[members]
        c_lo, c_hi = np.minimum.reduceat(c, offs), np.maximum.reduceat(c, offs)
        n_min.append(np.minimum.reduceat(box_min[members], offs))
        n_max.append(np.maximum.reduceat(box_max[members], offs))
        n_first.append(level_first)
        n_count.append(level_count)
        inner = level_count > leaf_size
        left = np.full(level_first.size, -1, dtype=np.int64)
        left[inner] = next_id + 2 * np.arange(np.count_nonzero(inner))
        right = np.where(inner, left + 1, -1)
        next_id += 2 * np.count_nonzero(inner)
        n_left.append(left)
        n_right.append(right)
        if not np.any(inner):
            break
        axis = np.argmax(c_hi - c_lo, axis=1)
        key = c[np.arange(owner.size), axis[owner]]
        perm = np.lexsort((key, owner))
        order[idx] = members[perm]
        f, k = level_first[inner], level_count[inner]
        half = k // 2
        level_first = np.stack([f, f + half], axis=1).ravel()
        level_count = np.stack([half, k - half], axis=1).ravel()
    cat = np.concatenate
    return order, cat(n_min), cat(n_max), cat(n_left), cat(n_right), cat(n_first), cat(n_count)


def _oriented_boxes(nets, degree, points, padding):
    """(L, 15) oriented boxes of the leaves' control points (see BVH.leaf_obb)."""
    n = points.shape[0]
    corner = np.empty((n, 4, 3))
    for (p, q) in np.unique(degree, axis=0):
        sel = (degree[:, 0] == p) & (degree[:, 1] == q)
        net = nets[sel]
        c = net[:, [0, p, 0, p], [0, 0, q, q]]  # P00, Pp0, P0q, Ppq
        corner[sel] = c[..., :3] / c[..., 3:4]
    du = corner[:, 1] + corner[:, 3] - corner[:, 0] - corner[:, 2]
    dv = corner[:, 2] + corner[:, 3] - corner[:, 0] - corner[:, 1]
    normal = np.cross(du, dv)
    axes = np.tile(np.eye(3), (n, 1, 1))
    lu, ln = np.linalg.norm(du, axis=1), np.linalg.norm(normal, axis=1)
    good = (lu > 0) & (ln > 1e-12 * np.maximum(lu, 1e-300) * np.linalg.norm(dv, axis=1))
    a0 = du[good] / lu[good, None]
    a2 = normal[good] / ln[good, None]
    axes[good] = np.stack([a0, np.cross(a2, a0), a2], axis=1)
    proj = np.einsum("lck,lak->lca", points, axes)  # (L, C, 3) coordinates along the axes
    lo, hi = proj.min(axis=1) - padding, proj.max(axis=1) + padding
    centre = np.einsum("la,lak->lk", 0.5 * (lo + hi), axes)
    return np.concatenate([centre, axes.reshape(n, 9), 0.5 * (hi - lo)], axis=1)


def build_bvh(
    patches: PatchSet,
    flatness: float = DEFAULT_FLATNESS,
    max_depth: int = DEFAULT_MAX_DEPTH,
    leaf_size: int = DEFAULT_LEAF_SIZE,
    padding: float | None = None,
) -> BVH:
    """Flatten ``patches`` (see the module doc) and build the tree.

    flatness: a piece is flat when its control points are within
    ``flatness * patches.scene_diagonal()`` of its corners' bilinear patch.
    padding: absolute padding of the leaf boxes (default 1e-9 of the scene
    diagonal, the default solver tolerance, plus rounding room).
    """
    diag = patches.scene_diagonal()
    if padding is None:
        padding = 1e-8 * diag
    patch, rect, depth, nets = flatten(patches, flatness, max_depth)
    n = patch.size
    c_max = max(b.shape[0] * b.shape[1] for b in patches.bezier)
    p_max = max(b.shape[0] for b in patches.bezier)
    q_max = max(b.shape[1] for b in patches.bezier)
    points = np.empty((n, c_max, 3))
    all_nets = np.zeros((n, p_max, q_max, 4))
    degree = np.zeros((n, 2), dtype=np.int64)
    for where, net in nets:
        all_nets[where, : net.shape[1], : net.shape[2]] = net
        degree[where] = (net.shape[1] - 1, net.shape[2] - 1)
        pts = (net[..., :3] / net[..., 3:4]).reshape(net.shape[0], -1, 3)
        points[where, : pts.shape[1]] = pts
        points[where, pts.shape[1] :] = pts[:, :1]
    obb = _oriented_boxes(all_nets, degree, points, padding)
    box_min = points.min(axis=1) - padding
    box_max = points.max(axis=1) + padding
    order, n_min, n_max, n_left, n_right, n_first, n_count = _build_tree(box_min, box_max, leaf_size)
    rect = rect[order]
    return BVH(
        patches=patches,
        leaf_patch=patch[order],
        leaf_surface=patches.surface[patch[order]],
        leaf_rect=rect,
        leaf_start=np.stack([0.5 * (rect[:, 0] + rect[:, 1]), 0.5 * (rect[:, 2] + rect[:, 3])], axis=1),
        leaf_min=box_min[order],
        leaf_max=box_max[order],
        leaf_obb=obb[order],
        leaf_points=points[order],
        leaf_net=all_nets[order],
        leaf_degree=degree[order],
        leaf_depth=depth[order],
        leaf_planar=obb[order, 14] <= padding * (1.0 + 1e-6) + 1e-12 * diag,
        node_min=n_min,
        node_max=n_max,
        node_bounds=np.ascontiguousarray(np.concatenate([n_min, n_max], axis=1).T),
        node_left=n_left,
        node_right=n_right,
        node_first=n_first,
        node_count=n_count,
        flatness=float(flatness),
        padding=float(padding),
    )


# ---------------------------------------------------------------------------
# Intersection


def _slab(box, origin, inv_dir):
    """Entry and exit distances of M rays into M boxes, all component-major.

    box: (6, M) (min x, y, z, max x, y, z); origin, inv_dir: (3, M).
    """
    near = far = None
    for k in range(3):
        t1 = (box[k] - origin[k]) * inv_dir[k]
        t2 = (box[k + 3] - origin[k]) * inv_dir[k]
        lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
        near = lo if near is None else np.maximum(near, lo)
        far = hi if far is None else np.minimum(far, hi)
    return near, far


def _obb_slab(obb, origin, direction):
    """Entry and exit distances of M rays into M oriented boxes.

    obb: (M, 15) rows of BVH.leaf_obb; origin, direction: (3, M).
    """
    rel = origin - obb[:, 0:3].T
    near = far = None
    for k in range(3):
        ax = obb[:, 3 + 3 * k : 6 + 3 * k].T
        o = ax[0] * rel[0] + ax[1] * rel[1] + ax[2] * rel[2]
        d = ax[0] * direction[0] + ax[1] * direction[1] + ax[2] * direction[2]
        d = np.where(np.abs(d) < 1e-300, 1e-300, d)
        h = obb[:, 12 + k]
        t1, t2 = (-h - o) / d, (h - o) / d
        lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
        near = lo if near is None else np.maximum(near, lo)
        far = hi if far is None else np.minimum(far, hi)
    return near, far


def _candidates(bvh: BVH, origin, direction, inv_d, ray_ids, t_min, t_max):
    """All (ray, leaf, entry distance) pairs of the rays ``ray_ids`` whose leaf box they enter.

    origin, direction, inv_d: (3, N) component-major. A pair needs the ray to
    enter the node boxes on the way down and the leaf's oriented box, all
    within [t_min, t_max]; entry = the oriented box's entry, >= t_min.
    """
    ray = ray_ids
    node = np.zeros(ray.size, dtype=np.int64)
    out_ray, out_leaf = [], []
    while ray.size:
        near, far = _slab(bvh.node_bounds[:, node], origin[:, ray], inv_d[:, ray])
        keep = (near <= far) & (far >= t_min[ray]) & (near <= t_max[ray])
        ray, node = ray[keep], node[keep]
        left = bvh.node_left[node]
        is_leaf = left < 0
        if np.any(is_leaf):
            idx, owner = _ranges(bvh.node_first[node[is_leaf]], bvh.node_count[node[is_leaf]])
            out_ray.append(ray[is_leaf][owner])
            out_leaf.append(idx)
        inner = ~is_leaf
        ray = np.repeat(ray[inner], 2)
        node = np.stack([left[inner], bvh.node_right[node[inner]]], axis=1).ravel()
    if not out_ray:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0)
    ray, leaf = np.concatenate(out_ray), np.concatenate(out_leaf)
    rs, ls, ts = [], [], []
    for a in range(0, ray.size, PAIR_CHUNK):
        r, lf = ray[a : a + PAIR_CHUNK], leaf[a : a + PAIR_CHUNK]
        near, far = _obb_slab(bvh.leaf_obb[lf], origin[:, r], direction[:, r])
        keep = (near <= far) & (far >= t_min[r]) & (near <= t_max[r])
        rs.append(r[keep])
        ls.append(lf[keep])
        ts.append(np.maximum(near[keep], t_min[r[keep]]))
    return np.concatenate(rs), np.concatenate(ls), np.concatenate(ts)


def _frame_cull(points, origin, e1, e2, d, t_min, t_max, tol):
    """Which pieces (control points (m, C, 3)) can the rays (m rows each) meet.

    In the ray's frame (e1, e2, d) a piece's convex hull must straddle the
    ray's axis; its extent along d bounds the hit distance. Returns
    (keep (m,) bool, z_lo (m,) lower bound of any hit's t).
    """
    rel = points - origin[:, None, :]
    x = np.einsum("mck,mk->mc", rel, e1)
    y = np.einsum("mck,mk->mc", rel, e2)
    z = np.einsum("mck,mk->mc", rel, d)
    keep = (x.min(axis=1) <= tol) & (x.max(axis=1) >= -tol) & (y.min(axis=1) <= tol) & (y.max(axis=1) >= -tol)
    z_lo, z_hi = z.min(axis=1) - tol, z.max(axis=1) + tol
    keep &= (z_hi >= t_min) & (z_lo <= t_max)
    return keep, z_lo


def _solve_pairs(bvh, rays, ray, leaf, t_min, t_max, tolerance, max_iterations, retry_depth, cull_tol, exclude):
    """Newton for (ray, leaf) pairs. Returns (ok, t, u, v, patch, residual, iterations) per pair.

    Newton starts at the leaf's centre. Pairs without a root in their leaf
    are retried ``retry_depth`` levels deep: the leaf's net is cut into
    quarters (de Casteljau), quarters the ray cannot meet are culled in the
    ray's frame, and Newton restarts from the centre of each survivor.
    """
    patches = bvh.patches
    surface = bvh.leaf_surface[leaf]
    start = bvh.leaf_start[leaf]
    res = find_roots(patches, rays, ray, surface, start[:, 0], start[:, 1], tolerance=tolerance,
                     max_iterations=max_iterations, stop_on_growth=True)
    u, v, t, patch, resid = res.u, res.v, res.t, res.patch, res.residual
    iters = res.iterations.astype(np.int64)
    ok, start = _accept(bvh, leaf, ray, res.converged, u, v, t, t_min, t_max, exclude)
    if not retry_depth:
        return ok, t, u, v, patch, resid, iters
    # A grazing ray can cross a leaf twice; Newton may have found the far root.
    acc = np.flatnonzero(ok)
    _, su, sv = patches.evaluate(patch[acc], u[acc], v[acc])
    normal = np.cross(su.T, sv.T)
    cos = np.abs(np.einsum("mk,km->m", normal, rays.direction[:, ray[acc]]))
    grazing = acc[cos < GRAZING_COSINE * np.linalg.norm(normal, axis=1)]
    # A leaf whose root is the secondary ray's own start is not retried: a
    # leaf flat to 2e-3 of the scene meets a ray leaving it again only at
    # grazing angles, where the light it would block contributes cos ~ 0.
    bad = np.union1d(np.flatnonzero(~ok & ~start), grazing)
    if not bad.size:
        return ok, t, u, v, patch, resid, iters
    deg = bvh.leaf_degree[leaf[bad]]
    o, d = rays.origin.T, rays.direction.T
    e1, e2 = rays.e1.T, rays.e2.T
    for p, q in np.unique(deg, axis=0):
        item = bad[(deg[:, 0] == p) & (deg[:, 1] == q)]
        nets = bvh.leaf_net[leaf[item], : p + 1, : q + 1]
        rects = bvh.leaf_rect[leaf[item]]
        for _ in range(retry_depth):
            if not item.size:
                break
            lo, hi = split_half(nets, 1)
            q00, q01 = split_half(lo, 2)
            q10, q11 = split_half(hi, 2)
            nets = np.concatenate([q00, q01, q10, q11])
            um = 0.5 * (rects[:, 0] + rects[:, 1])
            vm = 0.5 * (rects[:, 2] + rects[:, 3])
            u0, u1, v0, v1 = rects.T
            rects = np.concatenate([np.stack(x, axis=1) for x in (
                (u0, um, v0, vm), (u0, um, vm, v1), (um, u1, v0, vm), (um, u1, vm, v1))])
            item = np.tile(item, 4)
            r = ray[item]
            pts = (nets[..., :3] / nets[..., 3:4]).reshape(nets.shape[0], -1, 3)
            keep, z_lo = _frame_cull(pts, o[r], e1[r], e2[r], d[r], t_min[r], t_max[r], cull_tol)
            keep &= ~ok[item] | (z_lo < t[item])
            item, nets, rects, r = item[keep], nets[keep], rects[keep], r[keep]
            if not item.size:
                break
            r2 = find_roots(patches, rays, r, surface[item], 0.5 * (rects[:, 0] + rects[:, 1]),
                            0.5 * (rects[:, 2] + rects[:, 3]), tolerance=tolerance,
                            max_iterations=max_iterations, stop_on_growth=True)
            np.add.at(iters, item, r2.iterations)
            acc, _ = _accept(bvh, leaf[item], r, r2.converged, r2.u, r2.v, r2.t, t_min, t_max, exclude)
            if np.any(acc):
                a = np.flatnonzero(acc)
                a = a[np.lexsort((r2.t[a], item[a]))]
                a = a[np.concatenate([[True], item[a][1:] != item[a][:-1]])]
                a = a[~ok[item[a]] | (r2.t[a] < t[item[a]])]
                g = item[a]
                ok[g] = True
                u[g], v[g], t[g], patch[g], resid[g] = r2.u[a], r2.v[a], r2.t[a], r2.patch[a], r2.residual[a]
            # Keep cutting the pieces that found nothing, and those whose root
            # is grazing: a grazing ray may cross the piece twice, the root
            # found being the far one (culling keeps only what lies nearer).
            again = ~acc
            if np.any(acc):
                a = np.flatnonzero(acc)
                _, su, sv = patches.evaluate(r2.patch[a], r2.u[a], r2.v[a])
                normal = np.cross(su.T, sv.T)
                cos = np.abs(np.einsum("mk,km->m", normal, rays.direction[:, r[a]]))
                again[a[cos < GRAZING_COSINE * np.linalg.norm(normal, axis=1)]] = True
            item, nets, rects = item[again], nets[again], rects[again]
    return ok, t, u, v, patch, resid, iters


def _accept(bvh, leaf, ray, converged, u, v, t, t_min, t_max, exclude):
    """(ok, start): ok, the pair's root is a hit; start, its root is the excluded one."""
    rect = bvh.leaf_rect[leaf]
    su = RECT_SLACK * (rect[:, 1] - rect[:, 0])
    sv = RECT_SLACK * (rect[:, 3] - rect[:, 2])
    inside = (u >= rect[:, 0] - su) & (u <= rect[:, 1] + su) & (v >= rect[:, 2] - sv) & (v <= rect[:, 3] + sv)
    ok = converged & inside
    start = np.zeros_like(ok)
    if exclude is not None:
        surface, eu, ev, ru, rv = (a[ray] for a in exclude)
        start = ok & (bvh.leaf_surface[leaf] == surface) & (np.abs(u - eu) <= ru) & (np.abs(v - ev) <= rv)
    return ok & ~start & (t > t_min[ray]) & (t < t_max[ray]), start


def _leaves_own_plane(bvh: BVH, ray, leaf, exclude) -> np.ndarray:
    """(M,) bool: the pair's leaf is planar and holds the ray's start root.

    A ray leaving a plane never meets it again, so such a pair can only
    yield the excluded root: no need to run Newton on it (most secondary
    rays start on floors and water).
    """
    surface, u, v = exclude[0][ray], exclude[1][ray], exclude[2][ray]
    rect = bvh.leaf_rect[leaf]
    own = (bvh.leaf_surface[leaf] == surface) & (u >= rect[:, 0]) & (u <= rect[:, 1]) & (v >= rect[:, 2]) & (v <= rect[:, 3])
    return own & bvh.leaf_planar[leaf]


def intersect(
    bvh: BVH,
    origins: np.ndarray,
    directions: np.ndarray,
    t_min=0.0,
    t_max=np.inf,
    tolerance: float | None = None,
    max_iterations: int = 16,
    any_hit: bool = False,
    retry_depth: int = DEFAULT_RETRY_DEPTH,
    ray_chunk: int = 1 << 16,
    first_round: int = 1,
    exclude=None,
) -> Hits:
    """Nearest hit (or any hit) of N rays with the surfaces of ``bvh``.

    origins, directions: (N, 3) float64 (directions need not be unit; t is
    measured along the unit direction). t_min, t_max: scalars or (N,); a hit
    needs t_min < t < t_max. tolerance: absolute ray-surface distance for
    Newton's convergence (default 1e-9 of the scene diagonal).
    any_hit: stop each ray at its first valid root (shadow rays); t is then
    that root's, not necessarily the nearest.
    retry_depth: when Newton from a leaf's centre finds no root in the leaf,
    cut it into quarters (recursively, this many levels), cull the quarters
    the ray cannot meet and restart Newton from the survivors' centres.
    ray_chunk: rays traversed at once (bounds the memory of the pair lists).
    first_round: candidates per ray in the first Newton round; the count
    doubles every round.
    exclude: (surface, u, v, radius_u, radius_v), each (N,): a root on that
    surface within that parameter box around (u, v) is not a hit. Secondary
    rays pass the root they start from, so they never find it again (no
    self-shadowing acne) without an offset that would open a gap where two
    surfaces touch.
    """
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    n = directions.shape[0]
    origins = np.ascontiguousarray(np.broadcast_to(origins, (n, 3)))
    hits = Hits.empty(n)
    if n == 0:
        return hits
    t_min = np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,))
    t_max = np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))
    diag = bvh.patches.scene_diagonal()
    if tolerance is None:
        tolerance = 1e-9 * diag
    rays = Rays.from_arrays(origins, directions)
    with np.errstate(divide="ignore"):
        d = rays.direction
        inv_d = 1.0 / np.where(np.abs(d) < 1e-300, np.copysign(1e-300, d), d)
    iterations = np.zeros(n, dtype=np.int64)
    cull_tol = bvh.padding + tolerance
    for a in range(0, n, ray_chunk):
        ids = np.arange(a, min(n, a + ray_chunk))
        ray, leaf, entry = _candidates(bvh, rays.origin, rays.direction, inv_d, ids, t_min, t_max)
        if exclude is not None and ray.size:
            keep = ~_leaves_own_plane(bvh, ray, leaf, exclude)
            ray, leaf, entry = ray[keep], leaf[keep], entry[keep]
        if not ray.size:
            continue
        order = np.lexsort((entry, ray))
        ray, leaf, entry = ray[order], leaf[order], entry[order]
        # Per-ray candidate lists: first[r], count[r] (r local to the chunk).
        local = ray - a
        count = np.bincount(local, minlength=ids.size)
        first = np.concatenate([[0], np.cumsum(count)[:-1]])
        taken = np.zeros(ids.size, dtype=np.int64)
        best = np.full(ids.size, np.inf)
        active = np.flatnonzero(count > 0)
        per_round = first_round
        while active.size:
            take = np.minimum(per_round, count[active] - taken[active])
            idx, owner = _ranges(first[active] + taken[active], take)
            # Skip candidates entered beyond the ray's nearest root so far.
            idx = idx[entry[idx] < best[active][owner]]
            taken[active] += take
            r, lf = ray[idx], leaf[idx]
            ok, t, u, v, patch, resid, its = _solve_pairs(
                bvh, rays, r, lf, t_min, t_max, tolerance, max_iterations, retry_depth, cull_tol, exclude)
            iterations += np.bincount(r, weights=its, minlength=n).astype(np.int64)
            if np.any(ok):
                sel = np.flatnonzero(ok)
                # Nearest per ray among this round's roots.
                o = np.lexsort((t[sel], r[sel]))
                sel = sel[o]
                firsts = np.concatenate([[True], r[sel][1:] != r[sel][:-1]])
                sel = sel[firsts]
                rr = r[sel]
                better = t[sel] < best[rr - a]
                sel, rr = sel[better], rr[better]
                best[rr - a] = t[sel]
                hits.hit[rr] = True
                hits.t[rr] = t[sel]
                hits.u[rr], hits.v[rr], hits.patch[rr] = u[sel], v[sel], patch[sel]
                hits.surface[rr] = bvh.patches.surface[patch[sel]]
                hits.residual[rr] = resid[sel]
            more = taken[active] < count[active]
            active = active[more]
            if any_hit:
                active = active[~np.isfinite(best[active])]
            else:
                nxt = first[active] + taken[active]
                active = active[entry[nxt] < best[active]]
            per_round *= 2
    hits.iterations[:] = np.minimum(iterations, np.iinfo(np.int32).max)
    return hits
