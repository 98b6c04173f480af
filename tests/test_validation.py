"""Bad input at the edge (issue #16): every case gets exit code 2, exactly one
line on stderr naming the file and the key (or line, or entity), no
traceback and no output file; the legal extremes render.

Each case is a hand-made file run through the real command line in a child
process (`python -m bsrt.cli`), as a user would.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_io import BILINEAR_128, iges_text

import bsrt
from bsrt import cli, validate
from bsrt.errors import InputError
from bsrt.io import load_model

ROOT = Path(__file__).resolve().parent.parent
QUAD = (ROOT / "scenes" / "quad.toml").read_text()
BPT = "1\n1 1\n0 0 0\n0 1 0\n1 0 0\n1 1 0\n"  # the unit square z = 0


def bsrt_cli(*args, env=None, cwd=None) -> subprocess.CompletedProcess:
    environ = dict(os.environ, PYTHONPATH=str(ROOT))
    environ.update(env or {})
    return subprocess.run(
        [sys.executable, "-m", "bsrt", *map(str, args)],
        capture_output=True,
        text=True,
        env=environ,
        cwd=cwd,
        timeout=300,
    )


def refused(path: Path, *words: str, env=None, extra=(), named=True) -> str:
    """Render ``path``; assert exit 2, one stderr line holding ``words`` (and the file's name unless the
    fault is an option or the environment: ``named=False``), no traceback, no warning, no image."""
    out = path.parent / "out"
    out.mkdir(exist_ok=True)
    run = bsrt_cli("render", path, "-o", out / "image.png", *extra, env=env)
    lines = run.stderr.splitlines()
    assert run.returncode == 2, run.stderr
    assert len(lines) == 1 and lines[0].startswith("bsrt: error: "), run.stderr
    for word in (path.name, *words) if named else words:
        assert word in lines[0], lines[0]
    assert "Traceback" not in run.stderr and "Warning" not in run.stderr
    assert list(out.iterdir()) == []
    return lines[0]


def scene(tmp_path: Path, old: str, new: str, text: str = QUAD, name: str = "bad.toml") -> Path:
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return path


# ---------------------------------------------------------------------------
# Silently wrong images


def test_tolerance_below_float64_is_refused_with_the_smallest_usable_value(tmp_path):
    path = scene(tmp_path, 'method = "newton"', 'method = "newton"\ntolerance = 1e-17')
    line = refused(path, "render.tolerance", "1e-17", "smallest usable value is 2e-14")
    # 64 float64 steps of the largest coordinate (the eye's 4) over the diagonal 2 sqrt(2)
    assert validate.FLOAT_STEPS * np.finfo(float).eps * 4 / (2 * 2**0.5) == pytest.approx(2.0e-14, rel=0.01), line


@pytest.mark.gl
def test_the_smallest_usable_tolerance_finds_every_hit(tmp_path):
    """The quad fills a closed-form pixel block at 64 x 64 (44 x 44 = 1936 pixels) at the floor as at 1e-9."""
    quad = bsrt.load(ROOT / "scenes" / "quad.toml")
    floor = validate.smallest_tolerance([s.geometry for s in quad.surfaces], quad.camera.eye)
    assert floor == pytest.approx(2.0e-14, rel=0.01)
    for tolerance in (1e-9, floor):
        hits = bsrt.render(quad, width=64, height=64, tolerance=tolerance).aovs()["hit"]
        assert int(hits.sum()) == 1936


def test_a_scene_too_far_for_float64_names_the_eye(tmp_path):
    path = scene(tmp_path, "eye = [0.0, -4.0, 0.0]", "eye = [0.0, -9e14, 0.0]")
    refused(path, "camera.eye", "float64 cannot resolve")


# ---------------------------------------------------------------------------
# Input at fault, not an internal error


def test_coordinate_near_1e308_is_refused(tmp_path):
    path = scene(tmp_path, "[[1.0, 0.0, -1.0], [1.0, 0.0, 1.0]]", "[[1e308, 0.0, -1.0], [1.0, 0.0, 1.0]]")
    refused(path, "surface[0].points", "1e+15")


def test_scale_near_1e308_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(QUAD + "\n[surface.transform]\nscale = 1e308\n")
    refused(path, "surface[0].transform.scale")


def test_translation_that_moves_points_out_of_range_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(QUAD + "\n[surface.transform]\ntranslate = [1e15, 0, 0]\nscale = 2\n")
    refused(path, "surface[0].transform", "out of range")


def test_iges_124_entry_near_1e308_is_refused(tmp_path):
    path = tmp_path / "big124.igs"
    path.write_text(iges_text([(124, [1e308, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], 0, 0), (128, BILINEAR_128, 1, 0)]))
    refused(path, "entity 124 (DE 1)", "a matrix entry 1e+308 is too large")


def test_iges_124_chain_overflowing_when_composed_is_refused(tmp_path):
    scale = [1e15, 0, 0, 0, 0, 1e15, 0, 0, 0, 0, 1e15, 0]
    entities = [(124, scale, 2 * k - 1 if k else 0, 0) for k in range(30)] + [(128, BILINEAR_128, 59, 0)]
    path = tmp_path / "compose.igs"
    path.write_text(iges_text(entities))
    refused(path, "entity 124", "composed transformation matrix overflows")


def test_fov_of_5e_324_is_refused(tmp_path):
    refused(scene(tmp_path, "fov = 40.0", "fov = 5e-324"), "camera.fov", "at least 0.001")


def test_fov_override_below_the_limit_is_refused_for_a_model(tmp_path):
    path = tmp_path / "square.bpt"
    path.write_text(BPT)
    refused(path, "--fov: must be at least 0.001 degrees", extra=("--fov", "1e-300"), named=False)


def test_width_beyond_int64_is_refused(tmp_path):
    refused(scene(tmp_path, "width = 64", "width = 1000000000000000000000000000000"), "film.width", "65536")


def test_spp_beyond_int64_is_refused(tmp_path):
    path = scene(tmp_path, 'method = "newton"', 'method = "newton"\nspp = 100000000000000000000000000000')
    refused(path, "render.spp", "at most 256")


def test_film_that_needs_more_memory_than_the_machine_is_refused():
    with pytest.raises(InputError, match=r"^film: 65536 x 65536 pixels would need about 515 GB"):
        if validate.physical_memory() >= 515e9:
            raise AssertionError("this machine has over 515 GB: the case does not apply")
        validate.film(65536, 65536)


def test_toml_nested_50000_deep_is_refused(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("x = " + "[" * 50000 + "]" * 50000 + "\n" + QUAD)
    refused(path, "invalid TOML", "nested too deeply")


@pytest.mark.gl
def test_a_chain_of_1500_iges_124_transforms_renders(tmp_path):
    """Legal IGES: each 124 moves by 0.001 along x, so the chain moves the unit square by 1.5."""
    move = [1, 0, 0, 0.001, 0, 1, 0, 0, 0, 0, 1, 0]
    entities = [(124, move, 2 * k - 1 if k else 0, 0) for k in range(1500)] + [(128, BILINEAR_128, 2999, 0)]
    path = tmp_path / "chain.igs"
    path.write_text(iges_text(entities))
    model = load_model(path)
    assert np.allclose(model.surfaces[0].points[:, :, 0], [[1.5, 1.5], [2.5, 2.5]])
    run = bsrt_cli("render", path, "-o", tmp_path / "chain.png", "--width", 32, "--height", 32)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert (tmp_path / "chain.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_iges_124_loop_is_refused(tmp_path):
    move = [1, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0]
    path = tmp_path / "loop.igs"
    path.write_text(iges_text([(124, move, 3, 0), (124, move, 1, 0), (128, BILINEAR_128, 1, 0)]))
    refused(path, "refer to each other in a loop")


def test_import_name_over_255_characters_is_refused(tmp_path):
    path = tmp_path / "long.toml"
    path.write_text(QUAD.split("[[surface]]")[0] + '[[import]]\nfile = "' + "a" * 300 + '.bpt"\n')
    refused(path, "import[0].file", "File name too long")


def test_egl_device_index_that_is_not_a_number_is_refused(tmp_path):
    path = tmp_path / "quad.toml"
    path.write_text(QUAD)
    line = refused(path, env={"GLCONTEXT_DEVICE_INDEX": "abc"}, named=False)
    assert "GLCONTEXT_DEVICE_INDEX" in line and "'abc'" in line
    doctor = bsrt_cli("doctor", env={"BSRT_EGL_DEVICE": "abc"})  # the same one line, not an internal error
    assert doctor.returncode == 2 and doctor.stderr.splitlines() == [
        "bsrt: error: environment variable BSRT_EGL_DEVICE: expected an EGL device index (0, 1, ...), got 'abc'"
    ], doctor.stderr


# ---------------------------------------------------------------------------
# Wrong types


@pytest.mark.parametrize(
    "old, new, words",
    [
        ("degree = [1, 1]", "degree = [true, true]", ("surface[0].degree", "two whole numbers")),
        (
            "knots_u = [0.0, 0.0, 1.0, 1.0]",
            'knots_u = ["0", "0", "1", "1"]',
            ("surface[0].knots_u", "expected numbers"),
        ),
        (
            "[[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0]]",
            "[[true, 0.0, -1.0], [-1.0, 0.0, 1.0]]",
            ("surface[0].points", "expected numbers, got True"),
        ),
        ("degree = [1, 1]", "degree = [26, 1]", ("surface[0].degree", "at most 25")),
    ],
    ids=["boolean degrees", "string knots", "boolean point", "degree over 25"],
)
def test_wrong_types_in_scene_files_are_refused(tmp_path, old, new, words):
    refused(scene(tmp_path, old, new), *words)


@pytest.mark.parametrize(
    "name, text, words",
    [
        ("digits.bpt", BPT.replace("1 1\n", "１ 1\n", 1), (":2:", "'１'")),
        (
            "digits.nurbs",
            "uOrder 2\nvOrder 2\nuDimension ２\nvDimension 2\nuKnot [0 0 1 1]\nvKnot [0 0 1 1]\n"
            "controlPoint [0 0 0, 1 0 0, 0 1 0, 1 1 0]\n",
            (":3:", "'２'"),
        ),
        ("digits.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 ٠\n", (":4:", "'٠'")),
    ],
    ids=["bpt", "nurbs", "obj"],
)
def test_unicode_digits_in_model_files_are_refused(tmp_path, name, text, words):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    refused(path, *words)


def test_unicode_digits_in_iges_are_refused(tmp_path):
    path = tmp_path / "digits.igs"
    text = iges_text([(128, BILINEAR_128, 0, 0)])
    path.write_text(text.replace("128,1,1,1,1,", "128,1,1,1,１,", 1), encoding="utf-8")
    refused(path, "entity 128 (DE 1)", "'１'")


def test_weights_spanning_more_than_1e12_are_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(QUAD.rstrip() + "\nweights = [[1e-7, 1.0], [1.0, 1e6]]\n")
    refused(path, "surface[0].weights", "1e+12 times the smallest")


# ---------------------------------------------------------------------------
# Clear messages


def test_eye_at_1e300_names_the_eye_not_the_up_vector(tmp_path):
    line = refused(scene(tmp_path, "eye = [0.0, -4.0, 0.0]", "eye = [0.0, -1e300, 0.0]"), "camera.eye", "1e+15")
    assert "parallel" not in line


def test_surface_that_is_not_an_array_of_tables_names_the_file(tmp_path):
    path = tmp_path / "surfx.toml"
    path.write_text('surface = "x"\n' + QUAD.split("[[surface]]")[0])
    refused(path, "surfx.toml: surface: expected an array of tables")


def test_iges_range_within_1e_9_past_the_knots_says_so(tmp_path):
    path = tmp_path / "u0u1.igs"
    path.write_text(iges_text([(128, BILINEAR_128[:-4] + [1.0000000005, 1.000000001, 0, 1], 0, 0)]))
    line = refused(path, "entity 128 (DE 1)", "U0 U1", "covers no part of the knot domain [0, 1]")
    assert "points" not in line


@pytest.mark.gl
@pytest.mark.parametrize("name, text", [("bom.toml", QUAD), ("bom.bpt", BPT)])
def test_a_utf8_byte_order_mark_is_accepted_in_scene_and_model_files(tmp_path, name, text):
    path = tmp_path / name
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    run = bsrt_cli("render", path, "-o", tmp_path / "bom.png", "--width", 16, "--height", 16)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert (tmp_path / "bom.png").is_file()


def test_info_refuses_a_model_format_for_a_scene(tmp_path):
    path = tmp_path / "quad.toml"
    path.write_text(QUAD)
    run = bsrt_cli("info", path, "--format", "obj")
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.splitlines() == [f"bsrt: error: {path}: --format: only for model files; a .toml file is a scene"]


def test_render_refuses_a_model_format_for_a_scene(tmp_path):
    """--format is not silently ignored for a scene file (the CLI and bsrt.load share the loader)."""
    path = tmp_path / "quad.toml"
    path.write_text(QUAD)
    run = bsrt_cli("render", path, "--format", "bez", "-o", tmp_path / "out.png")
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.splitlines() == ["bsrt: error: --format: only for model files; quad.toml is a scene file (.toml)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["quad.toml"]


@pytest.mark.parametrize("methods", [",,", " , "])
def test_bench_with_no_method_is_refused(methods):
    run = bsrt_cli("bench", "--methods", methods)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.splitlines() == [
        "bsrt: error: --methods: names no method (expected a comma-separated list of gradient, fast, newton, martin)"
    ]


@pytest.mark.parametrize(
    "value, traceback",
    [("0", False), ("", False), ("no", False), ("false", False), ("1", True), ("true", True), ("YES", True)],
)
def test_bsrt_debug_shows_a_traceback_only_for_1_true_yes(monkeypatch, capsys, value, traceback):
    def broken(args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setitem(cli.COMMANDS, "doctor", broken)
    monkeypatch.setenv("BSRT_DEBUG", value)
    if traceback:
        with pytest.raises(ZeroDivisionError):
            cli.main(["doctor"])
        return
    assert cli.main(["doctor"]) == 1
    assert capsys.readouterr().err == (
        "bsrt: internal error: ZeroDivisionError: a bug (set BSRT_DEBUG=1 for a traceback)\n"
    )


# ---------------------------------------------------------------------------
# The legal extremes render without a warning


@pytest.mark.gl
@pytest.mark.parametrize(
    "old, new",
    [
        ("[[surface]]", "[[surface]]\ntransform = { scale = 1e14 }"),
        ("fov = 40.0", "fov = 0.001"),
        ("fov = 40.0", "fov = 179.9"),
        ('method = "newton"', 'method = "newton"\nmax_iterations = 10000\nmax_depth = 16\nspp = 2\ntolerance = 1.0'),
        ("intensity = 20.0", "intensity = 1e15"),
    ],
    ids=["scale 1e14", "fov 0.001", "fov 179.9", "top limits", "intensity 1e15"],
)
def test_extreme_but_accepted_values_render_silently(tmp_path, old, new):
    path = scene(tmp_path, old, new)
    if "scale = 1e14" in new:  # the camera and the key light move with the scene
        path.write_text(path.read_text().replace("-4.0", "-4e14"))
    run = bsrt_cli("render", path, "-o", tmp_path / "out.png", "--width", 16, "--height", 16)
    assert run.returncode == 0 and run.stderr == "", run.stderr


# ---------------------------------------------------------------------------
# The Python API checks as the scene file does


@pytest.mark.parametrize(
    "overrides, message",
    [
        (
            {"spp": 10**29},
            "spp: must be at most 256 (see Limits in docs/scene-format.md), got 100000000000000000000000000000",
        ),
        ({"width": 0}, "width: expected a whole number >= 1, got 0"),
        (
            {"max_iterations": 10_001},
            "max_iterations: must be at most 10000 (see Limits in docs/scene-format.md), got 10001",
        ),
        ({"fov": 1e-9}, "fov: must be at least 0.001 degrees (see Limits in docs/scene-format.md), got 1e-09"),
        (
            {"camera_eye": (0.0, -1e300, 0.0)},
            "camera_eye: value 1 (-1e+300) is beyond +-1e+15 (see Limits in docs/scene-format.md)",
        ),
        ({"camera_eye": (True, -4.0, 0.0)}, "camera_eye: expected numbers, got True"),
    ],
)
def test_api_overrides_are_checked_at_load(overrides, message):
    with pytest.raises(InputError) as exc:
        bsrt.load(ROOT / "scenes" / "quad.toml", **overrides)
    assert str(exc.value) == message


def test_api_tolerance_below_float64_is_refused_at_render():
    quad = bsrt.load(ROOT / "scenes" / "quad.toml")
    with pytest.raises(InputError, match=r"^quad.toml: render.tolerance: 1e-17 is below .* is 2e-14$"):
        bsrt.render(quad, width=8, height=8, tolerance=1e-17)


def test_map_command_checks_camera_overrides_too(tmp_path):
    """`bsrt map` does not go through the render options: the overrides are checked when loading."""
    for option, value, words in (
        ("--fov", "1e-300", "--fov: must be at least 0.001 degrees"),
        ("--camera-eye", "0,-1e300,0", "--camera-eye: value 1 (-1e+300) is beyond +-1e+15"),
    ):
        run = bsrt_cli("map", ROOT / "scenes" / "quad.toml", "-o", tmp_path / "map.png", option, value)
        assert run.returncode == 2 and len(run.stderr.splitlines()) == 1 and words in run.stderr, run.stderr
        assert not (tmp_path / "map.png").exists()


def test_automatic_camera_beyond_the_limit_names_the_model(tmp_path):
    """A model at the coordinate limit whose automatic eye would sit past it (found by the CLI fuzz):
    framing the square from x = -1e15 to 1 puts the eye at x = -1.78e15, beyond +-1e15."""
    path = tmp_path / "edge.bpt"
    path.write_text("1\n1 1\n-1e15 0 0\n-1e15 1 0\n1 0 0\n1 1 0\n")
    refused(path, "the automatic camera.eye", "beyond +-1e+15")
