"""The Python API (bsrt/api.py, bsrt/adapters.py): scenes from arrays render exactly
as the same scene file, to_toml round-trips bit for bit, errors are the scene
format's, and Splipy and geomdl surfaces land where their own evaluators put them."""

from __future__ import annotations

import inspect
import io
import json
import math
import subprocess
import sys
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from conftest import MODELS
from PIL import Image

import bsrt
from bsrt.errors import InputError
from bsrt.geometry.bspline import evaluate
from bsrt.io import load_model
from bsrt.scene import scene_for_model

SCENES = Path(__file__).resolve().parents[1] / "scenes"
W = math.sqrt(0.5)  # 0.7071067811865476: the weight of a 90-degree arc's middle point


# ---------------------------------------------------------------------------
# helpers


def same_scene(a, b) -> None:
    """Every array of a and b equal bit for bit; materials, lights, film, render settings equal."""
    assert a.film == b.film and a.render == b.render
    assert a.materials == b.materials and a.lights == b.lights
    for f in ("eye", "look_at", "up"):
        np.testing.assert_array_equal(getattr(a.camera, f), getattr(b.camera, f), strict=True)
    assert (a.camera.fov, a.camera.fov_axis) == (b.camera.fov, b.camera.fov_axis)
    assert len(a.surfaces) == len(b.surfaces)
    for s, t in zip(a.surfaces, b.surfaces):
        assert (s.name, s.material) == (t.name, t.material)
        g, h = s.geometry, t.geometry
        assert g.degree == h.degree
        for f in ("knots_u", "knots_v", "points"):
            np.testing.assert_array_equal(getattr(g, f), getattr(h, f), strict=True)
        assert (g.weights is None) == (h.weights is None)
        if g.weights is not None:
            np.testing.assert_array_equal(g.weights, h.weights, strict=True)
        assert len(g.trims) == len(h.trims)
        for loop, other in zip(g.trims, h.trims):
            assert len(loop.curves) == len(other.curves)
            for c, d in zip(loop.curves, other.curves):
                assert c.degree == d.degree
                np.testing.assert_array_equal(c.knots, d.knots, strict=True)
                np.testing.assert_array_equal(c.points, d.points, strict=True)
                assert (c.weights is None) == (d.weights is None)
                if c.weights is not None:
                    np.testing.assert_array_equal(c.weights, d.weights, strict=True)


def toml_value(value) -> str:
    """A TOML value for numbers, strings and (nested) lists of them, as one would type it."""
    return json.dumps(value)


def scene_text(surface: dict, header: str = "") -> str:
    """A small scene file around one [[surface]] table (None values left out)."""
    lines = [header, "[camera]", "eye = [0.0, -4.0, 0.0]", "look_at = [0.0, 0.0, 0.0]", "", "[[surface]]"]
    for key, value in surface.items():
        if key == "trim":
            continue
        if value is not None:
            lines.append(f"{key} = {toml_value(value)}")
    for loop in surface.get("trim") or ():
        lines += ["[[surface.trim]]", "curves = ["]
        lines += [
            "  { " + ", ".join(f"{k} = {toml_value(v)}" for k, v in c.items() if v is not None) + " }," for c in loop
        ]
        lines.append("]")
    return "\n".join(lines) + "\n"


