"""bsrt.intersect and bsrt scan on STEP files, judged by closed forms and by OpenCASCADE (its
IntCurvesFace_ShapeIntersector and BRepExtrema distances: tests/occ_reference.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import OCP  # noqa: F401  -- the extra must be installed: fail, never skip
import pytest
from occ_reference import distance
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder, BRepPrimAPI_MakeHalfSpace
from OCP.gp import gp_Ax2, gp_Dir, gp_Lin, gp_Pln, gp_Pnt
from OCP.IFSelect import IFSelect_RetDone
from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Reader, STEPControl_Writer

import bsrt
from bsrt.cli import main

MODELS = Path(__file__).resolve().parent / "data" / "models" / "step"
AS1 = MODELS / "pythonocc-core" / "as1-oc-214.stp"
PART = MODELS / "trimesh" / "featuretype.STEP"  # a trimmed part: 96 faces, pockets, holes, fillets


def write_step(shape, path: Path) -> Path:
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    assert writer.Write(str(path)) == IFSelect_RetDone
    return path


def read_back(path: Path):
    reader = STEPControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    return reader.OneShape()


def slanted_cylinder():
    """A solid cylinder, radius 1, axis z from 0 to 4, cut above the plane z = 2 + x / 2."""
    cylinder = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 1.0, 4.0).Shape()
    plane = BRepBuilderAPI_MakeFace(gp_Pln(gp_Pnt(0, 0, 2), gp_Dir(-0.5, 0, 1))).Face()
    above = BRepPrimAPI_MakeHalfSpace(plane, gp_Pnt(0, 0, 10)).Solid()
    return BRepAlgoAPI_Cut(cylinder, above).Shape()


def random_rays(lo, hi, n, seed):
    """From a sphere of radius twice the diagonal toward uniform points of the box (lo, hi)."""
    rng = np.random.default_rng(seed)
    diag = np.linalg.norm(hi - lo)
    s = rng.normal(size=(n, 3))
    origins = 0.5 * (lo + hi) + 2 * diag * s / np.linalg.norm(s, axis=1)[:, None]
    d = lo + rng.uniform(size=(n, 3)) * (hi - lo) - origins
    return origins, d / np.linalg.norm(d, axis=1)[:, None], diag


def test_cylinder_trimmed_by_a_plane(tmp_path):
    """Horizontal rays along -y from y = 5 at (x0, z0): the side at t = 5 - sqrt(1 - x0^2) below
    the plane z = 2 + x0 / 2, nothing above it; rays down from z = 10: the slanted cap at
    t = 10 - (2 + x0 / 2), its outward normal (-1/2, 0, 1) / |.|. Outward normals throughout."""
    scene = bsrt.load(write_step(slanted_cylinder(), tmp_path / "slanted.step"))
    x0 = np.array([-0.9, -0.5, 0.0, 0.3, 0.8])
    below, above = 2 + x0 / 2 - 0.05, 2 + x0 / 2 + 0.05
    origins = np.concatenate([np.stack([x0, np.full(5, 5.0), below], 1), np.stack([x0, np.full(5, 5.0), above], 1)])
    side = bsrt.intersect(scene, origins, np.tile([0.0, -1, 0], (10, 1)))
    assert side.hit.tolist() == [True] * 5 + [False] * 5
    assert np.allclose(side.t[:5], 5 - np.sqrt(1 - x0**2), rtol=0, atol=1e-8)
    assert np.allclose(side.normal[:5], np.stack([x0, np.sqrt(1 - x0**2), 0 * x0], 1), atol=1e-7)
    down = bsrt.intersect(scene, np.stack([x0, 0 * x0, np.full(5, 10.0)], 1), np.tile([0.0, 0, -1], (5, 1)))
    assert down.hit.all() and np.allclose(down.t, 10 - (2 + x0 / 2), rtol=0, atol=1e-8)
    assert np.allclose(down.normal, np.array([-0.5, 0, 1]) / math.sqrt(1.25), atol=1e-9)
    assert side.front_facing[:5].all() and down.front_facing.all()


@pytest.mark.parametrize("make", ["box_with_hole", "slanted_cylinder"])
def test_outward_normals_of_a_closed_solid(tmp_path, make):
    """Every hit along a ray through a closed solid alternates entering (front facing: the outward
    normal faces the origin) and leaving, starting with entering; the box's hole has REVERSED faces."""
    if make == "box_with_hole":
        box = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 40.0, 30.0, 20.0).Shape()
        drill = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 15, -5), gp_Dir(0, 0, 1)), 6.0, 30.0).Shape()
        shape = BRepAlgoAPI_Cut(box, drill).Shape()
        lo, hi = np.zeros(3), np.array([40.0, 30.0, 20.0])
    else:
        shape = slanted_cylinder()
        lo, hi = np.array([-1.0, -1, 0]), np.array([1.0, 1, 2.5])
    path = write_step(shape, tmp_path / f"{make}.step")
    assert any(bsrt.load(path).surfaces[k].reversed for k in range(len(bsrt.load(path).surfaces)))
    origins, directions, _ = random_rays(lo, hi, 600, seed=11)
    result = bsrt.intersect(path, origins, directions, mode="all")
    counts = result.count
    assert (counts > 0).sum() > 300 and (counts % 2 == 0).all()
    position = np.arange(len(result)) - np.repeat(result.offsets[:-1], counts)  # 0, 1, 2 ... along each ray
    assert np.array_equal(result.front_facing, position % 2 == 0)


