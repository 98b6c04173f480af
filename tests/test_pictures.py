"""The pictures a CAD user expects (issue 26): transparent and 16-bit output, the automatic
camera's framing and named views, turntables, the studio lights, ``bsrt scene`` and the bad
input of the new flags. Expected values are closed forms: a sphere's silhouette, coverage
fractions of a stratified sub-pixel grid, the PNG header."""

from __future__ import annotations

import inspect
import zlib

import numpy as np
import pytest
from conftest import MODELS
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

import bsrt
from bsrt.cli import main
from bsrt.io import load_model
from bsrt.scene import scene_for_model
from bsrt.scene.auto import FILL, fit_camera, surface_points, view_direction

SPHERE = MODELS / "nurbs" / "splipy" / "sphere.g2"
SPOUT = MODELS / "bezier-teaset" / "qt3d" / "teapot-spout.bez"


def _sphere():
    """(centre (3,), radius) of the model's sphere, from points on it."""
    pts = surface_points(load_model(SPHERE).surfaces)
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
    return centre, float(np.linalg.norm(pts - centre, axis=1).max())


@pytest.mark.parametrize("size", [(64, 64), (96, 54), (54, 96)], ids=["1:1", "16:9", "9:16"])
def test_the_automatic_camera_fits_a_sphere_to_90_percent_of_the_smaller_side_in_closed_form(size):
    width, height = size
    centre, radius = _sphere()
    scene = scene_for_model(load_model(SPHERE), width, height)
    cam = scene.camera
    # silhouette of angular radius a with tan(a) = FILL * tan(fov/2) on the smaller side:
    # the eye stands R / sin(a) from the centre, looking at it
    k = FILL * np.tan(np.radians(cam.fov) / 2.0) * min(1.0, width / height)
    # to the spacing of the 64 x 64 grid of points the camera is fitted to (a silhouette between
    # grid points: the distance is up to 1 - cos(half a grid step) short, about 0.1 %)
    assert np.linalg.norm(cam.eye - centre) == pytest.approx(radius * np.sqrt(1 + k * k) / k, rel=2e-3)
    np.testing.assert_allclose(cam.look_at, centre, atol=1e-3 * radius)  # to the grid of points


@pytest.mark.gl
@pytest.mark.parametrize("size", [(64, 64), (96, 54), (54, 96)], ids=["1:1", "16:9", "9:16"])
def test_the_sphere_fills_90_percent_of_the_pictures_smaller_side_centred(size):
    width, height = size
    hit = bsrt.render(SPHERE, width=width, height=height).hits.hit.reshape(height, width)
    rows, cols = np.flatnonzero(hit.any(axis=1)), np.flatnonzero(hit.any(axis=0))
    diameter = FILL * min(width, height)  # 57.6 or 48.6 pixels
    for span, side in ((rows, height), (cols, width)):
        assert abs(span.size - diameter) <= 1.0, (span.size, diameter)
        assert abs((span[0] + span[-1] + 1) / 2.0 - side / 2.0) <= 0.5  # centred to half a pixel


def test_named_views_look_along_the_axes_and_fit_any_model():
    pts = surface_points(load_model(SPOUT).surfaces)
    expected = {"front": (0, -1, 0), "back": (0, 1, 0), "left": (-1, 0, 0), "right": (1, 0, 0), "top": (0, 0, 1)}
    for view, to_eye in expected.items():
        np.testing.assert_allclose(view_direction(view, (0, 0, 1))[0], to_eye, atol=1e-15)
    np.testing.assert_allclose(view_direction("iso", (0, 0, 1))[0], np.ones(3) * [1, -1, 1] / np.sqrt(3))
    for view in ("front", "top", "iso"):
        for width, height in ((80, 45), (45, 80)):
            cam = fit_camera(pts, width, height, view)
            right, up, forward = cam.basis()
            rel = pts - cam.eye
            x = rel @ right / (rel @ forward) / (np.tan(np.radians(cam.fov) / 2) * width / height)
            y = rel @ up / (rel @ forward) / np.tan(np.radians(cam.fov) / 2)
            # inside 90 % of the frame, touching it on one axis, and centred on both
            assert max(abs(x).max(), abs(y).max()) == pytest.approx(FILL, abs=1e-9)
            assert abs(x.max() + x.min()) < 1e-6 and abs(y.max() + y.min()) < 1e-6