def load_text(tmp_path, text: str, name: str = "scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return bsrt.load(path)


# ---------------------------------------------------------------------------
# the package


def test_import_bsrt_loads_nothing_heavy():
    """`import bsrt` imports no NumPy, OpenGL or numba (the API loads on first use)."""
    code = (
        "import sys, time; t = time.perf_counter(); import bsrt; dt = time.perf_counter() - t; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('bsrt', 'numpy', 'moderngl', 'numba')), dt)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "['bsrt']"
    assert float(out[1]) < 0.05  # about 2 ms; generous for a busy machine


def test_the_api_names():
    for name in (
        "load",
        "render",
        "Scene",
        "Surface",
        "Camera",
        "Light",
        "Material",
        "Film",
        "Import",
        "RenderSettings",
        "RenderResult",
        "from_splipy",
        "from_geomdl",
        "InputError",
        "RenderError",
    ):
        assert hasattr(bsrt, name), name
    assert set(bsrt.__all__) == set(bsrt._LAZY) | set(bsrt._MODULES) | {"__version__", "render"}
    assert bsrt.InputError is InputError and bsrt.Material is bsrt.scene.Material
    with pytest.raises(AttributeError):
        bsrt.no_such_name  # noqa: B018 (the attribute lookup is the test)


def test_bsrt_render_is_the_api_and_the_pipeline_is_its_own_module():
    """bsrt.render(scene, ...) is the API's render; the pipeline is bsrt.rendering.pipeline."""
    import bsrt.rendering.pipeline as module
    from bsrt import api

    assert bsrt.render is api.render and module.Geometry.__name__ == "Geometry" and callable(module.render)


# ---------------------------------------------------------------------------
# scenes built in Python


def quad_parts():
    """scenes/quad.toml, built from arrays."""
    points = np.array([[[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0]], [[1.0, 0.0, -1.0], [1.0, 0.0, 1.0]]])
    knots = np.array([0.0, 0.0, 1.0, 1.0])
    surface = bsrt.Surface(degree=(1, 1), knots_u=knots, knots_v=knots, points=points, material="white", name="square")
    return dict(
        surfaces=[surface],
        camera=bsrt.Camera(eye=(0.0, -4.0, 0.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov=40.0),
        lights=[
            bsrt.Light.ambient(intensity=0.15),
            bsrt.Light.point((1.0, -4.0, 2.0), intensity=20.0),
            bsrt.Light.directional((0.5, 1.0, -0.5), intensity=0.3),
        ],
        materials=[bsrt.Material("white", color=(0.9, 0.9, 0.9), specular=0.1, shininess=10.0, reflectance=0.0)],
        film=bsrt.Film(64, 64, (0.05, 0.05, 0.08)),
        render={"method": "newton"},
    )


def test_a_scene_from_arrays_renders_exactly_as_the_scene_file(ctx):
    parts = quad_parts()
    built = bsrt.Scene.build(parts.pop("surfaces"), **parts)
    loaded = bsrt.load(SCENES / "quad.toml")
    same_scene(built, loaded)
    a, b = bsrt.render(built), bsrt.render(loaded)
    assert a.pixels.shape == (64, 64, 3) and a.pixels.dtype == np.uint8
    np.testing.assert_array_equal(a.pixels, b.pixels, strict=True)
    for key, value in b.aovs().items():
        np.testing.assert_array_equal(a.aovs()[key], value, strict=True)
    assert a.aovs()["hit"].sum() > 0 and a.stats["pixels"] == 64 * 64
    assert ctx.error == "GL_NO_ERROR"


def test_render_keywords_override_for_one_render(ctx):
    scene = bsrt.load(SCENES / "quad.toml")
    small = bsrt.render(scene, width=32, height=16, method="gradient", spp=4)
    assert small.pixels.shape == (16, 32, 3) and small.options.method == "gradient" and small.options.spp == 4
    assert scene.film.width == 64 and scene.render.method == "newton"  # the scene is unchanged
    moved = bsrt.render(scene, camera=bsrt.Camera((1.0, -4.0, 0.5), (0.0, 0.0, 0.0)))
    same = bsrt.render(bsrt.load(SCENES / "quad.toml", camera_eye=(1.0, -4.0, 0.5), camera_look_at=(0, 0, 0)))
    np.testing.assert_array_equal(moved.pixels, same.pixels)
    assert not np.array_equal(moved.pixels, bsrt.render(scene).pixels)
    by_path = bsrt.render(SCENES / "quad.toml")
    np.testing.assert_array_equal(by_path.pixels, bsrt.render(scene).pixels)


def test_render_reports_progress_to_a_function(ctx):
    calls = []
    bsrt.render(bsrt.load(SCENES / "quad.toml"), width=16, height=16, progress=lambda s, f: calls.append((s, f)))
    stages = [s for s, _ in calls]
    assert stages[0] == "map" and stages[-1] == "done" and {"solve", "shade"} <= set(stages)
    assert calls[-1][1] == 1.0 and all(0.0 <= f <= 1.0 for _, f in calls)
    assert [f for _, f in calls] == sorted(f for _, f in calls)


def test_render_result_shows_as_a_png(ctx):
    result = bsrt.render(bsrt.load(SCENES / "quad.toml"), width=24, height=20)
    data = result._repr_png_()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    image = Image.open(io.BytesIO(data))
    assert image.mode == "RGB" and image.size == (24, 20)
    np.testing.assert_array_equal(np.asarray(image), result.pixels)


@pytest.mark.gl
def test_render_takes_what_scene_build_takes_and_refuses_the_rest():
    square = bsrt.Surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[0, 0, 0], [0, 0, 1]], [[1, 0, 0], [1, 0, 1]]])
    built = bsrt.render(bsrt.Scene.build([square]), width=24, height=16)
    for given in (square, [square], (square,)):  # one surface, or a list: framed and lit as Scene.build does
        np.testing.assert_array_equal(bsrt.render(given, width=24, height=16).pixels, built.pixels)
    assert repr(built).startswith("<RenderResult 24x16, 1 spp, newton, ") and len(repr(built)) < 120
    with pytest.raises(TypeError, match="cannot make a bsrt.Surface from int"):
        bsrt.render(42)
    with pytest.raises(InputError, match=r"^width: expected a whole number >= 1, got 0$"):
        bsrt.render(bsrt.load(SCENES / "quad.toml"), width=0)
    with pytest.raises(InputError, match=r"^<python>: camera.fov: must be < 180, got 180$"):
        bsrt.render(bsrt.load(SCENES / "quad.toml"), camera=bsrt.Camera((0, -4, 0), (0, 0, 0), fov=180))
    with pytest.raises(TypeError, match="progress"):
        bsrt.render(bsrt.load(SCENES / "quad.toml"), progress="yes")


