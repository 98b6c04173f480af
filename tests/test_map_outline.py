"""The map's line pass draws the outline of each surface's picture (map_mesh.outline_edges).

A sliver thinner than a pixel covers no pixel centre, but its edges leave
fragments: the line pass draws them. Only the edges on the border of a
picture can leave fragments the triangles do not: a surface's own border and
its silhouette, where the triangles on either side of an edge face opposite
ways. Checked against closed forms: which edges of a tube's grid seen from
the side are its silhouette, and a tube thinner than a pixel before a plane,
whose pixels the map must show and the render must hit where the closed
form says.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bsrt.geometry.bspline import make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.rendering.map_mesh import EDGE_ON, _tessellation, outline_edges
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.rendering.prelim import render_map
from bsrt.scene import parse_scene
from bsrt.scene.camera import Camera, pixel_footprint, pixel_rays

W = math.sqrt(0.5)


def tube_keys(radius: float, x0: float, x1: float, y: float = 0.0, z: float = 0.0, turn: float = 0.0) -> dict:
    """The cylinder (y' - y)^2 + (z' - z)^2 = radius^2 for x0 <= x <= x1, as a scene's surface keys:
    four rational quadratic arcs in u (u in [0, 4], the first arc starting at angle ``turn`` in the
    (y, z) plane), linear in v."""
    angles = turn + np.arange(9) * math.pi / 4
    reach = np.where(np.arange(9) % 2 == 1, radius / W, radius)  # the arcs' middle points: the corners
    ring = np.stack([y + reach * np.cos(angles), z + reach * np.sin(angles)], axis=1)
    return {
        "degree": [2, 1],
        "knots_u": [0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 4],
        "knots_v": [0, 0, 1, 1],
        "points": [[[x, float(a), float(b)] for x in (x0, x1)] for a, b in ring],
        "weights": [[w, w] for w in (1, W, 1, W, 1, W, 1, W, 1)],
    }


def tube(*args, **keys):
    """tube_keys' surface."""
    k = tube_keys(*args, **keys)
    return make_surface(k["degree"], k["knots_u"], k["knots_v"], k["points"], k["weights"])


def test_a_flat_grid_facing_the_eye_is_outlined_by_its_border_alone():
    """A 3 x 2 grid of the plane z = 0, eye above: the 10 border edges, none of the 7 inside ones
    nor the 6 diagonals."""
    xs, ys = np.meshgrid(np.arange(4.0), np.arange(3.0), indexing="ij")
    vertices = np.zeros((12, 3), dtype=np.float32)
    vertices[:, 0], vertices[:, 1], vertices[:, 2] = xs.ravel() - 1.5, ys.ravel() - 1.0, -5.0  # eye-relative
    corner = (np.arange(3)[:, None] * 3 + np.arange(2)[None, :]).ravel()
    quad = np.stack([corner, corner + 3, corner + 4, corner + 1], axis=1)
    triangles = np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]).astype(np.uint32)
    edges = outline_edges(vertices, triangles)
    assert edges.shape == (10, 2)
    i, j = np.divmod(edges.astype(np.int64), 3)  # each end's grid (x, y)
    on_border = ((i[:, 0] == i[:, 1]) & np.isin(i[:, 0], [0, 3])) | ((j[:, 0] == j[:, 1]) & np.isin(j[:, 0], [0, 2]))
    assert on_border.all()


