"""Per-pixel loops of the map tracer (compiled): the preliminary map's merge
and decode, camera rays, the seeded roots as hits, the suspect pixels.

Each kernel does exactly the floating-point operations, in the same order,
of the NumPy expressions it replaces (kept as references in the tests), so
its results are bit-identical; it only skips their temporaries and copies.
Kernels take (start, stop) over flat pixel indices, for ``run_chunks``.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit
from bsrt.kernels.search import first_at_least


@njit(cache=True, nogil=True, error_model="numpy")
def decode_tile(
    start, stop, tri, tri_dist, line, line_dist, float_map, domain, row0, col0, surface, u, v, distance, picture
):
    """Merge the two passes of one tile and decode them into the map's arrays.

    tri, line: (h, w, 4) float32 (float map: r = index + 1, g, b in [0, 1])
    or uint8 (8-bit map, eq. 6) as OpenGL reads them, row 0 at the bottom;
    tri_dist, line_dist: (h, w) float32 eye distances. A line pixel wins where
    it has a surface and the triangles have none, or show another surface
    farther away. Pixel k = i * w + j (GL row i) lands at film row
    row0 + h - 1 - i, column col0 + j of surface (H, W) int64 (-1: empty),
    u, v (H, W) float64 (NaN: empty), distance (H, W) float64 (inf: empty)
    and picture (H, W, 3) uint8. domain: (S, 4) float64 surface domains.
    """
    h, w = tri.shape[0], tri.shape[1]
    i, j = start // w, start % w
    for _ in range(start, stop):
        t0, l0 = tri[i, j, 0], line[i, j, 0]
        d = tri_dist[i, j]
        r, c = row0 + h - 1 - i, col0 + j
        # scalars only in this loop: array variables and views would cost reference counting
        if l0 != 0 and (t0 == 0 or (l0 != t0 and line_dist[i, j] < d)):
            d = line_dist[i, j]
            ident, g, b, p0, p1, p2 = _decode(l0, line[i, j, 1], line[i, j, 2], float_map)
        else:
            ident, g, b, p0, p1, p2 = _decode(t0, tri[i, j, 1], tri[i, j, 2], float_map)
        picture[r, c, 0], picture[r, c, 1], picture[r, c, 2] = p0, p1, p2
        if ident >= 0:
            surface[r, c] = ident
            u[r, c] = domain[ident, 0] + (domain[ident, 1] - domain[ident, 0]) * g  # eq. 6
            v[r, c] = domain[ident, 2] + (domain[ident, 3] - domain[ident, 2]) * b
            distance[r, c] = np.float64(d)
        else:
            surface[r, c] = -1
            u[r, c] = np.nan
            v[r, c] = np.nan
            distance[r, c] = np.inf
        i, j = (i, j + 1) if j + 1 < w else (i + 1, 0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _decode(red, green, blue, float_map):
    """(surface index or -1, g, b in [0, 1], the picture's r, g, b uint8) of one raw pixel."""
    if float_map:
        ident = np.int64(np.rint(np.float64(red))) - 1
        g, b = np.float64(green), np.float64(blue)
        return (
            ident,
            g,
            b,
            np.uint8(min(max(ident + 1, 0), 255)),
            np.uint8(np.rint(g * 255)),
            np.uint8(np.rint(b * 255)),
        )
    ident = np.int64(red) - 1
    return ident, np.float64(green) / 255.0, np.float64(blue) / 255.0, np.uint8(red), np.uint8(green), np.uint8(blue)


@njit(cache=True, nogil=True, error_model="numpy")
def decode_merged(start, stop, record, float_map, domain, surface, u, v, distance, picture):
    """map_solve.glsl's merged map (the passes merged on the GPU) into the map's arrays, as decode_tile
    writes them: record (N, 4) float32 per pixel red, green, blue as drawn (float map: index + 1 and u,
    v in [0, 1]; 8-bit map: the bytes) and the eye distance; surface (N,) int64, u, v, distance (N,)
    float64 and picture (N, 3) uint8: the PrelimMap's arrays, flat."""
    for k in range(start, stop):
        ident, g, b, p0, p1, p2 = _decode(record[k, 0], record[k, 1], record[k, 2], float_map)
        picture[k, 0], picture[k, 1], picture[k, 2] = p0, p1, p2
        if ident >= 0:
            surface[k] = ident
            u[k] = domain[ident, 0] + (domain[ident, 1] - domain[ident, 0]) * g  # eq. 6
            v[k] = domain[ident, 2] + (domain[ident, 3] - domain[ident, 2]) * b
            distance[k] = np.float64(record[k, 3])
        else:
            surface[k] = -1
            u[k] = np.nan
            v[k] = np.nan
            distance[k] = np.inf


@njit(cache=True, nogil=True, error_model="numpy")
def gather_roots(start, stop, items, reals, ints, converged, trimmed, u, v, patch, t, residual, iterations):
    """Roots k = start .. stop - 1 of solve_core.glsl's buffers (solve_into) into RootResult's arrays:
    item items[k] of reals (N, 4) float64 (u, v, t, residual) and ints (N, 4) int32 (converged, patch,
    iterations, trimmed); converged, trimmed (M,) bool, u, v, t, residual (M,) float64, patch (M,)
    int64, iterations (M,) int32."""
    for k in range(start, stop):
        i = items[k]
        converged[k] = ints[i, 0] != 0
        trimmed[k] = ints[i, 3] != 0
        u[k], v[k], t[k], residual[k] = reals[i, 0], reals[i, 1], reals[i, 2], reals[i, 3]
        patch[k] = ints[i, 1]
        iterations[k] = ints[i, 2]


@njit(cache=True, nogil=True, error_model="numpy")
def pixel_rays_into(start, stop, forward, right, up, x, y, eye, directions, origins):
    """Unit ray directions of pixels k = i * W + j: forward + x[j] right + y[i] up,
    normalised, into directions (N, 3) float64 (x: (W,), y: (rows,) tangents).
    With origins (N, 3) (not (0, 3)): eye (3,) into each row, and each direction
    normalised a second time, as Rays.from_arrays would (normalise_rows): the
    rays of a map's pixels in one pass instead of two."""
    w = x.shape[0]
    rays = origins.shape[0] > 0
    i, j = start // w, start % w
    for k in range(start, stop):
        dx = forward[0] + x[j] * right[0] + y[i] * up[0]
        dy = forward[1] + x[j] * right[1] + y[i] * up[1]
        dz = forward[2] + x[j] * right[2] + y[i] * up[2]
        n = np.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx / n, dy / n, dz / n
        if rays:
            n = np.sqrt(dx * dx + dy * dy + dz * dz)
            dx, dy, dz = dx / n, dy / n, dz / n
            origins[k, 0], origins[k, 1], origins[k, 2] = eye[0], eye[1], eye[2]
        directions[k, 0], directions[k, 1], directions[k, 2] = dx, dy, dz
        i, j = (i, j + 1) if j + 1 < w else (i + 1, 0)


@njit(cache=True, nogil=True, error_model="numpy")
def film_rays_into(start, stop, xy, width, height, tx, ty, right, up, forward, directions):
    """Unit directions (N, 3) float64 from the eye through film positions xy (N, 2) float64 (pixels
    from the top-left corner) of a width x height film (tx, ty: the half field of view's tangents;
    right, up, forward: the camera's basis, (3,) each): screen.film_rays' NumPy steps, in order."""
    for k in range(start, stop):
        x = (2.0 * xy[k, 0] / width - 1.0) * tx
        y = (1.0 - 2.0 * xy[k, 1] / height) * ty
        dx = forward[0] + x * right[0] + y * up[0]
        dy = forward[1] + x * right[1] + y * up[1]
        dz = forward[2] + x * right[2] + y * up[2]
        n = np.sqrt(dx * dx + dy * dy + dz * dz)
        directions[k, 0], directions[k, 1], directions[k, 2] = dx / n, dy / n, dz / n


@njit(cache=True, nogil=True, error_model="numpy")
def normalise_rows(start, stop, d, out, origin, origin_out):
    """out[k] = d[k] / |d[k]| for rows k of d (N, 3) float64 (out may be d), and origin_out[k] =
    origin[k], or origin[0] for an origin (1, 3) shared by every ray (origin_out (N, 3))."""
    shared = origin.shape[0] == 1
    for k in range(start, stop):
        x, y, z = d[k, 0], d[k, 1], d[k, 2]
        n = np.sqrt(x * x + y * y + z * z)
        out[k, 0], out[k, 1], out[k, 2] = x / n, y / n, z / n
        o = 0 if shared else k
        origin_out[k, 0], origin_out[k, 1], origin_out[k, 2] = origin[o, 0], origin[o, 1], origin[o, 2]


@njit(cache=True, nogil=True, error_model="numpy")
def map_suspects(
    start,
    stop,
    surface,
    distance,
    u,
    v,
    domain,
    hit,
    t,
    failed,
    fold_scale,
    layer_scale,
    tolerance,
    seam_ratio,
    seam_floor,
    suspect,
    layer,
    seam,
):
    """The suspect pixels k = i * W + j of a solved map (hard_pixels' module doc).

    surface: (H, W) int64; distance: (H, W) float64 (inf where empty, taken
    as 0 for folds); u, v: (H, W) float64 the map's seeds; domain: (S, 4)
    float64 the surfaces' (u0, u1, v0, v1); hit, failed: (H * W,) bool; t:
    (H * W,) float64. layer[k] (bool (H * W,)): a hit farther from the map's
    distance than layer_scale * distance + tolerance. seam[k] (bool (H *
    W,)): three pixels along the row or column centred on k show one surface,
    and their seeds jump (_seam, with seam_ratio and seam_floor). suspect[k] (bool (H *
    W,)): layer, failed, one of the 8 neighbours (the edge repeated beyond
    the film) with another surface, a second difference of the distance along
    the row or column above fold_scale * the middle distance (none along an
    axis under 3 pixels), or seam.
    """
    h, w = surface.shape
    i, j = start // w, start % w
    for k in range(start, stop):
        s = surface[i, j]
        dist = distance[i, j]
        layer[k] = hit[k] and abs(t[k] - dist) > layer_scale * dist + tolerance
        seam[k] = False
        odd = layer[k] or failed[k]
        if not odd and 0 < i < h - 1 and 0 < j < w - 1:  # the 8 neighbours, without a branch each (5 -> 2.6 ms)
            odd = (
                (surface[i - 1, j - 1] != s)
                | (surface[i - 1, j] != s)
                | (surface[i - 1, j + 1] != s)
                | (surface[i, j - 1] != s)
                | (surface[i, j + 1] != s)
                | (surface[i + 1, j - 1] != s)
                | (surface[i + 1, j] != s)
                | (surface[i + 1, j + 1] != s)
            )
        elif not odd:  # on the film's edge: the clamped neighbours repeat these
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    odd |= surface[a, b] != s
        if not odd and 0 < i < h - 1:
            odd = _kink(distance[i - 1, j], dist, distance[i + 1, j], fold_scale)
        if not odd and 0 < j < w - 1:
            odd = _kink(distance[i, j - 1], dist, distance[i, j + 1], fold_scale)
        if not odd and s >= 0:  # all 8 neighbours show s
            su, sv = 1.0 / (domain[s, 1] - domain[s, 0]), 1.0 / (domain[s, 3] - domain[s, 2])
            if 0 < i < h - 1:
                seam[k] = _seam(
                    u[i - 1, j], v[i - 1, j], u[i, j], v[i, j], u[i + 1, j], v[i + 1, j], su, sv, seam_ratio, seam_floor
                )
            if not seam[k] and 0 < j < w - 1:
                seam[k] = _seam(
                    u[i, j - 1], v[i, j - 1], u[i, j], v[i, j], u[i, j + 1], v[i, j + 1], su, sv, seam_ratio, seam_floor
                )
            odd = seam[k]
        suspect[k] = odd
        i, j = (i, j + 1) if j + 1 < w else (i + 1, 0)


@njit(cache=True, nogil=True, error_model="numpy")
def _seam(ua, va, ub, vb, uc, vc, su, sv, ratio, floor):
    """Whether the seeds a, b, c of three pixels in a line jump between layers of their surface.

    Steps are measured in the max norm of (u, v) scaled by (su, sv): p = |b -
    a|, q = |c - b| and the mean step across b, |c - a| / 2. A jump: the
    longer of p and q exceeds ratio * the shortest of the three + floor.
    Across one sheet the map's (u, v) varies smoothly (linearly within a
    triangle), so the three are alike; where the depth test switches between
    two layers of the surface (a fold or a self-intersection whose layers lie
    within the tessellation's error of each other) the seeds jump: on one
    side of b (p or q is short), or on both (b alone shows the other layer,
    and |c - a| is short).
    """
    p = max(abs(ub - ua) * su, abs(vb - va) * sv)
    q = max(abs(uc - ub) * su, abs(vc - vb) * sv)
    r = 0.5 * max(abs(uc - ua) * su, abs(vc - va) * sv)
    return max(p, q) > ratio * min(min(p, q), r) + floor


@njit(cache=True, nogil=True, error_model="numpy")
def _kink(a, b, c, fold_scale):
    """|second difference| of three distances (non-finite as 0) above fold_scale * the middle one."""
    a = a if np.isfinite(a) else 0.0
    b = b if np.isfinite(b) else 0.0
    c = c if np.isfinite(c) else 0.0
    return abs((c - b) - (b - a)) > fold_scale * b


@njit(cache=True, nogil=True, error_model="numpy")
def seeded_hits(
    start,
    stop,
    covered,
    converged,
    t,
    u,
    v,
    patch,
    residual,
    iterations,
    patch_surface,
    hit_out,
    t_out,
    surface_out,
    patch_out,
    u_out,
    v_out,
    iterations_out,
    residual_out,
    failed,
):
    """The hits of pixels start..stop-1 from the roots of their map seeds.

    covered: (M,) sorted pixel index of each root item; converged, t, u, v,
    patch, residual, iterations: (M,) the items' RootResult fields;
    patch_surface: (P,) surface of each patch. Writes every pixel's Hits
    fields (*_out, (N,)): a hit where the item converged with t > 0 (as
    RootResult.as_hits), else no hit (NaN, -1, 0 iterations for an uncovered
    pixel); failed (N,) bool: covered without a hit.
    """
    m = first_at_least(covered, start)
    for p in range(start, stop):
        if m < covered.shape[0] and covered[m] == p:
            hit = converged[m] and t[m] > 0
            add = 0.0 if hit else np.nan
            hit_out[p], failed[p] = hit, not hit
            t_out[p], u_out[p], v_out[p], residual_out[p] = t[m] + add, u[m] + add, v[m] + add, residual[m] + add
            surface_out[p] = patch_surface[patch[m]] if hit else -1
            patch_out[p] = patch[m] if hit else -1
            iterations_out[p] = iterations[m]
            m += 1
        else:
            hit_out[p], failed[p] = False, False
            t_out[p] = u_out[p] = v_out[p] = residual_out[p] = np.nan
            surface_out[p] = patch_out[p] = -1
            iterations_out[p] = 0