def trimmed_rational_scene():
    """A rational quarter cylinder with a hole (a circle of two rational arcs), a coloured
    bicubic with a transform, a material given as an object, and an unusual name."""
    cyl = bsrt.Surface(
        degree=(2, 1),
        knots_u=[0, 0, 0, 1, 1, 1],
        knots_v=[0, 0, 1, 1],
        points=np.array([[[1, 0, 0], [1, 0, 1]], [[1, 1, 0], [1, 1, 1]], [[0, 1, 0], [0, 1, 1]]], dtype=float),
        weights=np.array([[1.0, 1.0], [W, W], [1.0, 1.0]]),
        material=bsrt.Material("brass", color=(0.8, 0.6, 0.2), specular=0.5, shininess=64.0, reflectance=0.25),
        name='cyl "quoted" \\ é',
        trims=[
            [
                {
                    "degree": 2,
                    "knots": [0, 0, 0, 1, 1, 1],
                    "points": [[0.75, 0.5], [0.75, 0.75], [0.5, 0.75]],
                    "weights": [1.0, W, 1.0],
                },
                {
                    "degree": 2,
                    "knots": [0, 0, 0, 1, 1, 1],
                    "points": [[0.5, 0.75], [0.25, 0.75], [0.25, 0.5]],
                    "weights": [1.0, W, 1.0],
                },
                {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0.25, 0.5], [0.75, 0.5]]},
            ],
            [
                {
                    "degree": 1,
                    "knots": [0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0],
                    "points": np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]),
                },
            ],
        ],
    )
    rng = np.random.default_rng(7)
    grid = np.stack(np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-1, 1, 4), indexing="ij"), axis=-1)
    bumpy = bsrt.Surface(
        degree=(3, 2),
        knots_u=[0, 0, 0, 0, 0.3, 1, 1, 1, 1],
        knots_v=[0, 0, 0, 0.6, 1, 1, 1],
        points=np.concatenate([grid, rng.normal(0, 0.3, (5, 4, 1))], axis=-1),
        color=(0.2, 0.5, 0.3),
        transform={"scale": 0.5, "rotate": [0, 0, 1, 30], "translate": [0.1, 0.2, -0.4]},
    )
    return bsrt.Scene.build(
        [cyl, bumpy],
        bsrt.Camera((3.0, 2.5, 1.5), (0.5, 0.5, 0.3), fov=35.0, fov_axis="x"),
        lights=[bsrt.Light.point((4.0, 3.0, 5.0), color=(1.0, 0.9, 0.8), intensity=40.0)],
        film=bsrt.Film(40, 30, (0.1, 0.2, 0.3)),
        render={"max_depth": 2, "tolerance": 1e-10},
    )


@pytest.mark.parametrize("source", ["quad", "column", "water-lily", "built", "iges-trimmed", "teapot"])
def test_to_toml_reads_back_to_the_same_scene(tmp_path, source):
    if source == "built":
        scene = trimmed_rational_scene()
    elif source == "iges-trimmed":
        scene = bsrt.load(MODELS / "iges" / "occt" / "hammer.iges", width=50, height=40)
    elif source == "teapot":
        scene = bsrt.load(MODELS / "bezier-teaset" / "qt3d" / "teapot.bez", camera_up=(0, 1, 0))
    else:
        scene = bsrt.load(SCENES / f"{source}.toml")
    text = scene.to_toml()
    again = load_text(tmp_path, text)
    same_scene(scene, again)

    def body(toml):  # the header comments name the source and its notes
        return toml[toml.index("\n[film]") :]

    assert body(again.to_toml()) == body(text)


def test_save_writes_the_scene_file(tmp_path):
    scene = trimmed_rational_scene()
    scene.save(tmp_path / "out.toml")
    same_scene(scene, bsrt.load(tmp_path / "out.toml"))
    assert scene.surfaces[0].name == 'cyl "quoted" \\ é' and scene.surfaces[0].geometry.is_trimmed
    with pytest.raises(InputError, match="must end in .toml"):
        scene.save(tmp_path / "out.txt")
    with pytest.raises(InputError, match="does not exist"):
        scene.save(tmp_path / "missing" / "out.toml")


def test_the_written_file_is_plain_toml_with_every_table():
    text = trimmed_rational_scene().to_toml()
    assert text.startswith("# Scene file (bsrt scene format version 1), written by bsrt ")
    for table in ("[film]", "[camera]", "[render]", "[[material]]", "[[light]]", "[[surface]]", "[[surface.trim]]"):
        assert f"\n{table}\n" in text
    assert 'name = "cyl \\"quoted\\" \\\\ é"' in text
    assert "weights = [\n  [1.0, 1.0],\n  [0.7071067811865476, 0.7071067811865476],\n" in text


def test_build_without_camera_or_lights_frames_like_a_model_file():
    surfaces = [bsrt.load(SCENES / "bench-64.toml").surfaces[0]]
    scene = bsrt.Scene.build(surfaces, film=bsrt.Film(80, 60))
    from bsrt.io import Model

    auto = scene_for_model(Model("x", [s.geometry for s in surfaces], ["a"]), 80, 60)
    for f in ("eye", "look_at", "up"):
        np.testing.assert_array_equal(getattr(scene.camera, f), getattr(auto.camera, f))
    assert scene.lights == auto.lights and len(scene.lights) == 4  # the studio rig: ambient, key, fill, rim
    assert bsrt.Scene.build(surfaces, lights=[]).lights == ()


def test_imports_and_surfaces_from_other_scenes(tmp_path):
    teapot = MODELS / "bezier-teaset" / "qt3d" / "teapot-spout.bez"
    quad = bsrt.load(SCENES / "quad.toml")
    scene = bsrt.Scene.build(
        [quad.surfaces[0], bsrt.Import(teapot, material="white", transform={"scale": 0.1}), quad.surfaces[0].geometry],
        quad.camera,
        materials=quad.materials,
        lights=quad.lights,
    )
    model = load_model(teapot)
    assert len(scene.surfaces) == 2 + len(model.surfaces)
    assert scene.surfaces[0].name == "square" and scene.surfaces[-1].name == "surface-1"
    np.testing.assert_array_equal(scene.surfaces[1].geometry.points, model.surfaces[0].points * 0.1)
    np.testing.assert_array_equal(scene.surfaces[-1].geometry.points, quad.surfaces[0].geometry.points)
    # a SceneSurface brings its geometry and name; its material is an index into its own scene's
    assert scene.materials[scene.surfaces[0].material].name == "default"
    assert {s.material for s in scene.surfaces[1:-1]} == {0} and scene.materials[0].name == "white"
    with pytest.raises(InputError, match=r"^<python>: import\[0\].file: no such file: "):
        bsrt.Scene.build([bsrt.Import("nope.bez")], quad.camera)