def test_an_orbit_of_a_model_stays_centred_and_in_the_frame():
    from bsrt.batches.animation import frame_cameras
    from bsrt.scene.loading import CameraOverrides, load_input

    scene = load_input(SPOUT, width=64, height=48, camera=CameraOverrides(turntable=True))
    pts = surface_points([s.geometry for s in scene.surfaces])
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
    for cam in frame_cameras(scene, 12, 360.0):
        np.testing.assert_allclose(cam.look_at, centre)  # the box's centre: the picture's centre
        right, up, forward = cam.basis()
        rel = pts - cam.eye
        x = rel @ right / (rel @ forward) / (np.tan(np.radians(cam.fov) / 2) * 64 / 48)
        y = rel @ up / (rel @ forward) / np.tan(np.radians(cam.fov) / 2)
        assert abs(x).max() <= FILL + 1e-9 and abs(y).max() <= FILL + 1e-9


@pytest.mark.gl
def test_transparent_alpha_is_0_outside_255_inside_and_the_coverage_at_the_silhouette(tmp_path):
    result = bsrt.render(SPHERE, width=40, height=40, spp=4, transparent=True, background=(1.0, 0.0, 0.0))
    rgba = result.image
    assert rgba.shape == (40, 40, 4) and rgba.dtype == np.uint8
    alpha = rgba[..., 3]
    assert alpha[0, 0] == 0 and alpha[20, 20] == 255
    assert alpha[~result.coverage.astype(bool)].max() == 0
    # 2 x 2 samples a pixel: alpha is k/4 of 255 for k = 0..4, and the silhouette has each
    assert set(np.unique(alpha)) == {0, 64, 128, 191, 255}
    # the red background is not mixed into the silhouette's colour (straight alpha)
    edge = (alpha > 0) & (alpha < 255)
    assert np.all(rgba[edge][:, 0].astype(int) - rgba[edge][:, 1] < 40)
    result.save(tmp_path / "t.png")
    with Image.open(tmp_path / "t.png") as png:
        assert png.mode == "RGBA" and np.array_equal(np.asarray(png), rgba)


@pytest.mark.gl
def test_transparent_alpha_follows_the_adaptive_samples_and_the_edges():
    # one sample a pixel plus adaptive anti-aliasing (default: 4 samples): the silhouette's alpha is
    # the fraction of the adaptive samples that hit, k/4, within 1/4 of --spp 16's
    adaptive = bsrt.render(SPHERE, width=40, height=40, transparent=True, background=(1.0, 0.0, 0.0))
    uniform = bsrt.render(SPHERE, width=40, height=40, spp=16, adaptive_spp=0, transparent=True)
    a, b = adaptive.image[..., 3].astype(int), uniform.image[..., 3].astype(int)
    partial = (a > 0) & (a < 255)
    assert partial.sum() > 20 and set(np.unique(a)) == {0, 64, 128, 191, 255}
    assert np.abs(a - b).max() <= 64 and np.abs(a - b)[partial].mean() < 28  # 25.1 (--spp 4: 26.8)
    # an outline drawn over the background is opaque as far as it covers: alpha over the lines
    lined = bsrt.render(SPHERE, width=40, height=40, transparent=True, adaptive_spp=0, edges=True, edge_width=3.0).image
    outside = adaptive.image[..., 3] == 0
    line = outside & (lined[..., 3] > 0)
    assert line.sum() > 20  # the silhouette line's outer half lies over the background
    assert lined[line][:, :3].max() < 60  # black lines, the red background not mixed in


@pytest.mark.gl
def test_16_bit_png_holds_the_8_bit_picture(tmp_path):
    result = bsrt.render(SPHERE, width=24, height=16, bit_depth=16)
    result.save(tmp_path / "deep.png")
    data = (tmp_path / "deep.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    assert (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big"), data[24], data[25]) == (
        24,
        16,
        16,
        2,
    )
    start = data.index(b"IDAT") + 4
    length = int.from_bytes(data[start - 8 : start - 4], "big")
    rows = np.frombuffer(zlib.decompress(data[start : start + length]), np.uint8)
    rows = rows.reshape(16, 1 + 24 * 6)
    assert not rows[:, 0].any()  # filter "none" on every row
    deep = rows[:, 1:].copy().view(">u2").reshape(16, 24, 3).astype(int)
    assert np.abs(deep / 257.0 - result.pixels).max() <= 0.5 + 1e-9


