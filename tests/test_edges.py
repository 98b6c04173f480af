"""Edges (rendering/edges.py) and adaptive anti-aliasing (rendering/antialias.py), against closed forms.

The box: six planes, each a patch wider than the face, trimmed by a square
loop to the face [-1, 1]^2 of the cube [-1, 1]^3. Seen from (4, 3, 5) the
faces +x, +y, +z face the eye: the nine edges they bound are visible, the
three edges meeting at (-1, -1, -1) are hidden. Where each edge falls on
the film is the camera's formula (the scene format's pinhole projection),
written out here.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bsrt.cli import _parser
from bsrt.errors import InputError
from bsrt.rendering.antialias import disagreeing, rotated_grid
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render, sample_grid
from bsrt.rendering.screen import film_rays
from bsrt.scene import load_scene, parse_scene

pytestmark = pytest.mark.gl

ROOT = Path(__file__).resolve().parents[1]

EYE = np.array([4.0, 3.0, 5.0])
FOV = 40.0


def _face(axis: int, sign: float) -> dict:
    """The plane x[axis] = sign as a bilinear patch over [-1.5, 1.5]^2, trimmed to [-1, 1]^2
    (uv in [0, 1] along the other two axes: the loop is [1/6, 5/6]^2)."""
    b, c = [k for k in range(3) if k != axis]
    points = []
    for i in (0, 1):
        row = []
        for j in (0, 1):
            p = [0.0, 0.0, 0.0]
            p[axis], p[b], p[c] = sign, -1.5 + 3.0 * i, -1.5 + 3.0 * j
            row.append(p)
        points.append(row)
    lo, hi = 1.0 / 6.0, 5.0 / 6.0
    square = [(lo, lo), (hi, lo), (hi, hi), (lo, hi)]
    loop = {
        "curves": [
            {"degree": 1, "knots": [0, 0, 1, 1], "points": [list(p), list(q)]}
            for p, q in zip(square, square[1:] + square[:1])
        ]
    }
    return {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": points,
        "trim": [loop],
        "material": "white",
    }


def _box_scene(size: int, **render_keys):
    return parse_scene(
        {
            "film": {"width": size, "height": size, "background": [1.0, 1.0, 1.0]},
            "camera": {"eye": EYE.tolist(), "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": FOV},
            "render": {"adaptive_spp": 0, **render_keys},
            "material": [{"name": "white", "color": [0.5, 0.5, 0.5], "specular": 0.0}],
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": [_face(a, s) for a in range(3) for s in (-1.0, 1.0)],
        }
    )


def _film_xy(points: np.ndarray, size: int) -> np.ndarray:
    """(N, 3) world points -> (N, 2) film positions in pixels (x right, y down; pixel (i, j)
    covers [j, j + 1) x [i, i + 1)): the pinhole projection of the scene format."""
    forward = -EYE / np.linalg.norm(EYE)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = math.tan(math.radians(FOV) / 2.0)  # square film: the same in x and y
    d = points - EYE
    x, y = (d @ right) / (d @ forward), (d @ up) / (d @ forward)
    return np.stack([(x / half + 1.0) * size / 2.0, (1.0 - y / half) * size / 2.0], axis=1)


CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.sum(CORNERS[a] != CORNERS[b]) == 1]
HIDDEN = [(a, b) for a, b in EDGES if np.all(CORNERS[a] + CORNERS[b] <= 0)]  # the edges at (-1, -1, -1)
VISIBLE = [e for e in EDGES if e not in HIDDEN]


def _distance_to_segments(xy: np.ndarray, segments) -> np.ndarray:
    """(N,) film distance from points xy (N, 2) to the nearest of the segments ((2,), (2,))."""
    best = np.full(xy.shape[0], np.inf)
    for a, b in segments:
        d = b - a
        s = np.clip(((xy - a) @ d) / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(xy - (a + s[:, None] * d), axis=1))
    return best


def _coverage(size: int, **keys) -> np.ndarray:
    """(H, W) the edges' coverage: 1 - with / without (black edges over a grey box on white)."""
    scene = _box_scene(size)
    geometry = Geometry(scene)
    plain = render(scene, RenderOptions.resolve(scene), geometry=geometry).linear[..., 0]
    drawn = render(scene, RenderOptions.resolve(scene, edges=True, **keys), geometry=geometry).linear[..., 0]
    return 1.0 - drawn / plain