def test_names_of_a_step_assembly_give_the_part_paths():
    """as1: 18 placed parts; every surface is FILE:as1/<assembly path>/<part>#k, and hits name them."""
    scene = bsrt.load(AS1)
    cam = scene.camera
    rays = bsrt.sensors.pinhole(cam.eye, cam.look_at, up=cam.up, fov=cam.fov, width=64, height=64)
    result = bsrt.intersect(scene, rays.origins, rays.directions)
    parts = {name.split(":", 1)[1].rsplit("#", 1)[0] for name in result.names}
    assert len(result.names) == 160 and len(parts) == 18 and all(p.startswith("as1/") for p in parts)
    assert "as1/rod-assembly_1/nut_1" in parts and "as1/l-bracket-assembly_2/nut-bolt-assembly_3/bolt_1" in parts
    seen = {name.split(":", 1)[1].rsplit("#", 1)[0] for name in result.surface_names() if name}
    assert len(seen) >= 5 and seen <= parts


def test_against_opencascade_on_a_trimmed_step_part():
    """1,500 random rays at featuretype.STEP: the same hit or miss as IntCurvesFace_ShapeIntersector
    on at least 99.5% of them, |dt| at most 1e-7 of the diagonal where both hit; mode "all": the
    same number of hits (OpenCASCADE's points closer than 1e-8 of the diagonal merged: a ray through
    an edge meets both faces) and the same t's."""
    shape = read_back(PART)
    scene = bsrt.load(PART)
    pts = np.concatenate([s.geometry.points.reshape(-1, 3) for s in scene.surfaces])
    origins, directions, _ = random_rays(pts.min(axis=0), pts.max(axis=0), 1500, seed=2)
    ours = bsrt.intersect(scene, origins, directions)
    every = bsrt.intersect(scene, origins, directions, mode="all")
    size = ours.diagonal
    intersector = IntCurvesFace_ShapeIntersector()  # as occ_reference.occt_hits, one origin per ray
    intersector.Load(shape, 1e-9 * size)
    hit, t, same_count, dt_all = np.zeros(1500, dtype=bool), np.full(1500, np.nan), 0, 0.0
    for k in range(1500):
        intersector.Perform(gp_Lin(gp_Pnt(*origins[k]), gp_Dir(*directions[k])), 0.0, math.inf)
        found = sorted(intersector.WParameter(i) for i in range(1, intersector.NbPnt() + 1))
        merged = [x for j, x in enumerate(found) if j == 0 or x - found[j - 1] > 1e-8 * size]
        if merged:
            hit[k], t[k] = True, merged[0]
        mine = every.t[every.offsets[k] : every.offsets[k + 1]]
        if len(mine) == len(merged):
            same_count += 1
            dt_all = max(dt_all, float(np.max(np.abs(mine - merged), initial=0.0)))
    assert hit.sum() > 500
    assert np.mean(ours.hit == hit) >= 0.995
    both = ours.hit & hit
    assert np.max(np.abs(ours.t[both] - t[both])) <= 1e-7 * size
    assert same_count >= 0.995 * 1500 and len(every) > 2 * hit.sum() and dt_all <= 1e-7 * size


