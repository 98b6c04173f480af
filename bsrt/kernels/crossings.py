"""An exact bound on how often a ray can cross a (rational) Bezier piece, compiled.

In the ray's frame (``roots.ray_frame``: unit e1, e2 across the ray), the
piece with homogeneous net H = (x w, y w, z w, w) meets the ray's line where

    G(u, v) = (e1 . (H_xyz - o H_w), e2 . (H_xyz - o H_w)) = 0

(w > 0, so G vanishes exactly where the point S = H_xyz / H_w lies on the
line). G is a polynomial of the piece's degree whose Bernstein coefficients
are the net's points taken the same way, so its partial derivatives G_u, G_v
are non-negative combinations of the differences of neighbouring
coefficients along u and along v. If det(a, b) has one strict sign for every
such difference a along u and b along v, every G_u lies in one cone A and
every G_v in a cone B with each of B turned by less than half a turn from
each of A the same way round; then for two parameter points of the (convex)
rectangle, G's difference is the integral of alpha G_u + beta G_v with fixed
signs of alpha, beta, which lies in a cone narrower than a half plane (A with
B or with -B), and cannot vanish: G is one-to-one, and the ray's line meets
the piece at most once.

Shadow and mirror rays start on a surface: a piece that holds the start's
parameters and passes this test meets the ray only at its start (the root
every secondary ray excludes), so it cannot block or reflect it, whatever the
angle it leaves at.

Both tests allocate nothing and count no references (``_nrt=False``): the
retries call them for every quarter.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit

ROUNDING = float(np.finfo(np.float64).eps)


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def crosses_once(net, p, q, ox, oy, oz, e, g):
    """Does the ray from (ox, oy, oz) with frame e (6,) (ray_frame's) meet the piece with
    homogeneous net ([:p+1, :q+1, 4]) at most once along its whole line? (module doc).
    g: (>= p + 1, >= q + 1, >= 2) float64 scratch for the projected coefficients (a spare net)."""
    reach = 0.0  # a bound on the coefficients' terms, for their rounding
    for i in range(p + 1):
        for j in range(q + 1):
            w = net[i, j, 3]
            x, y, z = net[i, j, 0] - ox * w, net[i, j, 1] - oy * w, net[i, j, 2] - oz * w
            g[i, j, 0] = e[0] * x + e[1] * y + e[2] * z
            g[i, j, 1] = e[3] * x + e[4] * y + e[5] * z
            reach = max(reach, abs(net[i, j, 0]) + abs(net[i, j, 1]) + abs(net[i, j, 2]))
            reach = max(reach, (abs(ox) + abs(oy) + abs(oz)) * abs(w))
    # a difference of two coefficients is off by at most slack (a few roundings of 2 reach each):
    # a determinant counts only with its sign beyond what that error can change
    slack = 64.0 * ROUNDING * reach
    sign = 0.0
    for i in range(p):
        for j in range(q + 1):
            ax, ay = g[i + 1, j, 0] - g[i, j, 0], g[i + 1, j, 1] - g[i, j, 1]
            for k in range(p + 1):
                for m in range(q):
                    bx, by = g[k, m + 1, 0] - g[k, m, 0], g[k, m + 1, 1] - g[k, m, 1]
                    d = ax * by - ay * bx
                    margin = slack * (abs(ax) + abs(ay) + abs(bx) + abs(by) + 2.0 * slack)
                    if sign == 0.0:
                        sign = 1.0 if d > 0.0 else -1.0
                    if not d * sign > margin:
                        return False
    return sign != 0.0


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def holds_once(net, p, q, rect, u, v, ox, oy, oz, e, g):
    """Does the piece with parameter rectangle rect (4,) (u0, u1, v0, v1) hold (u, v), and does the
    ray's line cross it at most once (crosses_once)? Then a root at (u, v) is the piece's only one."""
    return rect[0] <= u <= rect[1] and rect[2] <= v <= rect[3] and crosses_once(net, p, q, ox, oy, oz, e, g)
