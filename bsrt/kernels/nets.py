"""Control nets of Bezier pieces, compiled: halving, copying, and a leaf's net in the hierarchy.

Shared by the hierarchy's build (flatten.py) and the rays' retries
(traverse.py, lighting.py), which need none of the build's kernels. They
allocate nothing and count no references (``_nrt=False``): the retries call
them for every quarter (traverse.py's module doc).
"""

from __future__ import annotations

from bsrt.kernels.jit import njit, njit_typed


# Explicit signature: called with a literal axis (traverse) and a variable one (flatten._cut), numba
# would compile one specialisation per call site.
@njit_typed(
    "void(float64[:, :, ::1], float64[:, :, ::1], float64[:, :, ::1], int64, int64, int64, float64[::1])",
    cache=True,
    no_cpython_wrapper=True,
    _nrt=False,
)
def split_half(src, lo, hi, p, q, axis, tmp):
    """de Casteljau at the midpoint of net src ([:p+1, :q+1, 4]) along axis 0 (u) or 1 (v)
    into lo, hi; tmp: scratch of at least max(p, q) + 1 floats."""
    n, other = (p, q) if axis == 0 else (q, p)
    if n == 3:  # cubic along the axis (bicubic pieces): in registers, 30% of a retry's time saved
        _split_cubic(src, lo, hi, other, axis)
        return
    for j in range(other + 1):
        for c in range(4):
            for i in range(n + 1):
                tmp[i] = src[i, j, c] if axis == 0 else src[j, i, c]
            for r in range(n + 1):
                if r > 0:
                    for i in range(n - r + 1):
                        tmp[i] = 0.5 * (tmp[i] + tmp[i + 1])
                if axis == 0:
                    lo[r, j, c] = tmp[0]
                    hi[n - r, j, c] = tmp[n - r]
                else:
                    lo[j, r, c] = tmp[0]
                    hi[j, n - r, c] = tmp[n - r]


@njit(cache=True, no_cpython_wrapper=True, _nrt=False, inline="always")
def _split_cubic(src, lo, hi, other, axis):
    """split_half of a net cubic along axis (other + 1 rows across it): its loop unrolled, the
    same operations in the same order."""
    for j in range(other + 1):
        for c in range(4):
            if axis == 0:
                a0, a1, a2, a3 = src[0, j, c], src[1, j, c], src[2, j, c], src[3, j, c]
            else:
                a0, a1, a2, a3 = src[j, 0, c], src[j, 1, c], src[j, 2, c], src[j, 3, c]
            b0, b1, b2 = 0.5 * (a0 + a1), 0.5 * (a1 + a2), 0.5 * (a2 + a3)
            c0, c1 = 0.5 * (b0 + b1), 0.5 * (b1 + b2)
            d0 = 0.5 * (c0 + c1)
            if axis == 0:
                lo[0, j, c], lo[1, j, c], lo[2, j, c], lo[3, j, c] = a0, b0, c0, d0
                hi[0, j, c], hi[1, j, c], hi[2, j, c], hi[3, j, c] = d0, c1, b2, a3
            else:
                lo[j, 0, c], lo[j, 1, c], lo[j, 2, c], lo[j, 3, c] = a0, b0, c0, d0
                hi[j, 0, c], hi[j, 1, c], hi[j, 2, c], hi[j, 3, c] = d0, c1, b2, a3


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def copy_net(src, dst, p, q):
    for i in range(p + 1):
        for j in range(q + 1):
            for c in range(4):
                dst[i, j, c] = src[i, j, c]


@njit(cache=True, inline="always")
def leaf_net(patch_net, piece_net, row, leaf):
    """The (Pm, Qm, 4) net of a leaf: its patch's own (row < 0) or its piece's."""
    r = row[leaf]
    return piece_net[r] if r >= 0 else patch_net[-1 - r]