def test_grazing_rays_at_the_planar_face_of_a_box(tmp_path):
    """Rays down onto the top face z = 1 of a 4 x 3 x 1 box at |cos| 0.02-0.29 to its normal (a
    planar leaf, so no quarters are retried after its root): t is the plane crossing's closed form,
    the normal +z."""
    scene = bsrt.load(write_step(BRepPrimAPI_MakeBox(4.0, 3.0, 1.0).Shape(), tmp_path / "box.step"))
    rng = np.random.default_rng(5)
    n = 200
    cos, azimuth = rng.uniform(0.02, 0.29, n), rng.uniform(0.0, 2.0 * math.pi, n)
    target = np.stack([rng.uniform(0.5, 3.5, n), rng.uniform(0.5, 2.5, n), np.ones(n)], 1)
    sin = np.sqrt(1.0 - cos**2)
    direction = np.stack([sin * np.cos(azimuth), sin * np.sin(azimuth), -cos], 1)
    t = 0.4 / cos  # from 0.4 above the face: the ray leaves the box's top before it reaches a side
    got = bsrt.intersect(scene, target - t[:, None] * direction, direction)
    assert got.hit.all() and np.allclose(got.t, t, rtol=0, atol=1e-9 * got.diagonal / cos)
    assert np.allclose(got.normal, [0.0, 0.0, 1.0], atol=1e-9)


def test_pieces_the_trims_keep_wholly_skip_the_trim_test_with_the_same_hits():
    """featuretype.STEP's leaf_kept is trim.rect_state's INSIDE for each leaf (most of them; some
    are not), and 3,000 random rays give bit-identical hits (nearest and any) with it cleared."""
    from bsrt.kernels.trim import INSIDE, rect_states
    from bsrt.queries import prepared
    from bsrt.rendering.bvh import intersect

    _, caster = prepared(PART)
    bvh = caster.geometry.bvh
    kept, rect = bvh.arrays.leaf_kept, bvh.arrays.leaf_rect
    state = rect_states(bvh.patches.trims, bvh.arrays.leaf_surface, *(rect[:, c].copy() for c in range(4)))
    assert np.array_equal(kept, state == INSIDE) and 0.5 < kept.mean() < 1.0
    pts = bvh.leaf_min
    origins, directions, diag = random_rays(pts.min(axis=0), bvh.leaf_max.max(axis=0), 3000, seed=4)
    cleared = bvh.arrays._replace(leaf_kept=np.zeros_like(kept))
    for any_hit in (False, True):
        a = intersect(bvh, origins, directions, tolerance=1e-9 * diag, any_hit=any_hit)
        bvh.arrays, saved = cleared, bvh.arrays
        try:
            b = intersect(bvh, origins, directions, tolerance=1e-9 * diag, any_hit=any_hit)
        finally:
            bvh.arrays = saved
        assert a.hit.sum() > 1000
        for field in ("hit", "t", "u", "v", "patch", "residual", "iterations"):
            assert np.array_equal(getattr(a, field), getattr(b, field), equal_nan=True), field


def test_scan_writes_points_on_the_part(tmp_path, capsys):
    """bsrt scan part.step -o cloud.ply: a binary PLY whose points lie on the part (BRepExtrema:
    within 1e-6 of the diagonal); .npz: every array and the range image."""
    path = write_step(slanted_cylinder(), tmp_path / "part.step")
    cloud = tmp_path / "cloud.ply"
    assert main(["scan", str(path), "-o", str(cloud), "--horizontal-resolution", "1", "--channels", "16"]) == 0
    data = cloud.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    count = int(header.split("element vertex ")[1].split()[0])
    rows = np.frombuffer(data[end:], dtype=[("p", "<f8", 3), ("n", "<f4", 3), ("face", "<i4")])
    assert count == rows.size > 20 and "binary_little_endian" in header
    shape = read_back(path)
    size = math.sqrt(2**2 + 2**2 + 2.5**2)
    assert max(distance(shape, p) for p in rows["p"][:: max(1, count // 60)]) <= 1e-6 * size
    assert np.allclose(np.linalg.norm(rows["n"], axis=1), 1.0, atol=1e-6)
    npz = tmp_path / "cloud.npz"
    assert main(["scan", str(path), "-o", str(npz), "--sensor", "pinhole", "--width", "40", "--height", "30"]) == 0
    arrays = np.load(npz)
    assert arrays["range"].shape == (30, 40) and arrays["depth"].shape == (30, 40)
    assert np.isfinite(arrays["range"]).sum() == arrays["hit"].sum() > 50


@pytest.mark.parametrize(
    "args, message",
    [
        (["-o", "{tmp}/cloud.txt"], "must end in .ply or .npz"),
        (["-o", "{tmp}/cloud.ply", "--tolerance", "1e-15"], "below what float64 can give"),
        (["-o", "{tmp}/cloud.ply", "--vertical-fov", "1,2,3"], "expected two angles"),
    ],
)
def test_scan_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, args, message):
    path = write_step(slanted_cylinder(), tmp_path / "part.step")
    argv = ["scan", str(path)] + [a.format(tmp=tmp_path) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.glob("cloud*"))
