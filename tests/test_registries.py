"""The registries are the one owner of their facts: the help text, the API,
the scene format, the docs and the errors all agree with them."""

from __future__ import annotations

import inspect
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest

import bsrt
from bsrt import api, doc_tables
from bsrt.batches.api import animate, batch
from bsrt.cli import _parser
from bsrt.errors import InputError
from bsrt.io.formats import BY_EXTENSION, READERS, format_choices
from bsrt.methods import METHODS
from bsrt.rendering.options import RenderOptions
from bsrt.scene import parse_scene
from bsrt.settings import SETTINGS, Film, RenderSettings

ROOT = Path(__file__).resolve().parents[1]
SQUARE = {
    "degree": [1, 1],
    "knots_u": [0, 0, 1, 1],
    "knots_v": [0, 0, 1, 1],
    "points": [[[-1, 0, -1], [-1, 0, 1]], [[1, 0, -1], [1, 0, 1]]],
}
CAMERA = {"eye": [0, -4, 0], "look_at": [0, 0, 0]}


def help_text(*command: str) -> str:
    parser = _parser()
    for name in command:
        parser = next(a for a in parser._actions if a.dest == "command").choices[name]
    return " ".join(parser.format_help().split())  # argparse wraps lines anywhere


@pytest.mark.parametrize("command", ["render", "map", "info", "preview", "batch", "animate"])
def test_help_names_every_model_extension_and_format(command):
    text = help_text(command)
    for ext in BY_EXTENSION:
        assert ext in text, (command, ext)
    if command not in ("batch", "animate"):  # they read the format from each file's extension
        assert "{" + ",".join(format_choices()) + "}" in text.replace(" ", "")


@pytest.mark.parametrize("command", ["render", "batch", "animate"])
def test_every_setting_is_a_flag_of_the_rendering_commands(command):
    text = help_text(command)
    for s in SETTINGS:
        assert s.flag in text, (command, s.flag)
    args = _parser().parse_args(
        [
            command,
            "in.toml",
            *(["-o", "x.png"] if command == "render" else ["--out", "d"]),
            "--max-depth",
            "0",
            "--background",
            "0.1,0.2,0.3",
            "--tolerance",
            "1e-8",
        ]
    )
    assert (args.max_depth, args.background, args.tolerance) == (0, (0.1, 0.2, 0.3), 1e-8)


def test_a_bad_flag_value_has_the_settings_own_message(capsys):
    with pytest.raises(SystemExit) as exit_:
        _parser().parse_args(["render", "in.toml", "-o", "x.png", "--spp", "0"])
    assert exit_.value.code == 2
    assert "argument --spp: expected a whole number >= 1, got 0" in capsys.readouterr().err


def test_the_api_keywords_and_dataclasses_are_the_settings():
    names = [s.name for s in SETTINGS]
    for function in (bsrt.load, bsrt.render):
        params = inspect.signature(function).parameters
        assert [n for n in params if n in names] == names, function.__name__
    assert [f.name for f in fields(Film)] + [f.name for f in fields(RenderSettings)] == names
    assert [f.name for f in fields(RenderOptions)] == names + ["camera"]
    assert Film().background == RenderOptions.resolve(bsrt.Scene.build([api.Surface(**SQUARE)])).background
    for function in (batch, animate):  # batches take every setting through **settings
        assert inspect.signature(function).parameters["settings"].kind is inspect.Parameter.VAR_KEYWORD


@pytest.mark.parametrize("setting", SETTINGS, ids=lambda s: s.name)
def test_each_setting_is_read_from_its_scene_key_and_checked_the_same_everywhere(setting):
    value = {
        "int": lambda: setting.choices[-1] if setting.choices else setting.lo + 1,
        "float": lambda: 1e-6,
        "color": lambda: [0.5, 0.25, 0.125],
        "choice": lambda: setting.choices[-1],
        "bool": lambda: not setting.default,
    }[setting.kind]()
    scene = parse_scene({"camera": CAMERA, setting.table: {setting.name: value}, "surface": [SQUARE]}, "s.toml")
    assert getattr(getattr(scene, setting.table), setting.name) == setting.check(value)
    bad = {"int": -1, "float": -1.0, "color": [1, 2], "choice": "nonsense", "bool": "yes"}[setting.kind]
    with pytest.raises(InputError) as from_file:
        parse_scene({"camera": CAMERA, setting.table: {setting.name: bad}, "surface": [SQUARE]}, "s.toml")
    with pytest.raises(InputError) as from_python:
        RenderOptions.resolve(scene, **{setting.name: bad})
    assert str(from_file.value) == f"s.toml: {setting.key}: " + str(from_python.value).split(": ", 1)[1]


def test_defaults_are_the_registrys_wherever_a_scene_comes_from(tmp_path):
    built = bsrt.Scene.build([api.Surface(**SQUARE)], api.Camera((0, -4, 0), (0, 0, 0)))
    from_file = parse_scene({"camera": CAMERA, "surface": [SQUARE]})
    model = bsrt.load(ROOT / "tests" / "data" / "patches.bpt")
    for scene in (built, from_file, model):
        assert scene.film == Film() and scene.render == RenderSettings()


def test_methods_registry_feeds_the_cli_the_scene_and_the_preview():
    assert _parser().parse_args(["render", "x.toml", "-o", "x.png", "--method", "martin"]).method == "martin"
    from bsrt.preview.bindings import BINDINGS

    assert [BINDINGS[str(k)] for k in range(1, len(METHODS) + 1)] == [("method", m) for m in METHODS]
    with pytest.raises(InputError, match="expected one of " + ", ".join(METHODS)):
        parse_scene({"camera": CAMERA, "render": {"method": "bisection"}, "surface": [SQUARE]})


def test_readers_registry_feeds_loading_imports_and_errors(tmp_path):
    from bsrt.io import load_model

    with pytest.raises(InputError, match="supported formats are " + ", ".join(sorted(READERS))):
        load_model(tmp_path / "x.bez", format="stl")
    with pytest.raises(InputError, match=r"expected one of 'auto', 'bez'"):
        parse_scene({"camera": CAMERA, "import": [{"file": "x.bez", "format": "stl"}]}, "s.toml", tmp_path)


@pytest.mark.gl  # doctor opens a context
def test_doctor_lists_every_reader():
    out = subprocess.run([sys.executable, "-m", "bsrt", "doctor"], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    for name in READERS:
        assert f"reader {name}:" in out.stdout
    for part in ("window:", "OpenCASCADE:", "Dask:"):  # each "ready (...)" or what is missing and the fix
        line = next(x for x in out.stdout.splitlines() if x.startswith(part))
        assert "ready" in line or "pip install" in line or "xvfb-run" in line, line


@pytest.mark.parametrize("page", sorted((ROOT / "docs").glob("*.md")), ids=lambda p: p.name)
def test_the_docs_generated_tables_are_current(page):
    text = page.read_text(encoding="utf-8")
    assert doc_tables.regenerate(text) == text, f"stale: run python -m bsrt.doc_tables {page.relative_to(ROOT)}"


def test_the_docs_carry_every_generated_table():
    found = [name for page in (ROOT / "docs").glob("*.md") for name in doc_tables.blocks(page.read_text())]
    assert sorted(found) == sorted(doc_tables.TABLES)