def _along(edges, size, lo, hi):
    """Film positions (N, 2) of points at fractions lo..hi along each edge."""
    t = np.linspace(lo, hi, 4 * size)[:, None]
    return np.concatenate([_film_xy(CORNERS[a] + t * (CORNERS[b] - CORNERS[a]), size) for a, b in edges])


@pytest.mark.parametrize("size", [64, 151])
def test_the_box_edges_fall_on_the_pixels_its_visible_edges_cross_and_nowhere_else(size):
    width = 1.5
    cover = _coverage(size, edge_width=width)
    visible = [tuple(_film_xy(CORNERS[[a, b]], size)) for a, b in VISIBLE]
    # every pixel a visible edge crosses: its centre within sqrt(2)/2 of the line: coverage >= w/2 + 1/2 - 0.71
    on = np.floor(_along(VISIBLE, size, 0.02, 0.98)).astype(int)
    assert cover[on[:, 1], on[:, 0]].min() > width / 2 + 0.5 - math.sqrt(0.5) - 1e-9
    # every pixel whose centre is farther than w/2 + 1/2 from all visible edges: untouched
    i, j = np.mgrid[0:size, 0:size]
    centres = np.stack([j.ravel() + 0.5, i.ravel() + 0.5], axis=1)
    far = _distance_to_segments(centres, visible) > width / 2 + 0.5 + 0.02
    assert far.sum() > 0.8 * size * size
    assert np.abs(cover.ravel()[far]).max() < 1e-12
    # the hidden edges' pixels away from the visible edges are among them: no line there
    hidden = np.floor(_along(HIDDEN, size, 0.2, 0.8)).astype(int)
    hidden_far = far.reshape(size, size)[hidden[:, 1], hidden[:, 0]]
    assert hidden_far.sum() > size  # the test sees them
    assert np.abs(cover[hidden[:, 1], hidden[:, 0]][hidden_far]).max() < 1e-12


def test_hidden_edges_are_drawn_faint_and_dashed():
    size, width = 96, 1.5
    cover = _coverage(size, edge_width=width, hidden_edges=True)
    visible = [tuple(_film_xy(CORNERS[[a, b]], size)) for a, b in VISIBLE]
    on = _along(HIDDEN, size, 0.2, 0.8)
    keep = _distance_to_segments(np.floor(on) + 0.5, visible) > width / 2 + 0.5 + 0.02
    pixel = np.floor(on[keep]).astype(int)
    seen = cover[pixel[:, 1], pixel[:, 0]]
    assert seen.max() <= 0.45 + 1e-9  # faint: HIDDEN_WEIGHT of a full line
    assert (seen > 0.2).mean() > 0.3 and (seen < 1e-12).mean() > 0.1  # dashes and gaps


def test_a_wider_edge_in_a_colour_covers_as_its_width_says():
    size = 96
    thin, wide = _coverage(size, edge_width=1.0), _coverage(size, edge_width=4.0)
    # 1 to 1.5 pixels from a visible edge: inside a 4-pixel line (coverage 2.5 - d >= 1) is covered, a 1-pixel line's is not
    visible = [tuple(_film_xy(CORNERS[[a, b]], size)) for a, b in VISIBLE]
    i, j = np.mgrid[0:size, 0:size]
    d = _distance_to_segments(np.stack([j.ravel() + 0.5, i.ravel() + 0.5], axis=1), visible).reshape(size, size)
    ring = (d > 1.0) & (d < 1.5)
    assert ring.sum() > 50
    assert wide[ring].min() > 0.99 and thin[ring].max() < 1e-12
    scene = _box_scene(size)
    red = render(scene, RenderOptions.resolve(scene, edges=True, edge_width=4.0, edge_color=(1.0, 0.0, 0.0)))
    core = d < 1.0
    np.testing.assert_allclose(red.linear[core], [[1.0, 0.0, 0.0]] * int(core.sum()), atol=1e-12)