def test_lights_and_cameras_equal_the_scene_formats_own():
    loaded = bsrt.load(SCENES / "quad.toml")
    assert loaded.lights[1] == bsrt.Light.point((1.0, -4.0, 2.0), intensity=20.0)
    assert bsrt.Light.ambient(intensity=0.15) == loaded.lights[0]
    assert loaded.lights[0] == bsrt.Light.ambient(intensity=0.15)  # both ways round
    assert bsrt.Light.directional((0.5, 1.0, -0.5), intensity=0.3) == bsrt.Light(
        "directional", intensity=0.3, direction=(0.5, 1.0, -0.5)
    )
    assert bsrt.Light.ambient() != bsrt.Light.ambient(intensity=0.5)
    camera = bsrt.Camera([0, -4, 0], np.zeros(3))
    assert camera.eye.dtype == np.float64 and camera.up.tolist() == [0.0, 0.0, 1.0] and camera.fov == 40.0
    moved = replace(camera, fov=20.0)
    assert type(moved) is bsrt.Camera and moved.fov == 20.0


# ---------------------------------------------------------------------------
# errors: the scene format's messages


def base_surface():
    """A valid bicubic: 8 x 4 points."""
    pts = np.stack(np.meshgrid(np.arange(8.0), np.arange(4.0), indexing="ij"), axis=-1)
    return {
        "degree": [3, 3],
        "knots_u": [0.0, 0, 0, 0, 1, 2, 3, 4, 5, 5, 5, 5],
        "knots_v": [0.0, 0, 0, 0, 1, 1, 1, 1],
        "points": np.concatenate([pts, np.zeros((8, 4, 1))], axis=-1).tolist(),
    }


SQUARE_LOOP = [
    {
        "degree": 1,
        "knots": [0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0],
        "points": [[1.0, 0.2], [4.0, 0.2], [4.0, 0.8], [1.0, 0.8], [1.0, 0.2]],
    }
]

BAD_SURFACES = {
    "knot count": {"knots_u": [0.0, 0, 0, 0, 1, 2, 3, 4, 5, 5, 5]},
    "decreasing knots": {"knots_v": [0.0, 0, 0, 0, 1, 0.5, 1, 1]},
    "points not 3-D": {"points": np.zeros((8, 4, 2)).tolist()},
    "too few points": {"points": np.zeros((3, 4, 3)).tolist()},
    "degree zero": {"degree": [0, 3]},
    "degree not whole": {"degree": [2.5, 3]},
    "weights shape": {"weights": np.ones((4, 8)).tolist()},
    "weights zero": {"weights": np.concatenate([np.ones((7, 4)), np.zeros((1, 4))]).tolist()},
    "interior knot repeated": {"knots_u": [0.0, 0, 0, 0, 1, 1, 1, 1, 5, 5, 5, 5]},
    "unknown material": {"material": "gold"},
    "material and color": {"material": "gold", "color": [1.0, 0.0, 0.0]},
    "negative color": {"color": [1.0, -0.5, 0.0]},
    "open trim loop": {"trim": [[{**SQUARE_LOOP[0], "points": SQUARE_LOOP[0]["points"][:4] + [[1.0, 0.3]]}]]},
    "trim outside domain": {
        "trim": [[{**SQUARE_LOOP[0], "points": [[1.0, 0.2], [6.0, 0.2], [6.0, 0.8], [1.0, 0.8], [1.0, 0.2]]}]]
    },
    "trim knot count": {"trim": [[{**SQUARE_LOOP[0], "knots": [0.0, 1.0, 2.0]}]]},
}


@pytest.mark.parametrize("case", BAD_SURFACES)
def test_bad_arrays_give_the_messages_of_the_same_scene_file(tmp_path, case):
    table = {**base_surface(), **BAD_SURFACES[case]}
    with pytest.raises(InputError) as from_file:
        load_text(tmp_path, scene_text(table), "bad.toml")
    arrays = {k: np.array(v) if k in ("knots_u", "knots_v", "points", "weights") else v for k, v in table.items()}
    trims = arrays.pop("trim", ())
    with pytest.raises(InputError) as from_python:
        bsrt.Scene.build([bsrt.Surface(**arrays, trims=trims)], bsrt.Camera((0, -4, 0), (0, 0, 0)))
    file_where, file_message = str(from_file.value).split(": ", 1)
    python_where, python_message = str(from_python.value).split(": ", 1)
    assert (file_where, python_where) == ("bad.toml", "<python>")
    assert python_message == file_message
    assert python_message.startswith("surface[0].")


def test_the_valid_base_surface_and_trim_build():
    scene = bsrt.Scene.build([bsrt.Surface(**base_surface(), trims=[SQUARE_LOOP])], bsrt.Camera((0, -4, 0), (0, 0, 0)))
    assert scene.surfaces[0].geometry.is_trimmed and scene.surfaces[0].name == "surface-0"


def test_the_knot_count_message(tmp_path):
    table = {**base_surface(), **BAD_SURFACES["knot count"]}
    with pytest.raises(InputError) as exc:
        bsrt.Scene.build([bsrt.Surface(**table)], bsrt.Camera((0, -4, 0), (0, 0, 0)))
    assert str(exc.value) == "<python>: surface[0].knots_u: expected 12 values (8 points + degree 3 + 1), got 11"


