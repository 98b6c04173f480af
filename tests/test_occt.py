"""STEP, BREP and IGES through OpenCASCADE (bsrt.io.occt), judged by OpenCASCADE itself.

Real OpenCASCADE throughout, never mocked: OCP is imported at the top, so
without the ``bsrt[cad]`` extra every test here fails (none is skipped).

The shapes are built here with OpenCASCADE (a box with a filleted
through-hole, a sphere cut by a tilted cylinder, a torus, a lofted B-spline
solid), written to STEP (and IGES, BREP) and read back through
``bsrt.io.load_model``. For every face: points of the converted surface at
random (u, v) of its domain lie on the face's own surface, and points of
every trim curve, mapped through the surface, lie on the face's boundary as
its pcurves define it (both within 1e-7 of the model's diagonal, measured by
OpenCASCADE's projections and distance computations) and on its 3-D edges
to within their tolerance; the loops close and are as long in 3-D as the
face's edges.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import OCP  # noqa: F401  -- the extra must be installed: fail, never skip
import pytest
from occ_reference import interior, occt_hits
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex, BRepBuilderAPI_MakeWire
from OCP.BRepExtrema import BRepExtrema_DistShapeShape
from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
from OCP.BRepOffsetAPI import BRepOffsetAPI_ThruSections
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder, BRepPrimAPI_MakeSphere, BRepPrimAPI_MakeTorus
from OCP.BRepTools import BRepTools
from OCP.GCPnts import GCPnts_AbscissaPoint
from OCP.GeomAbs import GeomAbs_Circle
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.gp import gp_Ax2, gp_Dir, gp_Elips, gp_Pnt
from OCP.IFSelect import IFSelect_RetDone
from OCP.IGESControl import IGESControl_Reader, IGESControl_Writer
from OCP.Interface import Interface_Static
from OCP.Quantity import Quantity_Color, Quantity_TOC_RGB
from OCP.ShapeAnalysis import ShapeAnalysis_Surface
from OCP.STEPCAFControl import STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Reader, STEPControl_Writer
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDocStd import TDocStd_Document
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Compound
from OCP.XCAFApp import XCAFApp_Application
from OCP.XCAFDoc import XCAFDoc_ColorGen, XCAFDoc_ColorSurf, XCAFDoc_DocumentTool
from PIL import Image

from bsrt.cli import main
from bsrt.errors import InputError
from bsrt.geometry.bspline import basis_functions, evaluate, find_span
from bsrt.io import Model, load_model, occt
from bsrt.io.occt import reading as _occt_reading  # noqa: F401  (occt.reading below)
from bsrt.rendering.pipeline import render
from bsrt.scene import scene_for_model
from bsrt.scene.camera import pixel_rays

MODELS = Path(__file__).resolve().parent / "data" / "models"
AS1 = MODELS / "step" / "pythonocc-core" / "as1-oc-214.stp"
TOL = 1e-7  # of the model's diagonal


def _cast(kind, shape):
    return (getattr(TopoDS, kind, None) or getattr(TopoDS, kind + "_s"))(shape)


# ---------------------------------------------------------------------------
# Shapes, built with OpenCASCADE


def box_with_filleted_hole():
    box = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 40.0, 30.0, 20.0).Shape()
    drill = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(20, 15, -5), gp_Dir(0, 0, 1)), 6.0, 30.0).Shape()
    cut = BRepAlgoAPI_Cut(box, drill).Shape()
    fillet = BRepFilletAPI_MakeFillet(cut)
    for edge in _edges(cut):
        if BRepAdaptor_Curve(edge).GetType() == GeomAbs_Circle:  # the hole's two rims
            fillet.Add(2.0, edge)
    return fillet.Shape()


def sphere_cut_by_cylinder():
    sphere = BRepPrimAPI_MakeSphere(gp_Pnt(0, 0, 0), 10.0).Shape()
    tilted = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(3, 0, -20), gp_Dir(0, 0.3, 1)), 4.0, 40.0).Shape()
    return BRepAlgoAPI_Cut(sphere, tilted).Shape()


def torus():
    return BRepPrimAPI_MakeTorus(gp_Ax2(gp_Pnt(1, 2, 3), gp_Dir(0, 0, 1)), 10.0, 3.0).Shape()


def lofted_solid():
    loft = BRepOffsetAPI_ThruSections(True, False)  # a solid, smooth (B-spline) sides
    for z, rx, ry in ((0.0, 8.0, 5.0), (10.0, 4.0, 3.0), (20.0, 7.0, 6.0)):
        ellipse = gp_Elips(gp_Ax2(gp_Pnt(0.5 * z, 0, z), gp_Dir(0, 0, 1)), rx, ry)
        loft.AddWire(BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(ellipse).Edge()).Wire())
    loft.Build()
    return loft.Shape()


SHAPES = {
    "box-with-filleted-hole": box_with_filleted_hole,
    "sphere-cut-by-cylinder": sphere_cut_by_cylinder,
    "torus": torus,
    "lofted-solid": lofted_solid,
}


# ---------------------------------------------------------------------------
# Helpers: files, faces, distances


def _explore(shape, kind, cast):
    out = []
    explorer = TopExp_Explorer(shape, kind)
    while explorer.More():
        out.append(_cast(cast, explorer.Current()))
        explorer.Next()
    return out


def _faces(shape):
    return _explore(shape, TopAbs_FACE, "Face")


def _edges(shape):
    return _explore(shape, TopAbs_EDGE, "Edge")


def write_step(shape, path: Path) -> Path:
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    assert writer.Write(str(path)) == IFSelect_RetDone
    return path


def write_iges(shape, path: Path, brep_mode: int) -> Path:
    Interface_Static.SetIVal_s("write.iges.brep.mode", brep_mode)
    writer = IGESControl_Writer("MM", brep_mode)
    assert writer.AddShape(shape)
    writer.ComputeModel()
    assert writer.Write(str(path))
    return path


def read_back(path: Path):
    """The file as OpenCASCADE itself reads it (the reference for bsrt's surfaces)."""
    reader = STEPControl_Reader() if path.suffix.lower() in (".step", ".stp") else IGESControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    return reader.OneShape()


def tight_box(shape) -> np.ndarray:
    """(2, 3): OpenCASCADE's tight bounding box of the geometry (no triangulation, no tolerances)."""
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    lo, hi = box.CornerMin(), box.CornerMax()
    return np.array([[lo.X(), lo.Y(), lo.Z()], [hi.X(), hi.Y(), hi.Z()]])


def diagonal(shape) -> float:
    lo, hi = tight_box(shape)
    return float(np.linalg.norm(hi - lo))


def distance_to_surface(face, points: np.ndarray) -> np.ndarray:
    """Distance of each point to the face's (untrimmed) surface: the nearer of
    GeomAPI_ProjectPointOnSurf's orthogonal projections and ShapeAnalysis_Surface's
    projection (which also finds feet on the edges and corners of a bounded surface)."""
    surface = BRep_Tool.Surface_s(face)  # the face's location applied
    analysis = ShapeAnalysis_Surface(surface)
    out = []
    for p in points:
        point = gp_Pnt(*map(float, p))
        projector = GeomAPI_ProjectPointOnSurf(point, surface)
        d = projector.LowerDistance() if projector.NbPoints() > 0 else math.inf
        analysis.ValueOfUV(point, 1e-12)
        out.append(min(d, analysis.Gap()))
    return np.array(out)


def boundary(face):
    """A compound of the face's edges (degenerate ones as their vertices), for distances."""
    compound = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(compound)
    for edge in _edges(face):
        if BRep_Tool.Degenerated_s(edge):
            for vertex in _explore(edge, TopAbs_VERTEX, "Vertex"):
                builder.Add(compound, vertex)
        else:
            builder.Add(compound, edge)
    return compound


def boundary_in_parameters(face):
    """The face's boundary as OpenCASCADE's pcurves define it: a compound of edges
    whose only geometry is each edge's curve on the face's surface (evaluated
    exactly as S(c(t)) by BRepAdaptor_Curve), degenerate edges as their vertices.

    This is the boundary the face's (u, v) domain has, and the one bsrt's trim
    loops reproduce; OpenCASCADE's 3-D edges may be off it by up to the edge
    tolerance (2e-7 of the diagonal for the sphere cut by a cylinder)."""
    compound = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(compound)
    surface = BRep_Tool.Surface_s(face)  # with the face's location
    for edge in _edges(face):
        if BRep_Tool.Degenerated_s(edge):
            for vertex in _explore(edge, TopAbs_VERTEX, "Vertex"):
                builder.Add(compound, vertex)
            continue
        pcurve = BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0)
        first, last = BRep_Tool.Range_s(edge, face)
        maker = BRepBuilderAPI_MakeEdge(pcurve, surface, first, last)
        assert maker.IsDone()
        builder.Add(compound, maker.Edge())
    return compound


