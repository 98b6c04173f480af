"""The hierarchy's leaf criterion (kernels/cones.py, kernels/flatten.py) on hand-computable cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from bsrt.geometry.bspline import evaluate, make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.kernels import cones
from bsrt.kernels.flatten import CONE_DEGREES, _median_split, count_leaves
from bsrt.rendering import bvh as B
from bsrt.rendering.bvh import build_bvh, intersect


@njit(cache=False)
def _within(net, p, q, cos_gamma):
    h, hu, hv, uv, nrm, binom = cones.scratch(net.shape[0], net.shape[1])
    return cones.normal_cone_within(net, p, q, cos_gamma, h, hu, hv, uv, nrm, binom)


def arc_by_line(theta, radius=2.0, length=3.0):
    """Homogeneous (3, 2, 4) net: the rational quadratic arc of angle theta (u, centred on the
    x axis) times a segment along z (v): a piece of a cylinder, whose normals span exactly theta."""
    a = 0.5 * theta
    xy = radius * np.array([[math.cos(a), -math.sin(a)], [1.0 / math.cos(a), 0.0], [math.cos(a), math.sin(a)]])
    w = np.array([1.0, math.cos(a), 1.0])
    net = np.zeros((3, 2, 4))
    for i in range(3):
        for j in range(2):
            net[i, j] = w[i] * np.array([xy[i, 0], xy[i, 1], length * j, 1.0])
    return net


@pytest.mark.parametrize("degrees, within", [(10.0, True), (15.5, True), (16.5, False), (30.0, False)])
def test_cylinder_piece_cone_is_its_angle(degrees, within):
    """Normals of an arc of theta span theta: within 8 degrees of one axis iff theta <= 16 degrees
    (the bound is exact here; every coefficient of U x V lies in the arc's plane of normals)."""
    assert CONE_DEGREES == 8.0
    assert _within(arc_by_line(math.radians(degrees)), 2, 1, math.cos(math.radians(CONE_DEGREES))) == within


def _point(net, p, q, u, v):
    """(N, 3) points of the homogeneous Bezier net (p + 1, q + 1, 4) at (u, v) (N,)."""
    cu = np.stack([math.comb(p, i) * u**i * (1 - u) ** (p - i) for i in range(p + 1)], 1)
    cv = np.stack([math.comb(q, j) * v**j * (1 - v) ** (q - j) for j in range(q + 1)], 1)
    h = np.einsum("ni,nj,ijc->nc", cu, cv, net)
    return h[:, :3] / h[:, 3:]


def test_cone_holds_sampled_normals_of_random_rational_patches():
    """Soundness: where the bound says 'within gamma of one axis', the normals at 400 points
    (central differences of S = H / w) are pairwise within 2 gamma."""
    rng = np.random.default_rng(3)
    gamma = math.radians(20.0)
    accepted = 0
    for trial in range(200):
        p, q = (2, 2) if trial % 2 else (3, 1)
        base = np.stack(np.meshgrid(np.linspace(0, 1, p + 1), np.linspace(0, 1, q + 1), indexing="ij"), -1)
        pts = np.concatenate([base, np.zeros((p + 1, q + 1, 1))], -1) + rng.normal(0, 0.06, (p + 1, q + 1, 3))
        w = rng.uniform(0.4, 2.5, (p + 1, q + 1))
        net = np.concatenate([pts * w[..., None], w[..., None]], -1)
        if not _within(net, p, q, math.cos(gamma)):
            continue
        accepted += 1
        s = np.linspace(0.02, 0.98, 20)
        U, V = [x.ravel() for x in np.meshgrid(s, s, indexing="ij")]
        e = 1e-6
        n = np.cross(
            _point(net, p, q, U + e, V) - _point(net, p, q, U - e, V),
            _point(net, p, q, U, V + e) - _point(net, p, q, U, V - e),
        )
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        assert (n @ n.T).min() >= math.cos(2 * gamma) - 1e-6
    assert 50 < accepted < 200  # both answers occur


def test_counts_at_every_depth_match_separate_counts():
    """count_leaves' one walk per patch gives, for each depth bound d, what a walk cut at most d
    times counts (here: the leaves the flattening makes with max_depth = d)."""
    s = math.sqrt(0.5)
    sphere_octant = make_surface(
        (2, 2),
        [0, 0, 0, 1, 1, 1],
        [0, 0, 0, 1, 1, 1],
        np.array([[[1, 0, 0], [1, 1, 0], [0, 1, 0]], [[1, 0, 1], [1, 1, 1], [0, 1, 1]], [[0, 0, 1]] * 3], float),
        np.outer([1, s, 1], [1, s, 1]),
    )
    patches = PatchSet([sphere_octant])
    nets, degree = B.padded_nets(patches)
    eps = B.DEFAULT_FLATNESS * patches.scene_diagonal()
    by_depth = np.zeros((patches.size, 13), dtype=np.int64)
    count_leaves(0, patches.size, nets, degree, patches.bounds, eps, B.BEND, 0.0, 12, by_depth)
    for d in range(13):
        assert B.flatten(patches, max_depth=d)[0].size == by_depth[:, d].sum()
    assert by_depth[0, 0] == 1 and by_depth[0, 12] > 4


def _exact_sphere(radius):
    """The sphere of the given radius about the origin: a half circle (meridian) swept by the full
    circle, rational quadratic, with a pole at each end of v."""
    s = math.sqrt(0.5)
    ring = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], float)
    mer = np.array([[0, -1], [1, -1], [1, 0], [1, 1], [0, 1]], float)
    pts = np.zeros((9, 5, 3))
    for i in range(9):
        for j in range(5):
            pts[i, j] = radius * np.array([ring[i, 0] * mer[j, 0], ring[i, 1] * mer[j, 0], mer[j, 1]])
    knots_u = [0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 4]
    return make_surface(
        (2, 2), knots_u, [0, 0, 0, 1, 1, 2, 2, 2], pts, np.outer([1, s, 1, s, 1, s, 1, s, 1], [1, s, 1, s, 1])
    )


