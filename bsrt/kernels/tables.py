"""Building the large tables: the patch table's power-basis coefficients, and
reordering tables in place.

Both run once per scene over every patch or leaf; compiled, they need no
temporaries the size of the table (a million-patch surface has 0.4-0.5 GB
nets and coefficients, which NumPy's einsum and fancy indexing would copy).
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit


@njit(cache=True, nogil=True)
def power_coefficients(nets, ids, start, dim, to_u, to_v, coef):
    """Power-basis coefficients of the patches of one degree (p, q).

    nets: (K, p + 1, q + 1, 4) homogeneous Bezier nets of patches ids (K,);
    to_u (p + 1, p + 1), to_v (q + 1, q + 1): Bernstein -> power matrices
    (B_a(s) = sum_i to_u[a, i] s^i). Patch ids[k] gets, at coef[start[ids[k]]:],
    c[i][comp][j] = sum_a sum_b to_u[a, i] to_v[b, j] X[a, b, comp] (layout of
    kernels.patches.PatchArrays), X the Euclidean points (dim 3) or the
    homogeneous ones (dim 4).
    """
    p1, q1 = nets.shape[1], nets.shape[2]
    x = np.empty((p1, q1, 4))
    half = np.empty((p1, q1, 4))  # converted along u
    for k in range(nets.shape[0]):
        patch = ids[k]
        d = dim[patch]
        for a in range(p1):
            for b in range(q1):
                w = nets[k, a, b, 3]
                for c in range(d):
                    x[a, b, c] = nets[k, a, b, c] / w if d == 3 else nets[k, a, b, c]
        for i in range(p1):
            for b in range(q1):
                for c in range(d):
                    s = 0.0
                    for a in range(p1):
                        s += to_u[a, i] * x[a, b, c]
                    half[i, b, c] = s
        base = start[patch]
        for i in range(p1):
            for c in range(d):
                for j in range(q1):
                    s = 0.0
                    for b in range(q1):
                        s += to_v[b, j] * half[i, b, c]
                    coef[base + (i * d + c) * q1 + j] = s


@njit(cache=True, nogil=True)
def permute_rows(a, order):
    """a[i] becomes the old a[order[i]] for every row i of a (N, K) C-contiguous
    array; order (N,) int64 is a permutation of 0..N-1. (a[:] = a[order] in
    NumPy would build the reordered copy first; following the permutation's
    cycles needs one row of scratch.)"""
    n, k = a.shape
    done = np.zeros(n, dtype=np.bool_)
    row = np.empty(k, dtype=a.dtype)
    for first in range(n):
        if done[first]:
            continue
        for c in range(k):
            row[c] = a[first, c]
        i = first
        while True:
            done[i] = True
            j = order[i]
            if j == first:
                for c in range(k):
                    a[i, c] = row[c]
                break
            for c in range(k):
                a[i, c] = a[j, c]
            i = j
