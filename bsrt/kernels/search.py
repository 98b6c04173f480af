"""Binary search in sorted integer arrays, for kernels that find their items' rows.

numba's own ``np.searchsorted`` compiles in about 0.3 s of the first run for
each kernel that calls it; this loop compiles in a fraction of that, once.
"""

from __future__ import annotations

from bsrt.kernels.jit import njit


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def first_at_least(a, value):
    """The first index i of the ascending (N,) array a with a[i] >= value, N if there is none
    (``np.searchsorted(a, value)``)."""
    lo, hi = 0, a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo
