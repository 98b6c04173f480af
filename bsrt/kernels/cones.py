"""A cone that holds every normal of a (rational) Bezier piece, compiled.

(Inlined into flatten._cut. ``corner_turns``, how far a piece's corner normals
turn along u and along v, picks the direction flatten._cut cuts a piece whose
normals are not within the cone.)

For a piece with homogeneous net H (x w, y w, z w, w) of degree (p, q) and
S = H_xyz / w, the surface normal is

    S_u x S_v = U x V / w^4,   U = H_u w - H w_u,   V = H_v w - H w_v

(xyz parts; w > 0), so its direction is that of the polynomial U x V, of
degree (4p - 1, 4q - 1). Products of Bernstein polynomials have Bernstein
coefficients in closed form,

    (f g)_kl = sum  C(m, i) C(m', k - i) / C(m + m', k)
                  * C(n, j) C(n', l - j) / C(n + n', l) * f_ij g_(k-i)(l-j)

(f of degree (m, n), g of degree (m', n')), and a polynomial is a
non-negative combination of its coefficients, so if every coefficient of
U x V lies within the angle gamma of an axis a (a cone narrower than a half
space is closed under non-negative combinations), every normal of the piece
does. No bound on the weights' spread is needed: uneven weights move the
coefficients, not the argument. The constant factors p, q of the
derivatives are left out (directions only), and the points are first moved
so that the piece's first corner is the origin (U x V does not change,
its rounding does).

Coefficients shorter than ROUNDING (1e-6) of the longest are left out:
along a collapsed edge (a pole, an apex) the exact coefficients are zero,
and the computed ones are rounding noise pointing anywhere (measured: 2e-10
of the longest on a 0.005-wide piece at 250 from the origin, the noise of
its de Casteljau cuts). The coefficients left out add less than ROUNDING of
the longest to U x V, so they can turn the normal out of the cone only
where all the others nearly cancel or vanish too: within about ROUNDING of
the piece's size of a point where the normal vanishes.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit, njit_typed

# Coefficients shorter than this fraction of the longest are taken for rounding (module doc).
ROUNDING = 1e-6


@njit(cache=True, no_cpython_wrapper=True)
def binomials(n):
    """(n + 1, n + 1) float64: C(a, b) for b <= a <= n, 0 elsewhere."""
    table = np.zeros((n + 1, n + 1))
    for a in range(n + 1):
        table[a, 0] = 1.0
        for b in range(1, a + 1):
            table[a, b] = table[a - 1, b - 1] + table[a - 1, b]
    return table


# Explicit signatures: called with literal and variable component indices, numba would compile
# one specialisation per kind of call site (tests/test_compile.py wants one per kernel).
@njit_typed(
    "void(float64[:, :, ::1], int64, int64, int64, float64[:, :, ::1], int64, int64, int64, float64, "
    "float64[:, :, ::1], int64, float64[:, ::1])",
    cache=True,
    no_cpython_wrapper=True,
)
def _mul_add(f, fc, fu, fv, g, gc, gu, gv, sign, out, oc, binom):
    """out[oc] += sign * f[fc] g[gc] (f of degree (fu, fv), g of degree (gu, gv)), Bernstein
    coefficients before the division by C(fu + gu, k) C(fv + gv, l) (the caller's, once)."""
    for i in range(fu + 1):
        for j in range(fv + 1):
            a = sign * f[fc, i, j] * binom[fu, i] * binom[fv, j]
            if a == 0.0:
                continue
            for k in range(gu + 1):
                b = a * binom[gu, k]
                for m in range(gv + 1):
                    out[oc, i + k, j + m] += b * binom[gv, m] * g[gc, k, m]


@njit_typed("void(float64[:, :, ::1], int64, int64, int64, float64[:, ::1])", cache=True, no_cpython_wrapper=True)
def _normalise(out, c, du, dv, binom):
    for k in range(du + 1):
        for m in range(dv + 1):
            out[c, k, m] /= binom[du, k] * binom[dv, m]


@njit(cache=True, no_cpython_wrapper=True)
def scratch(pm, qm):
    """Work arrays for normal_cone_within on nets of up to (pm, qm) points:
    (h, hu, hv (4, pm, qm), uv (6, 2 pm, 2 qm), nrm (3, 4 pm, 4 qm), binom)."""
    return (
        np.empty((4, pm, qm)),
        np.empty((4, pm, qm)),
        np.empty((4, pm, qm)),
        np.empty((6, 2 * pm, 2 * qm)),
        np.empty((3, 4 * pm, 4 * qm)),
        binomials(4 * max(pm, qm)),
    )


@njit(cache=True, no_cpython_wrapper=True)
def normal_cone_within(net, p, q, cos_gamma, h, hu, hv, uv, nrm, binom):
    """Whether every normal of the piece lies within the angle acos(cos_gamma) of one axis
    (the sum of the coefficients of U x V), by the module doc's bound.

    net: homogeneous (>= p + 1, >= q + 1, 4) net, p, q >= 1; h, hu, hv, uv, nrm,
    binom: scratch(Pm, Qm) for Pm >= p + 1, Qm >= q + 1 (overwritten)."""
    w0 = net[0, 0, 3]
    ox, oy, oz = net[0, 0, 0] / w0, net[0, 0, 1] / w0, net[0, 0, 2] / w0
    for i in range(p + 1):
        for j in range(q + 1):
            w = net[i, j, 3]
            h[0, i, j] = net[i, j, 0] - ox * w
            h[1, i, j] = net[i, j, 1] - oy * w
            h[2, i, j] = net[i, j, 2] - oz * w
            h[3, i, j] = w
    for c in range(4):  # differences: H_u / p (degree (p - 1, q)), H_v / q (degree (p, q - 1))
        for i in range(p + 1):
            for j in range(q + 1):
                if i < p:
                    hu[c, i, j] = h[c, i + 1, j] - h[c, i, j]
                if j < q:
                    hv[c, i, j] = h[c, i, j + 1] - h[c, i, j]
    uv[:, : 2 * p + 1, : 2 * q + 1] = 0.0
    for c in range(3):  # U (uv[c], degree (2p - 1, 2q)), V (uv[3 + c], degree (2p, 2q - 1))
        _mul_add(hu, c, p - 1, q, h, 3, p, q, 1.0, uv, c, binom)
        _mul_add(h, c, p, q, hu, 3, p - 1, q, -1.0, uv, c, binom)
        _normalise(uv, c, 2 * p - 1, 2 * q, binom)
        _mul_add(hv, c, p, q - 1, h, 3, p, q, 1.0, uv, 3 + c, binom)
        _mul_add(h, c, p, q, hv, 3, p, q - 1, -1.0, uv, 3 + c, binom)
        _normalise(uv, 3 + c, 2 * p, 2 * q - 1, binom)
    nrm[:, : 4 * p, : 4 * q] = 0.0
    for c in range(3):  # U x V, degree (4p - 1, 4q - 1)
        c1, c2 = (c + 1) % 3, (c + 2) % 3
        _mul_add(uv, c1, 2 * p - 1, 2 * q, uv, 3 + c2, 2 * p, 2 * q - 1, 1.0, nrm, c, binom)
        _mul_add(uv, c2, 2 * p - 1, 2 * q, uv, 3 + c1, 2 * p, 2 * q - 1, -1.0, nrm, c, binom)
        _normalise(nrm, c, 4 * p - 1, 4 * q - 1, binom)
    ax = ay = az = 0.0
    largest = 0.0
    for k in range(4 * p):
        for m in range(4 * q):
            x, y, z = nrm[0, k, m], nrm[1, k, m], nrm[2, k, m]
            ax, ay, az = ax + x, ay + y, az + z
            largest = max(largest, x * x + y * y + z * z)
    length = np.sqrt(ax * ax + ay * ay + az * az)
    if not length > 0.0:
        return False
    floor = ROUNDING * ROUNDING * largest
    for k in range(4 * p):
        for m in range(4 * q):
            x, y, z = nrm[0, k, m], nrm[1, k, m], nrm[2, k, m]
            size2 = x * x + y * y + z * z
            if size2 > floor and x * ax + y * ay + z * az < cos_gamma * length * np.sqrt(size2):
                return False
    return True


@njit_typed("void(float64[:, :, ::1], int64, int64, int64, int64, float64[::1])", cache=True, no_cpython_wrapper=True)
def _corner_normal(net, i, j, di, dj, out):
    """The unit normal of a net's corner (i, j) from its two edge vectors towards (i + di, j) and
    (i, j + dj), signed as if di = dj = 1, into out (3,); zeros where an edge vanishes."""
    w, wa, wb = net[i, j, 3], net[i + di, j, 3], net[i, j + dj, 3]
    a0 = net[i + di, j, 0] / wa - net[i, j, 0] / w
    a1 = net[i + di, j, 1] / wa - net[i, j, 1] / w
    a2 = net[i + di, j, 2] / wa - net[i, j, 2] / w
    b0 = net[i, j + dj, 0] / wb - net[i, j, 0] / w
    b1 = net[i, j + dj, 1] / wb - net[i, j, 1] / w
    b2 = net[i, j + dj, 2] / wb - net[i, j, 2] / w
    sign = float(di * dj)
    n0, n1, n2 = sign * (a1 * b2 - a2 * b1), sign * (a2 * b0 - a0 * b2), sign * (a0 * b1 - a1 * b0)
    length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if length > 0.0:
        out[0], out[1], out[2] = n0 / length, n1 / length, n2 / length
    else:
        out[0] = out[1] = out[2] = 0.0


@njit(cache=True, no_cpython_wrapper=True)
def corner_turns(net, p, q):
    """(turn_u, turn_v): how far the corner normals of a net ([:p+1, :q+1, 4]) turn along u
    (between (0, j) and (p, j), both rows) and along v, as sums of 1 - cos of their angles;
    (0, 0) where a corner's normal vanishes (a pole: the corners do not tell)."""
    n00, np0, n0q, npq = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    _corner_normal(net, 0, 0, 1, 1, n00)
    _corner_normal(net, p, 0, -1, 1, np0)
    _corner_normal(net, 0, q, 1, -1, n0q)
    _corner_normal(net, p, q, -1, -1, npq)
    for n in (n00, np0, n0q, npq):
        if n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0:
            return 0.0, 0.0
    turn_u = _turn(n00, np0) + _turn(n0q, npq)
    turn_v = _turn(n00, n0q) + _turn(np0, npq)
    return turn_u, turn_v


@njit(cache=True, no_cpython_wrapper=True)
def _turn(a, b):
    """1 - cos of the angle between unit vectors a and b (3,)."""
    return 1.0 - (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
