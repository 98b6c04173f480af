"""Real third-party CAD parts, loaded by bsrt and judged by OpenCASCADE.

The parts are the STEP files of the corpus in ``tests/data/models``
(SOURCES.md, "Corpus of real CAD parts": CAD systems, faces, licences).
For each part:

* bsrt loads it the way users do (``load_model``) with every face trimmed
  (``Model.untrimmed == 0``) and nothing skipped except counted wireframe
  edges;
* at 48 x 48 pixels of the default camera, bsrt's hits and those of
  OpenCASCADE's exact ``IntCurvesFace_ShapeIntersector`` on the shape
  ``STEPControl_Reader`` reads from the same file agree away from edges
  (3 x 3 neighbourhoods that see one face, or nothing, in both labellings):
  the same pixels hit, at the same t to 1e-6 of the diagonal. A failure
  names the pixels and, for each side's hit, its distance to the shape
  (``BRepExtrema_DistShapeShape``): a hit off the shape is the wrong one.

EXPECTED TO FAIL, when written, wherever bsrt draws a face untrimmed:
faces whose wires do not close in the converted surface's domain (on
periodic surfaces, wires across the seam) are drawn whole
(``Model.untrimmed > 0``, with a warning naming the face), and such a face
shows its whole surface where OpenCASCADE sees nothing. The importer is
being fixed; these tests are its target, so they are plain tests (not
xfail, never skipped). Measured on 2026-11-24 with the importer of that
day, the parts below all passed; the parts that still showed untrimmed
faces were among those measured but not redistributed (SOURCES.md:
r0901_ec.stp, trj3_s1-ct-214.stp, trj6_k1-al-214.stp).
``scripts/judge_cad.py`` runs the same comparison on any folder of parts,
with more detail.

Real OpenCASCADE, never mocked: OCP is imported at the top. The parts were
chosen so that this module runs well within two minutes with the loader of
2026-11 on a shared 2-core machine (about 60 s measured, under load; the larger
parts are left to the script).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import OCP  # noqa: F401  -- the extra must be installed: fail, never skip
import pytest
from conftest import MODELS, model_files
from occ_reference import distance, interior, occt_hits
from OCP.Bnd import Bnd_Box
from OCP.BRepBndLib import BRepBndLib
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_Reader

from bsrt.io import load_model
from bsrt.rendering.pipeline import render
from bsrt.scene import scene_for_model
from bsrt.scene.camera import pixel_rays

TOL = 1e-6  # of the model's diagonal: |dt|, and a hit's distance to the shape
SIZE = 48
WIREFRAME = "edges not on any face (wireframe)"

#: the corpus parts run here (paths under MODELS); every one is listed in SOURCES.md
CORPUS = (
    "step/occt/screw.step",  # EUCLID: tori, cones, a cylinder
    "step/pythonocc-core/io1-ug-214.stp",  # Unigraphics 16: cylinders, a cone
    "step/pythonocc-core/stp_multiple_shp_at_root.stp",  # a translation service (Onshape?): cylinders
    "step/trimesh/base_interface_AP214.STEP",  # SolidWorks 2018: cylinders
    "step/trimesh/featuretype.STEP",  # SolidWorks 2013: cylinders, a B-spline
    "step/pythonocc-core/as1_pe_203.stp",  # Pro/ENGINEER 2008: an assembly, 160 faces
    "step/build123d/M6-1x12-countersunk-screw.step",  # build123d / OpenCASCADE 7.5: a thread
    "step/occt/linkrods.step",  # EUCLID: tori, cylinders, B-splines
    "step/trimesh/box_sides.STEP",  # SolidWorks 2015: 417 faces
)
# Not here: eight_cyl.stp (eight thin cylinders 500 units apart: at 48 x 48 pixels too few see one
# face in a 3 x 3 neighbourhood for the comparison to mean anything; the script judges it at 128).


def test_the_corpus_parts_are_listed_in_sources():
    listed = {p.relative_to(MODELS).as_posix() for p in model_files()}
    assert set(CORPUS) <= listed


@functools.cache
def _model(name: str):
    return load_model(MODELS / name)


@functools.cache
def _shape(name: str):
    reader = STEPControl_Reader()
    assert reader.ReadFile(str(MODELS / name)) == IFSelect_RetDone
    reader.TransferRoots()
    return reader.OneShape()


def _diagonal(shape) -> float:
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    lo, hi = box.CornerMin(), box.CornerMax()
    return math.dist((lo.X(), lo.Y(), lo.Z()), (hi.X(), hi.Y(), hi.Z()))


def _side(hit, t, shape, eye, direction, size) -> str:
    """One side's hit for a failure message: its t and its distance to the shape (of the diagonal)."""
    if not hit:
        return "miss"
    return f"t={t:.9g} (off the shape by {distance(shape, eye + t * direction) / size:.2g})"


@pytest.mark.parametrize("name", CORPUS)
def test_corpus_part_loads_with_every_face_trimmed(name):
    model = _model(name)
    assert model.untrimmed == 0, model.warnings
    assert set(model.skipped) <= {WIREFRAME}, model.skipped
    assert len(model.surfaces) > 0


@pytest.mark.gl
@pytest.mark.parametrize("name", CORPUS)
def test_corpus_part_hits_agree_with_occt_away_from_edges(name):
    model, shape = _model(name), _shape(name)
    size = _diagonal(shape)
    scene = scene_for_model(model, SIZE, SIZE)
    aovs = render(scene).aovs()
    directions = pixel_rays(scene.camera, SIZE, SIZE)
    hit, t, face = occt_hits(shape, scene.camera.eye, directions, size)
    hit, t, face = hit.reshape(SIZE, SIZE), t.reshape(SIZE, SIZE), face.reshape(SIZE, SIZE)
    assert hit.sum() > 0.05 * SIZE * SIZE  # the camera sees the part
    ours = np.where(aovs["hit"], aovs["surface"], -1)
    theirs = np.where(hit, face, -1)
    inside = interior(ours) & interior(theirs)
    both = inside & hit & aovs["hit"]
    assert both.sum() > 0.1 * hit.sum()
    depth = np.zeros_like(both)
    depth[both] = np.abs(aovs["t"][both] - t[both]) > TOL * size
    bad = np.argwhere(inside & ((aovs["hit"] != hit) | depth))
    if len(bad):
        eye = np.asarray(scene.camera.eye)
        dirs = directions.reshape(SIZE, SIZE, 3)
        lines = []
        for i, j in bad[:6]:
            lines.append(
                f"pixel {(int(i), int(j))}: bsrt {_side(aovs['hit'][i, j], aovs['t'][i, j], shape, eye, dirs[i, j], size)}"
                f" on {model.names[aovs['surface'][i, j]] if aovs['hit'][i, j] else '-'}, "
                f"OpenCASCADE {_side(hit[i, j], t[i, j], shape, eye, dirs[i, j], size)}"
            )
        extra = int((inside & aovs["hit"] & ~hit).sum())
        missed = int((inside & ~aovs["hit"] & hit).sum())
        raise AssertionError(
            f"{name}: {len(bad)} of {int(inside.sum())} pixels away from edges disagree ({extra} bsrt-only hits, "
            f"{missed} OpenCASCADE-only hits, {int(depth.sum())} at another depth; distances as fractions of "
            f"the diagonal; untrimmed faces: {model.untrimmed})\n" + "\n".join(lines)
        )