@pytest.mark.parametrize(
    "python, toml",
    [
        (dict(camera=bsrt.Camera((1, 2, 3), (1, 2, 3))), "[camera]\neye = [1, 2, 3]\nlook_at = [1, 2, 3]\n"),
        (dict(camera=bsrt.Camera((0, 0, 5), (0, 0, 0))), "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\n"),
        (
            dict(camera=bsrt.Camera((0, -4, 0), (0, 0, 0), fov_axis="z")),
            '[camera]\neye = [0, -4, 0]\nlook_at = [0, 0, 0]\nfov_axis = "z"\n',
        ),
        (dict(lights=[bsrt.Light.point((1.0, 2.0))]), '[[light]]\nkind = "point"\nposition = [1.0, 2.0]\n'),
        (dict(lights=[bsrt.Light("spot")]), '[[light]]\nkind = "spot"\n'),
        (
            dict(lights=[bsrt.Light.directional((0, 0, 0))]),
            '[[light]]\nkind = "directional"\ndirection = [0.0, 0.0, 0.0]\n',
        ),
        (dict(film=bsrt.Film(0, 10)), "[film]\nwidth = 0\nheight = 10\n"),
        (dict(render={"method": "bisection"}), '[render]\nmethod = "bisection"\n'),
        (dict(render={"spp": 2, "samples": 4}), "[render]\nspp = 2\nsamples = 4\n"),
        (
            dict(materials=[bsrt.Material("a"), bsrt.Material("a")]),
            '[[material]]\nname = "a"\n[[material]]\nname = "a"\n',
        ),
        (dict(materials=[bsrt.Material("a", specular=2.0)]), '[[material]]\nname = "a"\nspecular = 2.0\n'),
    ],
)
def test_bad_parts_give_the_messages_of_the_same_scene_file(tmp_path, python, toml):
    surface = {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[0, 0, 0], [0, 0, 1]], [[1, 0, 0], [1, 0, 1]]],
    }
    camera = "" if "camera" in python else "[camera]\neye = [0, -4, 0]\nlook_at = [0, 0, 0]\n"
    text = toml + "\n" + camera + "\n" + scene_text(surface).split("[[surface]]", 1)[1].join(["[[surface]]", ""])
    with pytest.raises(InputError) as from_file:
        load_text(tmp_path, text, "bad.toml")
    parts = {"camera": bsrt.Camera((0, -4, 0), (0, 0, 0)), "lights": [], **python}
    with pytest.raises(InputError) as from_python:
        bsrt.Scene.build([bsrt.Surface(**surface)], **parts)
    assert str(from_file.value).startswith("bad.toml: ") and str(from_python.value).startswith("<python>: ")
    assert str(from_python.value).split(": ", 1)[1] == str(from_file.value).split(": ", 1)[1]


# ---------------------------------------------------------------------------
# load() and its overrides


def test_load_overrides_become_part_of_the_scene():
    scene = bsrt.load(
        SCENES / "quad.toml",
        width=32,
        height=24,
        method="martin",
        spp=2,
        map="rgba8",
        tolerance=1e-8,
        max_iterations=10,
        max_depth=0,
        camera_eye=(0, -5, 1),
        camera_up=np.array([0, 0, 2]),
        fov=30,
    )
    assert (scene.film.width, scene.film.height) == (32, 24)
    assert scene.render == bsrt.RenderSettings("martin", "rgba8", 1e-8, 10, 2, 0)
    assert scene.camera.eye.tolist() == [0, -5, 1] and scene.camera.up.tolist() == [0, 0, 2] and scene.camera.fov == 30
    assert isinstance(scene, bsrt.Scene) and isinstance(scene, bsrt.scene.Scene)
    assert repr(scene) == "Scene('quad.toml', 1 surface, 3 lights, 32x24, martin, spp=2)"
    assert bsrt.Scene.load(SCENES / "quad.toml").film.width == 64


def test_a_model_file_gets_the_automatic_camera():
    path = MODELS / "bezier-teaset" / "qt3d" / "teacup.bez"
    scene = bsrt.load(path, width=64, height=48, camera_up=(0, 1, 0), fov=30)
    auto = scene_for_model(load_model(path), 64, 48, fov=30, up=(0.0, 1.0, 0.0))
    same_scene(scene, auto)
    assert scene.path == str(path)
    explicit = bsrt.load(path, format="bez", camera_eye=(10, 0, 0), camera_look_at=(0, 0, 0))
    assert explicit.camera.eye.tolist() == [10, 0, 0] and (explicit.film.width, explicit.film.height) == (512, 512)


@pytest.mark.parametrize(
    "overrides, message",
    [
        (dict(width=0), "width: expected a whole number >= 1, got 0"),
        (dict(height=2.5), "height: expected a whole number >= 1, got 2.5"),
        (dict(spp=True), "spp: expected a whole number >= 1, got True"),
        (dict(max_depth=-1), "max_depth: expected a whole number >= 0, got -1"),
        (dict(method="bisection"), "method: expected one of gradient, fast, newton, martin, got 'bisection'"),
        (dict(map="rgb"), "map: expected one of float, rgba8, got 'rgb'"),
        (dict(tolerance=2.0), "tolerance: expected a number in (0, 1], got 2.0"),
        (dict(fov=180), "fov: must be between 0 and 180 degrees, got 180"),
        (dict(camera_eye=(1, 2)), "camera_eye: expected three finite numbers like (1, 2, 3), got (1, 2)"),
        (dict(camera_look_at="0,0,0"), "camera_look_at: expected three finite numbers like (1, 2, 3), got '0,0,0'"),
        (
            dict(camera_up=(0, -1, 0)),
            "camera_eye / camera_look_at / camera_up: the view direction must not be zero or parallel to up",
        ),
        (dict(format="bez"), "format: only for model files; quad.toml is a scene file (.toml)"),
    ],
)
def test_bad_overrides_name_the_keyword(overrides, message):
    with pytest.raises(InputError) as exc:
        bsrt.load(SCENES / "quad.toml", **overrides)
    assert str(exc.value) == message


