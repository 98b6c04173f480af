"""The prepared-geometry cache (bsrt/rendering/prepared.py): a scene's patch table and hierarchy
found again by the content of its surfaces. Each test gets its own cache folder."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bsrt.kernels.hierarchy import BVHArrays
from bsrt.rendering import prepared
from bsrt.rendering.pipeline import Geometry
from bsrt.scene import parse_scene

SQUARE = [
    {"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]}
    for a, b in (([0.2, 0.2], [0.8, 0.2]), ([0.8, 0.2], [0.8, 0.8]), ([0.8, 0.8], [0.2, 0.8]), ([0.2, 0.8], [0.2, 0.2]))
]


def _scene(height: float = 0.5, material: str = "a"):
    """A curved sheet and a trimmed plate above it."""
    sheet = {
        "degree": [2, 2],
        "knots_u": [0, 0, 0, 1, 1, 1],
        "knots_v": [0, 0, 0, 1, 1, 1],
        "points": [[[i / 2, j / 2, 0.2 * ((i - 1) ** 2 - (j - 1) ** 2)] for j in range(3)] for i in range(3)],
        "material": material,
    }
    plate = {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[0, 0, height], [0, 1, height]], [[1, 0, height], [1, 1, height]]],
        "trim": [{"curves": SQUARE}],
    }
    return parse_scene(
        {
            "film": {"width": 8, "height": 8},
            "camera": {"eye": [0.5, -1.0, 2.0], "look_at": [0.5, 0.5, 0.0]},
            "material": [{"name": "a"}, {"name": "b"}],
            "surface": [sheet, plate],
        },
        "<test>",
    )


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("BSRT_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / "geometry"


def _same(a: Geometry, b: Geometry) -> None:
    """Every column of the two hierarchies and of the two patch tables is equal."""
    for name in BVHArrays._fields:
        np.testing.assert_array_equal(getattr(a.bvh.arrays, name), getattr(b.bvh.arrays, name), err_msg=name)
    for name in a.patches.arrays._fields:
        np.testing.assert_array_equal(getattr(a.patches.arrays, name), getattr(b.patches.arrays, name), err_msg=name)
    np.testing.assert_array_equal(a.material, b.material)
    assert a.diagonal == b.diagonal


def test_a_second_geometry_of_the_same_surfaces_comes_from_the_cache(folder, monkeypatch):
    scene = _scene()
    built = Geometry(scene, cache=True)
    assert len(list(folder.glob("*.geometry"))) == 1
    monkeypatch.setattr("bsrt.rendering.pipeline._prepare", _never)
    again = Geometry(_scene(), cache=True)  # another scene object, the same content
    _same(again, Geometry(scene))
    _same(again, built)
    assert again.bvh.patches is again.patches  # one table, shared as built
    # writable, as built: a read-only array is another type to numba (a kernel compiled again)
    assert all(a.flags.writeable for a in again.bvh.arrays) and all(a.flags.writeable for a in again.patches.arrays)


def test_the_surfaces_are_the_scenes_own_not_copies(folder):
    Geometry(_scene(), cache=True)
    scene = _scene()
    again = Geometry(scene, cache=True)
    assert all(a is s.geometry for a, s in zip(again.patches.surfaces, scene.surfaces, strict=True))


def test_other_surfaces_are_another_entry_and_materials_are_not_part_of_the_key(folder):
    Geometry(_scene(height=0.5), cache=True)
    moved = Geometry(_scene(height=0.6), cache=True)
    assert len(list(folder.glob("*.geometry"))) == 2
    _same(moved, Geometry(_scene(height=0.6)))
    recoloured = Geometry(_scene(material="b"), cache=True)
    assert len(list(folder.glob("*.geometry"))) == 2
    assert list(recoloured.material) == list(Geometry(_scene(material="b")).material)
    assert list(recoloured.material) != list(moved.material)


def test_without_the_cache_nothing_is_read_or_written(folder):
    assert Geometry(_scene(), cache=False).bvh.leaf_total > 0
    assert not folder.exists()


@pytest.mark.parametrize("damage", ["truncate", "flip", "garbage"])
def test_a_damaged_entry_is_rebuilt_with_one_note(folder, capsys, damage):
    Geometry(_scene(), cache=True)
    (entry,) = folder.glob("*.geometry")
    data = bytearray(entry.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "flip":
        data[-10] ^= 0xFF
    else:
        data = bytearray(b"not an entry at all")
    entry.write_bytes(bytes(data))
    capsys.readouterr()
    again = Geometry(_scene(), cache=True)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bsrt: note: geometry cache: ") and "rebuilt it" in err
    _same(again, Geometry(_scene()))
    assert len(entry.read_bytes()) > len(data) or damage == "flip"  # rewritten whole
    capsys.readouterr()
    Geometry(_scene(), cache=True)
    assert capsys.readouterr().err == ""


def test_a_payload_that_does_not_unpickle_is_rebuilt(folder, capsys):
    scene = _scene()
    surfaces = [s.geometry for s in scene.surfaces]
    key = prepared.entry_key(surfaces)
    folder.mkdir(parents=True)
    prepared.model_cache.write_entry(folder / (key.hex() + ".geometry"), key, b"\x80\x05junk", prepared.NOTES)
    again = Geometry(scene, cache=True)
    assert "cannot unpickle it" in capsys.readouterr().err
    _same(again, Geometry(_scene()))


def test_an_unwritable_folder_still_prepares_with_one_note(tmp_path, monkeypatch, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("BSRT_CACHE_DIR", str(blocker / "cache"))
    monkeypatch.setattr(prepared, "NOTES", prepared.model_cache.Notes("geometry", "built without the cache"))
    for _ in range(2):
        _same(Geometry(_scene(), cache=True), Geometry(_scene()))
    err = capsys.readouterr().err
    assert err.count("bsrt: note: geometry cache: cannot write to") == 1 and err.count("\n") == 1


def test_the_key_follows_every_field_of_the_surfaces():
    scene = _scene()
    surfaces = [s.geometry for s in scene.surfaces]
    key = prepared.entry_key(surfaces)
    assert prepared.entry_key([s.geometry for s in _scene().surfaces]) == key
    heavier = dataclasses.replace(surfaces[0], weights=np.ones(surfaces[0].shape))
    assert prepared.entry_key([heavier, surfaces[1]]) != key
    assert prepared.entry_key([surfaces[0], dataclasses.replace(surfaces[1], trims=())]) != key
    assert prepared.entry_key(surfaces[::-1]) != key


def _never(surfaces):
    raise AssertionError("built again")


@pytest.mark.gl
def test_the_python_api_uses_the_cache_unless_told_not_to(folder):
    import bsrt

    plain = bsrt.render(_scene(), cache=False)
    assert not folder.exists()
    cached = bsrt.render(_scene())
    assert len(list(folder.glob("*.geometry"))) == 1
    again = bsrt.render(_scene())
    np.testing.assert_array_equal(cached.pixels, plain.pixels)
    np.testing.assert_array_equal(again.pixels, plain.pixels)