@pytest.mark.gl
def test_the_studio_rig_lights_an_imported_part_on_white(tmp_path, capsys):
    scene = tmp_path / "part.toml"
    scene.write_text(f'[film]\nbackground = [1.0, 1.0, 1.0]\nwidth = 48\nheight = 36\n[[import]]\nfile = "{SPHERE}"\n')
    out = tmp_path / "part.png"
    assert main(["render", scene, "-o", out]) == 0
    assert "no [[light]]: lit by the default studio rig" in capsys.readouterr().err
    loaded = bsrt.load(scene)
    assert [light.kind for light in loaded.lights] == ["ambient", "point", "point", "point"]
    pixels = np.asarray(Image.open(out)).astype(float)
    again = bsrt.render(loaded)
    hit = again.hits.hit.reshape(36, 48)
    lit = pixels[hit].mean(axis=1)
    assert lit.mean() > 100 and np.percentile(lit, 5) > 40  # grey to white, no black silhouette
    assert pixels[again.coverage == 0].min() == 255  # the white background (no sample hit)


@pytest.mark.gl
def test_bsrt_scene_round_trips_to_the_same_picture(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["scene", SPHERE, "--width", "40", "--height", "30", "--view", "iso"]) == 0
    text = (tmp_path / "sphere.toml").read_text()
    assert "[[import]]" in text and "brightness" in text and len(text) < 2000  # small: no surfaces spelled out
    assert main(["render", SPHERE, "--width", "40", "--height", "30", "--view", "iso", "-o", "model.png"]) == 0
    assert main(["render", "sphere.toml"]) == 0  # -o: sphere.png, here
    a = np.asarray(Image.open("model.png")).astype(int)
    b = np.asarray(Image.open("sphere.png")).astype(int)
    assert a.shape == b.shape == (30, 40, 3) and np.abs(a - b).max() <= 1


@pytest.mark.parametrize(
    "args,message",
    [
        (["--background", "1,1"], "expected three numbers (linear RGB)"),
        (["--background", "1.5,0,0"], "expected three numbers in [0, 1]"),
        (["--background", "-0.1,0,0"], "expected three finite numbers >= 0"),
        (["--view", "sideways"], "invalid choice: 'sideways'"),
        (["-o", "{out}.tif"], "cannot tell the image format from '.tif'"),
        (["-o", "{out}.jpg", "--transparent"], "--transparent: JPEG has no transparency"),
        (["-o", "{out}.webp", "--bit-depth", "16"], "--bit-depth 16: only PNG holds 16 bits"),
        (["--bit-depth", "12"], "expected one of 8, 16"),
    ],
)
def test_bad_picture_flags_exit_2_with_one_message_and_nothing_written(tmp_path, capsys, args, message):
    out = str(tmp_path / "x")
    argv = ["render", SPHERE] + [a.replace("{out}", out) for a in args]
    if "-o" not in argv:
        argv += ["-o", out + ".png"]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []


def test_an_output_that_is_the_input_is_refused(tmp_path, capsys):
    model = tmp_path / "part.g2"
    model.write_bytes(SPHERE.read_bytes())
    assert main(["scene", model, "-o", tmp_path / "part.g2"]) == 2
    assert "must end in .toml" in capsys.readouterr().err
    scene = tmp_path / "s.toml"
    scene.write_text(f'[[import]]\nfile = "{model}"\n')
    assert main(["scene", scene]) == 2
    assert "is a scene file already" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["part.g2", "s.toml"]


def test_the_api_keywords_are_the_registrys_and_unknown_ones_are_refused():
    from bsrt.settings import SETTINGS

    params = inspect.signature(bsrt.render).parameters
    assert all(
        params[s.name].kind is inspect.Parameter.KEYWORD_ONLY and params[s.name].default is None for s in SETTINGS
    )
    with pytest.raises(TypeError, match="unknown render setting 'sharpness'"):
        bsrt.load(SPHERE, sharpness=3)


def test_ao_directions_are_cosine_weighted_over_the_hemisphere():
    from bsrt.rendering.occlusion import AO_RAYS, hemisphere_directions

    normal = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    d = hemisphere_directions(normal)
    assert d.shape == (2, AO_RAYS, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=2), 1.0)
    cos = np.einsum("krj,kj->kr", d, normal)
    assert cos.min() > 0
    # cosine-weighted: cos^2 is uniform on [0, 1]; the stratified grid's cos^2 are 1 - (i + 0.5) / 4, each 4 times
    np.testing.assert_allclose(np.sort(cos[0] ** 2), np.repeat([0.125, 0.375, 0.625, 0.875], 4))