def edge_tolerance(face) -> float:
    return max(BRep_Tool.Tolerance_s(e) for e in _edges(face))


def distance_to_shape(shape, points: np.ndarray) -> np.ndarray:
    out = []
    for p in points:
        d = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex(), shape)
        assert d.IsDone()
        out.append(d.Value())
    return np.array(out)


def edge_length(face) -> float:
    """Total length of the face's boundary as its pcurves define it (seams
    counted twice, once per side, as the loops run)."""
    return sum(GCPnts_AbscissaPoint.Length_s(BRepAdaptor_Curve(e), 1e-12) for e in _edges(boundary_in_parameters(face)))


def loop_length(surface, tol: float = 1e-12) -> float:
    """3-D length of the loops: adaptive Gauss-Legendre over each curve (the
    speed has kinks where a curve crosses the surface's knots)."""
    x10, w10 = np.polynomial.legendre.leggauss(10)
    x20, w20 = np.polynomial.legendre.leggauss(20)

    def speed(curve, s):
        span = find_span(curve.knots, curve.degree, curve.points.shape[0], s)
        basis, ders = basis_functions(curve.knots, curve.degree, span, s)
        ctrl = curve.homogeneous()[(span - curve.degree)[:, None] + np.arange(curve.degree + 1)[None, :]]
        h, dh = np.einsum("na,nak->nk", basis, ctrl), np.einsum("na,nak->nk", ders, ctrl)
        uv = h[:, :2] / h[:, 2:]
        duv = (dh[:, :2] - uv * dh[:, 2:]) / h[:, 2:]
        _, su, sv = evaluate(surface, uv[:, 0], uv[:, 1])
        return np.linalg.norm(su * duv[:, :1] + sv * duv[:, 1:], axis=1)

    def piece(curve, a, b, depth):
        m, r = 0.5 * (a + b), 0.5 * (b - a)
        coarse = r * float(w10 @ speed(curve, m + r * x10))
        fine = r * float(w20 @ speed(curve, m + r * x20))
        if abs(fine - coarse) <= tol or depth >= 40:
            return fine
        return piece(curve, a, m, depth + 1) + piece(curve, m, b, depth + 1)

    total = 0.0
    for loop in surface.trims:
        for curve in loop.curves:
            knots = np.unique(curve.knots[curve.degree : curve.points.shape[0] + 1])
            total += sum(piece(curve, a, b, 0) for a, b in zip(knots[:-1], knots[1:]))
    return total


