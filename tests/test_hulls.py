"""kernels/hulls.py: the separating-axis test between a ray and a piece's control points, on
bilinear pieces whose answers follow from their corners by hand."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from bsrt.kernels.hulls import straddles
from bsrt.kernels.roots import ray_frame


@njit
def _straddles(net, origin, direction, t_far, tol):  # straddles has no Python wrapper
    dx, dy, dz = direction[0], direction[1], direction[2]
    e = ray_frame(dx, dy, dz)
    return straddles(net, 1, 1, origin[0], origin[1], origin[2], e, dx, dy, dz, 0.0, t_far, tol)


def _net(corners) -> np.ndarray:
    """A bilinear net (2, 2, 4), weights 1, from corners [[p00, p01], [p10, p11]]."""
    net = np.ones((2, 2, 4))
    net[..., :3] = np.asarray(corners, dtype=float)
    return net


# The square |x| + |y| <= 1 in the plane z = 0 (a diamond: its box across a ray down the z axis is
# [-1, 1]^2, which holds points the diamond does not), corners in border order round the net.
DIAMOND = _net([[[1, 0, 0], [0, 1, 0]], [[0, -1, 0], [-1, 0, 0]]])
DOWN = np.array([0.0, 0.0, -1.0])


@pytest.mark.parametrize(
    "x, y, tol, meets",
    [
        (0.4, 0.4, 1e-9, True),  # inside the diamond
        (0.9, 0.9, 1e-9, False),  # inside its box, 0.57 beyond its border x + y = 1
        (-0.9, 0.9, 1e-9, False),  # beyond another border
        (0.5 + 1e-7, 0.5 + 1e-7, 1e-6, True),  # 1.4e-7 beyond the border: within the tolerance
        (0.5 + 1e-7, 0.5 + 1e-7, 1e-9, False),  # beyond the tolerance
        (0.0, 1.0 + 1e-10, 1e-9, True),  # beyond the corner by less than the tolerance
    ],
)
def test_a_ray_beside_a_slanted_border_is_culled_within_the_tolerance(x, y, tol, meets):
    assert _straddles(DIAMOND, np.array([x, y, 5.0]), DOWN, np.inf, tol) is meets


def test_a_piece_beyond_the_rays_end_is_culled():
    origin = np.array([0.2, 0.1, 5.0])  # the diamond lies 5 down the ray
    assert _straddles(DIAMOND, origin, DOWN, 6.0, 1e-9)
    assert not _straddles(DIAMOND, origin, DOWN, 4.0, 1e-9)


def test_a_piece_seen_edge_on_beside_the_ray_is_culled():
    """The square x = y, |x| <= 1, |z| <= 1 is a diagonal segment across a ray along z: its box
    across the ray, [-1, 1]^2, holds a ray 0.42 beside it; its normal (1, -1, 0) does not."""
    sliver = _net([[[-1, -1, -1], [-1, -1, 1]], [[1, 1, -1], [1, 1, 1]]])
    up = np.array([0.0, 0.0, 1.0])
    assert _straddles(sliver, np.array([0.3, 0.3, -5.0]), up, np.inf, 1e-9)  # through it
    assert not _straddles(sliver, np.array([0.3, -0.3, -5.0]), up, np.inf, 1e-9)  # beside it
    assert _straddles(sliver, np.array([0.3, 0.3 - 1e-10, -5.0]), up, np.inf, 1e-9)  # within tol of it