def test_ao_under_a_parallel_plane_is_the_closed_form():
    """A point facing a plane h above it, rays of reach R: a ray at angle theta from the normal meets
    it when h / cos(theta) <= R, so the open fraction of cosine-weighted directions is (h / R)^2."""
    from bsrt.rendering.occlusion import occlusion
    from bsrt.rendering.pipeline import Geometry

    def square(z, half):
        return bsrt.Surface(
            (1, 1),
            [0, 0, 1, 1],
            [0, 0, 1, 1],
            [[[-half, -half, z], [-half, half, z]], [[half, -half, z], [half, half, z]]],
        )

    h = 1.0
    scene = bsrt.Scene.build([square(0.0, 4.0), square(h, 4.0)], bsrt.Camera((0, -10, 5), (0, 0, 0)), lights=[])
    geometry = Geometry(scene)

    def trace(origins, directions, exclude, t_max, any_hit):
        n = len(origins)
        return geometry.intersect(
            origins,
            directions,
            t_min=0.0,
            t_max=np.full(n, t_max),
            tolerance=1e-9 * geometry.diagonal,
            any_hit=any_hit,
            exclude=exclude,
        )

    point, up = np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]])
    own = (np.array([0]), np.array([0.5]), np.array([0.5]), np.array([1e-6]), np.array([1e-6]))
    for reach, expected in ((h * np.sqrt(2.0), 0.5), (h * 2.0, 0.25), (h * 0.9, 1.0)):
        # the stratified directions have cos^2 = 1/8, 3/8, 5/8, 7/8: (h/R)^2 = 1/2, 1/4 fall between them
        assert occlusion(trace, point, up, own, reach)[0] == pytest.approx(expected)


@pytest.mark.gl
def test_the_ground_plane_takes_a_contact_shadow_under_a_sphere(tmp_path):
    scene = bsrt.load(SPHERE, width=64, height=48, view="iso")
    result = bsrt.render(scene, ground=True, background=(1.0, 1.0, 1.0))
    surface = result.hits.surface.reshape(48, 64)
    sphere, ground = surface == 0, surface == len(scene.surfaces)  # the ground: one surface more
    assert sphere.any() and ground.any()
    brightness = result.linear.mean(axis=2)
    near = np.zeros_like(sphere)  # ground pixels next to the sphere's silhouette: its base
    near[1:] |= sphere[:-1]
    near[:-1] |= sphere[1:]
    near &= ground
    far = ground.copy()
    far[:, 8:-8] = False  # the ground at the frame's sides, a model radius and more away
    assert near.any() and far.any()
    assert brightness[near].min() < 0.5 * np.median(brightness[far]), (
        brightness[near].min(),
        np.median(brightness[far]),
    )
    result.save(tmp_path / "ground.png")


@pytest.mark.gl
def test_the_ground_plane_hides_under_a_floor_of_the_models_own():
    """scenes/column.toml has a floor at the model's lowest point: the ground plane lies
    GROUND_GAP model radii under it, so every pixel that shows the model without the ground shows
    the same surface with it (in the floor's plane the two alternated pixel by pixel)."""
    scene = bsrt.load(MODELS.parents[2] / "scenes" / "column.toml", width=96, height=96)
    alone = bsrt.render(scene, spp=1, adaptive_spp=0)
    grounded = bsrt.render(scene, ground=True, spp=1, adaptive_spp=0)
    model = alone.hits.hit
    floor = alone.hits.surface == np.bincount(alone.hits.surface[model]).argmax()  # the most pixels: the floor
    assert floor.sum() > 1000
    np.testing.assert_array_equal(grounded.hits.surface[model], alone.hits.surface[model])
    assert (grounded.hits.surface[~model] == len(scene.surfaces)).any()  # the ground beyond the model


