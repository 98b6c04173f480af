"""B-spline evaluation: answers worked out by hand or from identities."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bsrt.errors import InputError
from bsrt.geometry.bspline import (
    basis_functions,
    bezier_patches,
    evaluate,
    find_span,
    insert_knot,
    make_surface,
)
from bsrt.geometry.patches import PatchSet


@st.composite
def knot_vectors(draw, max_degree=4):
    """(degree, n, knots): any valid vector, clamped or not, interior repeats <= degree."""
    p = draw(st.integers(1, max_degree))
    n_inner = draw(st.integers(0, 5))
    inner = sorted(draw(st.lists(st.sampled_from([0.1, 0.25, 0.4, 0.5, 0.7, 0.9]), min_size=n_inner, max_size=n_inner)))
    # cap repeats at p
    capped = []
    for x in inner:
        if capped.count(x) < p:
            capped.append(x)
    clamped = draw(st.booleans())
    if clamped:
        knots = [0.0] * (p + 1) + capped + [1.0] * (p + 1)
    else:
        knots = [-0.3 * (p - i) for i in range(p)] + [0.0] + capped + [1.0] + [1.0 + 0.2 * (i + 1) for i in range(p)]
    n = len(knots) - p - 1
    return p, n, np.array(knots)


@settings(max_examples=60, deadline=None)
@given(knot_vectors(), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
def test_basis_partition_of_unity_and_derivative(kv, us):
    p, n, knots = kv
    u = np.array(us)
    span = find_span(knots, p, n, u)
    vals, ders = basis_functions(knots, p, span, u)
    np.testing.assert_allclose(vals.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(vals >= -1e-14)
    np.testing.assert_allclose(ders.sum(axis=1), 0.0, atol=1e-9)
    # derivative against a central difference of the same basis functions
    h = 1e-6
    inner = (u > knots[p] + 2 * h) & (u < knots[n] - 2 * h)
    inner &= np.all(np.abs(u[:, None] - knots[None, :]) > 2 * h, axis=1)
    if inner.any():
        up, um = u[inner] + h, u[inner] - h
        vp, _ = basis_functions(knots, p, span[inner], up)
        vm, _ = basis_functions(knots, p, span[inner], um)
        np.testing.assert_allclose((vp - vm) / (2 * h), ders[inner], atol=2e-5 * max(1.0, np.abs(ders).max()))


def _random_surface(rng, p=3, q=2, rational=True):
    ku = np.array([0.0] * (p + 1) + [0.2, 0.5, 0.5, 0.9] + [1.0] * (p + 1))
    kv = np.array([-1.0 - 0.5 * i for i in range(q)][::-1] + [0.0, 1.0, 2.5, 3.0] + [3.5 + 0.5 * i for i in range(q)])
    nu, nv = ku.size - p - 1, kv.size - q - 1
    w = rng.uniform(0.5, 2.0, (nu, nv)) if rational else None
    return make_surface((p, q), ku, kv, rng.normal(size=(nu, nv, 3)), w)


@pytest.mark.parametrize("rational", [False, True])
def test_surface_derivatives_match_finite_differences(rational):
    rng = np.random.default_rng(1)
    surf = _random_surface(rng, rational=rational)
    (a, b), (c, d) = surf.domain_u, surf.domain_v
    u, v = rng.uniform(a + 0.01, b - 0.01, 200), rng.uniform(c + 0.01, d - 0.01, 200)
    S, Su, Sv = evaluate(surf, u, v)
    h = 1e-6
    np.testing.assert_allclose((evaluate(surf, u + h, v)[0] - evaluate(surf, u - h, v)[0]) / (2 * h), Su, atol=1e-6)
    np.testing.assert_allclose((evaluate(surf, u, v + h)[0] - evaluate(surf, u, v - h)[0]) / (2 * h), Sv, atol=1e-6)


def test_rational_matches_homogeneous_definition():
    rng = np.random.default_rng(2)
    surf = _random_surface(rng, rational=True)
    u, v = rng.uniform(0, 1, 50), rng.uniform(0, 3, 50)
    (p, q), (nu, nv) = surf.degree, surf.shape
    su = find_span(surf.knots_u, p, nu, u)
    sv = find_span(surf.knots_v, q, nv, v)
    bu, _ = basis_functions(surf.knots_u, p, su, u)
    bv, _ = basis_functions(surf.knots_v, q, sv, v)
    for k in range(u.size):
        num, den = np.zeros(3), 0.0
        for a in range(p + 1):
            for b in range(q + 1):
                i, j = su[k] - p + a, sv[k] - q + b
                wij = surf.weights[i, j] * bu[k, a] * bv[k, b]
                num += wij * surf.points[i, j]
                den += wij
        np.testing.assert_allclose(evaluate(surf, u[k : k + 1], v[k : k + 1])[0][0], num / den, atol=1e-12)


def test_knot_insertion_leaves_surface_unchanged():
    rng = np.random.default_rng(3)
    surf = _random_surface(rng)
    h = surf.homogeneous()
    ku, hu = surf.knots_u, h
    for x in (0.1, 0.5, 0.77, 0.77):
        ku, hu = insert_knot(ku, hu, surf.degree[0], x)
    w = hu[..., 3]
    refined = make_surface(surf.degree, ku, surf.knots_v, hu[..., :3] / w[..., None], w)
    u, v = rng.uniform(0, 1, 300), rng.uniform(0, 3, 300)
    for a, b in zip(evaluate(surf, u, v), evaluate(refined, u, v)):
        np.testing.assert_allclose(a, b, atol=1e-12)


def test_bezier_patches_reproduce_the_surface():
    rng = np.random.default_rng(4)
    surf = _random_surface(rng)
    ctrl, bounds = bezier_patches(surf)
    assert len(ctrl) == 4 * 3  # u spans [0,.2,.5,.9,1], v spans [0,1,2.5,3] (unclamped)
    assert np.allclose(bounds[0], [0.0, 0.2, 0.0, 1.0])
    patches = PatchSet([surf])
    u, v = rng.uniform(0, 1, 500), rng.uniform(0, 3, 500)
    pid = patches.locate(np.zeros(500, dtype=np.int64), u, v)
    got = patches.evaluate(pid, u, v)
    for a, b in zip(got, evaluate(surf, u, v)):
        np.testing.assert_allclose(a.T, b, atol=1e-11)


def test_patch_evaluation_mixed_degrees_and_high_degree():
    rng = np.random.default_rng(5)
    s1 = _random_surface(rng, 3, 2, True)
    s2 = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 2, 2], rng.normal(size=(2, 2, 3)))
    s3 = make_surface((7, 7), [0] * 8 + [1] * 8, [0] * 8 + [1] * 8, rng.normal(size=(8, 8, 3)))
    s4 = _random_surface(rng, 3, 3, False)  # bicubic polynomial: kernels/patches.py's copy of the loop for it
    ps = PatchSet([s1, s2, s3, s4])
    sid = rng.integers(0, 4, 900)
    d = ps.domain[sid]
    u, v = rng.uniform(d[:, 0], d[:, 1]), rng.uniform(d[:, 2], d[:, 3])
    S, Su, Sv = ps.evaluate(ps.locate(sid, u, v), u, v)
    for m, surf in enumerate((s1, s2, s3, s4)):
        k = sid == m
        ref = evaluate(surf, u[k], v[k])
        scale = np.abs(surf.points).max()
        for a, b in zip((S, Su, Sv), ref):
            np.testing.assert_allclose(a[:, k].T, b, atol=1e-10 * scale * 50)


BAD = [
    (dict(degree=[0, 1]), "degree: each degree must be >= 1"),
    (dict(knots_u=[0, 0, 1]), "knots_u: expected 4 values (2 points + degree 1 + 1), got 3"),
    (dict(knots_u=[0, 1, 0.5, 1]), "knots_u: knots must not decrease"),
    (dict(points=[[[0, 0, float("nan")], [0, 0, 1]], [[1, 0, 0], [1, 0, 1]]]), "points: point [0][0] has a non-finite"),
    (dict(degree=[2, 1], knots_u=[0, 0, 0, 1, 1]), "points: degree [2, 1] needs at least 3 x 2 points"),
    (dict(weights=[[1, 1], [1, -1]]), "weights: every weight must be a finite number > 0"),
    (dict(knots_u=[0, 0, 0, 0]), "knots_u: the parameter domain [0, 0]"),
]


@pytest.mark.parametrize("change,message", BAD)
def test_invalid_surfaces_name_the_key(change, message):
    args = dict(
        degree=[1, 1],
        knots_u=[0, 0, 1, 1],
        knots_v=[0, 0, 1, 1],
        points=[[[0, 0, 0], [0, 0, 1]], [[1, 0, 0], [1, 0, 1]]],
        weights=None,
    )
    args.update(change)
    with pytest.raises(InputError) as err:
        make_surface(args["degree"], args["knots_u"], args["knots_v"], args["points"], args["weights"])
    assert message in str(err.value)


def test_interior_knot_repeated_more_than_degree_is_refused():
    with pytest.raises(InputError, match="repeated 3 times, more than the degree 2"):
        make_surface((2, 1), [0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1], [0, 0, 1, 1], np.zeros((6, 2, 3)))