def test_the_edge_flags_and_keys_are_checked_as_settings(capsys):
    args = _parser().parse_args(["render", "in.toml", "-o", "x.png", "--edges", "--edge-color", "0.2,0,1"])
    assert (args.edges, args.edge_color, args.hidden_edges) == (True, (0.2, 0.0, 1.0), None)
    assert _parser().parse_args(["render", "in.toml", "-o", "x.png", "--no-edges"]).edges is False
    for bad, message in (
        (["--edge-width", "0"], "argument --edge-width: expected a number in (0, 64], got 0"),
        (["--edge-color", "1,2"], "argument --edge-color: expected three numbers (linear RGB)"),
        (["--adaptive-spp", "-1"], "argument --adaptive-spp: expected a whole number >= 0, got -1"),
    ):
        with pytest.raises(SystemExit) as exit_:
            _parser().parse_args(["render", "in.toml", "-o", "x.png", *bad])
        assert exit_.value.code == 2
        assert message in capsys.readouterr().err
    with pytest.raises(InputError, match="render.edges: expected true or false, got 'yes'"):
        _box_scene(16, edges="yes")


# ---------------------------------------------------------------- adaptive anti-aliasing


def _checker(size: int, **render_keys):
    """White squares of a 6 x 6 checker (one surface, one loop per square) on a black film, seen
    obliquely, lit by an ambient light: each pixel's value is the white area it covers."""
    n = 6
    loops = []
    for a in range(n):
        for b in range(n):
            if (a + b) % 2 == 0:
                u0, u1, v0, v1 = a / n, (a + 1) / n, b / n, (b + 1) / n
                square = [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
                loops.append(
                    {
                        "curves": [
                            {"degree": 1, "knots": [0, 0, 1, 1], "points": [list(p), list(q)]}
                            for p, q in zip(square, square[1:] + square[:1])
                        ]
                    }
                )
    return parse_scene(
        {
            "film": {"width": size, "height": size, "background": [0.0, 0.0, 0.0]},
            "camera": {"eye": [-0.4, -1.1, 1.6], "look_at": [0.5, 0.5, 0.0], "up": [0.0, 0.0, 1.0], "fov": 45.0},
            "render": render_keys,
            "material": [{"name": "white", "color": [1.0, 1.0, 1.0], "specular": 0.0}],
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": [
                {
                    "degree": [1, 1],
                    "knots_u": [0, 0, 1, 1],
                    "knots_v": [0, 0, 1, 1],
                    "points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]],
                    "trim": loops,
                    "material": "white",
                }
            ],
        }
    )


def test_adaptive_anti_aliasing_matches_spp16_at_a_fraction_of_its_samples():
    """The default (adaptive_spp 4) against --spp 16 on the checker, in camera samples and error."""
    size = 96
    scene = _checker(size)
    geometry = Geometry(scene)
    sixteen = render(scene, RenderOptions.resolve(scene, spp=16, adaptive_spp=0), geometry=geometry).linear
    adaptive = render(scene, RenderOptions.resolve(scene, spp=1), geometry=geometry)
    one = render(scene, RenderOptions.resolve(scene, spp=1, adaptive_spp=0), geometry=geometry)
    error = np.abs(adaptive.linear - sixteen).max(axis=2)
    # one straight edge across a pixel: 4 samples in 4 distinct columns and rows of spp 16's 4 x 4 grid
    # are off its area by at most 1/4; pixels left unmarked by a corner cut off (at most 1/8)
    assert error.max() <= 0.25 + 1e-9
    assert error.mean() < 0.006  # 0.0051 (--spp 4: 0.0039)
    assert np.abs(one.linear - sixteen).max() > 0.4  # without it, the edges are jagged
    stats = adaptive.stats
    marked, samples = stats["adaptive_pixels"], stats["adaptive_samples"]
    assert 0 < samples < 3 * marked  # interpolated where the centres around a sample agree
    assert stats["pixels"] + samples < 0.08 * 16 * size * size  # the camera samples: 0.073 of spp 16's
    assert "adaptive_pixels" not in one.stats