def test_load_of_a_missing_or_unknown_file(tmp_path):
    with pytest.raises(InputError, match=r"nope.toml: no such file$"):
        bsrt.load(tmp_path / "nope.toml")
    with pytest.raises(InputError, match=r"nope.bez: no such file$"):
        bsrt.load(tmp_path / "nope.bez")
    (tmp_path / "x.xyz").write_text("")
    with pytest.raises(InputError, match="unknown model file extension '.xyz'"):
        bsrt.load(tmp_path / "x.xyz")
    with pytest.raises(InputError, match=r"^camera_up: must not be the zero vector$"):
        bsrt.load(MODELS / "bezier-teaset" / "qt3d" / "teacup.bez", camera_up=(0, 0, 0))
    with pytest.raises(TypeError):
        bsrt.load(SCENES / "quad.toml", colour=1)


# ---------------------------------------------------------------------------
# Splipy and geomdl


def quarter_cylinder_toml(tmp_path, name):
    """A rational quarter cylinder (radius 1, height 1, axis z), written by hand."""
    return load_text(
        tmp_path,
        """
[film]
width = 48
height = 40

[camera]
eye = [3.0, 2.5, 1.5]
look_at = [0.5, 0.5, 0.4]
fov = 45.0

[[light]]
kind = "ambient"

[[surface]]
degree = [2, 1]
knots_u = [0, 0, 0, 1, 1, 1]
knots_v = [0, 0, 1, 1]
points = [
  [[1.0, 0.0, 0.0], [1.0, 0.0, 1.0]],
  [[1.0, 1.0, 0.0], [1.0, 1.0, 1.0]],
  [[0.0, 1.0, 0.0], [0.0, 1.0, 1.0]],
]
weights = [[1.0, 1.0], [0.7071067811865476, 0.7071067811865476], [1.0, 1.0]]
""",
        name,
    )


def cylinder_points_homogeneous():
    """(3, 2, 4): the quarter cylinder's (w x, w y, w z, w), [i along u, j along v]."""
    p = np.array([[[1, 0, 0], [1, 0, 1]], [[1, 1, 0], [1, 1, 1]], [[0, 1, 0], [0, 1, 1]]], dtype=float)
    w = np.array([[1.0, 1.0], [W, W], [1.0, 1.0]])
    return np.concatenate([p * w[..., None], w[..., None]], axis=-1)


def splipy_quarter_cylinder():
    from splipy import BSplineBasis, Surface

    h = cylinder_points_homogeneous()
    flat = [h[i, j] for j in range(2) for i in range(3)]  # Splipy's flat order: the first index fastest
    return Surface(BSplineBasis(3, [0, 0, 0, 1, 1, 1]), BSplineBasis(2, [0, 0, 1, 1]), flat, rational=True)


def geomdl_quarter_cylinder():
    from geomdl import NURBS

    s = NURBS.Surface()
    s.degree_u, s.degree_v = 2, 1
    h = cylinder_points_homogeneous()
    s.set_ctrlpts(h.reshape(-1, 4).tolist(), 3, 2)  # geomdl's flat order: v fastest; weighted points
    s.knotvector_u, s.knotvector_v = [0, 0, 0, 1, 1, 1], [0, 0, 1, 1]
    return s


BICUBIC_U = [0.0, 0.0, 0.0, 0.0, 0.15, 0.5, 0.55, 1.0, 1.0, 1.0, 1.0]
BICUBIC_V = [-1.0, -1.0, -1.0, -1.0, 0.25, 2.0, 2.0, 2.0, 2.0]


def bicubic_points():
    """(7, 5, 3): a bumpy non-uniform bicubic, nu != nv (a transposition would show)."""
    rng = np.random.default_rng(11)
    x, y = np.meshgrid(np.linspace(-1.2, 1.2, 7), np.linspace(-0.9, 0.9, 5), indexing="ij")
    return np.stack([x, y, np.round(rng.normal(0.0, 0.25, x.shape), 3)], axis=-1)


def bicubic_toml(tmp_path, name):
    pts = bicubic_points()
    rows = ",\n".join(
        "  [" + ", ".join("[" + ", ".join(repr(float(c)) for c in p) + "]" for p in row) + "]" for row in pts
    )
    return load_text(
        tmp_path,
        f"""
[film]
width = 48
height = 40

[camera]
eye = [1.5, -3.0, 2.5]
look_at = [0.0, 0.0, 0.0]

[[light]]
kind = "ambient"

[[surface]]
degree = [3, 3]
knots_u = {BICUBIC_U}
knots_v = {BICUBIC_V}
points = [
{rows},
]
""",
        name,
    )


def geomdl_bicubic(normalize=False):
    from geomdl import BSpline

    s = BSpline.Surface(normalize_kv=normalize)  # geomdl maps knot vectors to [0, 1] unless told not to
    s.degree_u, s.degree_v = 3, 3
    s.set_ctrlpts(bicubic_points().reshape(-1, 3).tolist(), 7, 5)
    s.knotvector_u, s.knotvector_v = BICUBIC_U, BICUBIC_V
    return s


def geomdl_bicubic_normalised():
    return geomdl_bicubic(normalize=True)


def splipy_bicubic():
    from splipy import BSplineBasis, Surface

    pts = bicubic_points()
    flat = [pts[i, j] for j in range(5) for i in range(7)]
    return Surface(BSplineBasis(4, BICUBIC_U), BSplineBasis(4, BICUBIC_V), flat)


