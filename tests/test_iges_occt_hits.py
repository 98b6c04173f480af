"""The shared trimmed IGES files, read by bsrt's own reader, against OpenCASCADE.

Every pixel's ray at 128 x 128 with the default camera is traced by bsrt and
by OpenCASCADE's IntCurvesFace_ShapeIntersector on the file's trimmed surfaces
(the 144s, as OpenCASCADE's IGES reader makes them). Where the two disagree
(a hit against a miss, or t apart by more than 1e-7 of the diagonal) the
distance of each hit to the shape (BRepExtrema_DistShapeShape, a vertex at
the hit against the whole shape) decides: a hit more than 1e-8 of the diagonal
(ten root tolerances) off the shape is wrong, and of two hits on the shape the nearer one is the
first hit (the other intersector missed it). bsrt must be right at every
pixel away from silhouettes and face edges.

OpenCASCADE's intersector is itself wrong on a few pixels (measured
2026-11-25, OCP 7.8, at the default camera):

* bearing.iges, 12 pixels. At 10 of them OpenCASCADE's hit lies 1.0e-6 to
  1.8e-3 of the diagonal off the shape (at (37, 38) and (37, 39) bsrt finds
  no hit). At (52, 50) and (67, 30) its hits, on faces 172 and 185, lie
  2.4e-7 and 6.4e-8 of the diagonal off the shape, t 5e-8 and 2e-8 nearer
  than bsrt's (faces 186 and 196, 6.3e-13 and 2.2e-10 off): the ray passes
  just outside those faces' trims (bsrt's root on each, at OpenCASCADE's t,
  is trimmed away), which OpenCASCADE's classifier takes as on the boundary
  within its tolerance; the first point on the shape is bsrt's. (Judged
  with the old bound of 1e-6 of the diagonal, these two looked like nearer
  hits bsrt missed, and the test was held at the camera of before issue 26.)
* marsCapsule.igs, 4 pixels, all at face edges: (112, 37) on face 7 and
  (93, 86), (100, 73), (107, 60) on face 4. Both hits lie on the shape (bsrt
  1.2e-10 of the diagonal or less, OpenCASCADE 1e-16), but bsrt's is nearer
  by 0.21 to 0.45 (t): OpenCASCADE's intersector misses that first crossing
  and reports the next. (Before the automatic camera took its trim-loop points
  from the trim table, 2026-11-25, the camera stood 8e-4 away and only
  (112, 37) showed.)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import OCP  # noqa: F401  -- the extra must be installed: fail, never skip
import pytest
from occ_reference import distance, interior, occt_hits
from OCP.Bnd import Bnd_Box
from OCP.BRepBndLib import BRepBndLib
from OCP.IFSelect import IFSelect_RetDone
from OCP.IGESControl import IGESControl_Reader
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp_Explorer

from bsrt.io import load_model
from bsrt.rendering.pipeline import render
from bsrt.scene import scene_for_model
from bsrt.scene.camera import pixel_rays

pytestmark = pytest.mark.gl  # every test here needs it (tests/conftest.py checks)

MODELS = Path(__file__).resolve().parent / "data" / "models" / "iges"
FILES = {"bearing": MODELS / "occt" / "bearing.iges", "marsCapsule": MODELS / "overtureframework" / "marsCapsule.igs"}
SIZE = 128
ON_SHAPE = 1e-8  # of the diagonal: ten times the roots' tolerance (the render's default, 1e-9)
SAME_T = 1e-7  # of the diagonal
DIFFER = {"bearing": 12, "marsCapsule": 4}  # pixels where the two disagree, measured at the default camera


def _trimmed_shape(path: Path):
    """The file's 144s as OpenCASCADE reads them (not its untrimmed or grouped entities)."""
    reader = IGESControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    selected = reader.GiveList("iges-type(144)")
    assert selected.Length() > 0
    reader.TransferList(selected)
    return reader.OneShape()


def _faces(shape) -> list:
    out, explorer = [], TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        out.append(explorer.Current())
        explorer.Next()
    return out


def _diagonal(shape) -> float:
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    lo, hi = box.CornerMin(), box.CornerMax()
    return math.dist((lo.X(), lo.Y(), lo.Z()), (hi.X(), hi.Y(), hi.Z()))


@pytest.mark.parametrize("name", sorted(FILES))
def test_shared_iges_hits_agree_with_opencascade_or_are_nearer_on_the_shape(name):
    path = FILES[name]
    shape = _trimmed_shape(path)
    faces = _faces(shape)
    size = _diagonal(shape)
    model = load_model(path)
    assert len(faces) == len(model.surfaces)
    scene = scene_for_model(model, SIZE, SIZE)
    aovs = render(scene).aovs()
    eye = np.asarray(scene.camera.eye, float)
    directions = pixel_rays(scene.camera, SIZE, SIZE)
    n = len(directions)
    hit, t, face = occt_hits(shape, eye, directions, size, faces)
    ours, ours_t = aovs["hit"].ravel(), aovs["t"].ravel()
    assert hit.sum() > 0.1 * n
    away = interior(np.where(hit, face, -1).reshape(SIZE, SIZE)).ravel()
    differ = (ours != hit) | (ours & hit & (np.abs(np.where(ours, ours_t, 0) - np.where(hit, t, 0)) > SAME_T * size))
    assert differ.sum() <= DIFFER[name]  # measured, all OpenCASCADE's (the module doc)
    wrong = []
    for k in np.flatnonzero(differ):
        mine = distance(shape, eye + ours_t[k] * directions[k]) / size if ours[k] else None
        theirs = distance(shape, eye + t[k] * directions[k]) / size if hit[k] else None
        bsrt_right = (
            (mine is not None and mine <= ON_SHAPE) and (theirs is None or theirs > ON_SHAPE or ours_t[k] < t[k])
        ) or (mine is None and (theirs is None or theirs > ON_SHAPE))
        if not bsrt_right:
            wrong.append((divmod(int(k), SIZE), mine, theirs, bool(away[k])))
    assert not [w for w in wrong if w[3]], wrong  # away from edges: none
    assert not wrong, wrong  # and, measured, none at the edges either
