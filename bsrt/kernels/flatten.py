"""Cutting Bezier patches into flat pieces (the hierarchy's leaves), compiled.

The criterion is bvh.py's (see its module doc): a piece is a leaf when its
projected control points lie within ``eps`` of its corners' bilinear patch
and its normals lie within CONE_DEGREES of one axis (cones.py; pieces of
degree p + q > CONE_MAX_DEGREE: deviation and twist within BEND x its
size), or it has
been cut ``max_depth`` times; otherwise it is cut at the parameter midpoint
across the direction with the larger directional deviation. Each patch is
cut depth-first with a stack of nets; two passes (count_leaves, which counts
the leaves for every depth bound at once, then flatten_patches to fill) so
the output arrays are allocated once and the caller can choose a lower
max_depth when the count exceeds its memory budget. Both run on slices of
the patches from every core (threads.run_chunks), as does leaf_boxes.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit, njit_typed

from .cones import corner_turns, normal_cone_within, scratch
from .nets import copy_net, leaf_net, split_half

# A piece's normals must lie within CONE_DEGREES of one axis (bvh.py's module doc); pieces of
# degree p + q > CONE_MAX_DEGREE (the bound's polynomial has degree (4p - 1, 4q - 1)) keep the
# older relative bound instead.
CONE_DEGREES = 8.0
COS_CONE = float(np.cos(np.radians(CONE_DEGREES)))
CONE_MAX_DEGREE = 8


@njit_typed("float64(float64[:, :, ::1], int64, int64, int64, int64)", cache=True, no_cpython_wrapper=True)
def _extent(net, i0, i1, j0, j1):
    """The diagonal of the box of the projected points net[i0:i1+1, j0:j1+1] (a row or a column)."""
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            w = net[i, j, 3]
            x0, x1, x2 = net[i, j, 0] / w, net[i, j, 1] / w, net[i, j, 2] / w
            lo0, lo1, lo2 = min(lo0, x0), min(lo1, x1), min(lo2, x2)
            hi0, hi1, hi2 = max(hi0, x0), max(hi1, x1), max(hi2, x2)
    return np.sqrt((hi0 - lo0) ** 2 + (hi1 - lo1) ** 2 + (hi2 - lo2) ** 2)


@njit(cache=True, no_cpython_wrapper=True)
def measures(net, p, q):
    """(dev, dev_u, dev_v, twist, size) of one homogeneous net ([:p+1, :q+1, 4])."""
    dev = dev_u = dev_v = 0.0
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    w00 = net[0, 0, 3]
    uneven = False
    for i in range(p + 1):
        for j in range(q + 1):
            if net[i, j, 3] != w00:
                uneven = True
    for i in range(p + 1):
        s = i / p
        for j in range(q + 1):
            t = j / q
            w = net[i, j, 3]
            e = e_u = e_v = 0.0
            x0, x1, x2 = net[i, j, 0] / w, net[i, j, 1] / w, net[i, j, 2] / w
            lo0, lo1, lo2 = min(lo0, x0), min(lo1, x1), min(lo2, x2)
            hi0, hi1, hi2 = max(hi0, x0), max(hi1, x1), max(hi2, x2)
            for k in range(3):
                x = net[i, j, k] / w
                a00, ap0 = net[0, 0, k] / net[0, 0, 3], net[p, 0, k] / net[p, 0, 3]
                a0q, apq = net[0, q, k] / net[0, q, 3], net[p, q, k] / net[p, q, 3]
                bil = (1 - s) * ((1 - t) * a00 + t * a0q) + s * ((1 - t) * ap0 + t * apq)
                row = (1 - s) * net[0, j, k] / net[0, j, 3] + s * net[p, j, k] / net[p, j, 3]
                col = (1 - t) * net[i, 0, k] / net[i, 0, 3] + t * net[i, q, k] / net[i, q, 3]
                e += (x - bil) ** 2
                e_u += (x - row) ** 2
                e_v += (x - col) ** 2
            dev, dev_u, dev_v = max(dev, np.sqrt(e)), max(dev_u, np.sqrt(e_u)), max(dev_v, np.sqrt(e_v))
    size = np.sqrt((hi0 - lo0) ** 2 + (hi1 - lo1) ** 2 + (hi2 - lo2) ** 2)
    twist = 0.0
    for k in range(3):
        twist += (
            net[0, 0, k] / net[0, 0, 3]
            - net[p, 0, k] / net[p, 0, 3]
            - net[0, q, k] / net[0, q, 3]
            + net[p, q, k] / net[p, q, 3]
        ) ** 2
    twist = 0.25 * np.sqrt(twist)
    if uneven:  # uneven weights bend the parametrisation even of a flat piece, along their line
        bend_u = bend_v = 0.0
        for j in range(q + 1):  # the rows (along u): their spread of weights times their extent
            wl, wh = np.inf, 0.0
            for i in range(p + 1):
                wl, wh = min(wl, net[i, j, 3]), max(wh, net[i, j, 3])
            bend_u = max(bend_u, (wh / wl - 1.0) * _extent(net, 0, p, j, j))
        for i in range(p + 1):  # the columns (along v)
            wl, wh = np.inf, 0.0
            for j in range(q + 1):
                wl, wh = min(wl, net[i, j, 3]), max(wh, net[i, j, 3])
            bend_v = max(bend_v, (wh / wl - 1.0) * _extent(net, i, i, 0, q))
        dev_u += bend_u
        dev_v += bend_v
        dev += max(bend_u, bend_v)
    return dev, dev_u, dev_v, twist, size


# Explicit signature: called with fill a literal False (count_leaves) and True (flatten_patches),
# numba would compile one specialisation per call site.
@njit_typed(
    "int64(float64[:, :, ::1], int64, int64, float64[::1], float64, float64, float64, int64, boolean, float64[:, ::1], "
    "int64[::1], float64[:, :, :, ::1], int64[::1])",
    cache=True,
    no_cpython_wrapper=True,
    nogil=True,
)
def _cut(net, p, q, rect, eps, bend, floor, max_depth, fill, out_rect, out_depth, out_net, hist):
    """Cut one patch depth-first. Returns the leaf count.

    floor: a piece whose box diagonal is at most this is not cut for its
    normals (cone, bend): the tolerance resolves nothing finer (bvh.py).

    fill: write its leaves into out_rect (n, 4), out_depth (n,), out_net
    (n, Pm, Qm, 4) from index 0. Otherwise count, into hist (2 * (max_depth
    + 1),) int64 (added to): hist[d] the pieces at depth d that are leaves
    by the criterion (or at max_depth), hist[max_depth + 1 + d] those cut
    at depth d; cut at most D <= max_depth times the patch then has
    sum(hist[:D + 1]) + hist[max_depth + 1 + D] leaves (the walk down to
    depth D is the same for every max_depth >= D).

    (Element loops, not array slices: numba compiles those far faster.)"""
    stack = np.empty((max_depth + 2, net.shape[0], net.shape[1], 4))
    rects = np.empty((max_depth + 2, 4))
    depth = np.empty(max_depth + 2, dtype=np.int64)
    piece = np.empty((net.shape[0], net.shape[1], 4))
    tmp = np.empty(max(net.shape[0], net.shape[1]))
    cone = p + q <= CONE_MAX_DEGREE  # else the older relative bound (dev, twist <= BEND x size)
    h, hu, hv, uv, nrm, binom = scratch(p + 1 if cone else 1, q + 1 if cone else 1)
    copy_net(net, stack[0], p, q)
    for k in range(4):
        rects[0, k] = rect[k]
    depth[0] = 0
    top, count = 1, 0
    while top > 0:
        top -= 1
        dev, dev_u, dev_v, twist, size = measures(stack[top], p, q)
        split = depth[top] < max_depth and dev > eps
        by_normals = False
        if depth[top] < max_depth and not split and size > floor:
            if cone:
                split = by_normals = not normal_cone_within(stack[top], p, q, COS_CONE, h, hu, hv, uv, nrm, binom)
            else:
                split = max(dev, twist) > bend * size
        if not split:
            if fill:
                for k in range(4):
                    out_rect[count, k] = rects[top, k]
                out_depth[count] = depth[top]
                copy_net(stack[top], out_net[count], p, q)
            else:
                hist[depth[top]] += 1
            count += 1
            continue
        if not fill:
            hist[max_depth + 1 + depth[top]] += 1
        axis = 0 if dev_u >= dev_v else 1
        if by_normals:  # cut across the direction the normals turn along (a twisted piece: along its rulings)
            turn_u, turn_v = corner_turns(stack[top], p, q)
            if turn_u != turn_v:
                axis = 0 if turn_u > turn_v else 1
        copy_net(stack[top], piece, p, q)
        split_half(piece, stack[top], stack[top + 1], p, q, axis, tmp)
        mid = 0.5 * (rects[top, 2 * axis] + rects[top, 2 * axis + 1])
        for k in range(4):
            rects[top + 1, k] = rects[top, k]
        rects[top, 2 * axis + 1] = mid
        rects[top + 1, 2 * axis] = mid
        depth[top] += 1
        depth[top + 1] = depth[top]
        top += 2
    return count


@njit(cache=True, nogil=True)
def count_leaves(start, stop, nets, degree, rects, eps, bend, floor, max_depth, counts):
    """Leaf counts of patches start..stop-1 at every depth bound, in one walk each.

    nets: (P, Pm, Qm, 4) homogeneous Bezier nets (degree (P, 2) fills the
    corner); rects: (P, 4) parameter rectangles; floor: see _cut; counts: (P, max_depth + 1)
    int64 out: counts[k, d] = the leaves of patch k cut at most d times.
    Called on slices by threads.run_chunks (patches are independent).
    """
    dummy_r, dummy_d, dummy_n = np.empty((0, 4)), np.empty(0, dtype=np.int64), np.empty((0,) + nets.shape[1:])
    hist = np.empty(2 * (max_depth + 1), dtype=np.int64)
    for k in range(start, stop):
        hist[:] = 0
        _cut(
            nets[k],
            degree[k, 0],
            degree[k, 1],
            rects[k],
            eps,
            bend,
            floor,
            max_depth,
            False,
            dummy_r,
            dummy_d,
            dummy_n,
            hist,
        )
        leaves = 0
        for d in range(max_depth + 1):
            leaves += hist[d]
            counts[k, d] = leaves + hist[max_depth + 1 + d]


@njit(cache=True, nogil=True)
def flatten_patches(
    start,
    stop,
    nets,
    degree,
    rects,
    eps,
    bend,
    floor,
    max_depth,
    counts,
    starts,
    net_starts,
    patch,
    out_rect,
    out_depth,
    row,
    out_net,
):
    """Leaves of patches start..stop-1 into the caller's arrays (slices by threads.run_chunks).

    nets, degree, rects: as count_leaves; counts (P,) int64: each patch's
    leaves cut at most max_depth times (count_leaves' column max_depth);
    starts (P + 1,): cumulative counts (patch k's leaves are rows
    starts[k]..starts[k + 1] - 1 of patch (L,), out_rect (L, 4), out_depth
    (L,), row (L,)); net_starts (P + 1,): the same over the cut patches
    (counts > 1) only, into out_net (R, Pm, Qm, 4). A patch that stays
    whole is its own leaf and keeps its net where it is (row -1 - patch,
    see nets.leaf_net); only the pieces of cut patches get a net of their own
    (row r >= 0: out_net[r]), so a model of many small patches holds no
    second copy of its nets.
    """
    hist = np.empty(0, dtype=np.int64)
    for k in range(start, stop):
        first = starts[k]
        if counts[k] == 1:
            for c in range(4):
                out_rect[first, c] = rects[k, c]
            out_depth[first] = 0
            row[first] = -1 - k
        else:
            _cut(
                nets[k],
                degree[k, 0],
                degree[k, 1],
                rects[k],
                eps,
                bend,
                floor,
                max_depth,
                True,
                out_rect[first:],
                out_depth[first:],
                out_net[net_starts[k] :],
                hist,
            )
            for i in range(counts[k]):
                row[first + i] = net_starts[k] + i
        for i in range(first, starts[k + 1]):
            patch[i] = k


SAH_BINS = 16
SAH_DEPTH = 24  # below this depth nodes are split at the median: the tree stays under traverse.STACK levels


@njit(cache=True, no_cpython_wrapper=True)
def _area(lo, hi):
    dx, dy, dz = max(hi[0] - lo[0], 0.0), max(hi[1] - lo[1], 0.0), max(hi[2] - lo[2], 0.0)
    return dx * dy + dy * dz + dz * dx


@njit(cache=True, no_cpython_wrapper=True)
def _reset(lo, hi):
    for k in range(3):
        lo[k], hi[k] = np.inf, -np.inf


@njit(cache=True, no_cpython_wrapper=True)
def _grow(lo, hi, bin_lo, bin_hi, j):
    for k in range(3):
        lo[k], hi[k] = min(lo[k], bin_lo[j, k]), max(hi[k], bin_hi[j, k])


@njit_typed("void(int64[::1], float64[:, ::1], int64, int64, int64)", cache=True, no_cpython_wrapper=True)
def _median_split(order, centre, f, c, axis):
    """Reorder order[f:f + c] in place so that its first c // 2 boxes have no larger centre[:, axis]
    than the rest (Hoare's selection; no sort: numba compiles np.argsort in 1-3 s of the first run)."""
    lo, hi, k = f, f + c - 1, f + c // 2
    while lo < hi:
        pivot = centre[order[(lo + hi) // 2], axis]
        i, j = lo, hi
        while i <= j:
            while centre[order[i], axis] < pivot:
                i += 1
            while centre[order[j], axis] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


@njit(cache=True)
def build_tree(box_min, box_max, leaf_size):
    """Binned surface-area-heuristic tree over L boxes (L, 3), built breadth first.

    (Long: one compiled loop; binning, the sweep and the split share its
    scratch arrays, which a helper would have to take a dozen arguments for.)

    Returns (order (L,): the boxes in tree order, K: the nodes made, node_min, node_max (C, 3),
    node_left, node_right, node_first, node_count (C,)), of which the first K rows are the tree
    (C = 2 L + 1 rows allocated; the caller keeps the K); node 0 is the root, a node's boxes are
    order[first:first + count], children -1 for a tree leaf (count <= leaf_size).
    Each inner node is cut at the best of 15 bin planes along the longest axis
    of its boxes' centres (cost: count x surface area on each side); where all
    centres coincide, or below depth
    SAH_DEPTH, at the median, by _median_split (the walks' stacks hold 64 nodes: a chain of
    one-box splits could otherwise go deeper; measured depths are 17-22).
    """
    n = box_min.shape[0]
    centre = np.empty((n, 3))
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[i] = i
        for k in range(3):
            centre[i, k] = 0.5 * (box_min[i, k] + box_max[i, k])
    cap = 2 * n + 1
    node_min, node_max = np.empty((cap, 3)), np.empty((cap, 3))
    left, right = np.full(cap, -1, dtype=np.int64), np.full(cap, -1, dtype=np.int64)
    first, count = np.zeros(cap, dtype=np.int64), np.zeros(cap, dtype=np.int64)
    count[0] = n
    level = np.zeros(cap, dtype=np.int64)
    made, node = 1, 0
    lo, hi, clo, chi = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    bin_count = np.zeros(SAH_BINS, dtype=np.int64)
    bin_lo, bin_hi = np.empty((SAH_BINS, 3)), np.empty((SAH_BINS, 3))
    run_lo, run_hi = np.empty(3), np.empty(3)
    below, above = np.empty(SAH_BINS - 1), np.empty(SAH_BINS - 1)
    while node < made:
        f, c = first[node], count[node]
        for k in range(3):
            lo[k], hi[k], clo[k], chi[k] = np.inf, -np.inf, np.inf, -np.inf
        for i in range(f, f + c):
            b = order[i]
            for k in range(3):
                lo[k], hi[k] = min(lo[k], box_min[b, k]), max(hi[k], box_max[b, k])
                clo[k], chi[k] = min(clo[k], centre[b, k]), max(chi[k], centre[b, k])
        for k in range(3):
            node_min[node, k], node_max[node, k] = lo[k], hi[k]
        if c > leaf_size:
            axis = 0
            for k in (1, 2):
                if chi[k] - clo[k] > chi[axis] - clo[axis]:
                    axis = k
            extent = chi[axis] - clo[axis]
            half = c // 2
            if extent > 0.0 and level[node] >= SAH_DEPTH:
                _median_split(order, centre, f, c, axis)
            elif extent > 0.0:
                for j in range(SAH_BINS):
                    bin_count[j] = 0
                    for k in range(3):
                        bin_lo[j, k], bin_hi[j, k] = np.inf, -np.inf
                scale = SAH_BINS * (1.0 - 1e-9) / extent
                for i in range(f, f + c):
                    b = order[i]
                    j = int((centre[b, axis] - clo[axis]) * scale)
                    bin_count[j] += 1
                    for k in range(3):
                        bin_lo[j, k], bin_hi[j, k] = min(bin_lo[j, k], box_min[b, k]), max(bin_hi[j, k], box_max[b, k])
                # areas of the boxes of bins below / above each plane, by a sweep from each end
                _reset(run_lo, run_hi)
                for j in range(SAH_BINS - 1):
                    if bin_count[j]:
                        _grow(run_lo, run_hi, bin_lo, bin_hi, j)
                    below[j] = _area(run_lo, run_hi)
                _reset(run_lo, run_hi)
                for j in range(SAH_BINS - 1, 0, -1):
                    if bin_count[j]:
                        _grow(run_lo, run_hi, bin_lo, bin_hi, j)
                    above[j - 1] = _area(run_lo, run_hi)
                best, best_cost, nl = -1, np.inf, 0
                for s in range(1, SAH_BINS):
                    nl += bin_count[s - 1]
                    if nl == 0 or nl == c:
                        continue
                    cost = nl * below[s - 1] + (c - nl) * above[s - 1]
                    if cost < best_cost:
                        best, best_cost, half = s, cost, nl
                if best > 0:  # partition in place: bins below the plane first
                    i, j = f, f + c - 1
                    while i <= j:
                        if int((centre[order[i], axis] - clo[axis]) * scale) < best:
                            i += 1
                        else:
                            order[i], order[j] = order[j], order[i]
                            j -= 1
                else:
                    half = c // 2
                    _median_split(order, centre, f, c, axis)
            left[node], right[node] = made, made + 1
            level[made] = level[made + 1] = level[node] + 1
            first[made], count[made] = f, half
            first[made + 1], count[made + 1] = f + half, c - half
            made += 2
        node += 1
    return order, made, node_min, node_max, left, right, first, count


@njit(cache=True, nogil=True)
def leaf_boxes(start, stop, patch_net, piece_net, row, degree, padding, box_min, box_max, obb):
    """For leaves start..stop-1 (slices by threads.run_chunks): boxes of each leaf's
    projected control points, padded by ``padding``, into
    box_min, box_max (L, 3) (axis-aligned) and obb (L, 15) (oriented: centre,
    axes as rows, half extents; axis 0 along the corners' u direction, axis 2
    their normal, the world axes where those degenerate). The leaves' nets:
    leaf_net(patch_net, piece_net, row, leaf), homogeneous (Pm, Qm, 4);
    degree (L, 2) fills their corner."""
    axes = np.empty((3, 3))
    lo, hi = np.empty(3), np.empty(3)
    du, dv = np.empty(3), np.empty(3)
    for n in range(start, stop):
        net = leaf_net(patch_net, piece_net, row, n)
        p, q = degree[n, 0], degree[n, 1]
        for k in range(3):  # (P10 + P11 - P00 - P01) and (P01 + P11 - P00 - P10), projected corners
            c00, cp0 = net[0, 0, k] / net[0, 0, 3], net[p, 0, k] / net[p, 0, 3]
            c0q, cpq = net[0, q, k] / net[0, q, 3], net[p, q, k] / net[p, q, 3]
            du[k] = cp0 + cpq - c00 - c0q
            dv[k] = c0q + cpq - c00 - cp0
        n0 = du[1] * dv[2] - du[2] * dv[1]
        n1 = du[2] * dv[0] - du[0] * dv[2]
        n2 = du[0] * dv[1] - du[1] * dv[0]
        lu = np.sqrt(du[0] * du[0] + du[1] * du[1] + du[2] * du[2])
        ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        lv = np.sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2])
        if lu > 0 and ln > 1e-12 * max(lu, 1e-300) * lv:
            for k in range(3):
                axes[0, k] = du[k] / lu
            axes[2, 0], axes[2, 1], axes[2, 2] = n0 / ln, n1 / ln, n2 / ln
            axes[1, 0] = axes[2, 1] * axes[0, 2] - axes[2, 2] * axes[0, 1]
            axes[1, 1] = axes[2, 2] * axes[0, 0] - axes[2, 0] * axes[0, 2]
            axes[1, 2] = axes[2, 0] * axes[0, 1] - axes[2, 1] * axes[0, 0]
        else:
            for a in range(3):
                for k in range(3):
                    axes[a, k] = 1.0 if a == k else 0.0
        for k in range(3):
            lo[k], hi[k] = np.inf, -np.inf
            box_min[n, k], box_max[n, k] = np.inf, -np.inf
        for i in range(p + 1):
            for j in range(q + 1):
                w = net[i, j, 3]
                x, y, z = net[i, j, 0] / w, net[i, j, 1] / w, net[i, j, 2] / w
                box_min[n, 0], box_max[n, 0] = min(box_min[n, 0], x), max(box_max[n, 0], x)
                box_min[n, 1], box_max[n, 1] = min(box_min[n, 1], y), max(box_max[n, 1], y)
                box_min[n, 2], box_max[n, 2] = min(box_min[n, 2], z), max(box_max[n, 2], z)
                for k in range(3):
                    d = axes[k, 0] * x + axes[k, 1] * y + axes[k, 2] * z
                    lo[k], hi[k] = min(lo[k], d), max(hi[k], d)
        for k in range(3):
            box_min[n, k] -= padding
            box_max[n, k] += padding
            obb[n, k] = 0.0
            obb[n, 12 + k] = 0.5 * (hi[k] - lo[k]) + padding
        for a in range(3):
            mid = 0.5 * (lo[a] + hi[a])
            for k in range(3):
                obb[n, k] += mid * axes[a, k]
                obb[n, 3 + 3 * a + k] = axes[a, k]
