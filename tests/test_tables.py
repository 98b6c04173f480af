"""Building the big tables: exact weights of polynomial patches, the compiled
power-basis conversion, in-place reordering, and leaves that share their
patch's net (bsrt/kernels/tables.py, bsrt/rendering/bvh.py)."""

from __future__ import annotations

import numpy as np
import pytest
from test_bvh import rational_bowl, wavy_surface

from bsrt.geometry.bspline import bezier_patches, evaluate, make_surface
from bsrt.geometry.patches import PatchSet, power_from_bernstein
from bsrt.kernels.tables import permute_rows
from bsrt.rendering.bvh import build_bvh


def test_a_polynomial_bspline_has_weights_exactly_one_and_polynomial_patches():
    """Knot insertion gives weights of 1 plus rounding; they are set to 1 exactly, so
    the patches are evaluated as polynomials (dim 3), and agree with de Boor."""
    rng = np.random.default_rng(2)
    surface = wavy_surface(rng, 9, 3)
    nets, _ = bezier_patches(surface)
    assert np.all(nets[..., 3] == 1.0)
    patches = PatchSet([surface])
    assert np.all(patches.arrays.dim == 3)
    u, v = rng.uniform(0, 1, 500), rng.uniform(0, 1, 500)
    got = patches.evaluate(patches.locate(np.zeros(500, np.int64), u, v), u, v, derivatives=False).T
    np.testing.assert_allclose(got, evaluate(surface, u, v)[0], rtol=0, atol=1e-13)


def test_power_coefficients_equal_the_matrix_product():
    """coef[i][c][j] = sum_ab M_u[a, i] M_v[b, j] X[a, b, c], checked against
    NumPy's einsum for polynomial and rational patches of two degrees."""
    rng = np.random.default_rng(3)
    patches = PatchSet([wavy_surface(rng, 8, 3), rational_bowl(rng), wavy_surface(rng, 5, 2)])
    a = patches.arrays
    assert set(a.dim) == {3, 4}
    for ids, nets in patches.groups:
        p, q = nets.shape[1] - 1, nets.shape[2] - 1
        for k, net in zip(ids, nets):
            x = net[..., :3] / net[..., 3:4] if a.dim[k] == 3 else net
            want = np.einsum("ai,bj,abc->icj", power_from_bernstein(p), power_from_bernstein(q), x).ravel()
            got = a.coef[a.coef_start[k] : a.coef_start[k] + want.size]
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())


@pytest.mark.parametrize("n, width", [(1, 3), (7, 1), (1000, 5)])
def test_permute_rows_in_place_equals_fancy_indexing(n, width):
    rng = np.random.default_rng(n)
    table = rng.normal(size=(n, width))
    for order in (rng.permutation(n), np.arange(n), np.roll(np.arange(n), 1)):
        want = table[order]
        got = table.copy()
        permute_rows(got, order.astype(np.int64))
        np.testing.assert_array_equal(got, want)


def test_a_whole_patch_leaf_shares_its_patchs_net_and_cut_pieces_have_their_own():
    """Leaves that are whole patches point at the patch table's net (row -1 - patch);
    a cut piece has its own net, whose corner points are the surface at its
    rectangle's corners (a Bezier net interpolates its corners)."""
    rng = np.random.default_rng(7)
    plane = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[-2, -2, -3], [-2, 2, -3]], [[2, -2, -3], [2, 2, -3]]])
    patches = PatchSet([wavy_surface(rng, 8, 3), plane])  # the flat plane stays one leaf
    bvh = build_bvh(patches)
    whole = bvh.leaf_depth == 0
    assert whole.any() and (~whole).any()
    assert np.all(bvh.leaf_net_row[whole] == -1 - bvh.leaf_patch[whole])
    assert np.all(bvh.leaf_net_row[~whole] >= 0)
    assert len(bvh.leaf_net) == (~whole).sum()  # no net stored twice
    for leaf in range(bvh.leaf_total):
        row = bvh.leaf_net_row[leaf]
        net = bvh.leaf_net[row] if row >= 0 else bvh.patch_net[-1 - row]
        p, q = bvh.leaf_degree[leaf]
        corners = net[[0, p, 0, p], [0, 0, q, q]]
        u0, u1, v0, v1 = bvh.leaf_rect[leaf]
        at = patches.evaluate(
            np.full(4, bvh.leaf_patch[leaf]), np.array([u0, u1, u0, u1]), np.array([v0, v0, v1, v1]), derivatives=False
        ).T
        np.testing.assert_allclose(corners[:, :3] / corners[:, 3:], at, rtol=0, atol=1e-12)