def test_a_marked_pixel_is_the_mean_of_its_rotated_grid_traced_or_interpolated():
    """Each marked pixel of the checker (white 1 where a ray hits, black 0 where not) takes the mean
    of its n samples of rotated_grid, as tracing every one of them gives it, though most of them are
    interpolated: a sample in a triangle of points that agree (the pixel centres around it, and for
    the second pass the neighbours' samples) is on their side of a straight edge. Where a square's
    corner falls between them, it is not (a few pixels, within 1/n each)."""
    size = 96
    scene = _checker(size)
    geometry = Geometry(scene)
    eye = scene.camera.eye[None, :]
    for n in (4, 9):
        adaptive = render(scene, RenderOptions.resolve(scene, spp=1, adaptive_spp=n), geometry=geometry)
        marks = disagreeing(render(scene, RenderOptions.resolve(scene, adaptive_spp=0), geometry=geometry).pixels)
        y, x = np.nonzero(marks)
        offset = rotated_grid(*sample_grid(n))
        xy = (np.stack([x, y], axis=1)[:, None, :] + offset[None, :, :]).reshape(-1, 2)
        hit = geometry.intersect(eye, film_rays(scene.camera, size, size, xy)).hit.reshape(-1, n)
        error = np.abs(adaptive.linear[y, x, 0] - hit.mean(axis=1))
        # off: 6 (n = 4) and 9 (n = 9) of the 752 marked pixels, by 1/n
        assert np.mean(error < 1e-9) > 0.985 and error.max() <= 2 / n + 1e-9, n
        assert adaptive.stats["adaptive_pixels"] == marks.sum()
        assert adaptive.stats["adaptive_samples"] < 0.6 * n * marks.sum(), n  # 0.52 (n = 4), 0.45 (n = 9)


def test_a_streamed_render_is_refined_nearly_as_a_kept_one():
    """A streamed film keeps 8-bit colours only: its samples are interpolated from those (the kept
    film's from linear RGB), and traced where a centre at 255 may stand for more than 1. The
    pictures differ by a level or two at a few pixels (at 512 x 512: about 1,000 of 262,144 pixels
    differ, 20 by more than 2 levels, up to 8 on the column and 26 on the water-lily)."""
    scene = load_scene(ROOT / "scenes" / "column.toml")
    options = RenderOptions.resolve(scene, width=96, height=80)
    geometry = Geometry(scene)
    kept = render(scene, options, geometry=geometry)
    streamed = render(scene, options, geometry=geometry, keep=False)
    assert streamed.stats["adaptive_pixels"] == kept.stats["adaptive_pixels"] > 0
    assert streamed.stats["adaptive_samples"] >= kept.stats["adaptive_samples"]
    diff = np.abs(kept.pixels.astype(int) - streamed.pixels).max(axis=2)
    assert diff.max() <= 2 and np.mean(diff > 0) < 0.05  # 1.4% of the pixels, by at most 2


