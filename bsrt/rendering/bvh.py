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

   For a rational piece, the spread of its weights along each row (along u)
   adds ``(max w / min w - 1) * extent`` (extent = the diagonal of that
   row's points' box; the largest over the rows, to dev_u and dev), and the
   same along each column to dev_v and dev, since uneven weights bend the
   parametrisation even of a flat piece, along the line where they vary.
   (It was the spread times the whole piece's diagonal: a long thin
   rational cylinder, 70 across and 1,140 long, was cut into 1,159 slivers
   of 0.3 degrees instead of 35 pieces, and the 1,018-face 11752.stp had
   206 k leaves, 192 MB cached, instead of 27 k.) A piece is a leaf when
   ``dev <= flatness * scene_diagonal`` or it has been cut ``max_depth``
   times; otherwise it is cut across the direction with the larger
   directional measure. dev is zero exactly when the piece *is* the bilinear
   patch of its corners with the uniform parametrisation; it bounds both the
   piece's departure from a plane and the non-linearity of its
   parametrisation, which is what limits Newton's basin from the centre.
   A second, relative bound (on the normals, like Martin's curvature
   bound) also splits a piece while its normals do not all lie within
   CONE_DEGREES = 8 degrees of one axis (``kernels/cones.py``: the Bernstein
   coefficients of U x V, U = H_u w - H w_u, V = H_v w - H w_v, bound every
   normal of a rational piece, the weights included, without a bound on
   their spread). Two normals of a leaf then differ by at most 16 degrees;
   a ray that crosses a leaf twice is tangent to it somewhere between, so at
   either crossing |cos(normal, ray)| <= sin 16 deg = 0.28, below the
   grazing retries' threshold (0.3): such a ray is always retried. A piece
   cut for its normals is cut across the direction its corner normals turn
   along (``cones.corner_turns``; the directional measures where a corner
   normal vanishes or both turn alike): a twisted ruled piece's normals turn
   along its straight rulings, where the measures are 0, and cutting only
   across u made a 16-span band 57,348 leaves deep to the depth bound
   (110 now; the column 13,233 -> 4,721, 11752.stp 26,502 -> 21,712). Without
   a relative bound, small strongly curved features (the column's
   mouldings) made leaves that a ray at cos 0.3-0.5 crosses twice, and
   Newton from the centre found the far root. (This replaced ``dev >
   BEND * size`` or a corner twist above that, BEND = 0.02, with the
   weights' spread in dev: it cut a sphere into pieces of 3-6 degrees, and
   at its poles down to max_depth; a 2,046-face STEP part needed 1.79 M
   leaves, 0.67 M under the memory cap below, now 53 k.) Pieces of degree
   p + q > 8 keep that older bound: the cone's polynomial has degree
   (4p - 1, 4q - 1).
   Default ``flatness = 5e-4`` (``DEFAULT_FLATNESS``), ``max_depth = 12``
   (at most 4096 leaves per Bezier patch), lowered for the whole scene while
   the leaves' nets would exceed LEAF_NET_FLOATS (256 MB) or LEAVES_PER_PATCH
   nets per patch (``flatten``): high-degree patches stay in bounded memory. Finer values make
   Newton from the centre fail less often, so shadow rays retry less: against 2e-3 (the default
   until 2026-11), the render stage of 512x512 renders with shadows took 4-23% less time (column
   4,721 -> 6,865 leaves, 11752.stp 21,712 -> 23,599, U_Joint_2 3,145 -> 4,933; water-lily 7%),
   the CAD parts' hierarchies built as fast and the column's 0.04 s slower; at 2.5e-4 the
   water-lily is slower again (docs/performance.md).

