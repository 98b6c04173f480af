"""Shading a band of hits in one compiled pass: frames, exclusion boxes, shadow rays, Blinn-Phong.

``shade_hits`` does per hit what the NumPy pipeline did in a dozen passes:
the surface frame (``shading.surface_frame``), the parameter box its
secondary rays must not hit again, one any-hit shadow ray per light the point
faces (``occluded``), and the radiance (``shading.radiance``). Mirror bounces
stay with the caller (rendering/pipeline.py), which gets each hit's position,
normal and exclusion box from here.

``occluded`` is the any-hit walk of shadow rays: the same tests and the same
per-piece solve as ``traverse.trace_rays`` with ``any_hit``, without the
nearest-first bookkeeping. It walks a packet: the shadow rays toward one light
from up to PACKET consecutive hits whose points lie in a box at most
``spread`` wide (bvh.BVH.packet_spread, about a leaf: farther apart, rays
share less of the walk than a looser packet adds). The packet enters a node
when the interval of its rays' origins and inverse directions may
(``_packet_slab``, conservative to the bit), so the tree's upper levels are
walked once for all; at a leaf node each ray takes its own box test and the
pieces' tests. Each ray first tries a piece that blocked a ray of the
previous packet toward the same light (neighbouring points are mostly
shadowed by the same piece; none after a packet that was all lit). The piece
holding the ray's start is skipped where trace_rays skips it (the ray leaves
it steeply), and also where the ray's line meets it only once
(``crossings.crosses_once``, an exact bound): that one crossing is the start,
the root every shadow ray excludes. Whether a ray is blocked is otherwise the
same answer trace_rays gives: a piece that yields a valid root would yield it
inside the walk too, and the packet enters every node its rays would.
Measured (scripts/shadow_cost.py, one core): the shading pass 5-18 % faster
than one ray at a time at 512x512 and 25-30 % at 2048x2048.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.crossings import crosses_once
from bsrt.kernels.hulls import straddles
from bsrt.kernels.jit import njit
from bsrt.kernels.nets import leaf_net
from bsrt.kernels.patches import frame, locate
from bsrt.kernels.roots import ray_frame
from bsrt.kernels.shading import radiance, surface_frame_of
from bsrt.kernels.traverse import STACK, _cross, _leaves_grazing, _normal, _obb_slab, _slab, _solve_piece

PACKET = 16  # the most hits whose shadow rays toward a light are walked together (occluded)


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def _leaf_blocks(P, T, B, leaf, ox, oy, oz, dx, dy, dz, e, t_max, tol, max_iterations, retry_depth, cull_tol, ex, s):
    """(blocked, iterations): does piece ``leaf`` hold a valid root in (0, t_max)? (trace_rays's tests:
    oriented box, hull straddle, the piece's solve with its retries). ex: (surface, u, v, ru, rv) of
    the start root; s: the scratch (nets, rects, depth, tmp)."""
    lo, hi = _obb_slab(B.leaf_obb[leaf], ox, oy, oz, dx, dy, dz)
    if not (lo <= hi and hi >= 0.0 and lo <= t_max):
        return False, 0
    net = leaf_net(B.patch_net, B.leaf_net, B.leaf_net_row, leaf)
    p, q = B.leaf_degree[leaf, 0], B.leaf_degree[leaf, 1]
    if not straddles(net, p, q, ox, oy, oz, e, dx, dy, dz, 0.0, t_max, cull_tol):
        return False, 0
    found, _, _, _, _, _, its = _solve_piece(
        P,
        T,
        B,
        leaf,
        ox,
        oy,
        oz,
        dx,
        dy,
        dz,
        e,
        0.0,
        t_max,
        tol,
        max_iterations,
        retry_depth,
        cull_tol,
        ex[0],
        ex[1],
        ex[2],
        ex[3],
        ex[4],
        s[0],
        s[1],
        s[2],
        s[3],
        retry_depth >= 0,  # True (any hit), as a run-time value: a literal would compile _solve_piece twice
    )
    return found, its


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def _crosses_once(B, leaf, ox, oy, oz, e, g):
    """crossings.crosses_once for piece ``leaf``: does the ray meet it at most once? g: a scratch net
    (the retries never use the last: traverse._solve_piece)."""
    net = leaf_net(B.patch_net, B.leaf_net, B.leaf_net_row, leaf)
    return crosses_once(net, B.leaf_degree[leaf, 0], B.leaf_degree[leaf, 1], ox, oy, oz, e, g)


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def _packet_slab(b, o_lo, o_hi, i_lo, i_hi):
    """Bounds (near below every ray's, far above every ray's) of _slab's entry and exit distances into
    box b (6,) for rays whose origins lie in the box o_lo..o_hi (3,) and inverse directions in
    i_lo..i_hi (3,): the corners of each interval product. Rounding is monotone, so the bounds hold
    for each ray's own _slab as computed, to the bit."""
    near, far = -np.inf, np.inf
    for a in range(3):
        lo, hi = np.inf, -np.inf
        for c in (b[a], b[a + 3]):
            x0, x1 = c - o_hi[a], c - o_lo[a]
            p0, p1, p2, p3 = x0 * i_lo[a], x0 * i_hi[a], x1 * i_lo[a], x1 * i_hi[a]
            lo = min(lo, min(min(p0, p1), min(p2, p3)))
            hi = max(hi, max(max(p0, p1), max(p2, p3)))
        near, far = max(near, lo), min(far, hi)
    return near, far


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def occluded(
    P,
    T,
    B,
    n,
    origin,
    direction,
    t_max,
    tol,
    max_iterations,
    retry_depth,
    cull_tol,
    budget,
    ex_m,
    ex_box,
    start,
    item,
    hint,
    stack,
    s,
    frames,
    bounds,
    leaf_of,
    iterations,
):
    """Any-hit shadow rays 0..n-1 from origin (W, 3) along the unit direction (W, 3) with
    0 < t < t_max (W,), walked together: the hierarchy once for the packet, each node entered if the
    interval of the packet's origins and inverse directions may enter it (_packet_slab), each piece
    tested per ray as trace_rays tests it. So each ray's answer is its own walk's: the packet enters
    every node any of its rays enters, and a piece that yields a ray a valid root yields it there too.

    ex_m (W,) int64, ex_box (W, 4) (u, v, radius_u, radius_v): the start roots, as _leaf_blocks's ex,
    and start (W, 4): traverse._normal at each; ray r's are at row item[r] (item: (W,) int64).
    hint: a leaf to try first (-1: none); stack: (STACK,) int64 and s (_leaf_blocks's) scratch;
    frames (W, 6), bounds (4, 3): scratch.
    Outputs (W,): leaf_of, the leaf that blocked each ray, -1 lit, -2 out of budget (``budget``
    Newton iterations spent without a blocker: taken as lit, counted); iterations, each ray's.
    No reference counting (``_nrt=False``, as traverse.py's per-piece helpers): it would cost a third
    of a shadow ray's time. Returns the last blocking leaf (-1: none), a hint for the next packet."""
    last = -1
    active = 0
    g = s[0][s[0].shape[0] - 1]  # _crosses_once's scratch net
    for r in range(n):
        dx, dy, dz = direction[r, 0], direction[r, 1], direction[r, 2]
        e = ray_frame(dx, dy, dz)
        for c in range(6):
            frames[r, c] = e[c]
        leaf_of[r], iterations[r] = -1, 0
        if hint < 0:
            active += 1
            continue
        w = item[r]
        ex = (ex_m[w], ex_box[w, 0], ex_box[w, 1], ex_box[w, 2], ex_box[w, 3])
        hr = B.leaf_rect[hint]
        at_start = B.leaf_surface[hint] == ex[0] and hr[0] <= ex[1] <= hr[1] and hr[2] <= ex[2] <= hr[3]
        skip_start = ex[0] >= 0 and not _leaves_grazing(
            (start[w, 0], start[w, 1], start[w, 2], start[w, 3]), dx, dy, dz
        )
        ox, oy, oz = origin[r, 0], origin[r, 1], origin[r, 2]
        if not (at_start and (skip_start or _crosses_once(B, hint, ox, oy, oz, e, g))):
            blocked, its = _leaf_blocks(
                P, T, B, hint, ox, oy, oz, dx, dy, dz, e, t_max[r], tol, max_iterations, retry_depth, cull_tol, ex, s
            )
            iterations[r] += its
            if blocked:
                leaf_of[r] = last = hint
                continue
        active += 1
    if active == 0:
        return last
    # the packet's interval: origins o_lo..o_hi, inverse directions i_lo..i_hi, the farthest t_max
    for a in range(3):
        bounds[0, a] = bounds[2, a] = np.inf
        bounds[1, a] = bounds[3, a] = -np.inf
    reach = 0.0
    for r in range(n):
        if leaf_of[r] != -1:
            continue
        reach = max(reach, t_max[r])
        for a in range(3):
            d = direction[r, a]
            inv = 1.0 / d if abs(d) > 1e-300 else np.copysign(1e300, d)
            bounds[0, a], bounds[1, a] = min(bounds[0, a], origin[r, a]), max(bounds[1, a], origin[r, a])
            bounds[2, a], bounds[3, a] = min(bounds[2, a], inv), max(bounds[3, a], inv)
    near, far = _packet_slab(B.node_bounds[0], bounds[0], bounds[1], bounds[2], bounds[3])
    if not (near <= far and far >= 0.0 and near <= reach):
        return last
    stack[0] = 0
    top = 1
    while top > 0 and active > 0:
        top -= 1
        node = stack[top]
        left = B.node_left[node]
        if left >= 0:
            right = B.node_right[node]
            n1, f1 = _packet_slab(B.node_bounds[left], bounds[0], bounds[1], bounds[2], bounds[3])
            n2, f2 = _packet_slab(B.node_bounds[right], bounds[0], bounds[1], bounds[2], bounds[3])
            hit1 = n1 <= f1 and f1 >= 0.0 and n1 <= reach
            hit2 = n2 <= f2 and f2 >= 0.0 and n2 <= reach
            if hit1 and hit2 and top + 2 <= stack.shape[0]:  # a full stack drops what trace_rays drops
                stack[top], stack[top + 1] = right, left
                top += 2
            elif hit1:
                stack[top] = left
                top += 1
            elif hit2:
                stack[top] = right
                top += 1
            continue
        box = B.node_bounds[node]
        for r in range(n):
            if leaf_of[r] != -1:
                continue
            ox, oy, oz = origin[r, 0], origin[r, 1], origin[r, 2]
            dx, dy, dz = direction[r, 0], direction[r, 1], direction[r, 2]
            ix = 1.0 / dx if abs(dx) > 1e-300 else np.copysign(1e300, dx)
            iy = 1.0 / dy if abs(dy) > 1e-300 else np.copysign(1e300, dy)
            iz = 1.0 / dz if abs(dz) > 1e-300 else np.copysign(1e300, dz)
            near, far = _slab(box, ox, oy, oz, ix, iy, iz)
            if not (near <= far and far >= 0.0 and near <= t_max[r]):
                continue  # this ray's own walk does not enter the node
            e = (frames[r, 0], frames[r, 1], frames[r, 2], frames[r, 3], frames[r, 4], frames[r, 5])
            w = item[r]
            ex = (ex_m[w], ex_box[w, 0], ex_box[w, 1], ex_box[w, 2], ex_box[w, 3])
            skip_start = ex[0] >= 0 and not _leaves_grazing(
                (start[w, 0], start[w, 1], start[w, 2], start[w, 3]), dx, dy, dz
            )
            for leaf in range(B.node_first[node], B.node_first[node] + B.node_count[node]):
                if leaf == hint:
                    continue  # tried above (or the start's piece, skipped below too)
                if B.leaf_surface[leaf] == ex[0]:
                    lr = B.leaf_rect[leaf]
                    if lr[0] <= ex[1] <= lr[1] and lr[2] <= ex[2] <= lr[3]:
                        if skip_start or _crosses_once(B, leaf, ox, oy, oz, e, g):
                            continue
                blocked, its = _leaf_blocks(
                    P,
                    T,
                    B,
                    leaf,
                    ox,
                    oy,
                    oz,
                    dx,
                    dy,
                    dz,
                    e,
                    t_max[r],
                    tol,
                    max_iterations,
                    retry_depth,
                    cull_tol,
                    ex,
                    s,
                )
                iterations[r] += its
                if blocked:
                    leaf_of[r] = last = leaf
                    active -= 1
                    break
                if iterations[r] >= budget:
                    leaf_of[r] = -2
                    active -= 1
                    break
    return last


@njit(cache=True, nogil=True)
def shade_hits(
    start,
    stop,
    P,
    T,
    B,
    hit,
    patch,
    surface,
    u,
    v,
    direction,
    material_of,
    albedo,
    specular,
    shininess,
    kind,
    light_position,
    light_direction,
    strength,
    background,
    eps,
    tol,
    max_iterations,
    retry_depth,
    cull_tol,
    budget,
    spread,
    colour,
    position,
    normal,
    radius,
    shadow_rays,
    exhausted,
):
    """Colour of rays start..stop-1 of K, lit with shadows (mirrors left to the caller).

    hit: (K,) bool; patch, surface: (K,) int64; u, v: (K,) float64: the hits; direction: (K, 3)
    unit ray directions. material_of: (S,) int64 material of each surface; albedo (M, 3), specular,
    shininess (M,); lights as rendering.shade.light_arrays gives them: kind (L,), light_position (L, 3), light_direction
    (L, 3) (unit, toward the light), strength (L, 3);
    background (3,). eps: the exclusion half-width in scene units (1e-6 of the diagonal); tol,
    max_iterations, retry_depth, cull_tol: the shadow rays' solve (bvh.intersect's); budget: a
    shadow ray's Newton iterations (bvh.py, "Budget"); spread: the widest box (scene units) of hit
    points whose shadow rays toward a light are walked together (occluded; bvh.BVH.packet_spread).
    Outputs, (K, ...): colour (K, 3) linear RGB (background where no hit); position, normal (K, 3)
    (normal facing the ray's origin) and radius (K, 2) (the exclusion box's half-widths in u, v:
    eps / |S_u|, eps / |S_v|, at most a quarter of the patch), NaN where no hit; shadow_rays (K,)
    int64, the shadow rays traced from each hit; exhausted (K,) int64, those of them that spent
    their budget (taken as lit).
    """
    n_lights = kind.shape[0]
    pm, qm = B.patch_net.shape[1], B.patch_net.shape[2]
    size = 4 * retry_depth + 8
    stack = np.empty(STACK, dtype=np.int64)  # scratch, once per slice
    s = (np.empty((size, pm, qm, 4)), np.empty((size, 4)), np.empty(size, dtype=np.int64), np.empty(max(pm, qm)))
    hints = np.full(n_lights, -1, dtype=np.int64)  # per light: a leaf that blocked the last packet (-1: none)
    # one packet's hits (PACKET consecutive items): start roots and their normals, visibility per light
    ex_m, ex_box, start_normal = np.empty(PACKET, dtype=np.int64), np.empty((PACKET, 4)), np.empty((PACKET, 4))
    visibility = np.empty((PACKET, n_lights))
    # one light's shadow rays of the packet, and occluded's scratch and answers
    item = np.empty(PACKET, dtype=np.int64)
    origin, towards, reach = np.empty((PACKET, 3)), np.empty((PACKET, 3)), np.empty(PACKET)
    frames, bounds = np.empty((PACKET, 6)), np.empty((4, 3))
    leaf_of, iterations = np.empty(PACKET, dtype=np.int64), np.empty(PACKET, dtype=np.int64)
    first, carried = start, -1  # carried: the previous packet's slot holding this one's first hit
    while first < stop:
        # the packet: up to PACKET consecutive items whose hits lie in a box at most `spread` wide
        xlo = ylo = zlo = np.inf
        xhi = yhi = zhi = -np.inf
        last = first
        while last < stop and last - first < PACKET:
            i, w = last, last - first
            for j in range(n_lights):
                visibility[w, j] = 1.0
            if carried >= 0:  # its frame is at hand, in the previous packet's slot
                ex_m[0] = ex_m[carried]
                for c in range(4):  # scalar copies: an array slice's assignment compiles a numba impl of its own
                    ex_box[0, c], start_normal[0, c] = ex_box[carried, c], start_normal[carried, c]
                carried = -1
            else:
                shadow_rays[i] = 0
                exhausted[i] = 0
                if not hit[i]:
                    colour[i, 0], colour[i, 1], colour[i, 2] = background[0], background[1], background[2]
                    for c in range(3):
                        position[i, c] = normal[i, c] = np.nan
                    radius[i, 0] = radius[i, 1] = np.nan
                    last += 1
                    continue
                k = patch[i]
                f = frame(P, k, u[i], v[i])
                px, py, pz, nx, ny, nz, su, sv = surface_frame_of(
                    P, k, u[i], v[i], f, direction[i, 0], direction[i, 1], direction[i, 2]
                )
                b = P.bounds[k]
                position[i, 0], position[i, 1], position[i, 2] = px, py, pz
                normal[i, 0], normal[i, 1], normal[i, 2] = nx, ny, nz
                radius[i, 0] = min(eps / su if su > 0.0 else np.inf, 0.25 * (b[1] - b[0]))
                radius[i, 1] = min(eps / sv if sv > 0.0 else np.inf, 0.25 * (b[3] - b[2]))
                ex_m[w], ex_box[w, 0], ex_box[w, 1] = surface[i], u[i], v[i]
                ex_box[w, 2], ex_box[w, 3] = radius[i, 0], radius[i, 1]
                # the start's normal, for every light: that of the patch trace_rays locates (mostly the hit's own)
                at = locate(P, surface[i], u[i], v[i])
                cx, cy, cz, length = _cross(f) if at == k else _normal(P, at, u[i], v[i])
                start_normal[w, 0], start_normal[w, 1], start_normal[w, 2], start_normal[w, 3] = cx, cy, cz, length
            px, py, pz = position[i, 0], position[i, 1], position[i, 2]
            x0, y0, z0, x1, y1, z1 = min(xlo, px), min(ylo, py), min(zlo, pz), max(xhi, px), max(yhi, py), max(zhi, pz)
            if w > 0 and max(x1 - x0, max(y1 - y0, z1 - z0)) > spread:
                carried = w  # the next packet's first
                break
            xlo, ylo, zlo, xhi, yhi, zhi = x0, y0, z0, x1, y1, z1
            last += 1
        for j in range(n_lights):
            if kind[j] == 0:
                continue
            n = np.int64(0)  # not a literal 0: numba would compile occluded for that type too
            for i in range(first, last):
                if not hit[i]:
                    continue
                px, py, pz = position[i, 0], position[i, 1], position[i, 2]
                if kind[j] == 1:
                    lx, ly, lz = light_position[j, 0] - px, light_position[j, 1] - py, light_position[j, 2] - pz
                    dist = np.sqrt(lx * lx + ly * ly + lz * lz)
                    d = max(dist, 1e-300)
                    lx, ly, lz = lx / d, ly / d, lz / d
                else:
                    lx, ly, lz = light_direction[j, 0], light_direction[j, 1], light_direction[j, 2]
                    dist = np.inf
                if not normal[i, 0] * lx + normal[i, 1] * ly + normal[i, 2] * lz > 0.0:
                    continue  # facing away: radiance adds nothing, no shadow ray
                shadow_rays[i] += 1
                length = np.sqrt(lx * lx + ly * ly + lz * lz)  # the tracer's own normalisation (Rays)
                w = i - first
                item[n] = w
                origin[n, 0], origin[n, 1], origin[n, 2] = px, py, pz
                towards[n, 0], towards[n, 1], towards[n, 2] = lx / length, ly / length, lz / length
                reach[n] = dist
                n += 1
            if n == 0:
                continue
            blocker = occluded(
                P,
                T,
                B,
                n,
                origin,
                towards,
                reach,
                tol,
                max_iterations,
                retry_depth,
                cull_tol,
                budget,
                ex_m,
                ex_box,
                start_normal,
                item,
                hints[j],
                stack,
                s,
                frames,
                bounds,
                leaf_of,
                iterations,
            )
            hints[j] = blocker
            for r in range(n):
                if leaf_of[r] >= 0:
                    visibility[item[r], j] = 0.0
                elif leaf_of[r] == -2:
                    exhausted[first + item[r]] += 1
        for i in range(first, last):
            if not hit[i]:
                continue
            colour[i, 0], colour[i, 1], colour[i, 2] = radiance(
                position[i, 0],
                position[i, 1],
                position[i, 2],
                normal[i, 0],
                normal[i, 1],
                normal[i, 2],
                direction[i, 0],
                direction[i, 1],
                direction[i, 2],
                material_of[surface[i]],
                albedo,
                specular,
                shininess,
                kind,
                light_position,
                light_direction,
                strength,
                visibility[i - first],
            )
        first = last