def boundary_extent(surfaces) -> np.ndarray:
    """(2, 3): the smallest and largest coordinates on the surfaces' trim loops.

    64 samples per curve; the eight best curves per direction then refined by
    golden-section search on the curve's parameter."""
    candidates = []  # (curve, surface, t samples, (64, 3) points)
    for surface in surfaces:
        for loop in surface.trims:
            for curve in loop.curves:
                t = np.linspace(*curve.domain, 64)
                uv = curve.evaluate(t)
                candidates.append((curve, surface, t, evaluate(surface, uv[:, 0], uv[:, 1])[0]))
    extent = np.empty((2, 3))
    g = (math.sqrt(5) - 1) / 2
    for side, sign in enumerate((-1.0, 1.0)):
        for axis in range(3):
            scored = sorted(candidates, key=lambda c: -(sign * c[3][:, axis]).max())
            best = -np.inf
            for curve, surface, t, pts in scored[:8]:

                def f(x, curve=curve, surface=surface):
                    uv = curve.evaluate([x])
                    return sign * evaluate(surface, uv[:, 0], uv[:, 1])[0][0, axis]

                k = int(np.argmax(sign * pts[:, axis]))
                a, b = t[max(k - 1, 0)], t[min(k + 1, t.size - 1)]
                for _ in range(60):
                    c, d = b - g * (b - a), a + g * (b - a)
                    if f(c) > f(d):
                        b = d
                    else:
                        a = c
                best = max(best, sign * pts[k, axis], f(0.5 * (a + b)))
            extent[side, axis] = sign * best
    return extent