@pytest.mark.parametrize(
    "make, reference",
    [
        (splipy_quarter_cylinder, quarter_cylinder_toml),
        (geomdl_quarter_cylinder, quarter_cylinder_toml),
        (geomdl_bicubic, bicubic_toml),
        (splipy_bicubic, bicubic_toml),
    ],
)
def test_adapted_surfaces_render_the_hits_of_the_hand_written_scene(ctx, tmp_path, make, reference):
    hand = reference(tmp_path, "hand.toml")
    obj = make()
    adapted = bsrt.Scene.build([bsrt.Surface.from_object(obj)], hand.camera, lights=hand.lights, film=hand.film)
    a, b = bsrt.render(adapted).aovs(), bsrt.render(hand).aovs()
    diagonal = float(np.linalg.norm(np.ptp(hand.surfaces[0].geometry.points.reshape(-1, 3), axis=0)))
    assert b["hit"].sum() > 250
    np.testing.assert_array_equal(a["hit"], b["hit"])
    np.testing.assert_array_equal(a["surface"], b["surface"])
    hit = b["hit"]
    np.testing.assert_allclose(a["t"][hit], b["t"][hit], rtol=0, atol=1e-9 * diagonal)
    np.testing.assert_allclose(a["u"][hit], b["u"][hit], rtol=0, atol=1e-8)
    np.testing.assert_allclose(a["v"][hit], b["v"][hit], rtol=0, atol=1e-8)
    assert ctx.error == "GL_NO_ERROR"


def library_points(obj, u, v) -> np.ndarray:
    """(N, 3) points from the library's own evaluator."""
    if hasattr(obj, "evaluate_list"):  # geomdl
        return np.array(obj.evaluate_list(list(zip(u.tolist(), v.tolist()))))
    return np.asarray(obj.evaluate(u, v, tensor=False))  # splipy


def splipy_sphere():
    from splipy import surface_factory

    return surface_factory.sphere(r=2.0, center=(1.0, 0.0, -1.0))  # rational, periodic in one direction


def splipy_torus():
    from splipy import surface_factory

    return surface_factory.torus(minor_r=0.5, major_r=2.0)  # rational, periodic in both directions


def splipy_planar():
    from splipy import BSplineBasis, Surface

    rng = np.random.default_rng(3)
    flat = rng.normal(size=(4 * 2, 2))  # 2-D control points: z = 0; v: not clamped at its end
    return Surface(BSplineBasis(3, [0, 0, 0, 0.3, 1, 1, 1]), BSplineBasis(2, [0, 0, 0.5, 1]), flat)


def geomdl_nurbs_random():
    from geomdl import NURBS

    rng = np.random.default_rng(5)
    s = NURBS.Surface()
    s.degree_u, s.degree_v = 2, 3
    pts = rng.normal(size=(5 * 6, 3))
    w = rng.uniform(0.3, 3.0, (5 * 6, 1))
    s.set_ctrlpts(np.concatenate([pts * w, w], axis=1).tolist(), 5, 6)
    s.knotvector_u = [0, 0, 0, 0.2, 0.7, 1, 1, 1]
    s.knotvector_v = [0, 0, 0, 0, 0.4, 0.45, 1, 1, 1, 1]
    return s


@pytest.mark.parametrize(
    "make",
    [
        splipy_quarter_cylinder,
        splipy_bicubic,
        splipy_sphere,
        splipy_torus,
        splipy_planar,
        geomdl_quarter_cylinder,
        geomdl_bicubic,
        geomdl_bicubic_normalised,
        geomdl_nurbs_random,
    ],
)
def test_adapted_surfaces_evaluate_as_the_library_does(make):
    obj = make()
    surface = bsrt.Surface.from_object(obj).geometry()
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    rng = np.random.default_rng(1)
    u, v = rng.uniform(u0, u1, 200), rng.uniform(v0, v1, 200)
    u[:4], v[:4] = [u0, u1, u0, u1], [v0, v0, v1, v1]
    expected = library_points(obj, u, v)
    assert expected.shape[1] in (2, 3)
    expected = np.pad(expected, ((0, 0), (0, 3 - expected.shape[1])))
    scale = float(np.abs(expected).max())
    np.testing.assert_allclose(evaluate(surface, u, v)[0], expected, rtol=0, atol=1e-13 * scale)


