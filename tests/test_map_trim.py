"""The trim-aware preliminary map (map_mesh.TRIM_MAP) changes seeds, never hits.

Every render below is done twice on the real GL context, with the map's
trim handling on and off: the hits (hit or miss, surface, t within 1e-9 of
the scene's diagonal) must be identical; only the work to find them changes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bsrt import api
from bsrt.rendering import map_mesh, prelim
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene.camera import pixel_rays

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
IGES = [p for p in sorted((DATA / "iges").glob("*.igs")) if p.name != "curves.igs"]  # curves.igs: no surfaces
OCCT = [DATA / "models" / "iges" / "occt" / name for name in ("bearing.iges", "hammer.iges")]


def both(scene, monkeypatch):
    """(hits without, hits with the trim-aware map, stats without, stats with, diagonal)."""
    geometry = Geometry(scene)
    out = []
    for flag in (False, True):
        monkeypatch.setattr(map_mesh, "TRIM_MAP", flag)
        out.append(render(scene, RenderOptions.resolve(scene), geometry=geometry))
    return out[0], out[1], geometry.diagonal


def assert_same_hits(a, b, diagonal, name):
    """Same hit or miss and surface; t within 1e-9 of the diagonal, or (two roots
    of one surface, each within the solver's tolerance of it, found from other
    seeds) within 2 tolerance / |cos| of the ray's angle to the surface normal."""
    ha, hb = a.hits, b.hits
    differ = ha.hit != hb.hit
    assert not differ.any(), f"{name}: {int(differ.sum())} pixels hit with one map and miss with the other"
    both_hit = ha.hit & hb.hit
    surface = both_hit & (ha.surface != hb.surface)
    assert not surface.any(), f"{name}: {int(surface.sum())} pixels hit another surface"
    dt = np.abs(ha.t - hb.t)
    far = both_hit & (dt > 1e-9 * diagonal)
    if far.any():
        opts = a.options
        rays = pixel_rays(opts.camera, opts.width, opts.height)[far]
        cos = np.abs((a.normal[far] * rays).sum(axis=1))
        bound = 2.0 * opts.tolerance * diagonal / np.maximum(cos, 1e-300)
        worst = np.argmax(dt[far] / bound)
        assert (dt[far] <= bound).all(), (
            f"{name}: t differs by {dt[far][worst]:.3g} at |cos| {cos[worst]:.3g} (diagonal {diagonal:.3g})"
        )


@pytest.mark.parametrize("name", ["column", "quad", "water-lily", "bench-64"])
def test_untrimmed_scenes_render_the_same(ctx, monkeypatch, name):
    scene = api.load(ROOT / "scenes" / f"{name}.toml", width=96, height=96)
    a, b, diagonal = both(scene, monkeypatch)
    assert_same_hits(a, b, diagonal, name)
    assert a.stats["suspect"] == b.stats["suspect"]  # nothing to trim: the same map


@pytest.mark.parametrize("path", IGES, ids=lambda p: p.name)
def test_trimmed_iges_files_render_the_same(ctx, monkeypatch, path):
    scene = api.load(path, width=128, height=128)
    a, b, diagonal = both(scene, monkeypatch)
    assert_same_hits(a, b, diagonal, path.name)


@pytest.mark.parametrize("path", OCCT, ids=lambda p: p.name)
def test_cad_parts_render_the_same_with_fewer_trimmed_roots(ctx, monkeypatch, path):
    scene = api.load(path, width=192, height=192)
    a, b, diagonal = both(scene, monkeypatch)
    assert_same_hits(a, b, diagonal, path.name)
    # the map now shows the face one sees: fewer seeds land in trimmed-away parts
    assert b.stats["trimmed_roots"] < a.stats["trimmed_roots"]
    assert b.stats["suspect"] < a.stats["suspect"]


@pytest.mark.cad
def test_a_step_part_renders_the_same(ctx, monkeypatch, tmp_path):
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

    box = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 40.0, 30.0, 20.0).Shape()
    drill = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 15, -5), gp_Dir(0, 0, 1)), 6.0, 30.0).Shape()
    cut = BRepAlgoAPI_Cut(box, drill).Shape()
    fillet = BRepFilletAPI_MakeFillet(cut)
    explorer = TopExp_Explorer(cut, TopAbs_EDGE)
    while explorer.More():
        edge = (getattr(TopoDS, "Edge", None) or TopoDS.Edge_s)(explorer.Current())
        if BRepAdaptor_Curve(edge).GetType() == GeomAbs_Circle:  # the hole's two rims
            fillet.Add(2.0, edge)
        explorer.Next()
    writer = STEPControl_Writer()
    writer.Transfer(fillet.Shape(), STEPControl_AsIs)
    path = tmp_path / "box_with_filleted_hole.step"
    assert writer.Write(str(path)) == IFSelect_RetDone
    scene = api.load(path, width=160, height=160)
    a, b, diagonal = both(scene, monkeypatch)
    assert_same_hits(
        a, b, diagonal, path.name
    )  # (little is in front of a trimmed-away part here: the counts barely move)


def test_the_map_leaves_out_what_the_trims_remove(ctx, monkeypatch):
    """A plane with a small disc kept: its one tessellation cell is mostly
    trimmed away, and the map now shows the plane only around the disc."""
    scene = api.load(DATA / "iges" / "plane_circle_144.igs", width=128, height=128)
    patches = Geometry(scene).patches
    camera = RenderOptions.resolve(scene).camera
    covered = []
    for flag in (False, True):
        monkeypatch.setattr(map_mesh, "TRIM_MAP", flag)
        m = prelim.render_map(patches, camera, 128, 128)
        covered.append(int((m.surface >= 0).sum()))
    assert covered[1] < covered[0]


@pytest.mark.parametrize("path", OCCT + [p for p in IGES if "144" in p.name], ids=lambda p: p.name)
def test_the_per_fragment_trim_test_alone_renders_the_same(ctx, monkeypatch, path):
    """No cutting on the CPU: every triangle a trim curve crosses is drawn with
    shaders/prelim.glsl's per-fragment test (the fallback the cutting leaves
    for pieces still undecided at map_mesh.SUB_PIXELS)."""
    monkeypatch.setattr(map_mesh, "SUB_PIXELS", np.inf)
    scene = api.load(path, width=160, height=160)
    a, b, diagonal = both(scene, monkeypatch)
    assert_same_hits(a, b, diagonal, path.name)
    assert b.stats["trimmed_roots"] <= a.stats["trimmed_roots"]
