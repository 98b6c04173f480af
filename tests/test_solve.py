"""Root finders against closed forms and against points we shot at."""

from __future__ import annotations

import numpy as np
import pytest

from bsrt.geometry.bspline import evaluate, make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.kernels.roots import ray_frame
from bsrt.methods import MAP_METHODS as METHODS
from bsrt.rendering.solve import Rays, find_roots

np.seterr(all="raise", under="ignore")


def test_orthonormal_frames():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(1000, 3))
    d[:3] = [[0, 0, 1], [0, 0, -1], [1e-300, 0, -1]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    frames = np.array([ray_frame(*x) for x in d])  # (N, 6): e1, e2
    e1, e2 = frames[:, :3], frames[:, 3:]
    for a, b in ((e1, e2), (e1, d), (e2, d)):
        np.testing.assert_allclose(np.einsum("ij,ij->i", a, b), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(e1, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(e2, axis=1), 1.0, atol=1e-12)


def _wavy_surface():
    """Bicubic, non-uniform knots with a repeated interior knot."""
    ku = [0, 0, 0, 0, 0.15, 0.5, 0.5, 0.8, 1, 1, 1, 1]
    kv = [0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1]
    gx, gy = np.meshgrid(np.linspace(-1, 1, 8), np.linspace(-1, 1, 6), indexing="ij")
    z = 0.25 * np.sin(2.5 * gx) * np.cos(2 * gy)
    return make_surface((3, 3), ku, kv, np.stack([gx, gy, z], axis=-1))


@pytest.mark.parametrize("method", METHODS)
def test_rays_shot_at_points_recover_t_and_uv(method):
    rng = np.random.default_rng(1)
    surf = _wavy_surface()
    ps = PatchSet([surf])
    n = 3000
    u, v = rng.uniform(0.02, 0.98, n), rng.uniform(0.02, 0.98, n)
    target, Su, Sv = evaluate(surf, u, v)
    origin = target + rng.normal(size=(n, 3)) * [0.5, 0.5, 0.5] + [0, 0, 3.0]
    d = target - origin
    t_true = np.linalg.norm(d, axis=1)
    rays = Rays.from_arrays(origin, d)
    seed_u = np.clip(u + rng.normal(0, 2e-3, n), 0, 1)
    seed_v = np.clip(v + rng.normal(0, 2e-3, n), 0, 1)
    tol = 1e-9 * ps.scene_diagonal()
    res = find_roots(
        ps,
        rays,
        np.arange(n),
        np.zeros(n, dtype=np.int64),
        seed_u,
        seed_v,
        method=method,
        tolerance=tol,
        max_iterations=200,
    )
    assert res.converged.mean() > (0.999 if method == "newton" else 0.97)
    ok = res.converged
    assert np.all(res.residual[ok] <= tol)
    # the hit point is within the tolerance of the ray; t and (u, v) follow
    np.testing.assert_allclose(res.t[ok], t_true[ok], atol=20 * tol)
    speed = np.minimum(np.linalg.norm(Su, axis=1), np.linalg.norm(Sv, axis=1))[ok]
    assert np.all(np.abs(res.u[ok] - u[ok]) * speed < 1e-6)
    assert np.all(np.abs(res.v[ok] - v[ok]) * speed < 1e-6)


def _camera_rays(eye, n_side, half=0.9, target=(0.0, 0.0, 0.0)):
    """Rays from eye through a grid of points on the plane z = 0 around target."""
    g = np.linspace(-half, half, n_side)
    x, y = np.meshgrid(g, g, indexing="ij")
    pts = np.stack([x.ravel() + target[0], y.ravel() + target[1], np.full(x.size, target[2])], axis=1)
    origin = np.broadcast_to(np.asarray(eye, float), pts.shape)
    return origin, pts - origin


@pytest.mark.parametrize("method", METHODS)
def test_hyperbolic_bilinear_patch_closed_form(method):
    # S(u, v) = (u, v, u v): a ray o + t d meets it where
    # dx dy t^2 + (ox dy + oy dx - dz) t + ox oy - oz = 0.
    surf = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 1]]])
    ps = PatchSet([surf])
    origin, d = _camera_rays((0.3, 0.2, 3.0), 25, half=0.45, target=(0.5, 0.5, 0.0))
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    o = origin
    a = d[:, 0] * d[:, 1]
    b = o[:, 0] * d[:, 1] + o[:, 1] * d[:, 0] - d[:, 2]
    c = o[:, 0] * o[:, 1] - o[:, 2]
    # stable quadratic formula; c / q is the root that survives a = 0
    q = -0.5 * (b + np.copysign(np.sqrt(b * b - 4 * a * c), b))
    with np.errstate(divide="ignore"):
        roots = np.stack([np.where(a != 0, q / np.where(a != 0, a, 1.0), np.inf), c / q], axis=1)
    roots[roots <= 0] = np.inf
    t_true = roots.min(axis=1)
    hit_point = o + t_true[:, None] * d
    n = len(o)
    rays = Rays.from_arrays(o, d)
    res = find_roots(
        ps,
        rays,
        np.arange(n),
        np.zeros(n, dtype=np.int64),
        np.full(n, 0.5),
        np.full(n, 0.5),
        method=method,
        tolerance=1e-12,
        max_iterations=500,
    )
    assert res.converged.all()
    np.testing.assert_allclose(res.t, t_true, atol=1e-10)
    np.testing.assert_allclose(res.u, hit_point[:, 0], atol=1e-10)
    np.testing.assert_allclose(res.v, hit_point[:, 1], atol=1e-10)