def check_faces(model: Model, faces, size: float, seed: int = 0, third_party: bool = False) -> None:
    """Every surface of the model against the OpenCASCADE face of the same index.

    third_party: a file whose B-rep is only consistent to its tolerances
    (OpenCASCADE's 3-D edges off the pcurves, pcurves whose ends miss each
    other or leave the surface's domain): the loops are then checked against
    the pcurves only, and where a loop runs along the domain's edge (an
    excursion of a pcurve out of the domain, cut off) not at all."""
    rng = np.random.default_rng(seed)
    assert len(model.surfaces) == len(faces)
    for k, (surface, face) in enumerate(zip(model.surfaces, faces)):
        (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
        u, v = rng.uniform(u0, u1, 24), rng.uniform(v0, v1, 24)
        u[:4], v[:4] = [u0, u1, u0, u1], [v0, v0, v1, v1]  # the corners too
        on_surface = distance_to_surface(face, evaluate(surface, u, v)[0])
        assert on_surface.max() < TOL * size, (k, on_surface.max() / size)
        assert surface.trims or BRep_Tool.NaturalRestriction_s(face), f"face {k} has no loops"
        in_parameters, edges = boundary_in_parameters(face), boundary(face)
        slack = TOL * size + edge_tolerance(face)
        for i, loop in enumerate(surface.trims):
            uv = np.concatenate([c.evaluate(np.linspace(*c.domain, 17)) for c in loop.curves])
            if third_party:
                eps = 1e-12 * max(u1 - u0, v1 - v0)
                uv = uv[
                    (np.abs(uv[:, 0] - u0) > eps)
                    & (np.abs(uv[:, 0] - u1) > eps)
                    & (np.abs(uv[:, 1] - v0) > eps)
                    & (np.abs(uv[:, 1] - v1) > eps)
                ]
            pts = evaluate(surface, uv[:, 0], uv[:, 1])[0]
            off = distance_to_shape(in_parameters, pts)
            assert off.max(initial=0.0) < TOL * size, (k, i, off.max() / size)
            if not third_party:  # the 3-D edges, to their own tolerance
                off = distance_to_shape(edges, pts)
                assert off.max() < slack, (k, i, "3-D", off.max() / size)
        for loop in surface.trims:  # closed, end to end, exactly
            ends = [c.ends() for c in loop.curves]
            for a, b in zip(ends, ends[1:] + ends[:1]):
                assert np.array_equal(a[1], b[0])
        if not third_party:
            assert loop_length(surface) == pytest.approx(edge_length(face), rel=1e-7, abs=TOL * size)


# ---------------------------------------------------------------------------
# The shapes through STEP


@pytest.mark.parametrize("name", SHAPES)
def test_step_faces_are_exact_surfaces_with_loops_on_their_edges(tmp_path, name):
    shape = SHAPES[name]()
    path = write_step(shape, tmp_path / f"{name}.step")
    model = load_model(path)
    reference = read_back(path)
    size = diagonal(reference)
    assert diagonal(shape) == pytest.approx(size, rel=1e-9)
    assert len(model.surfaces) == len(_faces(shape)) == len(_faces(reference))
    assert model.untrimmed == 0 and not model.warnings and not model.skipped
    assert all(n.startswith(f"{name}.step:") and n.endswith(f"#{k}") for k, n in enumerate(model.names))
    assert len(set(model.names)) == len(model.names)
    check_faces(model, _faces(reference), size)


def test_step_periodic_faces_and_seams(tmp_path):
    """The torus: one face, periodic in u and v, two seams (each used twice) and
    one degenerate-free loop of four iso-lines around the whole domain."""
    model = load_model(write_step(torus(), tmp_path / "torus.stp"))
    (surface,) = model.surfaces
    assert surface.is_rational and surface.degree == (2, 2)
    (loop,) = surface.trims
    assert len(loop.curves) == 4 and all(c.degree == 1 for c in loop.curves)  # exact straight segments
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    # the loop runs round the domain's edges, 1e-9 of the span outside them (so a hit on a seam is kept)
    corners = np.array([c.ends()[0] for c in loop.curves])
    expected = np.array([(a, b) for a in (u0, u1) for b in (v0, v1)])
    gap = np.abs(corners[:, None, :] - expected[None, :, :]).max(axis=2)
    assert np.all(gap.min(axis=1) <= 2e-9 * (u1 - u0)) and len({tuple(x) for x in gap.argmin(axis=1)[:, None]}) == 4
    assert np.all((corners[:, 0] < u0) | (corners[:, 0] > u1)) and np.all((corners[:, 1] < v0) | (corners[:, 1] > v1))


def test_sphere_poles_are_degenerate_edges_mapped_to_the_domain_ends(tmp_path):
    model = load_model(write_step(BRepPrimAPI_MakeSphere(gp_Pnt(1, 1, 1), 5.0).Shape(), tmp_path / "ball.step"))
    (surface,) = model.surfaces
    (loop,) = surface.trims
    (v0, v1) = surface.domain_v
    ends = np.concatenate([c.ends() for c in loop.curves])
    assert np.isclose(ends[:, 1], v0).any() and np.isclose(ends[:, 1], v1).any()
    check_faces(model, _faces(read_back(tmp_path / "ball.step")), 10.0 * math.sqrt(3))


def test_brep_reads_the_same_faces(tmp_path):
    shape = sphere_cut_by_cylinder()
    path = tmp_path / "cut.brep"
    assert BRepTools.Write_s(shape, str(path))
    model = load_model(path)
    assert model.colors == []
    check_faces(model, _faces(shape), diagonal(shape))


@pytest.mark.parametrize("brep_mode", [1, 0])
def test_iges_through_occt_matches_step(tmp_path, brep_mode):
    shape = box_with_filleted_hole()
    step = load_model(write_step(shape, tmp_path / "part.step"))
    iges_path = write_iges(shape, tmp_path / "part.igs", brep_mode)
    iges = load_model(iges_path, format="occt")
    reference = read_back(iges_path)
    size = diagonal(reference)
    assert len(iges.surfaces) == len(step.surfaces) == len(_faces(reference))
    check_faces(iges, _faces(reference), size)
    # the same geometry as through STEP: every surface's loops have a twin of the same length
    lengths_step = sorted(loop_length(s) for s in step.surfaces)
    lengths_iges = sorted(loop_length(s) for s in iges.surfaces)
    assert np.allclose(lengths_iges, lengths_step, rtol=1e-7, atol=TOL * size)


@pytest.mark.parametrize("name", ["occt/hammer.iges", "overtureframework/marsCapsule.igs"])
def test_third_party_iges_through_occt(name):
    """Real IGES files read with format "occt": OpenCASCADE's faces, placed as its
    XCAF document says, are bsrt's surfaces, in order (hammer's pcurves leave
    their surfaces' domains by up to 3e-5 of it: cut off at the domain's edge)."""
    path = MODELS / "iges" / name
    model = load_model(path, format="occt")
    assert model.untrimmed == 0 and not model.warnings
    leaves = occt.reading.read_leaves(str(path), "iges")
    faces = [_cast("Face", f.Moved(leaf.location)) for leaf in leaves for f in _faces(leaf.shape)]
    check_faces(model, faces, occt.reading.diagonal(leaves), third_party=True)


def test_step_face_colour_overrides_the_part_colour(tmp_path):
    """A colour on one face (an XCAF sub-shape) wins over the part's; colours are linear RGB."""
    shape = box_with_filleted_hole()
    doc = TDocStd_Document(TCollection_ExtendedString("MDTV-XCAF"))
    XCAFApp_Application.GetApplication_s().InitDocument(doc)
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colours = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    part = shapes.AddShape(shape, False)
    colours.SetColor(part, Quantity_Color(0.5, 0.25, 0.125, Quantity_TOC_RGB), XCAFDoc_ColorGen)
    face = shapes.AddSubShape(part, _faces(shape)[1])
    colours.SetColor(face, Quantity_Color(0.0, 0.0, 1.0, Quantity_TOC_RGB), XCAFDoc_ColorSurf)
    writer = STEPCAFControl_Writer()
    assert writer.Transfer(doc, STEPControl_AsIs)
    path = tmp_path / "coloured.step"
    assert writer.Write(str(path)) == IFSelect_RetDone
    model = load_model(path)
    assert len(model.colors) == len(model.surfaces) == 9
    assert model.colors[1] == pytest.approx((0.0, 0.0, 1.0), abs=1e-6)
    for k in (0, 2, 3, 4, 5, 6, 7, 8):
        assert model.colors[k] == pytest.approx((0.5, 0.25, 0.125), abs=1e-6)
    assert load_model(write_step(shape, tmp_path / "plain.step")).colors == []  # no colours: an empty list


# ---------------------------------------------------------------------------
# The shared assembly


def _as1_reference():
    reader = STEPControl_Reader()
    assert reader.ReadFile(str(AS1)) == IFSelect_RetDone
    reader.TransferRoots()
    return reader.OneShape()


def test_as1_assembly_has_every_face_in_place_with_colours():
    model = load_model(AS1)
    shape = _as1_reference()
    faces = _faces(shape)
    distinct = []
    for f in faces:
        if not any(f.IsPartner(g) for g in distinct):  # the same TShape, placed elsewhere
            distinct.append(f)
    assert len(distinct) == 53  # the file's 53 ADVANCED_FACEs ...
    assert len(model.surfaces) == len(faces) == 160  # ... placed 160 times by the assembly
    assert model.untrimmed == 0 and not model.warnings
    size = diagonal(shape)
    # parts in place: the extent of the faces' boundaries (where this model's
    # extremes are) is OpenCASCADE's tight box of the whole assembly
    extent = boundary_extent(model.surfaces)
    assert np.allclose(extent, tight_box(shape), rtol=0, atol=TOL * size), extent - tight_box(shape)
    # ... and surface by surface, on the faces of the same index
    check_faces(model, faces, size)
    # colours: every face has one; the parts' colours from the file (linear RGB)
    assert len(model.colors) == 160 and all(c is not None for c in model.colors)
    by_part = {}
    for name, color in zip(model.names, model.colors):
        by_part.setdefault(name.split("/")[-1].split("#")[0].rstrip("_0123456789"), set()).add(color)
    assert by_part["nut"] == {(1.0, 0.0, 0.0)} and by_part["bolt"] == {(0.0, 0.0, 1.0)}
    assert by_part["l-bracket"] == {(0.0, 1.0, 0.0)}
    (plate,) = by_part["plate"]  # COLOUR_RGB(0.8, 1, 0) in the file: sRGB 0.8 is linear 0.6038
    assert plate == pytest.approx((0.6038273, 1.0, 0.0), abs=1e-6)


# ---------------------------------------------------------------------------
# Errors and the command line


def test_garbage_step_is_one_input_error(tmp_path, capfd):
    path = tmp_path / "garbage.step"
    path.write_text("this is not\na STEP file\n")
    with pytest.raises(InputError) as err:
        load_model(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: OpenCASCADE cannot read this STEP file") and "\n" not in msg
    out, errs = capfd.readouterr()
    assert out == "" and errs == ""  # OpenCASCADE's own chatter is swallowed
    empty = tmp_path / "empty.stp"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="OpenCASCADE cannot read this STEP file"):
        load_model(empty)
    brep = tmp_path / "garbage.brep"
    brep.write_text("nonsense")
    with pytest.raises(InputError, match="cannot read this BREP file"):
        load_model(brep)
    with pytest.raises(InputError, match=r"format 'occt' reads STEP, BREP and IGES files"):
        load_model(tmp_path / "x.obj", format="occt")


def test_without_opencascade_one_message_names_the_extra(tmp_path, monkeypatch):
    """Without OCP (simulated: bsrt.io.occt.available says so) STEP, BREP and
    IGES-through-occt are one InputError naming the extra (the CLI exits 2)."""
    monkeypatch.setattr(occt, "available", lambda: False)
    for name, fmt, what in (
        ("a.step", "auto", "STEP"),
        ("b.STP", "auto", "STEP"),
        ("c.brep", "auto", "BREP"),
        ("d.igs", "occt", "IGES with format 'occt'"),
    ):
        with pytest.raises(InputError) as err:
            load_model(tmp_path / name, format=fmt)
        assert str(err.value) == f"{tmp_path / name}: reading {what} needs OpenCASCADE: pip install 'bsrt[cad]'"


@pytest.mark.gl
def test_cli_info_and_render_a_step_file(tmp_path, capsys):
    path = write_step(box_with_filleted_hole(), tmp_path / "x.step")
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{path}: 9 surfaces")
    png = tmp_path / "x.png"
    assert main(["render", str(path), "-o", str(png), "--width", "48", "--height", "48"]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    img = np.asarray(Image.open(png))
    assert png.stat().st_size > 0 and img.shape == (48, 48, 3)
    assert (img != img[0, 0]).any(axis=-1).sum() > 100  # the part is in the picture


def test_cli_garbage_step_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.stp"
    path.write_text("ISO-10303-21;\nnonsense\n")
    out = tmp_path / "bad.png"
    assert main(["render", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "bad.stp" in err and not out.exists()


# ---------------------------------------------------------------------------
# Every pixel against OpenCASCADE's exact ray / shape intersector


@pytest.mark.gl
@pytest.mark.parametrize("name", list(SHAPES) + ["as1-oc-214"])
def test_hits_agree_against_occt_intersector(tmp_path, name):
    """Every pixel's ray, traced by bsrt (trims included) and by OpenCASCADE's
    IntCurvesFace_ShapeIntersector on the faces OpenCASCADE reads from the same
    file: away from silhouettes and face edges (3 x 3 neighbourhoods that see
    one face) the same pixels hit, the same faces, at the same t to 1e-7 of
    the diagonal."""
    if name == "as1-oc-214":
        path, reference = AS1, _as1_reference()
    else:
        path = write_step(SHAPES[name](), tmp_path / f"{name}.step")
        reference = read_back(path)
    model = load_model(path)
    faces = _faces(reference)
    size = diagonal(reference)
    width = height = 96
    scene = scene_for_model(model, width, height)
    aovs = render(scene).aovs()
    directions = pixel_rays(scene.camera, width, height)
    hit, t, face = occt_hits(reference, scene.camera.eye, directions, size, faces)
    hit, t, face = hit.reshape(height, width), t.reshape(height, width), face.reshape(height, width)
    assert hit.sum() > 0.1 * width * height
    ours = np.where(aovs["hit"], aovs["surface"], -1)
    theirs = np.where(hit, face, -1)
    inside = interior(theirs)  # away from silhouettes and from the faces' edges
    both = inside & hit
    assert both.sum() > 0.25 * hit.sum()
    assert np.array_equal(aovs["hit"][inside], hit[inside])
    assert np.array_equal(ours[inside], theirs[inside])
    assert np.max(np.abs(aovs["t"][both] - t[both])) < TOL * size


@pytest.mark.gl
@pytest.mark.parametrize("brep_mode", [0, 1])
def test_step_and_iges_through_bsrts_own_reader_render_the_same_hits(tmp_path, brep_mode):
    """The box with a filleted hole written as STEP (read through OpenCASCADE) and as IGES
    (faces, or B-rep mode 186/514/510, read by bsrt's own IGES reader): the same hits."""
    from bsrt.rendering.options import RenderOptions
    from bsrt.scene import scene_for_model

    shape = box_with_filleted_hole()
    step = load_model(write_step(shape, tmp_path / "part.step"))
    iges = load_model(write_iges(shape, tmp_path / "part.igs", brep_mode), format="iges")
    assert len(iges.surfaces) == len(step.surfaces)
    assert all(s.is_trimmed for s in iges.surfaces)
    scene = scene_for_model(step, 96, 96)
    results = []
    for model in (step, iges):
        other = scene_for_model(model, 96, 96)
        other = type(other)(
            scene.film,
            scene.camera,
            other.render,
            other.materials,
            other.lights,
            other.surfaces,
            other.path,
            other.notes,
        )
        results.append(render(other, RenderOptions.resolve(other)).hits)
    a, b = results
    size = diagonal(read_back(tmp_path / "part.step"))
    away = interior(np.where(a.hit, 1, 0).reshape(96, 96)).ravel()
    np.testing.assert_array_equal(a.hit[away], b.hit[away])
    both = a.hit & b.hit & away
    assert both.sum() > 1000
    np.testing.assert_allclose(a.t[both], b.t[both], atol=1e-7 * size)
