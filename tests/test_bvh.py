"""Tests of bsrt.rendering.bvh: flattening, the tree, and the intersector against references."""

from __future__ import annotations

import numpy as np
import pytest

from bsrt.geometry.bspline import evaluate, make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.rendering.bvh import build_bvh, intersect

# ---------------------------------------------------------------------------
# Scenes


def clamped(inner, p):
    return [0.0] * (p + 1) + list(inner) + [1.0] * (p + 1)


def wavy_surface(rng, n, p, shift=(0.0, 0.0, 0.0)):
    """A bumpy height field over [-2, 2]^2 with non-uniform knots in u and v."""
    x = np.linspace(-2.0, 2.0, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    Z = 0.6 * np.sin(2.3 * X) * np.cos(1.7 * Y) + rng.normal(0.0, 0.15, X.shape)
    ku = clamped(np.sort(rng.uniform(0.05, 0.95, n - p - 1)), p)
    kv = clamped(np.sort(rng.uniform(0.05, 0.95, n - p - 1)) ** 2, p)
    pts = np.stack([X, Y, Z], axis=-1) + np.asarray(shift)
    return make_surface((p, p), ku, kv, pts)


def rational_bowl(rng, shift=(4.5, 0.0, 0.5)):
    """A concave bowl z ~ 1.5 (x^2 + y^2), degree 2, non-uniform knots, non-unit weights."""
    n = 6
    x = np.linspace(-1.0, 1.0, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    Z = 1.5 * (X**2 + Y**2)
    w = rng.uniform(0.5, 2.0, (n, n))
    pts = np.stack([X, Y, Z], axis=-1) + np.asarray(shift)
    return make_surface((2, 2), clamped([0.2, 0.5, 0.6], 2), clamped([0.1, 0.3, 0.7], 2), pts, w)


@pytest.fixture(scope="module")
def mixed_scene():
    rng = np.random.default_rng(7)
    surfaces = [
        wavy_surface(rng, 8, 3),
        wavy_surface(rng, 7, 2, shift=(0.0, 0.0, 2.0)),
        rational_bowl(rng),
    ]
    patches = PatchSet(surfaces)
    return surfaces, patches, build_bvh(patches)


# ---------------------------------------------------------------------------
# Exhaustive reference: dense (u, v) samples + Newton polishing, with the
# plain Cox-de Boor evaluator and a loop over rays.


def _frame(d):
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(d, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def reference_hits(surfaces, origins, directions, t_min=0.0, grid=40, iterations=30):
    """(hit, t, surface) of the nearest root of each ray, found the slow way."""
    samples = []
    for surf in surfaces:
        (u0, u1), (v0, v1) = surf.domain_u, surf.domain_v
        U, V = np.meshgrid(np.linspace(u0, u1, grid), np.linspace(v0, v1, grid), indexing="ij")
        S = evaluate(surf, U.ravel(), V.ravel())[0].reshape(grid, grid, 3)
        cell = max(np.linalg.norm(np.diff(S, axis=0), axis=-1).max(), np.linalg.norm(np.diff(S, axis=1), axis=-1).max())
        samples.append((U.ravel(), V.ravel(), S.reshape(-1, 3), cell))
    lo = np.min([s[2].min(axis=0) for s in samples], axis=0)
    hi = np.max([s[2].max(axis=0) for s in samples], axis=0)
    tol = 1e-11 * np.linalg.norm(hi - lo)
    n = len(origins)
    hit, best, which = np.zeros(n, bool), np.full(n, np.inf), np.full(n, -1)
    for r in range(n):
        o, d = origins[r], directions[r] / np.linalg.norm(directions[r])
        e1, e2 = _frame(d)
        for m, (U, V, S, cell) in enumerate(samples):
            rel = S - o
            along = rel @ d
            perp = np.linalg.norm(rel - along[:, None] * d, axis=1)
            near = np.flatnonzero((perp < 2.0 * cell) & (along > t_min - 2.0 * cell))
            if not near.size:
                continue
            surf = surfaces[m]
            u, v = U[near].copy(), V[near].copy()
            for _ in range(iterations):
                P, Pu, Pv = evaluate(surf, u, v)
                qx, qy = (P - o) @ e1, (P - o) @ e2
                a, b, c, e = Pu @ e1, Pv @ e1, Pu @ e2, Pv @ e2
                det = a * e - b * c
                det = np.where(np.abs(det) < 1e-300, 1e-300, det)
                u = np.clip(u - (e * qx - b * qy) / det, *surf.domain_u)
                v = np.clip(v - (a * qy - c * qx) / det, *surf.domain_v)
            P = evaluate(surf, u, v)[0]
            res = np.hypot((P - o) @ e1, (P - o) @ e2)
            t = (P - o) @ d
            good = (res < tol) & (t > t_min)
            if np.any(good) and t[good].min() < best[r]:
                best[r], which[r], hit[r] = t[good].min(), m, True
    return hit, best, which


def test_random_rays_match_exhaustive_search(mixed_scene):
    surfaces, patches, bvh = mixed_scene
    rng = np.random.default_rng(11)
    lo, hi = patches.scene_box()
    n = 200
    origins = rng.uniform(lo - 0.5, hi + 0.5, (n, 3))
    # A third of the rays start inside the bowl's concavity.
    origins[: n // 3] = np.array([4.5, 0.0, 1.3]) + rng.uniform(-0.4, 0.4, (n // 3, 3)) * [1.0, 1.0, 0.5]
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    # And a third aim at a random surface point, so that many rays hit.
    k = np.arange(n // 3, 2 * n // 3)
    targets = rng.uniform(lo, hi, (k.size, 3))
    directions[k] = targets - origins[k]
    directions[k] /= np.linalg.norm(directions[k], axis=1, keepdims=True)
    hits = intersect(bvh, origins, directions)
    ref_hit, ref_t, ref_surface = reference_hits(surfaces, origins, directions)
    assert ref_hit.sum() > n // 4
    np.testing.assert_array_equal(hits.hit, ref_hit)
    both = ref_hit
    np.testing.assert_array_equal(hits.surface[both], ref_surface[both])
    scale = patches.scene_diagonal()
    np.testing.assert_allclose(hits.t[both], ref_t[both], rtol=0, atol=1e-7 * scale)
    # The reported (patch, u, v) is a point of the ray at distance t.
    P = patches.evaluate(hits.patch[both], hits.u[both], hits.v[both], derivatives=False).T
    d = directions[both]
    np.testing.assert_allclose(P, origins[both] + hits.t[both, None] * d, atol=1e-7 * scale)
    assert np.all(hits.residual[both] <= 1e-9 * scale)
    assert np.all(np.isnan(hits.t[~both])) and np.all(hits.surface[~both] == -1)
    miss = ~both  # a miss as Hits holds one (written by the kernel itself)
    assert np.isnan(hits.u[miss]).all() and np.isnan(hits.v[miss]).all() and np.isnan(hits.residual[miss]).all()
    assert (hits.patch[miss] == -1).all() and hits.iterations.dtype == np.int32 and (hits.iterations >= 0).all()
    np.testing.assert_array_equal(hits.surface[both], patches.surface[hits.patch[both]])

    shadow = intersect(bvh, origins, directions, any_hit=True)
    np.testing.assert_array_equal(shadow.hit, hits.hit)
    assert np.all(shadow.t[hits.hit] >= hits.t[hits.hit] - 1e-9 * scale)


# ---------------------------------------------------------------------------
# Closed forms


def test_flat_bilinear_patch_matches_ray_plane():
    corners = np.array([[[0.0, 0.0, 1.0], [0.0, 2.0, 1.5]], [[3.0, 0.0, 1.0], [3.0, 2.0, 1.5]]])
    surf = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], corners)
    bvh = build_bvh(PatchSet([surf]))
    rng = np.random.default_rng(3)
    n = 2000
    origins = rng.uniform([-1.0, -1.0, 3.0], [4.0, 3.0, 5.0], (n, 3))
    targets = rng.uniform([-0.5, -0.5, 0.0], [3.5, 2.5, 0.0], (n, 3))
    directions = targets - origins
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    # Plane through (0, 0, 1) with the normal of the corners' plane z = 1 + y / 4.
    normal = np.array([0.0, -0.25, 1.0])
    t = ((np.array([0.0, 0.0, 1.0]) - origins) @ normal) / (directions @ normal)
    x = origins + t[:, None] * directions
    inside = (x[:, 0] >= 0) & (x[:, 0] <= 3) & (x[:, 1] >= 0) & (x[:, 1] <= 2)
    margin = np.minimum.reduce([x[:, 0], 3 - x[:, 0], x[:, 1], 2 - x[:, 1]])
    clear = np.abs(margin) > 1e-9  # skip rays exactly on the border
    hits = intersect(bvh, origins, directions)
    np.testing.assert_array_equal(hits.hit[clear], inside[clear])
    h = hits.hit
    np.testing.assert_allclose(hits.t[h], t[h], atol=1e-9)
    np.testing.assert_allclose(hits.u[h], x[h, 0] / 3.0, atol=1e-9)
    np.testing.assert_allclose(hits.v[h], x[h, 1] / 2.0, atol=1e-9)


def paraboloid_surface():
    """z = x^2 + y^2 on [-1, 1]^2 as one biquadratic Bezier patch.

    x = 2u - 1 has Bezier ordinates (-1, 0, 1); x^2 = 4u^2 - 4u + 1 has
    (1, -1, 1) (b0 = f(0), b2 = f(1), b1 = b0 + f'(0) / 2); sums of a
    function of u and one of v add their ordinates: z_ij = a_i + a_j.
    """
    xs = np.array([-1.0, 0.0, 1.0])
    a = np.array([1.0, -1.0, 1.0])
    pts = np.array([[[xs[i], xs[j], a[i] + a[j]] for j in range(3)] for i in range(3)])
    return make_surface((2, 2), [0, 0, 0, 1, 1, 1], [0, 0, 0, 1, 1, 1], pts)


def paraboloid_hits(origins, directions, t_min=0.0):
    """Nearest t > t_min of o + t d on z = x^2 + y^2, |x|, |y| <= 1 (inf if none)."""
    o, d = origins.T, directions.T
    A = d[0] ** 2 + d[1] ** 2
    B = 2 * (o[0] * d[0] + o[1] * d[1]) - d[2]
    C = o[0] ** 2 + o[1] ** 2 - o[2]
    best = np.full(len(origins), np.inf)
    disc = B * B - 4 * A * C
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    for sign in (-1.0, 1.0):
        with np.errstate(divide="ignore", invalid="ignore"):
            # Stable roots: q = -(B + sign(B) sq) / 2, roots q / A and C / q.
            q = -0.5 * (B + np.copysign(sq, B))
            t = q / A if sign < 0 else C / q
        p = origins + t[:, None] * directions
        good = ok & np.isfinite(t) & (t > t_min) & (np.abs(p[:, 0]) <= 1) & (np.abs(p[:, 1]) <= 1)
        best = np.where(good & (t < best), t, best)
    return best


def test_paraboloid_matches_quadratic():
    surf = paraboloid_surface()
    u = np.linspace(0, 1, 7)
    P = evaluate(surf, u, u[::-1])[0]
    np.testing.assert_allclose(P[:, 2], P[:, 0] ** 2 + P[:, 1] ** 2, atol=1e-14)
    bvh = build_bvh(PatchSet([surf]))
    rng = np.random.default_rng(5)
    n = 3000
    origins = rng.uniform([-1.5, -1.5, -1.0], [1.5, 1.5, 3.0], (n, 3))
    origins[: n // 2] = rng.uniform([-0.5, -0.5, 0.8], [0.5, 0.5, 1.8], (n // 2, 3))  # inside the cup
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    expect = paraboloid_hits(origins, directions)
    hits = intersect(bvh, origins, directions)
    # Skip rays within 1e-7 of the patch border or tangent (ill-conditioned either way).
    p = origins + np.where(np.isfinite(expect), expect, 0)[:, None] * directions
    border = np.isfinite(expect) & (np.maximum(np.abs(p[:, 0]), np.abs(p[:, 1])) > 1 - 1e-7)
    # A hit is within the tolerance eps of the ray, so t is within eps / cos of
    # the exact root (cos between the ray and the normal); near tangency the
    # root itself is ill-conditioned.
    normal = np.stack([-2 * p[:, 0], -2 * p[:, 1], np.ones(n)], axis=1)
    cos = np.abs(np.einsum("ij,ij->i", normal, directions)) / np.linalg.norm(normal, axis=1)
    tangent = np.isfinite(expect) & (cos < 1e-3)
    assert np.isfinite(expect).sum() > n // 4
    keep = ~border & ~tangent
    np.testing.assert_array_equal(hits.hit[keep], np.isfinite(expect)[keep])
    h = hits.hit & keep
    eps = 1e-9 * bvh.patches.scene_diagonal()
    assert np.all(np.abs(hits.t[h] - expect[h]) <= 1.01 * eps / cos[h] + 1e-12)


# ---------------------------------------------------------------------------
# t range and shadow rays


def test_t_min_t_max_and_self_hits():
    surf = paraboloid_surface()
    bvh = build_bvh(PatchSet([surf]))
    rng = np.random.default_rng(9)
    n = 500
    # Rays that start on the surface and head into the cup hit it again.
    xy = rng.uniform(-0.6, 0.6, (n, 2))
    origins = np.column_stack([xy, (xy**2).sum(axis=1)])
    # Aim at another point of the cup: the chord lies inside the convex cup.
    other = np.clip(-0.8 * xy + rng.normal(0.0, 0.2, (n, 2)), -0.95, 0.95)
    directions = np.column_stack([other, (other**2).sum(axis=1)]) - origins
    directions[:, 2] += rng.uniform(-0.05, 0.05, n)
    apart = np.linalg.norm(other - xy, axis=1) > 0.3  # no near-tangent chords
    origins, directions, n = origins[apart], directions[apart], int(apart.sum())
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    far = paraboloid_hits(origins, directions, t_min=1e-6)
    hits = intersect(bvh, origins, directions, t_min=1e-6)
    again = np.isfinite(far)
    assert again.sum() > n // 2
    np.testing.assert_array_equal(hits.hit, again)
    assert np.all(hits.t[hits.hit] > 1e-3)  # never the start point itself
    np.testing.assert_allclose(hits.t[again], far[again], atol=1e-8)
    # t_max just below / above the hit, per ray.
    t = far[again]
    below = intersect(bvh, origins[again], directions[again], t_min=1e-6, t_max=0.999 * t)
    above = intersect(bvh, origins[again], directions[again], t_min=np.full(t.size, 1e-6), t_max=1.001 * t)
    assert not below.hit.any()
    assert above.hit.all()
    # A t_min beyond the hit leaves nothing (the cup is crossed once more at most).
    beyond = intersect(bvh, origins[again], directions[again], t_min=1.001 * t)
    assert not beyond.hit.any()
    # Shadow rays agree on hit/miss.
    shadow = intersect(bvh, origins, directions, t_min=1e-6, any_hit=True)
    np.testing.assert_array_equal(shadow.hit, hits.hit)


def test_empty_and_missing_rays(mixed_scene):
    _, patches, bvh = mixed_scene
    hits = intersect(bvh, np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(hits) == 0
    lo, hi = patches.scene_box()
    hits = intersect(bvh, np.tile(hi + 10.0, (3, 1)), np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]))
    assert not hits.hit.any()


# ---------------------------------------------------------------------------
# Flattening and tree structure


def test_leaves_tile_and_cover_every_patch(mixed_scene):
    _, patches, bvh = mixed_scene
    assert bvh.leaf_total > patches.size  # the wavy surfaces needed cutting
    for k in range(patches.size):
        mine = np.flatnonzero(bvh.leaf_patch == k)
        u0, u1, v0, v1 = patches.bounds[k]
        r = bvh.leaf_rect[mine]
        area = ((r[:, 1] - r[:, 0]) * (r[:, 3] - r[:, 2])).sum()
        assert area == pytest.approx((u1 - u0) * (v1 - v0), rel=1e-12)
        assert np.all(r[:, 0] >= u0) and np.all(r[:, 1] <= u1) and np.all(r[:, 2] >= v0) and np.all(r[:, 3] <= v1)
        s = np.linspace(0.0, 1.0, 23)
        U, V = [x.ravel() for x in np.meshgrid(u0 + s * (u1 - u0), v0 + s * (v1 - v0), indexing="ij")]
        P = patches.evaluate(np.full(U.size, k), U, V, derivatives=False).T
        inside = (
            (U[:, None] >= r[None, :, 0])
            & (U[:, None] <= r[None, :, 1])
            & (V[:, None] >= r[None, :, 2])
            & (V[:, None] <= r[None, :, 3])
        )
        assert inside.any(axis=1).all()
        for i, j in zip(*np.nonzero(inside)):
            leaf = mine[j]
            assert np.all(P[i] >= bvh.leaf_min[leaf]) and np.all(P[i] <= bvh.leaf_max[leaf])
            obb = bvh.leaf_obb[leaf]
            local = obb[3:12].reshape(3, 3) @ (P[i] - obb[:3])
            assert np.all(np.abs(local) <= obb[12:] + 1e-12)
    np.testing.assert_array_equal(bvh.leaf_surface, patches.surface[bvh.leaf_patch])


def test_tree_nodes_bound_their_leaves(mixed_scene):
    _, _, bvh = mixed_scene
    assert bvh.node_first[0] == 0 and bvh.node_count[0] == bvh.leaf_total
    for k in range(bvh.node_total):
        a, b = bvh.node_first[k], bvh.node_first[k] + bvh.node_count[k]
        assert np.all(bvh.leaf_min[a:b] >= bvh.node_min[k]) and np.all(bvh.leaf_max[a:b] <= bvh.node_max[k])
        left, right = bvh.node_left[k], bvh.node_right[k]
        if left < 0:
            assert right < 0 and 1 <= bvh.node_count[k] <= 2
        else:
            assert bvh.node_first[left] == a and bvh.node_first[right] == bvh.node_first[left] + bvh.node_count[left]
            assert bvh.node_count[left] + bvh.node_count[right] == bvh.node_count[k]
    leaves = np.flatnonzero(bvh.node_left < 0)
    covered = np.zeros(bvh.leaf_total, int)
    for k in leaves:
        covered[bvh.node_first[k] : bvh.node_first[k] + bvh.node_count[k]] += 1
    assert np.all(covered == 1)


def test_finer_flatness_gives_more_leaves():
    patches = PatchSet([wavy_surface(np.random.default_rng(1), 8, 3)])
    coarse, fine = build_bvh(patches, flatness=1e-2), build_bvh(patches, flatness=1e-3)
    assert fine.leaf_total > coarse.leaf_total
    capped = build_bvh(patches, flatness=1e-9, max_depth=2)
    assert capped.leaf_total == 4 * patches.size