def test_rational_sphere_hits_through_the_hierarchy_match_the_closed_form():
    """Rays from outside toward random points of the box, grazing ones included, through the
    hierarchy alone: every hit's S(u, v) is on the sphere to rounding and o + t d within the
    solver's tolerance (1e-9 of the size), at the nearer root of
    |o + t d| = R (t within the tolerance / |cos|, and 1e-8 of the size), and every ray whose
    line passes inside the sphere hits."""
    radius = 3.0
    patches = PatchSet([_exact_sphere(radius)])
    bvh = build_bvh(patches)
    assert bvh.leaf_depth.max() < B.DEFAULT_MAX_DEPTH  # the pieces at the poles do not run to the depth bound
    rng = np.random.default_rng(11)
    n = 4000
    away = rng.normal(size=(n, 3))
    origins = 4.0 * radius * away / np.linalg.norm(away, axis=1, keepdims=True)
    targets = rng.uniform(-1.05 * radius, 1.05 * radius, (n, 3))
    d = targets - origins
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = intersect(bvh, origins, d)
    b = np.einsum("ij,ij->i", origins, d)
    disc = b * b - (np.einsum("ij,ij->i", origins, origins) - radius**2)
    inside = disc > (1e-6 * radius) ** 2
    assert hits.hit[inside].all()
    assert not hits.hit[disc < -((1e-6 * radius) ** 2)].any()
    h = hits.hit
    size = 2.0 * radius * math.sqrt(3.0)
    on_surface = patches.evaluate(hits.patch[h], hits.u[h], hits.v[h], derivatives=False).T
    assert np.abs(np.linalg.norm(on_surface, axis=1) - radius).max() <= 1e-12 * size
    position = origins[h] + hits.t[h, None] * d[h]  # within the solver's tolerance of the surface
    assert np.abs(np.linalg.norm(position, axis=1) - radius).max() <= 1e-9 * size
    t_near = -b[h] - np.sqrt(np.maximum(disc[h], 0.0))
    cosine = np.abs(np.einsum("ij,ij->i", position / radius, d[h]))
    err = np.abs(hits.t[h] - t_near)
    tolerance = 1e-9 * patches.scene_diagonal()  # intersect's default: ray-surface distance
    assert np.all(err * cosine <= 1.01 * tolerance)  # t is off by at most the distance / |cos|
    assert err.max() <= 1e-8 * size  # grazing roots polished (the older code: 2.6e-8 here)
    assert (cosine < 0.3).sum() > 50  # grazing rays were tried


