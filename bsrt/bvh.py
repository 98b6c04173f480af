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

3. **Intersection** (:func:`intersect`): compiled, one ray per loop
   iteration (``kernels/traverse.py``): a depth-first walk of the tree,
   nearer child first, skipping nodes entered beyond the nearest root so
   far; every piece whose oriented box the ray enters runs Newton from the
   piece's centre (stop on growth); a root counts if it converged, its t is
   in (t_min, t_max), its (u, v) lies in the piece's rectangle grown by 1e-9
   of its size, it is not the secondary ray's own start, and the surface's
   trims keep it. Any-hit rays stop at the first such root.

   Robustness: Newton from a piece's centre can miss a root of a curved piece
   or, for a grazing ray that crosses the piece twice, find the far root. So
   (``retry_depth``, default 4) a piece whose centre start finds no root in
   it, or whose root is grazing (|cos(normal, ray)| < 0.3), has its net cut
   into quarters by de Casteljau; quarters whose control points do not
   straddle the ray in the ray's frame (or lie beyond the root found) are
   culled and Newton restarts from the survivors' centres, recursively;
   quarters whose root is again grazing are cut further too (the nearer of
   two crossings may be in the same quarter).
   Measured against an exhaustive search (Newton from 10 x 10 starts on
   every Bezier patch whose box the ray enters): 30,000 random rays at
   three non-uniform surfaces (degrees 3, 2 and a rational bowl, a third of
   the rays starting inside the bowl), 12,493 hits: centre start only
   misses or mis-orders 10 rays at flatness 2e-3 (76 at 1e-2); with the
   retries, 0 (2 at 1e-2).

Leaf boxes: an axis-aligned box (for the tree) and an oriented box (axes
from the corners' u direction and normal) tested per (ray, leaf) pair.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .hits import Hits
from .patches import PatchSet
from .kernels.traverse import BVHArrays, Exclusion, trace_rays
from .solve import Rays

DEFAULT_FLATNESS = 2e-3
DEFAULT_MAX_DEPTH = 12
DEFAULT_LEAF_SIZE = 2
DEFAULT_RETRY_DEPTH = 4
BEND = 0.02  # a leaf deviates from its bilinear patch by at most this fraction of its size


@dataclass(eq=False)
class BVH:
    """Leaves (flat Bezier pieces) and the tree over them.

    L leaves, stored in tree order (each node's leaves are contiguous), K
    nodes (node 0 is the root):

      patches: the PatchSet the leaves were cut from.
      leaf_patch: (L,) int64, PatchSet patch id.
      leaf_surface: (L,) int64, surface index.
      leaf_rect: (L, 4) float64, (u0, u1, v0, v1) in the surface's knot domain.
      leaf_min, leaf_max: (L, 3) float64, box of the piece's projected
        control points, padded by ``padding``.
      leaf_obb: (L, 15) float64, a tighter oriented box of the same points
        (padded likewise): centre (3), three orthonormal axes (3 x 3, row
        k = axis k; axis 0 ~ u, axis 1 ~ v, axis 2 ~ the corners' normal),
        half extents (3).
      leaf_net: (L, P, Q, 4) float64, the piece's homogeneous Bezier net
        (P, Q the largest p + 1, q + 1; a net of degree leaf_degree fills
        the [:p + 1, :q + 1] corner, the rest is zero).
      leaf_degree: (L, 2) int64, (p, q) of the piece.
      leaf_depth: (L,) int64, number of cuts from the Bezier patch.
      leaf_planar: (L,) bool, the piece's control points lie in one plane
        (its oriented box has no thickness beyond the padding).
      node_min, node_max: (K, 3) float64, node boxes (union of their leaves).
      node_left, node_right: (K,) int64, children, -1 for a tree leaf.
      node_first, node_count: (K,) int64, the node's leaves are
        first .. first + count - 1 (every node, inner ones included).
      flatness: the criterion's constant (fraction of the scene diagonal).
      padding: absolute box padding (scene units).
      arrays: the same as kernels.traverse.BVHArrays, for the kernels.
    """

    patches: PatchSet
    leaf_patch: np.ndarray
    leaf_surface: np.ndarray
    leaf_rect: np.ndarray
    leaf_min: np.ndarray
    leaf_max: np.ndarray
    leaf_obb: np.ndarray
    leaf_net: np.ndarray
    leaf_degree: np.ndarray
    leaf_depth: np.ndarray
    leaf_planar: np.ndarray
    node_min: np.ndarray
    node_max: np.ndarray
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

    @cached_property
    def arrays(self) -> BVHArrays:
        return BVHArrays(
            node_bounds=np.ascontiguousarray(np.concatenate([self.node_min, self.node_max], axis=1)),
            node_left=self.node_left, node_right=self.node_right, node_first=self.node_first,
            node_count=self.node_count, leaf_surface=self.leaf_surface, leaf_rect=self.leaf_rect,
            leaf_obb=self.leaf_obb, leaf_net=self.leaf_net, leaf_degree=self.leaf_degree,
            leaf_planar=self.leaf_planar,
        )


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
        leaf_min=box_min[order],
        leaf_max=box_max[order],
        leaf_obb=obb[order],
        leaf_net=all_nets[order],
        leaf_degree=degree[order],
        leaf_depth=depth[order],
        leaf_planar=obb[order, 14] <= padding * (1.0 + 1e-6) + 1e-12 * diag,
        node_min=n_min,
        node_max=n_max,
        node_left=n_left,
        node_right=n_right,
        node_first=n_first,
        node_count=n_count,
        flatness=float(flatness),
        padding=float(padding),
    )