def test_a_tube_seen_from_the_side_is_outlined_by_its_borders_and_its_two_silhouettes():
    """The tube y^2 + z^2 = 1 along x, eye at distance 6 on the z axis. A quad between the angles
    a and b of the circle is planar, facing the eye where cos((a + b) / 2) > cos((b - a) / 2) / 6
    (its plane lies cos((b - a) / 2) from the axis): the kept edges are the borders (the ends'
    rings, the seam at u = 0 and u = 4, drawn on both sides) and the straight edges between a
    quad facing the eye and one facing away, nothing else."""
    patches = PatchSet([tube(1.0, -2.0, 2.0)])
    camera = Camera(np.array([0.0, 0.0, 6.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 50.0)
    mesh = _tessellation(patches, camera, 96, 96)
    p = mesh.vertices[:, :3].astype(np.float64) + camera.eye  # world positions
    angle = np.arctan2(p[:, 2], p[:, 1])  # around the axis, from +y toward +z (the eye's side)
    tri = mesh.indices.astype(np.int64)
    a, b = np.unwrap(angle[tri[:, [0, 1, 2]]], axis=1).min(axis=1), np.unwrap(angle[tri], axis=1).max(axis=1)
    half, middle = (b - a) / 2, (a + b) / 2
    facing = np.cos(middle - math.pi / 2) - np.cos(half) / 6.0  # > 0: faces the eye (at angle pi / 2)
    assert np.abs(facing).min() > 10 * EDGE_ON  # no quad near edge-on here: the expectation is exact
    assert (facing > 0).any() and (facing < 0).any()
    kept = {tuple(sorted(e)) for e in mesh.edges.astype(np.int64).tolist()}
    # every edge of the grid, with the facing of the triangles that have it
    sides: dict[tuple[int, int], list[bool]] = {}
    for k, (i, j, m) in enumerate(tri):
        for e in ((i, j), (j, m), (m, i)):
            sides.setdefault(tuple(sorted(e)), []).append(bool(facing[k] > 0))
    ends = np.isclose(np.abs(p[:, 0]), 2.0)
    seam = np.isclose(angle, 0.0, atol=1e-9)  # u = 0 and u = 4: two columns of vertices at one place
    expected = set()
    for e, faces in sides.items():
        border = len(faces) == 1
        if border:  # the rings at the ends and the two seam columns, nothing else
            assert (ends[e[0]] and ends[e[1]]) or (seam[e[0]] and seam[e[1]])
        if border or faces[0] != faces[1]:
            expected.add(e)
    assert kept == expected
    silhouettes = [e for e in expected if len(sides[e]) == 2]
    assert silhouettes and all(np.isclose(p[e[0], 1:], p[e[1], 1:]).all() for e in silhouettes)  # along x
    segments = np.unique(np.round(p[:, 0], 9)).size - 1  # quads along the tube
    assert len(silhouettes) == 2 * segments  # one straight line of edges on each side


@pytest.mark.parametrize("offset", [0.3, -0.3])
def test_a_tube_thinner_than_a_pixel_is_in_the_map_and_hit_where_the_closed_form_says(ctx, offset):
    """A tube of radius 0.35 pixel footprints along x, 0.3 footprints off a row of pixel centres,
    before the plane z = -1: its arcs start at 45 degrees, so its one quad per arc spans only
    0.25 footprints each side of the axis and pixels whose ray meets the tube have no triangle of
    it at their centre; the line pass shows it there or next to it, and the render hits the tube
    exactly at every pixel whose ray meets it (away from 1e-3 footprints of its silhouette) and
    the plane elsewhere (offset: of the row of centres from the axis, above or below)."""
    size = 48
    camera = Camera(np.array([0.0, 0.0, 10.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 30.0)
    step = pixel_footprint(camera, size, size) * 10.0  # a pixel at the tube (z = 0)
    radius, centre = 0.35 * step, 0.5 * step - offset * step  # the row above y = 0: y = step / 2
    plane = {"degree": [1, 1], "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
             "points": [[[-3, -3, -1], [-3, 3, -1]], [[3, -3, -1], [3, 3, -1]]]}  # fmt: skip
    scene = parse_scene(
        {
            "film": {"width": size, "height": size},
            "camera": {"eye": [0.0, 0.0, 10.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov": 30.0},
            "render": {"adaptive_spp": 0},
            "surface": [tube_keys(radius, -2.0, 2.0, y=centre, turn=math.pi / 4), plane],
        }
    )
    d = pixel_rays(camera, size, size)
    # closed form: o + t d with (y - centre)^2 + z^2 = radius^2, o = (0, 0, 10)
    oy, oz = -centre, 10.0
    qa = d[:, 1] ** 2 + d[:, 2] ** 2
    qb = oy * d[:, 1] + oz * d[:, 2]
    disc = qb**2 - qa * (oy**2 + oz**2 - radius**2)
    t_tube = (-qb - np.sqrt(np.maximum(disc, 0.0))) / qa
    x = t_tube * d[:, 0]
    meets = (disc > 0) & (np.abs(x) < 2.0)
    gap = np.abs(np.sqrt(np.maximum(disc, 0.0)) / qa)  # half the chord through the tube, along t
    sure_hit, sure_miss = meets & (gap > 1e-3 * step), (disc < 0) & (np.sqrt(-np.minimum(disc, 0) / qa) > 1e-3 * step)
    assert sure_hit.sum() > 20 and (sure_hit.reshape(size, size).any(axis=1).sum() == 1)  # one row of pixels
    geometry = Geometry(scene)
    patches = geometry.patches
    mesh = _tessellation(patches, camera, size, size)
    inside = _centres_inside(mesh, camera, d)
    assert (sure_hit & ~inside).sum() > 0  # pixels the triangles alone would not show
    prelim = render_map(patches, camera, size, size, ctx=ctx)
    shown = (prelim.surface == 0).reshape(size, size)
    near = shown | np.roll(shown, 1, 0) | np.roll(shown, -1, 0)  # in the map, or next to it in the column
    assert near.ravel()[sure_hit].all()
    options = RenderOptions.resolve(scene)
    assert np.array_equal(pixel_rays(options.camera, size, size), d)
    hits = render(scene, options, geometry=geometry).hits
    assert (hits.surface[sure_hit] == 0).all()
    assert (hits.surface[sure_miss & (np.abs(d[:, 0] * 11.0 / -d[:, 2]) < 3)] == 1).all()
    tolerance = options.tolerance * geometry.diagonal
    cosine = np.abs(qb[sure_hit] + qa[sure_hit] * t_tube[sure_hit]) / (radius * np.sqrt(qa[sure_hit]))
    assert np.all(np.abs(hits.t[sure_hit] - t_tube[sure_hit]) * cosine <= 1.01 * tolerance)


def _centres_inside(mesh, camera, d):
    """(N,) bool: the pixel's centre ray crosses one of the tube's (surface 0's) map triangles."""
    vertices = mesh.vertices.astype(np.float64)
    tri = mesh.indices.astype(np.int64)
    tri = tri[vertices[tri[:, 0], 5] == 1]
    a, b, c = (vertices[tri[:, k], :3] for k in range(3))  # eye-relative
    # the ray s d crosses triangle (a, b, c) where the signed volumes with d's sides agree
    ab = np.einsum("ij,kj->ki", np.cross(a, b), d)
    bc = np.einsum("ij,kj->ki", np.cross(b, c), d)
    ca = np.einsum("ij,kj->ki", np.cross(c, a), d)
    same = ((ab >= 0) & (bc >= 0) & (ca >= 0)) | ((ab <= 0) & (bc <= 0) & (ca <= 0))
    return same.any(axis=1)