@pytest.mark.parametrize("degrees", [2.0, 4.0, 6.0])
def test_a_ray_leaving_a_concave_leaf_meets_the_same_leaf_again(degrees):
    """A shadow ray from inside a cylinder (radius 2, one rational quadratic arc of 60 degrees, so
    its leaves are the 8-degree-cone pieces, with a far plane in the scene) toward another point of the same arc, `degrees` away,
    leaves its start (excluded, as the pipeline's secondary rays do) and meets the surface again at
    the chord, t = 2 r sin(degrees / 2): a cupped surface shadows itself. The start and the target
    share a leaf (normals within 16 degrees), where a flat leaf could only be re-crossed at grazing."""
    r, span = 2.0, math.radians(60.0)
    a = 0.5 * span
    pts = np.zeros((3, 2, 3))
    w = np.array([1.0, math.cos(a), 1.0])
    xy = r * np.array([[math.cos(-a), math.sin(-a)], [1.0 / math.cos(a), 0.0], [math.cos(a), math.sin(a)]])
    for i in range(3):
        for j in range(2):
            pts[i, j] = [xy[i, 0], xy[i, 1], 3.0 * j]
    surface = make_surface((2, 1), [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], pts, np.repeat(w[:, None], 2, axis=1))
    # a far plane makes the scene 100 times larger: the absolute flatness (5e-4 of the diagonal) then
    # leaves the arc's leaves to the relative bound, as a small cupped part of a large model has them
    far = [[[100.0, 100.0, 0.0], [100.0, 101.0, 0.0]], [[101.0, 100.0, 0.0], [101.0, 101.0, 0.0]]]
    patches = PatchSet([surface, make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], far)])
    tree = build_bvh(patches)
    start = -0.4 * span  # angles on the arc (0 = its middle): start and target in one leaf of 15 degrees
    end = start + math.radians(degrees)
    origin = np.array([[r * math.cos(start), r * math.sin(start), 1.5]])
    target = np.array([[r * math.cos(end), r * math.sin(end), 1.5]])
    # the start's parameter: the arc's u at that angle (tan-half-angle map of a rational quadratic arc)
    u0 = 0.5 * (1.0 + math.tan(0.5 * start) / math.tan(0.5 * a))
    exclude = (np.array([0]), np.array([u0]), np.array([0.5]), np.array([1e-6]), np.array([1e-6]))
    hits = intersect(tree, origin, target - origin, tolerance=1e-9 * patches.scene_diagonal(), exclude=exclude)
    assert hits.hit[0], "the ray passes through the surface it starts on"
    assert hits.t[0] == pytest.approx(2 * r * math.sin(0.5 * math.radians(degrees)), rel=1e-9)


