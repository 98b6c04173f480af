"""The command line: outputs, exit codes, and one clear message for bad input."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from bsrt.cli import main

SCENES = Path(__file__).resolve().parents[1] / "scenes"
QUAD = (SCENES / "quad.toml").read_text()


@pytest.mark.gl
def test_render_writes_png_stats_and_aov(tmp_path, capsys):
    out, aov = tmp_path / "quad.png", tmp_path / "quad.npz"
    clock = time.perf_counter()
    code = main(["render", str(SCENES / "quad.toml"), "-o", str(out), "--aov", str(aov), "--stats"])
    wall = time.perf_counter() - clock
    assert code == 0
    img = np.asarray(Image.open(out))
    assert img.shape == (64, 64, 3) and img.dtype == np.uint8
    stats = json.loads(capsys.readouterr().out)
    for stage in ("map", "solve", "shade", "write"):
        assert 0 < stats["seconds"][stage] < wall, stage
    assert sum(stats["seconds"][s] for s in ("map", "solve", "shade", "write")) < wall
    # the square |x|, |z| <= 1 at distance 4 under a 40 degree field: pixel centres 10..53 of 64 on each axis
    assert stats["hits"] == 44 * 44
    assert {"iterations_mean", "iterations_max", "non_converged"} <= stats.keys()
    with np.load(aov) as data:
        assert data["hit"].sum() == stats["hits"]
        # background where there is no hit: film background in sRGB
        bg = (np.array([0.05, 0.05, 0.08]) ** (1 / 2.4) * 1.055 - 0.055) * 255
        assert np.all(np.abs(img[~data["hit"]] - np.rint(bg)) <= 1)


@pytest.mark.gl
def test_overrides_and_map_command(tmp_path):
    out = tmp_path / "small.png"
    assert (
        main(
            [
                "render",
                str(SCENES / "quad.toml"),
                "-o",
                str(out),
                "--width",
                "40",
                "--height",
                "30",
                "--method",
                "gradient",
                "--map",
                "rgba8",
            ]
        )
        == 0
    )
    assert Image.open(out).size == (40, 30)
    fig = tmp_path / "map.png"
    assert main(["map", str(SCENES / "quad.toml"), "-o", str(fig)]) == 0
    pic = np.asarray(Image.open(fig))
    assert set(np.unique(pic[..., 0])) == {0, 1}  # red = surface index + 1


def _write(tmp_path, text, name="bad.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _replace(old, new):
    assert old in QUAD, old
    return QUAD.replace(old, new, 1)


BAD_SCENES = [
    ("malformed TOML", "[film\nwidth = 3", "bad.toml: invalid TOML"),
    (
        "wrong knot count",
        _replace("knots_u = [0.0, 0.0, 1.0, 1.0]", "knots_u = [0.0, 0.0, 1.0]"),
        "bad.toml: surface[0].knots_u: expected 4 values (2 points + degree 1 + 1), got 3",
    ),
    (
        "decreasing knots",
        _replace("knots_v = [0.0, 0.0, 1.0, 1.0]", "knots_v = [0.0, 1.0, 0.5, 1.0]"),
        "bad.toml: surface[0].knots_v: knots must not decrease",
    ),
    (
        "degree 0",
        _replace("degree = [1, 1]", "degree = [0, 1]"),
        "bad.toml: surface[0].degree: each degree must be >= 1",
    ),
    (
        "NaN coordinate",
        _replace("[-1.0, 0.0, -1.0]", "[nan, 0.0, -1.0]"),
        "bad.toml: surface[0].points: point [0][0] has a non-finite coordinate",
    ),
    (
        "0x0 film",
        _replace("width = 64\nheight = 64", "width = 0\nheight = 0"),
        "bad.toml: film.width: expected a whole number >= 1, got 0",
    ),
    (
        "up parallel to view",
        _replace("up = [0.0, 0.0, 1.0]", "up = [0.0, 2.0, 0.0]"),
        "bad.toml: camera.up: must not be parallel to the view direction",
    ),
    ("unknown key", _replace("fov = 40.0", "fov = 40.0\nzoom = 2"), "bad.toml: camera.zoom: unknown key"),
    ("unknown table", QUAD + "\n[lens]\nf = 1\n", "bad.toml: lens: unknown table"),
    (
        "unknown method",
        _replace('method = "newton"', 'method = "bisection"'),
        "bad.toml: render.method: expected one of gradient, fast, newton, martin, got 'bisection'",
    ),
    (
        "unknown material",
        _replace('material = "white"', 'material = "gold"'),
        "bad.toml: surface[0].material: no [[material]] named 'gold'",
    ),
    ("string for a number", _replace("fov = 40.0", 'fov = "wide"'), "bad.toml: camera.fov: expected a number"),
    (
        "weights of the wrong shape",
        _replace("degree = [1, 1]", "degree = [1, 1]\nweights = [[1.0, 1.0, 1.0], [1.0, 2.0, 1.0]]"),
        "bad.toml: surface[0].weights: expected 2 x 2 values (one per point), got shape (2, 3)",
    ),
    (
        "zero weight",
        _replace("degree = [1, 1]", "degree = [1, 1]\nweights = [[1.0, 0.0], [1.0, 2.0]]"),
        "bad.toml: surface[0].weights: every weight must be a finite number > 0",
    ),
    ("fov out of range", _replace("fov = 40.0", "fov = 180.0"), "bad.toml: camera.fov: must be < 180"),
]


@pytest.mark.parametrize("label,text,message", BAD_SCENES, ids=[b[0] for b in BAD_SCENES])
def test_bad_scenes_exit_2_with_one_message_and_no_output(tmp_path, capsys, label, text, message):
    scene = _write(tmp_path, text)
    out = tmp_path / "out.png"
    assert main(["render", str(scene), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [scene]  # no temporary files left either


def test_usage_errors_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["render", str(SCENES / "quad.toml"), "-o", str(tmp_path / "x.png"), "--method", "nope"])
    assert exc.value.code == 2
    assert main(["render", str(SCENES / "quad.toml"), "-o", str(tmp_path / "x.tif")]) == 2  # no such format
    assert "cannot tell the image format from '.tif'" in capsys.readouterr().err
    assert main(["render", str(tmp_path / "missing.toml"), "-o", str(tmp_path / "x.png")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["render", str(SCENES / "quad.toml"), "-o", str(tmp_path / "nodir" / "x.png")]) == 2


@pytest.mark.gl
def test_console_script_runs_in_a_fresh_process(tmp_path):
    """The installed entry point, stderr quiet when not a terminal, no traceback on errors."""
    out = tmp_path / "q.png"
    ok = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(SCENES / "quad.toml"), "-o", str(out), "--stats"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert ok.returncode == 0, ok.stderr
    assert ok.stderr == "" and out.exists()
    # the process ends without the interpreter's teardown (bsrt.__main__.run): all written first
    assert json.loads(ok.stdout)["pixels"] == 64 * 64
    with Image.open(out) as picture:
        assert picture.size == (64, 64) and np.ptp(np.asarray(picture)) > 0  # not one flat colour
    bad = _write(tmp_path, "[camera]\neye = [0, 0, 0]\n")
    fail = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(bad), "-o", str(tmp_path / "b.png")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert fail.returncode == 2
    assert fail.stderr.startswith("bsrt: error: bad.toml: camera.look_at: missing")
    assert "Traceback" not in fail.stderr


@pytest.mark.gl
def test_doctor_reports_the_gl_renderer(capsys):
    assert main(["doctor"]) == 0
    out = capsys.readouterr().out
    assert "OpenGL renderer:" in out and "OK" in out


@pytest.mark.gl
def test_outputs_get_ordinary_permissions(tmp_path):
    """Written atomically, but with the usual mode (0o666 less the umask), not a temp file's 0o600."""
    import os

    out = tmp_path / "q.png"
    assert main(["render", str(SCENES / "quad.toml"), "-o", str(out), "--width", "8", "--height", "8"]) == 0
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask


def test_version(capsys):
    import bsrt

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"bsrt {bsrt.__version__}\n"  # "bsrt 0.2.0"


NEGATIVE_CAMERA = [("--camera-eye", "-1.5,-4,0.5"), ("--camera-look-at", "-0.25,0,-0.125"), ("--camera-up", "-0.1,0,1")]


@pytest.mark.gl
@pytest.mark.parametrize("command", ["render", "map"])
def test_vector_options_take_negative_first_components(tmp_path, command):
    """`--camera-eye -1.5,-4,0.5` (argparse alone takes '-1.5,...' for an option) gives
    the same picture as `--camera-eye=-1.5,-4,0.5`, and not the scene's own camera."""

    def run(name, camera):
        out = tmp_path / name
        assert main([command, str(SCENES / "quad.toml"), "-o", str(out), *camera]) == 0
        return np.asarray(Image.open(out))

    separate = run("separate.png", [arg for option, value in NEGATIVE_CAMERA for arg in (option, value)])
    joined = run("joined.png", [f"{option}={value}" for option, value in NEGATIVE_CAMERA])
    default = run("default.png", [])
    assert np.array_equal(separate, joined)
    assert not np.array_equal(separate, default)
    # abbreviated options and '-.5'-style numbers too
    short = run("short.png", ["--camera-e", "-1.5,-4,.5", "--camera-l", "-.25,0,-.125", "--camera-u", "-.1,0,1"])
    assert np.array_equal(short, joined)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--camera-eye", "-1,a,3"], "argument --camera-eye: expected three numbers like 1,2,3, got '-1,a,3'"),
        (["--camera-look-at", "-1,2"], "argument --camera-look-at: expected three numbers like 1,2,3, got '-1,2'"),
        (["--camera-up", "-inf,0,1"], "argument --camera-up: expected three numbers like 1,2,3, got '-inf,0,1'"),
        (["--camera-eye"], "argument --camera-eye: expected one argument"),
    ],
)
def test_malformed_vectors_exit_2_with_one_message(tmp_path, capsys, args, message):
    out = tmp_path / "x.png"
    with pytest.raises(SystemExit) as exc:
        main(["render", str(SCENES / "quad.toml"), "-o", str(out), *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert errors == [f"bsrt render: error: {message}"], err
    assert not out.exists()


@pytest.mark.parametrize("fov", ["-5", "-1e3", "-.5"])
def test_negative_fov_is_refused_with_one_message(tmp_path, capsys, fov):
    out = tmp_path / "x.png"
    assert main(["render", str(SCENES / "quad.toml"), "-o", str(out), "--fov", fov]) == 2
    err = capsys.readouterr().err
    assert err == f"bsrt: error: --fov: must be between 0 and 180 degrees, got {float(fov):g}\n"
    assert not out.exists()


def test_negative_values_are_joined_only_to_a_preceding_long_option():
    from bsrt.cli import _join_negative_values as join

    assert join(["render", "s.toml", "--camera-eye", "-1,-2,3", "--fov", "-5"]) == [
        "render",
        "s.toml",
        "--camera-eye=-1,-2,3",
        "--fov=-5",
    ]
    assert join(["--camera-eye=-1,2,3", "-4"]) == ["--camera-eye=-1,2,3", "-4"]  # already has its value
    assert join(["-o", "-1.png"]) == ["-o", "-1.png"]  # short options are left to argparse
    assert join(["--width", "-x"]) == ["--width", "-x"]  # not a number: argparse's own error
    assert join(["--", "--camera-eye", "-1,2,3"]) == ["--", "--camera-eye", "-1,2,3"]  # after '--': untouched


@pytest.mark.gl
def test_negative_vectors_in_a_fresh_process(tmp_path):
    """The console entry point (sys.argv, not an argument list) joins them too."""
    out = tmp_path / "q.png"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "bsrt",
            "render",
            str(SCENES / "quad.toml"),
            "-o",
            str(out),
            "--camera-look-at",
            "-4281,19153,5738",
            "--camera-eye",
            "-4281,19149,5738",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert out.exists()
    version = subprocess.run([sys.executable, "-m", "bsrt", "--version"], capture_output=True, text=True, timeout=60)
    assert version.returncode == 0 and version.stdout.startswith("bsrt ")
