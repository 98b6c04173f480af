"""kernels/nets.py: halving control nets, held to de Casteljau's definition and to the surface it describes."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from bsrt.kernels.nets import split_half


@njit(cache=False)
def _split(src, lo, hi, p, q, axis, tmp):  # split_half has no Python wrapper of its own
    split_half(src, lo, hi, p, q, axis, tmp)


def _de_casteljau(src: np.ndarray, p: int, q: int, axis: int):
    """The halves of a net ([:p+1, :q+1, 4]) at the midpoint along axis, by the textbook rounds,
    in plain Python floats: round r replaces point i by the mean of points i and i + 1; the lower
    half takes each round's first point, the upper half its last."""
    lo, hi = np.zeros_like(src), np.zeros_like(src)
    n, other = (p, q) if axis == 0 else (q, p)
    for j in range(other + 1):
        for c in range(4):
            row = [float(src[i, j, c] if axis == 0 else src[j, i, c]) for i in range(n + 1)]
            for r in range(n + 1):
                if r:
                    row = [0.5 * (row[i] + row[i + 1]) for i in range(n - r + 1)]
                for out, k, value in ((lo, r, row[0]), (hi, n - r, row[-1])):
                    if axis == 0:
                        out[k, j, c] = value
                    else:
                        out[j, k, c] = value
    return lo, hi


def _bernstein(net: np.ndarray, p: int, q: int, s: float, t: float) -> np.ndarray:
    """The rational surface point of a homogeneous net at (s, t) in [0, 1]^2: (3,)."""
    from math import comb

    bu = np.array([comb(p, i) * s**i * (1 - s) ** (p - i) for i in range(p + 1)])
    bv = np.array([comb(q, j) * t**j * (1 - t) ** (q - j) for j in range(q + 1)])
    h = np.einsum("i,j,ijc->c", bu, bv, net[: p + 1, : q + 1])
    return h[:3] / h[3]


@pytest.mark.parametrize("p, q", [(3, 3), (3, 2), (2, 3), (1, 3), (3, 1), (2, 2), (4, 3)])
@pytest.mark.parametrize("axis", [0, 1])
def test_split_half_is_de_casteljau_to_the_bit_and_halves_the_surface(p, q, axis):
    """The bicubic nets take an unrolled path of their own (nets._split_cubic): it must give the
    very numbers of the rounds, as every other degree does; and the halves must describe the two
    halves of the same rational surface."""
    rng = np.random.default_rng(100 * p + 10 * q + axis)
    size = 5  # a scratch net larger than the piece, as the walks' are
    src = np.zeros((size, size, 4))
    src[: p + 1, : q + 1, :3] = rng.normal(size=(p + 1, q + 1, 3))
    src[: p + 1, : q + 1, 3] = rng.uniform(0.5, 2.0, size=(p + 1, q + 1))
    src[: p + 1, : q + 1, :3] *= src[: p + 1, : q + 1, 3:]  # homogeneous: (x w, y w, z w, w)
    lo, hi = np.full_like(src, np.nan), np.full_like(src, np.nan)
    _split(src, lo, hi, p, q, axis, np.empty(size))
    want_lo, want_hi = _de_casteljau(src, p, q, axis)
    assert np.array_equal(lo[: p + 1, : q + 1], want_lo[: p + 1, : q + 1])
    assert np.array_equal(hi[: p + 1, : q + 1], want_hi[: p + 1, : q + 1])
    for s, t in [(0.0, 0.0), (0.3, 0.8), (1.0, 0.5), (0.77, 0.0)]:
        low, high = ((0.5 * s, t), (0.5 + 0.5 * s, t)) if axis == 0 else ((s, 0.5 * t), (s, 0.5 + 0.5 * t))
        assert np.allclose(_bernstein(lo, p, q, s, t), _bernstein(src, p, q, *low), rtol=0, atol=1e-12)
        assert np.allclose(_bernstein(hi, p, q, s, t), _bernstein(src, p, q, *high), rtol=0, atol=1e-12)