def test_a_twisted_ruled_band_is_cut_along_its_rulings_and_every_aimed_ray_hits():
    """A ruled band between a quarter circle of radius 1 at z = 0 and a half circle of radius 2
    at z = 3 (cubic in u, 16 spans; linear in v) turns its normals along the rulings (v) however
    narrow a piece is in u. Cutting only across u (the flatness measures say u: the rulings are
    straight) made 57,348 leaves to the depth bound and 19 of these 81 rays ran out of budget;
    the cut follows the corners' normals now. Rays aimed along the normal from distance 2 hit
    at t = 2."""
    spans, deg = 16, 3
    s = np.linspace(0.0, 1.0, spans * deg + 1)
    inner = np.stack([np.cos(s * np.pi / 2), np.sin(s * np.pi / 2), 0 * s], 1)
    outer = np.stack([2 * np.cos(s * np.pi), 2 * np.sin(s * np.pi), 3 + 0 * s], 1)
    knots_u = np.concatenate([[0.0] * (deg + 1), np.repeat(np.arange(1, spans) / spans, deg), [1.0] * (deg + 1)])
    band = make_surface((deg, 1), knots_u, [0, 0, 1, 1], np.stack([inner, outer], 1))
    tree = build_bvh(PatchSet([band]))
    assert tree.arrays.leaf_rect.shape[0] < 1000  # 110 measured
    a, v = (x.ravel() for x in np.meshgrid(np.linspace(0.05, 0.95, 9), np.linspace(0.05, 0.95, 9)))
    point, du, dv = evaluate(band, a, v)
    normal = np.cross(du, dv)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    hits = intersect(tree, point + 2.0 * normal, -normal)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.t, 2.0, atol=1e-8)


@njit
def _split(order, centre, f, c, axis):  # _median_split has no Python wrapper
    _median_split(order, centre, f, c, axis)


def test_the_median_split_puts_the_smaller_half_first():
    """build_tree's median split (a selection, not a sort) of a slice order[f:f + c]: the slice is
    a permutation of what it was, its first c // 2 boxes have no larger centre than the rest, and
    the rest of order is untouched; with ties (centres drawn from 3 values), with a single value,
    and with sorted and reversed input."""
    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(2, 60))
        centre = rng.random((n, 3))
        kind = trial % 5
        if kind == 1:  # ties
            centre = rng.integers(0, 3, (n, 3)).astype(float)
        elif kind == 2:  # one value
            centre[:] = 0.5
        elif kind == 3:
            centre = np.sort(centre, axis=0)
        elif kind == 4:
            centre = np.ascontiguousarray(np.sort(centre, axis=0)[::-1])
        order = rng.permutation(n)
        f = int(rng.integers(0, n - 1))
        c = int(rng.integers(2, n - f + 1))
        axis = int(rng.integers(0, 3))
        before = order.copy()
        _split(order, centre, f, c, axis)
        assert sorted(order[f : f + c]) == sorted(before[f : f + c])
        assert np.array_equal(order[:f], before[:f]) and np.array_equal(order[f + c :], before[f + c :])
        keys = centre[order[f : f + c], axis]
        assert keys[: c // 2].max() <= keys[c // 2 :].min()


def test_the_tree_stays_shallower_than_the_walks_stack():
    """2,000 tiny boxes at x = 1.2^k: the surface-area heuristic splits one box off at a time
    (depth 131 before, past the walks' 64-entry stacks, which numba does not bound-check);
    below depth SAH_DEPTH nodes are split at the median, so the depth is at most SAH_DEPTH +
    log2(2000 / 2) + 1, and every box is in exactly one leaf."""
    from bsrt.kernels.flatten import SAH_DEPTH, build_tree
    from bsrt.kernels.traverse import STACK

    n = 2000
    box_min = np.zeros((n, 3))
    box_min[:, 0] = 1.2 ** np.arange(n)
    order, made, _, _, left, right, first, count = build_tree(box_min, box_min + 1e-3, 2)
    left, right, first, count = left[:made], right[:made], first[:made], count[:made]
    depth = np.zeros(left.size, dtype=np.int64)
    for k in range(left.size):  # breadth first: parents before children
        if left[k] >= 0:
            depth[left[k]] = depth[right[k]] = depth[k] + 1
    assert depth.max() <= SAH_DEPTH + math.ceil(math.log2(n / 2)) + 1 < STACK
    leaves = left < 0
    assert count[leaves].sum() == n and sorted(order.tolist()) == list(range(n))
    assert np.all(count[leaves] <= 2)