def test_adapter_conventions():
    cyl = bsrt.from_splipy(splipy_quarter_cylinder(), name="cyl", color=(1, 0, 0))
    assert cyl.degree == (2, 1) and cyl.name == "cyl" and cyl.color == (1, 0, 0)
    np.testing.assert_array_equal(cyl.knots_u, [0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(cyl.weights, [[1.0, 1.0], [W, W], [1.0, 1.0]])
    np.testing.assert_array_equal(cyl.points[1], [[1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
    g = bsrt.from_geomdl(geomdl_bicubic())
    assert g.weights is None and np.shape(g.points) == (7, 5, 3)
    np.testing.assert_array_equal(g.points, bicubic_points())
    np.testing.assert_array_equal(g.knots_v, BICUBIC_V)
    normalised = bsrt.from_geomdl(geomdl_bicubic_normalised())  # u, v are then geomdl's, in [0, 1]
    np.testing.assert_allclose(normalised.knots_v, (np.array(BICUBIC_V) + 1.0) / 3.0, rtol=0, atol=1e-15)
    torus = bsrt.from_splipy(splipy_torus())
    assert np.shape(torus.points) == (8 + 1, 8 + 1, 3)  # periodic (C0): the first row repeated at the end
    with pytest.raises(TypeError, match="cannot make a bsrt.Surface from int"):
        bsrt.Surface.from_object(3)
    with pytest.raises(TypeError, match="expected a geomdl"):
        bsrt.from_geomdl(splipy_torus())


def test_splipy_trimmed_surface_brings_its_loops():
    from splipy import BSplineBasis, Curve, TrimmedSurface

    hole = [
        Curve(BSplineBasis(2, [0, 0, 1, 1]), [a, b])
        for a, b in [
            ((0.2, 0.2), (0.2, 0.8)),
            ((0.2, 0.8), (0.8, 0.8)),
            ((0.8, 0.8), (0.8, 0.2)),
            ((0.8, 0.2), (0.2, 0.2)),
        ]
    ]
    outer = [
        Curve(BSplineBasis(2, [0, 0, 1, 1]), [a, b])
        for a, b in [((0, 0), (1, 0)), ((1, 0), (1, 1)), ((1, 1), (0, 1)), ((0, 1), (0, 0))]
    ]
    trimmed = TrimmedSurface(
        BSplineBasis(2), BSplineBasis(2), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], loops=[outer, hole]
    )
    surface = bsrt.from_splipy(trimmed).geometry()
    assert len(surface.trims) == 2 and [len(loop.curves) for loop in surface.trims] == [4, 4]
    from bsrt.geometry.trim_table import kept

    keep = kept(surface, np.array([0.1, 0.5, 0.9, 0.5]), np.array([0.5, 0.5, 0.5, 0.1]))
    assert keep.tolist() == [True, False, True, True]


def test_geomdl_trims_are_refused_not_dropped():
    s = geomdl_bicubic()
    from geomdl import BSpline

    curve = BSpline.Curve()
    curve.degree = 1
    curve.ctrlpts = [[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9], [0.1, 0.1]]
    curve.knotvector = [0, 0, 0.25, 0.5, 0.75, 1, 1]
    s.trims = [curve]
    with pytest.raises(InputError, match="geomdl: the surface has trim curves"):
        bsrt.from_geomdl(s)
    assert bsrt.from_geomdl(s, trims=[]).trims == []


def test_surface_from_scene_surfaces_and_geometry():
    hammer = bsrt.load(MODELS / "iges" / "occt" / "hammer.iges")
    s = bsrt.Surface.from_object(hammer.surfaces[3])
    assert s.name == hammer.surfaces[3].name and len(s.trims) == len(hammer.surfaces[3].geometry.trims) > 0
    geometry = s.geometry()
    np.testing.assert_array_equal(geometry.points, hammer.surfaces[3].geometry.points)
    assert repr(s).startswith("Surface(degree=")
    renamed = bsrt.Surface.from_object(s, name="other")
    assert renamed.name == "other" and renamed.points is s.points
    for f in fields(bsrt.Surface):
        assert f.name in inspect.signature(bsrt.Surface).parameters


# ---------------------------------------------------------------------------
# the documented examples run


def python_blocks(text: str) -> list[str]:
    import re

    return re.findall(r"```python\n(.*?)```", text, re.DOTALL)


def test_the_readme_and_docs_examples_run(tmp_path, ctx, monkeypatch):
    root = Path(__file__).resolve().parents[1]
    readme = (root / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("\n## Python\n") : readme.index("\n## Documentation\n")]
    docs = python_blocks((root / "docs" / "python-api.md").read_text(encoding="utf-8"))
    (tmp_path / "scenes").symlink_to(root / "scenes")
    monkeypatch.chdir(tmp_path)
    for name, code in [("readme", python_blocks(section)[0]), ("docs", docs[0]), ("splipy", docs[2])]:
        exec(compile(code, f"<{name} example>", "exec"), {})
    for png, toml in [("bump.png", "bump.toml")]:
        again = bsrt.render(bsrt.load(tmp_path / toml))
        np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / png)), again.pixels)
    assert Image.open(tmp_path / "sphere.png").size == (256, 256)
    assert Image.open(tmp_path / "column.jpg").format == "JPEG"  # the README's: save() by the extension
    assert Image.open(tmp_path / "column.jpg").size == (320, 240)


def test_errors_in_pythons_idiom(tmp_path):
    assert issubclass(bsrt.InputError, ValueError)
    with pytest.raises(FileNotFoundError, match=r"missing\.toml: no such file$") as missing:
        bsrt.load(tmp_path / "missing.toml")
    assert isinstance(missing.value, bsrt.InputError) and missing.value.filename == str(tmp_path / "missing.toml")
    with pytest.raises(FileNotFoundError):
        bsrt.load(tmp_path / "missing.step")
    with pytest.raises(ValueError, match=r"^<python>: camera: expected a mapping \(a dict\) or the bsrt object$"):
        bsrt.Scene.build([], camera=5)
    with pytest.raises(ValueError, match=r"^<python>: no surfaces given \(nothing to render\)$"):
        bsrt.Scene.build([])


@pytest.mark.gl
def test_save_writes_the_format_its_extension_names_or_nothing(tmp_path):
    result = bsrt.render(bsrt.load(SCENES / "quad.toml", width=32, height=24))
    for name, kind in [("a.png", "PNG"), ("b.JPG", "JPEG"), ("c.jpeg", "JPEG"), ("d.webp", "WEBP")]:
        result.save(tmp_path / name)
        with Image.open(tmp_path / name) as image:
            assert (image.format, image.size) == (kind, (32, 24))
    with Image.open(tmp_path / "d.webp") as image:  # lossless
        np.testing.assert_array_equal(np.asarray(image.convert("RGB")), result.pixels)
    np.testing.assert_array_equal(np.asarray(result.to_pil()), result.pixels)
    for name in ("e.bmp", "f", "g.tiff"):
        with pytest.raises(ValueError, match="cannot tell the image format"):
            result.save(tmp_path / name)
        assert not (tmp_path / name).exists()


def test_the_package_ships_its_type_hints():
    assert (Path(bsrt.__file__).parent / "py.typed").is_file()
