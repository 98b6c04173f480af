"""Can a ray meet a Bezier piece? Separating axes between the ray and its control points, compiled.

A rational Bezier piece with positive weights lies in the convex hull of its
control points, so where the control points, projected across the ray (the
plane of the ray frame's x and y, ``roots.ray_frame``), all lie more than
the tolerance to one side of the ray along some direction of that plane,
the piece cannot meet the ray: the hierarchy's walks (traverse.py,
lighting.py) cull it before Newton. The directions tried: x and y; the
piece's normal seen across the ray (a piece seen edge-on beside the ray is
a thin sliver); and the normal of each border chord, corner to corner (a
piece the ray passes just beyond a slanted border). Any direction is a
valid separating axis, so none of them can cull a piece the ray meets.
``shaders/anyhit.glsl``'s ``straddles`` is the GLSL twin.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit, njit_typed


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def straddles(net, p, q, ox, oy, oz, e, dx, dy, dz, t_min, t_far, tol):
    """Can the ray meet the piece with this net before t_far? Its control points, in the ray's frame
    (x, y across the ray, z along it), must surround the ray within tol along x and y, along the
    piece's normal as the ray sees it (the corners' diagonals' cross product projected across the
    ray), and across each border edge of the projected net (the corners' chords): a piece seen
    edge-on beside the ray is a thin sliver, a piece the ray passes just beyond a slanted border
    lies on one side of that border's line, and in both cases the x-y box may still hold the ray.
    Separating axes: the hull holds the piece, so a piece culled cannot meet the ray."""
    cx, cy, cz = _corner_normal(net, p, q)
    a = e[0] * cx + e[1] * cy + e[2] * cz  # that normal across the ray: (a, b) in (x, y)
    b = e[3] * cx + e[4] * cy + e[5] * cz
    x0, y0 = _across(net, 0, 0, ox, oy, oz, e)  # the corners across the ray, in border order
    x1, y1 = _across(net, p, 0, ox, oy, oz, e)
    x2, y2 = _across(net, p, q, ox, oy, oz, e)
    x3, y3 = _across(net, 0, q, ox, oy, oz, e)
    g0, h0, g1, h1 = y0 - y1, x1 - x0, y1 - y2, x2 - x1  # each chord's normal in (x, y)
    g2, h2, g3, h3 = y2 - y3, x3 - x2, y3 - y0, x0 - x3
    xlo = ylo = zlo = nlo = lo0 = lo1 = lo2 = lo3 = np.inf
    xhi = yhi = zhi = nhi = hi0 = hi1 = hi2 = hi3 = -np.inf
    for i in range(p + 1):
        for j in range(q + 1):
            px, py, pz = _point(net, i, j)
            px, py, pz = px - ox, py - oy, pz - oz
            x = e[0] * px + e[1] * py + e[2] * pz
            y = e[3] * px + e[4] * py + e[5] * pz
            z = dx * px + dy * py + dz * pz
            xlo, xhi = min(xlo, x), max(xhi, x)
            ylo, yhi = min(ylo, y), max(yhi, y)
            zlo, zhi = min(zlo, z), max(zhi, z)
            nlo, nhi = min(nlo, a * x + b * y), max(nhi, a * x + b * y)
            lo0, hi0 = min(lo0, g0 * x + h0 * y), max(hi0, g0 * x + h0 * y)
            lo1, hi1 = min(lo1, g1 * x + h1 * y), max(hi1, g1 * x + h1 * y)
            lo2, hi2 = min(lo2, g2 * x + h2 * y), max(hi2, g2 * x + h2 * y)
            lo3, hi3 = min(lo3, g3 * x + h3 * y), max(hi3, g3 * x + h3 * y)
    return (
        xlo <= tol
        and xhi >= -tol
        and ylo <= tol
        and yhi >= -tol
        and zhi + tol >= t_min
        and zlo - tol < t_far
        and _holds_zero(nlo, nhi, tol * np.sqrt(a * a + b * b))
        and _holds_zero(lo0, hi0, tol * np.sqrt(g0 * g0 + h0 * h0))
        and _holds_zero(lo1, hi1, tol * np.sqrt(g1 * g1 + h1 * h1))
        and _holds_zero(lo2, hi2, tol * np.sqrt(g2 * g2 + h2 * h2))
        and _holds_zero(lo3, hi3, tol * np.sqrt(g3 * g3 + h3 * h3))
    )


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _holds_zero(lo, hi, reach):
    """Does [lo, hi] come within reach of 0 (the ray, on an axis across it)?"""
    return lo <= reach and hi >= -reach


# Explicit signature: called with literal and variable indices, numba would compile one per call site.
@njit_typed(
    "UniTuple(float64, 2)(float64[:, :, ::1], int64, int64, float64, float64, float64, UniTuple(float64, 6))",
    cache=True,
    no_cpython_wrapper=True,
    _nrt=False,
)
def _across(net, i, j, ox, oy, oz, e):
    """Control point (i, j) of a net in the ray's frame, across the ray: (x, y)."""
    px, py, pz = _point(net, i, j)
    px, py, pz = px - ox, py - oy, pz - oz
    return e[0] * px + e[1] * py + e[2] * pz, e[3] * px + e[4] * py + e[5] * pz


@njit(cache=True, no_cpython_wrapper=True, _nrt=False, inline="always")
def _point(net, i, j):
    """Control point (i, j) of a homogeneous net in space: (x, y, z). A weight of exactly 1 (every
    point of a polynomial piece) divides nothing: the same numbers, without three divisions."""
    w = net[i, j, 3]
    if w == 1.0:
        return net[i, j, 0], net[i, j, 1], net[i, j, 2]
    return net[i, j, 0] / w, net[i, j, 1] / w, net[i, j, 2] / w


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _corner_normal(net, p, q):
    """The cross product of the diagonals of a net's corner points (a normal of its bilinear patch)."""
    ax, ay, az = _point(net, 0, 0)
    bx, by, bz = _point(net, p, q)
    cx, cy, cz = _point(net, 0, q)
    dx, dy, dz = _point(net, p, 0)
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - dx, cy - dy, cz - dz
    return uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
