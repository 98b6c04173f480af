"""The bound on a ray's crossings of a piece (kernels/crossings.py) on hand-worked and constructed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from test_flatten import _point, arc_by_line  # tests/test_flatten.py: a cylinder piece, Bezier points

from bsrt.kernels.crossings import crosses_once
from bsrt.kernels.roots import ray_frame


@njit(cache=False)
def _once(net, p, q, origin, direction):
    e = ray_frame(direction[0], direction[1], direction[2])
    g = np.empty((p + 1, q + 1, 4))
    return crosses_once(net, p, q, origin[0], origin[1], origin[2], e, g)


def _unit(x):
    x = np.asarray(x, dtype=np.float64)
    return x / np.linalg.norm(x)


def _ray_at(theta, beta, radius=2.0):
    """The ray from the cylinder's point at angle theta (on the arc of arc_by_line, half height)
    in the plane z = 1.5, turned by beta from the circle's tangent there toward the outside."""
    point = np.array([radius * math.cos(theta), radius * math.sin(theta), 1.5])
    tangent = np.array([-math.sin(theta), math.cos(theta), 0.0])
    outward = np.array([math.cos(theta), math.sin(theta), 0.0])
    return point, _unit(math.cos(beta) * tangent + math.sin(beta) * outward)


@pytest.mark.parametrize("degrees", [90.0, 30.0, 2.0, 0.1])
def test_a_plane_is_crossed_once_at_any_angle(degrees):
    """A flat bilinear piece meets a line not parallel to it once: the bound says so even at 0.1
    degrees from the plane (G is affine and one-to-one)."""
    net = np.zeros((2, 2, 4))
    for i in range(2):
        for j in range(2):
            net[i, j] = (3.0 * i, 2.0 * j + 0.5 * i, 0.0, 1.0)
    a = math.radians(degrees)
    assert _once(net, 1, 1, np.array([1.0, 1.0, 0.0]), _unit([math.cos(a), 0.3 * math.cos(a), math.sin(a)]))


def test_a_chord_of_a_cylinder_piece_crosses_it_twice():
    """A line through two points of a 90-degree arc of a cylinder (a chord): two crossings, so
    the bound must not say once, from either end and either way along it."""
    net = arc_by_line(math.radians(90.0))
    a = np.array([2.0 * math.cos(-0.6), 2.0 * math.sin(-0.6), 1.0])
    b = np.array([2.0 * math.cos(0.5), 2.0 * math.sin(0.5), 2.0])
    assert not _once(net, 2, 1, a, _unit(b - a))
    assert not _once(net, 2, 1, b, _unit(a - b))


@pytest.mark.parametrize("beta_degrees", [1.0, 10.0, 30.0, 60.0])
def test_a_ray_leaving_a_narrow_convex_piece_outward_crosses_it_once(beta_degrees):
    """A ray leaving the middle of a 10-degree arc (+-5 degrees) outward at beta from the tangent:
    its line meets the circle again 2 beta behind the start, inside the arc at beta = 1 degree
    (two crossings: the bound must not say once) and outside it at 10 degrees and more (one
    crossing, and the bound finds it)."""
    net = arc_by_line(math.radians(10.0))
    origin, direction = _ray_at(0.0, math.radians(beta_degrees))
    once = _once(net, 2, 1, origin, direction)
    assert once == (beta_degrees >= 5.0)


def test_never_once_where_a_line_meets_a_random_rational_piece_twice():
    """Soundness: for random rational bicubic pieces (bent, weights 0.5-2; nearly flat, weights
    0.9-1.1) and lines through two of their points, S(a) and S(b), the bound never says once;
    and it does say once for most steep rays off the nearly flat pieces (it is not vacuous)."""
    rng = np.random.default_rng(11)
    said_once = 0
    for trial in range(400):
        net = np.zeros((4, 4, 4))
        grid = np.stack(np.meshgrid(np.arange(4.0), np.arange(4.0), indexing="ij"), -1)
        bend = 0.05 if trial % 2 else 1.5
        xyz = np.concatenate([grid, np.zeros((4, 4, 1))], -1) + bend * rng.normal(size=(4, 4, 3))
        w = rng.uniform(0.5, 2.0, size=(4, 4, 1)) if bend > 1.0 else rng.uniform(0.9, 1.1, size=(4, 4, 1))
        net[..., :3], net[..., 3:] = xyz * w, w
        uv = rng.uniform(0.0, 1.0, size=(2, 2))
        a, b = _point(net, 3, 3, uv[:, 0], uv[:, 1])
        assert not _once(net, 3, 3, a, _unit(b - a)), trial
        assert not _once(net, 3, 3, b, _unit(a - b)), trial
        if bend < 1.0:
            said_once += _once(net, 3, 3, a, _unit([0.1, -0.2, 1.0]))
    assert said_once >= 150