def paraboloid():
    """z = x^2 + y^2 on [-1, 1]^2, exactly, as a biquadratic Bezier patch.

    x = 2u - 1 has Bernstein coefficients (-1, 0, 1); (2u - 1)^2 has (1, -1, 1),
    so P[i][j] = (x_i, y_j, a_i + a_j) with a = (1, -1, 1).
    """
    xs, a = [-1.0, 0.0, 1.0], [1.0, -1.0, 1.0]
    pts = [[[xs[i], xs[j], a[i] + a[j]] for j in range(3)] for i in range(3)]
    return make_surface((2, 2), [0, 0, 0, 1, 1, 1], [0, 0, 0, 1, 1, 1], pts)


@pytest.mark.parametrize("method", METHODS)
def test_paraboloid_closed_form(method):
    surf = paraboloid()
    ps = PatchSet([surf])
    origin, d = _camera_rays((0.4, -0.3, 4.0), 21, half=1.3, target=(0.0, 0.0, 0.5))
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    o = origin
    # (oz + t dz) = (ox + t dx)^2 + (oy + t dy)^2
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]) - d[:, 2]
    c = o[:, 0] ** 2 + o[:, 1] ** 2 - o[:, 2]
    assert np.all(c < 0)  # the eye is inside the bowl: one root in front, one behind
    t_true = (-b + np.sqrt(b * b - 4 * a * c)) / (2 * a)
    p = o + t_true[:, None] * d
    n = len(o)
    rays = Rays.from_arrays(o, d)
    # seeds: the true (u, v) moved by up to 0.02, like a coarse map
    rng = np.random.default_rng(3)
    u0 = np.clip((p[:, 0] + 1) / 2 + rng.uniform(-0.02, 0.02, n), 0, 1)
    v0 = np.clip((p[:, 1] + 1) / 2 + rng.uniform(-0.02, 0.02, n), 0, 1)
    res = find_roots(
        ps, rays, np.arange(n), np.zeros(n, dtype=np.int64), u0, v0, method=method, tolerance=1e-11, max_iterations=500
    )
    inside = np.all(np.abs(p[:, :2]) <= 1.0, axis=1)  # else the ray meets z = x^2 + y^2 off the patch
    assert 100 < inside.sum() < n
    assert res.converged[inside].all()
    assert not res.converged[np.all(np.abs(p[:, :2]) > 1.01, axis=1)].any()
    np.testing.assert_allclose(res.t[inside], t_true[inside], atol=1e-9)
    np.testing.assert_allclose(2 * res.u[inside] - 1, p[inside, 0], atol=1e-9)
    np.testing.assert_allclose(2 * res.v[inside] - 1, p[inside, 1], atol=1e-9)