2. **BVH** over the leaves, arrays only, built breadth first (compiled,
   ``kernels/flatten.build_tree``): a node's leaves are split by the binned
   surface-area heuristic (16 bins along the longest axis of their box
   centres; the median where the centres coincide), until a node holds at
   most ``leaf_size`` leaves (default 2).

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
   two crossings may be in the same quarter). A planar piece (``leaf_planar``)
   meets a ray once, so it is cut only when its centre start finds no root
   (its grazing roots were most of the retries of random rays at the
   160-face as1 assembly, whose plates are planar). A grazing root then takes one
   more Newton step (kept if it is still a valid root of the piece, that
   near): its t is off by up to its residual / |cos|, and the step takes the
   residual from the tolerance down to rounding. The piece holding a
   secondary ray's start is skipped unless the ray leaves the start grazing;
   then it is solved and retried like any other, its start root excluded
   (a cupped surface shadowing itself within one leaf: water-lily's petals).
   Measured against an exhaustive search (Newton from 10 x 10 starts on
   every Bezier patch whose box the ray enters): 30,000 random rays at
   three non-uniform surfaces (degrees 3, 2 and a rational bowl, a third of
   the rays starting inside the bowl), 12,493 hits: centre start only
   misses or mis-orders 10 rays at flatness 2e-3 (76 at 1e-2); with the
   retries, 0 (2 at 1e-2).

Budget: a ray spends at most ``ray_budget(max_iterations)`` = RAY_BUDGET_PIECES
(256) x max_iterations Newton iterations (its retries included) on the pieces
it meets; then no further piece is solved (the one being solved completes)
and the nearest valid root found so far is its answer (a miss if none). Such
rays are counted (``out_of_budget`` in ``--stats``); their hit is a true root
of the scene, possibly not the nearest. On the scenes of ``scenes/`` at
128 x 128 no ray needs more than 591 iterations, so the budget never binds
there. It binds when the tolerance (a fraction of the scene diagonal) is
large against the part of the scene in view: one control point at 1e9 in a
scene of size 10 makes the diagonal ~1e9, the tolerance and the boxes'
padding ~1 scene unit, and then every ray enters, and solves, thousands of
padded boxes (5.6 million iterations a pixel, before the budget).

Leaf boxes: an axis-aligned box (for the tree) and an oriented box (axes
from the corners' u direction and normal) tested per (ray, leaf) pair.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.flatten import build_tree, count_leaves, flatten_patches, leaf_boxes
from bsrt.kernels.hierarchy import BVHArrays
from bsrt.kernels.tables import permute_rows
from bsrt.kernels.threads import run_chunks
from bsrt.kernels.traverse import Exclusion, trace_rays
from bsrt.kernels.trim import INSIDE, OUTSIDE, rect_states
from bsrt.rendering.hits import Hits
from bsrt.rendering.solve import Rays

DEFAULT_FLATNESS = 5e-4
DEFAULT_MAX_DEPTH = 12
DEFAULT_LEAF_SIZE = 2
DEFAULT_RETRY_DEPTH = 4
DEFAULT_MAX_ITERATIONS = 16
RAY_BUDGET_PIECES = 256  # a ray's work: Newton's full iterations on this many pieces (module doc, "Budget")
BEND = 0.02  # a leaf deviates from its bilinear patch by at most this fraction of its size
LEAF_NET_FLOATS = 1 << 25  # the leaves' nets hold at most this many floats (256 MB) ...
LEAVES_PER_PATCH = 4  # ... or this many nets per patch, if more (a patch is at least one leaf)
PACKET_SPREAD = 1.0  # shade_hits' packets: hit points within this many median leaf sizes (BVH.packet_spread)
PATCH_CHUNK, PATCH_SLICES = 16, 32  # flattening slices: patches cost very unevenly (1 to 4096 leaves)


@dataclass(eq=False)
class BVH:
    """Leaves (flat Bezier pieces) and the tree over them.

    patches: the PatchSet the leaves were cut from.
    arrays: the table the kernels read (kernels.hierarchy.BVHArrays, which
      declares it: L leaves in tree order, K nodes); its columns are
      attributes of the BVH too (``bvh.leaf_obb``, ``bvh.node_left``, ...).
    leaf_patch: (L,) int64, PatchSet patch id.
    leaf_min, leaf_max: (L, 3) float64, axis-aligned box of the piece's
      projected control points, padded by ``padding``.
    leaf_depth: (L,) int64, number of cuts from the Bezier patch.
    flatness: the criterion's constant (fraction of the scene diagonal).
    padding: absolute box padding (scene units).
    """

    patches: PatchSet
    arrays: BVHArrays
    leaf_patch: np.ndarray
    leaf_min: np.ndarray
    leaf_max: np.ndarray
    leaf_depth: np.ndarray
    flatness: float
    padding: float

    def __getattr__(self, name: str):
        if name in BVHArrays._fields and "arrays" in self.__dict__:
            return getattr(self.__dict__["arrays"], name)
        raise AttributeError(name)

    @cached_property
    def packet_spread(self) -> float:
        """The widest box (scene units) of hit points whose shadow rays kernels/lighting.py's
        shade_hits walks together: PACKET_SPREAD of the median leaf's largest extent. Rays from
        farther apart share less of their walk than the per-ray tests a looser packet adds."""
        if not self.leaf_total:
            return 0.0
        return PACKET_SPREAD * 2.0 * float(np.median(self.arrays.leaf_obb[:, 12:15].max(axis=1)))

    @property
    def node_min(self) -> np.ndarray:
        """(K, 3) float64: the nodes' box corners (node_bounds[:, :3])."""
        return self.arrays.node_bounds[:, :3]

    @property
    def node_max(self) -> np.ndarray:
        """(K, 3) float64 (node_bounds[:, 3:])."""
        return self.arrays.node_bounds[:, 3:]

    @property
    def leaf_total(self) -> int:
        return int(self.leaf_patch.shape[0])

    @property
    def node_total(self) -> int:
        return int(self.arrays.node_bounds.shape[0])


# ---------------------------------------------------------------------------
# Flattening


def padded_nets(patches: PatchSet):
    """(nets (P, Pm, Qm, 4), degree (P, 2)): every patch's homogeneous net in the corner of one array."""
    degree = patches.arrays.degree
    pm, qm = (int(degree[:, 0].max()) + 1, int(degree[:, 1].max()) + 1) if patches.size else (1, 1)
    if len(patches.groups) == 1 and patches.groups[0][0].size == patches.size:  # one degree: the table itself, no copy
        return patches.groups[0][1], degree
    nets = np.zeros((patches.size, pm, qm, 4))
    for ids, group in patches.groups:
        nets[ids, : group.shape[1], : group.shape[2]] = group
    return nets, degree


def flatten(
    patches: PatchSet, flatness: float = DEFAULT_FLATNESS, max_depth: int = DEFAULT_MAX_DEPTH, floor: float = 0.0
):
    """Cut every Bezier patch into flat pieces (compiled: kernels/flatten.py).

    The leaves' nets are bounded: the largest depth bound <= max_depth at
    which they hold at most max(LEAF_NET_FLOATS, LEAVES_PER_PATCH floats per
    patch's net) floats is used (a high-degree patch then keeps coarser,
    curved leaves; the grazing/miss retries cut those further per ray); one
    counting walk gives the leaf counts at every bound. floor: a piece
    whose box diagonal is at most this is not cut for its normals (build_bvh
    passes the box padding: the module doc's "Budget").
    Returns (patch (L,) int64, rect (L, 4), depth (L,) int64, degree (L, 2)
    int64, and the nets: patch_net (P, Pm, Qm, 4), piece_net (R, Pm, Qm, 4),
    row (L,) int64 as BVH.patch_net, leaf_net, leaf_net_row).
    """
    nets, degree = padded_nets(patches)
    eps = flatness * patches.scene_diagonal()
    n = patches.size
    per_leaf = int(np.prod(nets.shape[1:]))
    allowance = max(LEAF_NET_FLOATS, LEAVES_PER_PATCH * per_leaf * n)
    by_depth = np.zeros((n, max_depth + 1), dtype=np.int64)
    run_chunks(
        count_leaves,
        n,
        nets,
        degree,
        patches.bounds,
        eps,
        BEND,
        float(floor),
        max_depth,
        by_depth,
        min_chunk=PATCH_CHUNK,
        per_worker=PATCH_SLICES,
    )
    copied = np.where(by_depth > 1, by_depth, 0).sum(axis=0)  # (max_depth + 1,): a whole patch keeps its net
    while max_depth > 0 and int(copied[max_depth]) * per_leaf > allowance:
        max_depth -= 1
    counts = np.ascontiguousarray(by_depth[:, max_depth])
    del by_depth
    starts = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=starts[1:])
    net_starts = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.where(counts > 1, counts, 0), out=net_starts[1:])
    total = int(starts[n])
    patch, rect = np.empty(total, dtype=np.int64), np.empty((total, 4))
    depth, row = np.empty(total, dtype=np.int64), np.empty(total, dtype=np.int64)
    piece_nets = np.zeros((int(net_starts[n]),) + nets.shape[1:])
    run_chunks(
        flatten_patches,
        n,
        nets,
        degree,
        patches.bounds,
        eps,
        BEND,
        float(floor),
        max_depth,
        counts,
        starts,
        net_starts,
        patch,
        rect,
        depth,
        row,
        piece_nets,
        min_chunk=PATCH_CHUNK,
        per_worker=PATCH_SLICES,
    )
    return patch, rect, depth, degree[patch], (nets, piece_nets, row)