def test_a_streamed_render_on_a_white_background_traces_no_more_than_a_kept_one():
    """On a white background the streamed film's 8-bit background (255) is known to be exact: the
    film's hit counts tell it from a highlight, so it traces only the samples next to the column's
    own pixels at 255 beyond the kept film's (here 2,125 against 2,043; before, when every sample
    next to the background was traced too, 2,546)."""
    scene = load_scene(ROOT / "scenes" / "column.toml")
    options = RenderOptions.resolve(scene, width=96, height=80, background=(1.0, 1.0, 1.0))
    geometry = Geometry(scene)
    kept = render(scene, options, geometry=geometry)
    streamed = render(scene, options, geometry=geometry, keep=False)
    assert streamed.stats["adaptive_pixels"] == kept.stats["adaptive_pixels"] > 0
    assert streamed.stats["adaptive_samples"] <= 1.1 * kept.stats["adaptive_samples"]
    diff = np.abs(kept.pixels.astype(int) - streamed.pixels).max(axis=2)
    assert diff.max() <= 2 and np.mean(diff > 0) < 0.05


def test_the_rotated_grid_has_one_sample_in_each_cell_row_and_column():
    """rotated_grid(columns, rows): one sample in each cell of the columns x rows grid, and the n
    samples in n distinct columns and n distinct rows of the n x n grid (n = columns * rows)."""
    assert np.allclose(rotated_grid(2, 2), [[1 / 8, 3 / 8], [3 / 8, 7 / 8], [5 / 8, 1 / 8], [7 / 8, 5 / 8]])
    for n in (1, 2, 3, 4, 5, 6, 9, 12, 16, 64):
        columns, rows = sample_grid(n)
        offset = rotated_grid(columns, rows)
        cells = np.floor(offset * [columns, rows]).astype(int)
        assert len({tuple(c) for c in cells}) == n
        for axis in (0, 1):
            assert np.allclose(np.sort(offset[:, axis]), (np.arange(n) + 0.5) / n), (n, axis)
    assert [0.5, 0.5] in rotated_grid(3, 3).tolist()  # an odd grid's middle sample is the centre ray's


def test_a_periodic_seam_is_no_edge():
    """A whole cylinder x^2 + y^2 = 1, |z| <= 1, as one untrimmed surface whose u = 0 and u = 1 borders
    are the same line (1, 0, z): seen from (5, 0, 0), that seam runs down the middle of the film. Its
    top and bottom borders (circles) and its silhouettes (y = +-1) are edges; the seam is not."""
    r = math.sqrt(0.5)
    circle = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0)]
    weights = [1, r, 1, r, 1, r, 1, r, 1]
    size = 64
    scene = parse_scene(
        {
            "film": {"width": size, "height": size, "background": [1.0, 1.0, 1.0]},
            "camera": {"eye": [5.0, 0.0, 0.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": 40.0},
            "render": {"adaptive_spp": 0},
            "material": [{"name": "white", "color": [0.5, 0.5, 0.5], "specular": 0.0}],
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": [
                {
                    "degree": [2, 1],
                    "knots_u": [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1],
                    "knots_v": [0, 0, 1, 1],
                    "points": [[[x, y, -1.0], [x, y, 1.0]] for x, y in circle],
                    "weights": [[w, w] for w in weights],
                    "material": "white",
                }
            ],
        }
    )
    geometry = Geometry(scene)
    plain = render(scene, RenderOptions.resolve(scene), geometry=geometry).linear[..., 0]
    cover = 1.0 - render(scene, RenderOptions.resolve(scene, edges=True), geometry=geometry).linear[..., 0] / plain
    # the seam (1, 0, z) projects to x = 32 (between columns 31 and 32); z = +-0.6 to rows 32 -+ 32 * 0.6 / (4 tan 20)
    half = 0.6 / (4.0 * math.tan(math.radians(20.0))) * size / 2
    rows = slice(int(np.ceil(size / 2 - half)), int(size / 2 + half))
    assert np.abs(cover[rows, 28:36]).max() < 1e-12
    # the top border z = 1 at the seam: the point (1, 0, 1) at row 32 - 32 / (4 tan 20) is drawn
    top = int(size / 2 - 1.0 / (4.0 * math.tan(math.radians(20.0))) * size / 2)
    assert cover[top - 1 : top + 2, 31:33].max() > 0.5