# ---------------------------------------------------------------------------
# Intersection


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
    exclude=None,
) -> Hits:
    """Nearest hit (or any hit) of N rays with the surfaces of ``bvh``.

    origins, directions: (N, 3) float64 (origins may be (1, 3); directions
    need not be unit; t is measured along the unit direction). t_min, t_max:
    scalars or (N,); a hit needs t_min < t < t_max. tolerance: absolute
    ray-surface distance for Newton's convergence (default 1e-9 of the scene
    diagonal). any_hit: stop each ray at its first valid root (shadow rays);
    t is then that root's, not necessarily the nearest. retry_depth: see
    the module doc. exclude: (surface, u, v, radius_u, radius_v), each (N,):
    a root on that surface within that parameter box around (u, v) is not a
    hit. Secondary rays pass the root they start from, so they never find it
    again (no self-shadowing acne) without an offset that would open a gap
    where two surfaces touch.
    """
    rays = Rays.from_arrays(origins, directions)
    n = len(rays)
    hits = Hits.empty(n)
    if n == 0 or bvh.leaf_total == 0:
        return hits
    t_min = np.ascontiguousarray(np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,)))
    t_max = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,)))
    if tolerance is None:
        tolerance = 1e-9 * bvh.patches.scene_diagonal()
    if exclude is None:
        none = np.zeros(n)
        ex = Exclusion(np.full(n, -1, dtype=np.int64), none, none, none, none)
    else:
        ex = Exclusion(*(np.ascontiguousarray(a, dtype=dt) for a, dt in zip(exclude, (np.int64,) + (np.float64,) * 4)))
    iterations = np.zeros(n, dtype=np.int64)
    trace_rays(bvh.patches.arrays, bvh.patches.trims, bvh.arrays, rays.origin, rays.direction, t_min, t_max,
               float(tolerance), int(max_iterations), bool(any_hit), int(retry_depth), bvh.padding + float(tolerance),
               ex, hits.hit, hits.t, hits.u, hits.v, hits.patch, hits.residual, iterations)
    miss = ~hits.hit
    hits.t[miss], hits.u[miss], hits.v[miss], hits.residual[miss], hits.patch[miss] = np.nan, np.nan, np.nan, np.nan, -1
    hits.surface[hits.hit] = bvh.patches.surface[hits.patch[hits.hit]]
    hits.iterations[:] = np.minimum(iterations, np.iinfo(np.int32).max)
    return hits
