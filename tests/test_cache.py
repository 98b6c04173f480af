"""The converted-model cache (bsrt/io/cache.py): real files, real OpenCASCADE, real processes.

Each test gets its own cache folder (BSRT_CACHE_DIR under tmp_path); the
session's default one is set in conftest.py, never the user's ~/.cache.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import textwrap
from io import StringIO
from pathlib import Path

import numpy as np
import OCP  # noqa: F401  -- the extra must be installed: fail, never skip
import pytest
from OCP.BRepAdaptor import BRepAdaptor_Curve
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.GeomAbs import GeomAbs_Circle
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
from OCP.TopAbs import TopAbs_EDGE
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS

import bsrt
from bsrt.cli import main
from bsrt.io import cache, load_model
from bsrt.progress import Progress

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "tests" / "data" / "models"
AS1 = MODELS / "step" / "pythonocc-core" / "as1-oc-214.stp"  # 160 faces, colours, an assembly
ASMO = MODELS / "iges" / "overtureframework" / "asmo.igs"  # bsrt's own IGES reader


@pytest.fixture
def folder(tmp_path, monkeypatch) -> Path:
    """This test's own cache folder (not created: the cache creates it)."""
    where = tmp_path / "cache"
    monkeypatch.setenv("BSRT_CACHE_DIR", str(where))
    return where


@pytest.fixture(scope="module")
def step_bytes(tmp_path_factory) -> bytes:
    """A small STEP part written by OpenCASCADE: a box with a filleted hole (planes, a
    cylinder, tori; trimmed faces)."""
    box = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 40.0, 30.0, 20.0).Shape()
    drill = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 15, -5), gp_Dir(0, 0, 1)), 6.0, 30.0).Shape()
    cut = BRepAlgoAPI_Cut(box, drill).Shape()
    fillet = BRepFilletAPI_MakeFillet(cut)
    explorer = TopExp_Explorer(cut, TopAbs_EDGE)
    while explorer.More():
        edge = (getattr(TopoDS, "Edge", None) or TopoDS.Edge_s)(explorer.Current())
        if BRepAdaptor_Curve(edge).GetType() == GeomAbs_Circle:
            fillet.Add(2.0, edge)
        explorer.Next()
    path = tmp_path_factory.mktemp("step") / "part.step"
    writer = STEPControl_Writer()
    writer.Transfer(fillet.Shape(), STEPControl_AsIs)
    assert writer.Write(str(path)) == IFSelect_RetDone
    return path.read_bytes()


@pytest.fixture
def step(tmp_path, step_bytes) -> Path:
    path = tmp_path / "part.step"
    path.write_bytes(step_bytes)
    return path


def entries(where: Path) -> list[Path]:
    return sorted(where.glob("*" + cache.SUFFIX)) if where.is_dir() else []