# ---------------------------------------------------------------------------
# Tree


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
    patch, rect, depth, degree, (patch_net, piece_net, row) = flatten(patches, flatness, max_depth, padding)
    kept = np.ones(patch.size, dtype=bool)
    if patches.trimmed:  # pieces the trims remove entirely hold no hit (their nets stay, unused)
        state = rect_states(patches.trims, patches.surface[patch], rect[:, 0], rect[:, 1], rect[:, 2], rect[:, 3])
        keep = state != OUTSIDE
        patch, rect, depth, degree, row = patch[keep], rect[keep], depth[keep], degree[keep], row[keep]
        kept = state[keep] == INSIDE
    box_min, box_max, obb = np.empty((patch.size, 3)), np.empty((patch.size, 3)), np.empty((patch.size, 15))
    run_chunks(leaf_boxes, patch.size, patch_net, piece_net, row, degree, float(padding), box_min, box_max, obb)
    order, made, n_min, n_max, n_left, n_right, n_first, n_count = build_tree(box_min, box_max, leaf_size)
    permute_rows(obb, order)  # into tree order in place: no second copy of the largest per-leaf table
    rect = rect[order]
    return BVH(
        patches=patches,
        arrays=BVHArrays(
            node_bounds=np.concatenate([n_min[:made], n_max[:made]], axis=1),
            node_left=n_left[:made].copy(),
            node_right=n_right[:made].copy(),
            node_first=n_first[:made].copy(),
            node_count=n_count[:made].copy(),
            leaf_surface=patches.surface[patch[order]],
            leaf_rect=rect,
            leaf_obb=obb,
            patch_net=patch_net,
            leaf_net=piece_net,
            leaf_net_row=row[order],
            leaf_degree=degree[order],
            leaf_planar=obb[:, 14] <= padding * (1.0 + 1e-6) + 1e-12 * diag,
            leaf_kept=kept[order],
        ),
        leaf_patch=patch[order],
        leaf_min=box_min[order],
        leaf_max=box_max[order],
        leaf_depth=depth[order],
        flatness=float(flatness),
        padding=float(padding),
    )


