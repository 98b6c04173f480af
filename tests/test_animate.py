"""bsrt animate: camera paths on closed forms (orbit, keyframes), keyframe errors,
and real animations on a local Dask cluster (frames, animated WebP and APNG)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from distributed import LocalCluster
from PIL import Image

import bsrt
from bsrt.batches.animation import frame_cameras, orbit_camera
from bsrt.errors import InputError
from bsrt.rendering.warm_up import warm_up
from bsrt.scene import load_scene
from bsrt.scene.camera import Camera
from bsrt.scene.keyframes import Keyframe, keyframe_camera

SCENES = Path(__file__).resolve().parent.parent / "scenes"


@pytest.fixture(scope="module")
def cluster():
    """One local cluster (2 worker processes, 1 thread each) for the module's tests."""
    warm_up()  # compiled once here (a fresh install), not by every worker at once: they load the cache
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c


def bsrt_cli(*args):
    return subprocess.run([sys.executable, "-m", "bsrt", *map(str, args)], capture_output=True, text=True, timeout=600)


def test_orbit_positions_on_closed_forms():
    cam = Camera(np.array([0.0, -4.0, 1.0]), np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0]), 40.0)
    eyes = [orbit_camera(cam, 360.0, k, 8).eye for k in range(1, 10)]
    assert np.array_equal(eyes[0], cam.eye)  # frame 1 is the scene's camera, exactly
    expected = [(4 * np.sin(np.pi / 4 * j), -4 * np.cos(np.pi / 4 * j), 1.0) for j in range(9)]
    np.testing.assert_allclose(eyes, expected, atol=1e-14)  # right-handed about +z: (0,-4) -> (4,0) at 90 deg
    np.testing.assert_allclose(eyes[8], eyes[0], atol=1e-14)  # frame N + 1 = frame 1: the loop closes
    np.testing.assert_allclose(eyes[2], (4.0, 0.0, 1.0), atol=1e-14)
    tilted = Camera(np.array([1.0, 0.0, 0.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 30.0)
    np.testing.assert_allclose(orbit_camera(tilted, 180.0, 3, 2).eye, (-1.0, 0.0, 0.0), atol=1e-15)
    np.testing.assert_allclose(orbit_camera(tilted, 90.0, 2, 1).eye, (0.0, 0.0, -1.0), atol=1e-15)  # y up: x -> -z
    assert orbit_camera(tilted, 90.0, 2, 1).fov == 30.0


def test_keyframes_interpolate_linearly_and_hold_at_the_ends(tmp_path):
    scene = tmp_path / "kf.toml"
    scene.write_text(
        (SCENES / "quad.toml")
        .read_text()
        .replace(
            "fov = 40.0\n",
            "fov = 40.0\n\n[[camera.keyframe]]\nframe = 2\neye = [0.0, -4.0, 0.0]\n\n"
            "[[camera.keyframe]]\nframe = 6\neye = [0.0, -8.0, 2.0]\nlook_at = [1.0, 0.0, 0.0]\nfov = 20.0\n",
            1,
        )
    )
    s = load_scene(scene)
    assert [k.frame for k in s.keyframes] == [2, 6]
    assert s.keyframes[0] == Keyframe(2, (0.0, -4.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0)
    cams = frame_cameras(s, 7, None)
    np.testing.assert_array_equal(
        [c.eye for c in cams], [[0, -4, 0], [0, -4, 0], [0, -5, 0.5], [0, -6, 1], [0, -7, 1.5], [0, -8, 2], [0, -8, 2]]
    )
    np.testing.assert_array_equal([c.look_at[0] for c in cams], [0, 0, 0.25, 0.5, 0.75, 1, 1])
    assert [c.fov for c in cams] == [40, 40, 35, 30, 25, 20, 20]
    assert np.array_equal(keyframe_camera(s.camera, s.keyframes, 4).up, (0.0, 0.0, 1.0))


@pytest.mark.parametrize(
    "table, message",
    [
        ("frame = 0", "camera.keyframe[0].frame: must be >= 1, got 0"),
        (
            "frame = 3\n[[camera.keyframe]]\nframe = 3",
            "camera.keyframe[1].frame: must be greater than the previous keyframe's (3), got 3",
        ),
        ("frame = 1\neye = [1, 2]", "camera.keyframe[0].eye: expected 3 numbers, got [1, 2]"),
        ("frame = 1\nzoom = 2", "camera.keyframe[0].zoom: unknown key"),
        ("frame = 1\nfov = 180", "camera.keyframe[0].fov: must be < 180, got 180"),
        ("frame = 1\neye = [0, 0, 0]", "camera.keyframe[0].look_at: must differ from eye"),
        ("frame = 1\nup = [0, 1, 0]", "camera.keyframe[0].up: must not be zero or parallel to the view direction"),
        ("eye = [0, -4, 0]", "camera.keyframe[0].frame: missing (required)"),
    ],
)
def test_a_bad_keyframe_is_one_line_naming_file_and_key_exit_2(tmp_path, table, message):
    scene = tmp_path / "bad.toml"
    scene.write_text(
        (SCENES / "quad.toml").read_text().replace("fov = 40.0\n", f"fov = 40.0\n[[camera.keyframe]]\n{table}\n", 1)
    )
    for command in (
        ["animate", scene, "--out", tmp_path / "out", "--frames", 2],
        ["render", scene, "-o", tmp_path / "x.png"],
    ):
        run = bsrt_cli(*command)
        assert (run.returncode, run.stderr.startswith(f"bsrt: error: bad.toml: {message}")) == (2, True), run.stderr
        assert len(run.stderr.splitlines()) == 1
    assert not (tmp_path / "out").exists() and not (tmp_path / "x.png").exists()


def test_animate_without_a_path_is_usage_error(tmp_path):
    run = bsrt_cli("animate", SCENES / "quad.toml", "--out", tmp_path / "out", "--frames", 3)
    assert run.returncode == 2 and run.stderr.startswith("bsrt: error: ") and "--orbit" in run.stderr
    with pytest.raises(InputError, match="--frames: required with --orbit"):
        bsrt.animate(SCENES / "quad.toml", tmp_path / "out", orbit=90.0)


@pytest.mark.gl
def test_orbit_of_8_frames_with_animated_webp(tmp_path, cluster):
    out = tmp_path / "out"
    run = bsrt_cli(
        "animate",
        SCENES / "column.toml",
        "--out",
        out,
        "--frames",
        8,
        "--orbit",
        360,
        "--width",
        64,
        "--height",
        64,
        "--webp",
        "--fps",
        10,
        "--scheduler",
        cluster.scheduler_address,
        "--summary",
        tmp_path / "s.json",
    )
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in out.iterdir()) == ["column.webp"] + [f"frame_{k:04d}.png" for k in range(1, 9)]
    # Frame 1 is the scene's own camera: the same bytes as `bsrt render`.
    single = subprocess.run(
        [
            sys.executable,
            "-m",
            "bsrt",
            "render",
            SCENES / "column.toml",
            "-o",
            tmp_path / "single.png",
            "--width",
            "64",
            "--height",
            "64",
        ],
        capture_output=True,
    )
    assert single.returncode == 0 and (out / "frame_0001.png").read_bytes() == (tmp_path / "single.png").read_bytes()
    frames = [np.asarray(Image.open(out / f"frame_{k:04d}.png")) for k in range(1, 9)]
    assert not np.array_equal(frames[0], frames[1])  # the camera moved
    with Image.open(out / "column.webp") as anim:
        assert (anim.format, anim.n_frames, anim.size, anim.info["loop"]) == ("WEBP", 8, (64, 64), 0)
        for k in range(8):  # lossless: every frame exactly
            anim.seek(k)
            assert np.array_equal(np.asarray(anim.convert("RGB")), frames[k]), k
            assert anim.info["duration"] == 100
    summary = json.loads((tmp_path / "s.json").read_text())
    assert [i["status"] for i in summary["items"]] == ["ok"] * 9


@pytest.mark.gl
def test_keyframes_as_animated_png(tmp_path, cluster):
    scene = tmp_path / "kf.toml"
    scene.write_text(
        (SCENES / "quad.toml")
        .read_text()
        .replace(
            "fov = 40.0\n",
            "fov = 40.0\n[[camera.keyframe]]\nframe = 1\n[[camera.keyframe]]\nframe = 4\neye = [2.0, -4.0, 1.0]\n",
            1,
        )
    )
    summary = bsrt.animate(
        scene, tmp_path / "out", animation="apng", width=32, height=32, scheduler=cluster.scheduler_address
    )
    assert summary.exit_code == 0 and len(summary.items) == 5
    with Image.open(tmp_path / "out" / "kf.png") as anim:
        assert (anim.format, anim.n_frames, getattr(anim, "is_animated", False)) == ("PNG", 4, True)
        anim.seek(3)
        last = np.asarray(anim.convert("RGB"))
    assert np.array_equal(last, np.asarray(Image.open(tmp_path / "out" / "frame_0004.png")))