def assert_same(a, b, where="model"):
    """Equal field by field, arrays bit for bit (dtype and shape too), over dataclasses, lists,
    tuples and dicts: a new field of Model, BSplineSurface, TrimLoop or TrimCurve is compared
    without a change here. Model.load (how it was loaded) is not part of the model."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            if f.compare:
                assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape, where
        assert np.array_equal(a, b, equal_nan=True), where
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, dict):
        assert type(a) is type(b) and list(a) == list(b), where
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    else:
        assert type(a) is type(b) and a == b, f"{where}: {a!r} != {b!r}"


def run_python(code: str, env_cache: Path, *args) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), BSRT_CACHE_DIR=str(env_cache))
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *map(str, args)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )


# ---------------------------------------------------------------------------
# Hits and misses


def test_second_load_of_a_real_step_part_comes_from_the_cache_and_is_equal(folder):
    first = load_model(AS1)
    assert first.load.cached is False and first.load.faces == (160, 160)
    assert len(entries(folder)) == 1
    second = load_model(AS1)
    assert second.load.cached is True and second.load.faces is None
    assert len(second.surfaces) == 160 and len(second.colors) == 160 and any(s.trims for s in second.surfaces)
    assert_same(first, second)  # surfaces (knots, points, weights, trims), names, colours, warnings, skipped
    assert_same(load_model(AS1, cache=False), second)
    assert second.load.seconds < first.load.seconds


def test_bsrt_own_iges_reader_is_cached_too(folder):
    first = load_model(ASMO)
    second = load_model(ASMO)
    assert (first.load.cached, second.load.cached) == (False, True)
    assert first.warnings or first.skipped or first.surfaces  # a real file, read in full
    assert_same(first, second)


def test_one_changed_byte_misses(folder, step):
    first = load_model(step)
    data = bytearray(step.read_bytes())
    at = data.index(b"FILE_NAME")  # the header's file name and date: any byte there keeps the part
    at = data.index(b"'", at) + 1
    data[at] = ord("x") if data[at] != ord("x") else ord("y")
    step.write_bytes(bytes(data))
    second = load_model(step)
    assert (first.load.cached, second.load.cached) == (False, False)
    assert len(entries(folder)) == 2
    assert_same(first, second)  # the same part, read again
    assert load_model(step).load.cached is True


def test_the_key_has_the_format(folder, tmp_path):
    path = tmp_path / "asmo.igs"
    shutil.copy(ASMO, path)
    assert load_model(path, "iges").load.cached is False
    occt = load_model(path, "occt")  # the same file through OpenCASCADE: another entry
    assert occt.load.cached is False and len(entries(folder)) == 2
    assert load_model(path, "occt").load.cached is True


@pytest.mark.parametrize("which", ["step", "iges"])
def test_a_copy_in_another_folder_is_a_hit_with_its_own_path(folder, tmp_path, step, which):
    """The key has the file's name, not its folder (a batch worker's unpacked copy): the
    readers of the cached formats name the folder only in Model.path, so the copy's model
    from the cache is the one a fresh read gives, bit for bit."""
    source = step if which == "step" else ASMO
    assert load_model(source).load.cached is False
    other = tmp_path / "elsewhere" / "deeper" / source.name
    other.parent.mkdir(parents=True)
    shutil.copy(source, other)
    cached = load_model(other)
    assert cached.load.cached is True and cached.path == str(other)
    assert_same(load_model(other, cache=False), cached)
    assert load_model(source).path == str(source)


def test_the_small_text_formats_are_not_cached(folder):
    model = load_model(MODELS / "bezier-teaset" / "qt3d" / "teapot.bez")
    assert model.load.cached is False and not folder.exists()


# ---------------------------------------------------------------------------
# Bypass, damage, concurrency, an unwritable folder, eviction


def test_no_cache_bypasses_and_writes_nothing(folder, step, capsys):
    assert load_model(step, cache=False).load.cached is False
    assert bsrt.load(step, cache=False).loads[0].cached is False
    assert main(["info", "--no-cache", str(step)]) == 0
    assert not folder.exists()
    assert "(read: " in capsys.readouterr().out
    load_model(step)
    assert len(entries(folder)) == 1
    assert load_model(step, cache=False).load.cached is False  # an entry exists: still bypassed


@pytest.mark.parametrize("damage", ["truncate", "flip-payload", "flip-header", "empty", "garbage"])
def test_a_damaged_entry_is_rebuilt_with_a_note(folder, step, capsys, damage):
    first = load_model(step)
    (entry,) = entries(folder)
    data = bytearray(entry.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "flip-payload":
        data[-10] ^= 0x40
    elif damage == "flip-header":
        data[len(cache.MAGIC) + 3] ^= 0x01  # a byte of the stored key
    elif damage == "empty":
        data = bytearray()
    else:
        data = bytearray(b"not a cache entry at all\n" * 10)
    entry.write_bytes(bytes(data))
    capsys.readouterr()
    again = load_model(step)
    err = capsys.readouterr().err
    assert again.load.cached is False
    assert err.count("\n") == 1 and err.startswith("bsrt: note: model cache: ") and "rebuilt it" in err
    assert again.warnings == first.warnings  # a note about the cache, not a warning about the model
    assert_same(first, again)
    third = load_model(step)  # the rewritten entry is whole
    assert third.load.cached is True and capsys.readouterr().err == ""
    assert_same(first, third)


def test_two_processes_loading_one_file_at_once_both_succeed(folder, tmp_path):
    """Two fresh processes convert the 160-face part at the same time and write the same
    entry; both succeed, and the entry is whole afterwards. Then eight processes rewrite
    one entry 40 times each, all at once."""
    code = """
        import sys
        from bsrt.io import load_model
        m = load_model(sys.argv[1])
        print(len(m.surfaces), m.load.cached)
    """
    env = dict(os.environ, PYTHONPATH=str(ROOT), BSRT_CACHE_DIR=str(folder))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", textwrap.dedent(code), str(AS1)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        for _ in range(2)
    ]
    results = [p.communicate(timeout=600) for p in procs]
    for p, (out, err) in zip(procs, results):
        assert p.returncode == 0, err
        assert out.split() == ["160", "False"] and err == ""
    (entry,) = entries(folder)
    reference = load_model(AS1, cache=False)
    cached = load_model(AS1)
    assert cached.load.cached is True
    assert_same(reference, cached)

    stress = """
        import sys
        from pathlib import Path
        from bsrt.io import cache, load_model
        model = load_model(sys.argv[1], cache=False)
        entry, key = Path(sys.argv[2]), bytes.fromhex(Path(sys.argv[2]).stem)
        for _ in range(40):
            cache._store(entry, key, model)
    """
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", textwrap.dedent(stress), str(AS1), str(entry)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(8)
    ]
    for p in procs:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0 and err == "", err
    assert entries(folder) == [entry] and not list(folder.glob(".*.tmp"))
    cached = load_model(AS1)
    assert cached.load.cached is True
    assert_same(reference, cached)


def test_an_unwritable_cache_folder_still_loads_with_one_note(tmp_path, step):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder\n")
    code = """
        import sys
        from bsrt.io import load_model
        for _ in range(3):
            m = load_model(sys.argv[1])
            print(len(m.surfaces), m.load.cached)
    """
    run = run_python(code, blocker / "cache", step)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split()[1::2] == ["False"] * 3
    assert run.stderr.count("bsrt: note: model cache: cannot write to") == 1 and run.stderr.count("\n") == 1


def test_the_folder_is_kept_under_its_size_limit_least_recently_used_first(folder, monkeypatch, step):
    load_model(step)
    (a,) = entries(folder)
    load_model(ASMO)
    (b,) = set(entries(folder)) - {a}
    os.utime(a, (1e9, 1e9))
    os.utime(b, (1.1e9, 1.1e9))
    assert load_model(step).load.cached is True  # a hit: a is now the most recently used
    stale = folder / ".0123456789abcdef-1-00000000.tmp"  # a killed writer's temporary file
    stale.write_bytes(b"partial")
    os.utime(stale, (1e9, 1e9))
    cache.evict(folder, a.stat().st_size + b.stat().st_size - 1)
    assert entries(folder) == [a] and not stale.exists()
    monkeypatch.setenv("BSRT_CACHE_MAX_MB", "0")  # every write evicts everything, itself included
    assert load_model(ASMO).load.cached is False
    assert entries(folder) == []


# ---------------------------------------------------------------------------
# The API, scene imports, progress, --stats, bsrt info


def test_scene_imports_and_the_api_use_the_cache(folder, tmp_path, step):
    scene_file = tmp_path / "scene.toml"
    scene_file.write_text('[camera]\neye = [100, -80, 60]\nlook_at = [20, 15, 10]\n\n[[import]]\nfile = "part.step"\n')
    first = bsrt.load(scene_file)
    second = bsrt.load(scene_file)
    assert [r.cached for r in first.loads + second.loads] == [False, True]
    assert first.loads[0].faces is not None and first.loads[0].faces[0] == first.loads[0].faces[1] > 0
    built = bsrt.Scene.build([bsrt.Import("part.step")], folder=tmp_path)
    assert built.loads[0].cached is True
    assert bsrt.Scene.build([bsrt.Import("part.step")], folder=tmp_path, cache=False).loads[0].cached is False
    assert bsrt.load(step).loads[0].cached is True
    assert len(entries(folder)) == 1


def test_the_load_stage_in_the_progress(folder, step):
    seen = []
    bsrt.load(step, progress=lambda stage, fraction: seen.append((stage, fraction)))
    assert seen and {s for s, _ in seen} == {"load"} and seen[-1][1] == 1.0
    assert [f for _, f in seen] == sorted(f for _, f in seen)
    from bsrt.scene.loading import load_input

    stream = StringIO()
    load_input(step, cache=False, progress=Progress(stream, lines=True))
    lines = stream.getvalue().splitlines()
    assert lines and all(line.startswith("bsrt: ") and "% load " in line and " faces, " in line for line in lines)


def test_the_bar_starts_again_after_the_load(folder):
    now = [0.0]
    stream = StringIO()
    bar = Progress(stream, lines=True, clock=lambda: now[0])
    now[0] = 4.0
    bar("load", 0.5, "80/160 faces")
    now[0] = 10.0
    bar("load", 1.0, "160/160 faces")
    bar("setup", 0.0)
    now[0] = 12.0
    bar("solve", 0.5)
    assert stream.getvalue().splitlines() == [
        "bsrt:  50% load 80/160 faces, 4.0 s, about 4.0 s left",
        "bsrt: 100% load 160/160 faces, 10 s",
        "bsrt:   0% setup, 10 s",
        "bsrt:  50% solve, 12 s, about 2.0 s left",  # the time left counts from the render's start
    ]


@pytest.mark.gl
def test_stats_show_the_load_stage(folder, tmp_path, step, capsys):
    for cached in (False, True):
        out = tmp_path / f"out-{cached}.png"
        assert (
            main(["render", str(step), "-o", str(out), "--width", "32", "--height", "24", "--stats", "--no-progress"])
            == 0
        )
        stats = json.loads(capsys.readouterr().out)
        load = stats["load"]
        assert load["cached"] is cached and load["files"] == 1 and 0 < load["seconds"] < 60
        assert 0 < load["framing_seconds"] < 60  # a model file alone: the automatic camera framed it
        if cached:
            assert "faces_converted" not in load
        else:
            assert load["faces_converted"] == load["faces_total"] > 0
    assert (
        main(
            [
                "render",
                str(step),
                "-o",
                str(tmp_path / "none.png"),
                "--width",
                "32",
                "--height",
                "24",
                "--stats",
                "--no-cache",
                "--no-progress",
            ]
        )
        == 0
    )
    assert json.loads(capsys.readouterr().out)["load"]["cached"] is False


def test_info_shows_the_load_time(folder, step, capsys):
    assert main(["info", str(step)]) == 0
    first = capsys.readouterr().out
    assert main(["info", str(step)]) == 0
    second = capsys.readouterr().out
    faces = len(load_model(step, cache=False).surfaces)
    assert "  loaded in " in first and f"(read: {faces} of {faces} faces converted)" in first
    assert "  loaded in " in second and "(from the model cache)" in second
    assert main(["info", "--no-cache", str(MODELS / "bezier-teaset" / "qt3d" / "teapot.bez")]) == 0
    assert "(read)" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["render", "map", "info", "preview", "batch", "animate"])
def test_every_command_that_loads_models_has_no_cache(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert "--no-cache" in capsys.readouterr().out