def test_a_point_lights_brightness_is_its_strength_at_the_models_centre(tmp_path):
    scene = tmp_path / "b.toml"
    scene.write_text(
        f'[[import]]\nfile = "{SPHERE}"\n'
        '[[light]]\nkind = "point"\nposition = [3.0, 4.0, 12.0]\nbrightness = 0.5\n'
        '[[light]]\nkind = "point"\nposition = [0.0, 0.0, 2.0]\nintensity = 7.0\n'
    )
    centre, _ = _sphere()
    lights = bsrt.load(scene).lights
    assert len(lights) == 2  # lights given: no studio rig
    assert lights[0].intensity == pytest.approx(0.5 * np.sum((np.array([3.0, 4.0, 12.0]) - centre) ** 2), rel=1e-12)
    assert lights[1].intensity == 7.0
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace("brightness = 0.5\n", "brightness = 0.5\nintensity = 1.0\n", 1))
    with pytest.raises(bsrt.InputError, match="light.0..brightness: give either intensity or brightness, not both"):
        bsrt.load(bad)
    bad.write_text(f'[[import]]\nfile = "{SPHERE}"\nfile_colors = 1\n')
    with pytest.raises(bsrt.InputError, match=r"import\[0\].file_colors: expected true or false, got 1"):
        bsrt.load(bad)
    bad.write_text(
        "[[surface]]\ndegree = [1, 1]\nknots_u = [0, 0, 1, 1]\nknots_v = [0, 0, 1, 1]\n"
        "points = [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]]\n"
    )
    with pytest.raises(bsrt.InputError, match=r"camera: missing table \[camera\] \(only a scene with \[\[import\]\]"):
        bsrt.load(bad)


@pytest.mark.gl
@pytest.mark.cad
def test_bsrt_scene_of_a_coloured_step_assembly_keeps_its_colours(tmp_path):
    step = MODELS / "step" / "pythonocc-core" / "as1-oc-214.stp"
    part = tmp_path / "as1.toml"
    assert main(["scene", step, "-o", part, "--width", "48", "--height", "32", "--background", "1,1,1"]) == 0
    assert part.stat().st_size < 2000
    scene = bsrt.load(part)
    assert len({m.color for m in scene.materials}) > 3  # the file's colours, on the model's material
    a = bsrt.render(step, width=48, height=32, background=(1.0, 1.0, 1.0)).pixels.astype(int)
    b = bsrt.render(scene).pixels.astype(int)
    assert np.abs(a - b).max() <= 1


def test_an_animations_summary_counts_its_frames_and_its_file_apart():
    from bsrt.batches.engine import Item, Summary

    items = [Item("p.step", f"o/frame_{k:04d}.png", "ok") for k in range(1, 13)] + [Item("p.step", "o/p.webp", "ok")]
    summary = Summary(items, 2.0, "o", frames=12)
    assert summary.line().startswith("12 frames: 12 rendered, 0 skipped, 0 failed, and the animated file p.webp")
    assert summary.to_dict()["frames"] == 12 and len(summary.to_dict()["items"]) == 13
    assert Summary(items[:3], 1.0, "o").line().startswith("3 items: 3 rendered")


def _encoded_whole(linear, coverage, background, transparent, bits):
    """The picture encoded from the whole arrays at once: the reference for encode_picture's bands."""
    from bsrt.rendering.image import srgb_encode, srgb_encode16

    encode = srgb_encode if bits == 8 else srgb_encode16
    if not transparent:
        return encode(linear)
    a = coverage[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        colour = np.where(a > 0, (linear - (1.0 - a) * np.asarray(background)) / a, 0.0)
    alpha = np.rint(np.clip(coverage, 0.0, 1.0) * (255.0 if bits == 8 else 65535.0))
    return np.concatenate([encode(colour), alpha.astype(np.uint8 if bits == 8 else np.uint16)[..., None]], axis=2)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 200), st.integers(1, 9), st.booleans(), st.sampled_from([8, 16]), st.integers(0, 2**32 - 1))
def test_the_picture_encoded_in_bands_of_rows_is_the_whole_pictures(height, width, transparent, bits, seed):
    """encode_picture works through bands of rows on the thread pool: every row, whatever the
    height against the bands (ENCODE_ROWS = 16), gets what the whole arrays' encoding gives (NaN,
    out-of-range values, zero and partial coverage included)."""
    from bsrt.rendering.image import encode_picture

    rng = np.random.default_rng(seed)
    linear = rng.random((height, width, 3)) * 1.4 - 0.2
    linear[rng.random((height, width, 3)) < 0.05] = np.nan
    coverage = np.where(rng.random((height, width)) < 0.3, 0.0, rng.random((height, width)))
    want = _encoded_whole(linear, coverage, (0.2, 0.5, 0.9), transparent, bits)
    got = encode_picture(linear, coverage, (0.2, 0.5, 0.9), transparent, bits)
    assert got.dtype == want.dtype and got.shape == want.shape
    np.testing.assert_array_equal(got, want)
