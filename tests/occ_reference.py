"""OpenCASCADE as the tests' reference for hits: its exact ray/shape intersector, the distance of a
point to a shape, and which pixels lie away from edges (one copy for every test that judges bsrt's
hits against OpenCASCADE)."""

from __future__ import annotations

import math

import numpy as np
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
from OCP.BRepExtrema import BRepExtrema_DistShapeShape
from OCP.gp import gp_Dir, gp_Lin, gp_Pnt
from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector


def occt_hits(shape, eye, directions, size: float, faces=None):
    """Each ray's nearest hit by IntCurvesFace_ShapeIntersector: (hit (N,) bool, t (N,) float64, NaN where
    none, face (N,) int64: the index in ``faces`` of the face hit, or with faces None a label that only
    compares equal for the same face; -1 where none). eye: (3,); directions: (N, 3) unit rays."""
    intersector = IntCurvesFace_ShapeIntersector()
    intersector.Load(shape, 1e-9 * size)
    n = len(directions)
    hit, t, face = np.zeros(n, dtype=bool), np.full(n, np.nan), np.full(n, -1, dtype=np.int64)
    origin = gp_Pnt(*map(float, eye))
    for k, d in enumerate(directions):
        intersector.Perform(gp_Lin(origin, gp_Dir(*map(float, d))), 0.0, math.inf)
        if intersector.IsDone() and intersector.NbPnt() > 0:
            i = min(range(1, intersector.NbPnt() + 1), key=intersector.WParameter)
            hit[k], t[k] = True, intersector.WParameter(i)
            f = intersector.Face(i)
            face[k] = (
                next(j for j, g in enumerate(faces) if g.IsSame(f))
                if faces is not None
                else hash(f) & 0x3FFFFFFFFFFFFFFF
            )
    return hit, t, face


def distance(shape, point) -> float:
    """The distance from point (3,) to the shape (BRepExtrema), inf if it cannot be measured."""
    tool = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, point))).Vertex(), shape)
    return float(tool.Value()) if tool.IsDone() else math.inf


def interior(labels: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose 3 x 3 neighbourhood all see the same face (or all nothing) in labels (H, W)."""
    h, w = labels.shape
    pad = np.pad(labels, 1, constant_values=-2)
    same = np.ones((h, w), dtype=bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            same &= pad[1 + di : 1 + di + h, 1 + dj : 1 + dj + w] == labels
    return same