def test_fast_reaches_a_skewed_planes_root_in_two_steps_where_gradient_zigzags():
    """S(u, v) = u A + v B with A and B 15 degrees apart: Q is affine in (u, v),
    so the Gauss-Newton model is exact and fast's two steps on one Jacobian
    (the second conjugate to the first) land on the root: 3 evaluations (the
    seed, the first step, the root). gradient's steps zig-zag down the narrow
    valley of w. The root is the closed-form ray-plane intersection."""
    a, b = np.array([1.0, 0.0, 0.0]), 0.5 * np.array([np.cos(np.radians(15)), np.sin(np.radians(15)), 0.0])
    surf = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[0, 0, 0], b], [a, a + b]])
    ps = PatchSet([surf])
    rng = np.random.default_rng(4)
    n = 400
    u, v = rng.uniform(0.3, 0.7, n), rng.uniform(0.3, 0.7, n)
    target = u[:, None] * a + v[:, None] * b
    origin = np.array([0.3, -0.4, 2.0]) + rng.normal(0, 0.3, (n, 3))
    rays = Rays.from_arrays(origin, target - origin)
    t_true = np.linalg.norm(target - origin, axis=1)
    seed_u, seed_v = u + rng.uniform(-0.05, 0.05, n), v + rng.uniform(-0.05, 0.05, n)
    results = {
        m: find_roots(
            ps,
            rays,
            np.arange(n),
            np.zeros(n, dtype=np.int64),
            seed_u,
            seed_v,
            method=m,
            tolerance=1e-10,
            max_iterations=500,
        )
        for m in ("fast", "gradient")
    }
    for res in results.values():
        assert res.converged.all()
        np.testing.assert_allclose(res.t, t_true, atol=1e-10)
        np.testing.assert_allclose(res.u, u, atol=1e-9)
        np.testing.assert_allclose(res.v, v, atol=1e-9)
    assert results["fast"].iterations.max() <= 3
    assert np.median(results["gradient"].iterations) >= 6


def test_roots_outside_the_domain_are_not_converged():
    surf = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]])
    ps = PatchSet([surf])
    # rays that meet the plane z = 0 outside the unit square
    o = np.array([[2.0, 0.5, 1.0], [0.5, -1.0, 1.0]])
    d = np.array([[0, 0, -1.0], [0, 0, -1.0]])
    res = find_roots(
        ps,
        Rays.from_arrays(o, d),
        np.arange(2),
        np.zeros(2, dtype=np.int64),
        np.full(2, 0.5),
        np.full(2, 0.5),
        tolerance=1e-9,
        max_iterations=64,
    )
    assert not res.converged.any()
    assert res.iterations.max() < 64  # stuck at the border: given up early


def test_singular_jacobian_gives_finite_steps():
    # a collapsed edge (all points of the u = 0 row equal): S_v = 0 there
    pts = np.array([[[0, 0, 0], [0, 0, 0]], [[1, -1, 0], [1, 1, 0]]], dtype=float)
    surf = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], pts)
    ps = PatchSet([surf])
    o = np.array([[0.5, 0.1, 1.0]])
    d = np.array([[0, 0, -1.0]])
    res = find_roots(
        ps,
        Rays.from_arrays(o, d),
        np.arange(1),
        np.zeros(1, dtype=np.int64),
        np.zeros(1),
        np.full(1, 0.5),
        tolerance=1e-12,
        max_iterations=64,
    )
    assert res.converged.all()
    np.testing.assert_allclose(evaluate(surf, res.u, res.v)[0], [[0.5, 0.1, 0.0]], atol=1e-10)