# ---------------------------------------------------------------------------
# Intersection


def ray_budget(max_iterations: int = DEFAULT_MAX_ITERATIONS) -> int:
    """A ray's bound on Newton iterations through the hierarchy (module doc, "Budget")."""
    return RAY_BUDGET_PIECES * int(max_iterations)


def out_of_budget(hits: Hits, budget: int) -> int:
    """How many of these hits (from intersect with this budget) spent their ray's budget."""
    return int(np.count_nonzero(hits.iterations >= budget))


def intersect(
    bvh: BVH,
    origins: np.ndarray,
    directions: np.ndarray,
    t_min=0.0,
    t_max=np.inf,
    tolerance: float | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    any_hit: bool = False,
    retry_depth: int = DEFAULT_RETRY_DEPTH,
    exclude=None,
    budget: int | None = None,
    out: Hits | None = None,
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
    where two surfaces touch. budget: Newton iterations per ray (default
    ray_budget(max_iterations); the module doc's "Budget"); a ray that spent
    it has hits.iterations >= budget (out_of_budget). out: N records to write the hits into
    (Hits.empty's, or views of a larger one's: Hits.take of a slice), returned.
    """
    rays = Rays.from_arrays(origins, directions)
    n = len(rays)
    if n == 0 or bvh.leaf_total == 0:
        if out is None:
            return Hits.empty(n)
        out.put(slice(None), Hits.empty(n))
        return out
    hits = Hits.blank(n) if out is None else out  # every field written below
    # writable C arrays (a broadcast or caller's array may be read-only: another compiled signature)
    t_min = np.require(np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,)), np.float64, ("C", "W"))
    t_max = np.require(np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,)), np.float64, ("C", "W"))
    if tolerance is None:
        tolerance = 1e-9 * bvh.patches.scene_diagonal()
    if exclude is None:
        none = np.zeros(n)
        ex = Exclusion(np.full(n, -1, dtype=np.int64), none, none, none, none)
    else:
        ex = Exclusion(*(np.require(a, dt, ("C", "W")) for a, dt in zip(exclude, (np.int64,) + (np.float64,) * 4)))
    run_chunks(
        trace_rays,
        n,
        bvh.patches.arrays,
        bvh.patches.trims,
        bvh.arrays,
        rays.origin,
        rays.direction,
        t_min,
        t_max,
        float(tolerance),
        int(max_iterations),
        bool(any_hit),
        int(retry_depth),
        bvh.padding + float(tolerance),
        ex,
        hits.hit,
        hits.t,
        hits.u,
        hits.v,
        hits.patch,
        hits.surface,
        hits.residual,
        hits.iterations,
        ray_budget(max_iterations) if budget is None else int(budget),
        stoppable=True,
    )
    return hits
