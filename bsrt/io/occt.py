"""STEP, BREP and IGES B-reps through OpenCASCADE (the optional extra ``bsrt[cad]``).

(Over 500 lines on purpose: it keeps every use of the optional OCP bindings
in one module.) This is the only module that imports OpenCASCADE (the ``OCP`` bindings of
``cadquery-ocp-novtk``), and it does so inside functions, so the rest of bsrt
never needs it. ``read(path, format)`` turns every face of the file into one
trimmed :class:`~bsrt.bspline.BSplineSurface`:

1. **Shapes, placements, colours.** STEP and IGES go through the XCAF
   readers (``STEPCAFControl_Reader`` / ``IGESCAFControl_Reader``) into an
   XCAF document; ``XCAFPrs_DocumentExplorer`` walks its assembly tree and
   gives every leaf part its world placement and inherited style, and
   ``XCAFPrs::CollectStyleSettings`` the colours set on the part's
   sub-shapes (solids, shells, faces). A face's colour is its own, else that
   of the smallest sub-shape holding it, else the part's (instance
   colours override part colours). BREP files have no colours.
2. **Surfaces, exactly.** Each face's surface is cut to the face's (u, v)
   bounds and converted by ``GeomConvert::SurfaceToBSplineSurface``
   (the face's location applied to the control points afterwards):
   planes, cylinders, cones, spheres, tori, surfaces of revolution and
   extrusion, offsets of analytic surfaces and B-spline / Bezier surfaces
   all become exact (rational) B-splines, made non-periodic. A face that
   goes all the way round a periodic direction is cut at its own seam (see
   :func:`_convert_surface`). The conversion is checked at a 7 x 7 grid
   against the original surface; faces whose surface OpenCASCADE could
   only approximate (offsets of free-form surfaces) are counted in one
   warning. A part placed several times is converted once.
3. **Trim loops.** Every wire of the face (outer and inner alike: bsrt's
   rule is even-odd) becomes one :class:`~bsrt.trim.TrimLoop`, its edges'
   curves on the surface (pcurves) converted to 2-D B-splines by
   ``Geom2dConvert`` over the edge's range and reversed for reversed edges,
   so consecutive edges chain end to end. The faces are read FORWARD (bsrt
   shades both sides, so a reversed face looks the same). Seam edges of
   periodic surfaces occur twice in a wire with their two pcurves, one per
   side of the seam; pcurves a whole period off the face's bounds are
   shifted back. A face bounded by its surface's own bounds
   (``NaturalRestriction``) gets no loop.

   Converting an analytic surface changes its parametrisation: the
   B-spline's u of a cylinder is not the angle (it agrees with it only at
   the knots), so the original pcurves do not apply to the converted
   surface as they are. (``BRepBuilderAPI_NurbsConvert`` re-projects them,
   but only approximately: 6e-7 of the model's size off for a sphere cut by
   a cylinder, measured.) The reparametrisation is separable, u' = phi(u)
   and v' = psi(v), each a monotone function found by inverting the
   converted surface along one regular iso-line; this module computes it
   (and checks it on the grid). Pcurves on surfaces whose parametrisation
   is unchanged (planes, B-splines) are used as they are; iso-line pcurves
   (seams, the circles of cylinders and tori, the degenerate edges at a
   sphere's poles) map to exact straight segments; any other pcurve is
   mapped point by point and fitted, piecewise between the knots of both
   parametrisations, by polynomial pieces of degree 7 to within 1e-10 of
   the model's size. (OpenCASCADE's own pcurves and 3-D edges agree only
   to the edge tolerances: 2e-7 of the size for that sphere; the loops
   follow the pcurves, which define the face in its (u, v) domain.)

   The ends of consecutive curves are snapped together (they differ by at
   most the vertex tolerances), and a pcurve's excursions out of the
   surface's domain (third-party files have them, by about the edge
   tolerance) are cut off at the domain's edge. A face whose wires cannot
   be turned into closed loops in the surface's domain is drawn untrimmed,
   counted in ``Model.untrimmed``, with a warning saying why.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..bspline import BSplineSurface, evaluate, insert_knot, make_surface
from ..errors import InputError
from ..files import check_input_file
from ..trim import TrimCurve, TrimLoop, make_trim_curve

#: format name -> the extensions it reads (lower case, with the dot)
EXTENSIONS = {
    "step": (".step", ".stp", ".p21"),
    "brep": (".brep", ".brp"),
    "iges": (".igs", ".iges"),
}

_FIT_DEGREE = 7
_FIT_TOLERANCE = 1e-10  # fitted pcurves: largest 3-D error, as a fraction of the model's diagonal
_EXACT_TOLERANCE = 1e-9  # surfaces: the conversion counts as exact below this, as a fraction of the diagonal
_MAX_SPLITS = 40  # per edge: halvings of fitted pieces beyond the knots (a safeguard; none needed so far)


def available() -> bool:
    """Whether OpenCASCADE's Python bindings (``OCP``) are installed."""
    return importlib.util.find_spec("OCP") is not None


_WHAT = {"step": "STEP", "brep": "BREP", "iges": "IGES with format 'occt'"}


def needs_message(path: str, kind: str) -> str:
    """The one-line message for a file of ``kind`` ("step", "brep", "iges") when OpenCASCADE is missing."""
    return f"{path}: reading {_WHAT[kind]} needs OpenCASCADE: pip install 'bsrt[cad]'"


def kind_of(path: str, format: str) -> str:
    """"step", "brep" or "iges": which OpenCASCADE reader ``format`` ("step", "brep" or "occt") uses."""
    if format in ("step", "brep"):
        return format
    ext = os.path.splitext(path)[1].lower()
    for kind, exts in EXTENSIONS.items():
        if ext in exts:
            return kind
    known = ", ".join(e for exts in EXTENSIONS.values() for e in exts)
    raise InputError(
        f"{path}: format 'occt' reads STEP, BREP and IGES files by their extension ({known}), "
        f"not {ext or '(none)'!r}"
    )


def read(path, format: str = "occt", progress=None):
    """Read a STEP, BREP or IGES file through OpenCASCADE into a :class:`~bsrt.io.Model`.

    (Long: the reader's steps (transfer, assembly walk, face conversion,
    colours, warnings) run in one OCP session whose objects must stay alive.)

    format: "step", "brep", or "occt" (the reader is chosen by the extension,
    IGES included). Every face becomes one trimmed surface, in the file's
    assembly order, named ``FILE:ASSEMBLY/.../PART#k`` (k counts the faces of
    the part). ``Model.colors`` holds one linear RGB colour per surface (None
    where the file gives none) or is empty when the file has no colours.
    Raises InputError (one sentence naming the file) if OpenCASCADE is
    missing or cannot read the file. progress: None, or called as
    ``progress(done, total)`` (faces) as the faces are converted.
    """
    from . import Model

    path = os.fspath(path)
    kind = kind_of(path, format)
    try:
        import OCP  # noqa: F401
    except ImportError:
        raise InputError(needs_message(path, kind)) from None
    check_input_file(path, "model file")  # a FIFO or a device would block or never end
    try:
        with open(path, "rb"):
            pass
    except OSError as e:
        raise InputError(f"{path}: cannot read the file ({e.strerror or e})") from None
    leaves = _read_leaves(path, kind)
    diagonal = _diagonal(leaves)
    surfaces, names, colors, warnings = [], [], [], []
    untrimmed_reasons: list[str] = []
    approximated, worst_approx, skipped = 0, 0.0, {}
    free_edges = 0
    base = os.path.basename(path)
    converted: dict = {}  # a part placed several times is converted once, in its own frame
    total_faces, done = sum(1 for leaf in leaves if leaf.visible for _ in _faces(leaf.shape)), 0
    for leaf in leaves:
        if not leaf.visible:
            skipped["parts the file marks invisible"] = skipped.get("parts the file marks invisible", 0) + 1
            continue
        free_edges += _count_free_edges(leaf.shape)
        trsf = leaf.location.Transformation()
        scale = abs(float(trsf.ScaleFactor())) or 1.0
        placed = not leaf.location.IsIdentity()
        for k, face in enumerate(_faces(leaf.shape)):
            if progress is not None:
                progress(done, total_faces)
            done += 1
            key = _Key(face)
            if key not in converted:
                try:
                    converted[key] = convert_face(face, diagonal / scale)
                except _FaceError as e:
                    converted[key] = e
            result = converted[key]
            if isinstance(result, _FaceError):
                what = f"faces OpenCASCADE could not convert ({result})"
                skipped[what] = skipped.get(what, 0) + 1
                continue
            surface, info = result
            if info.untrimmed_reason:
                untrimmed_reasons.append(f"{leaf.name}#{k}: {info.untrimmed_reason}")
            if info.deviation * scale > _EXACT_TOLERANCE * diagonal:
                approximated += 1
                worst_approx = max(worst_approx, info.deviation * scale)
            surfaces.append(surface.transformed(_matrix(trsf)) if placed else surface)
            names.append(f"{base}:{leaf.name}#{k}")
            colors.append(leaf.face_colors.get(key, leaf.color))
    if progress is not None:
        progress(done, total_faces)
    if not surfaces:
        raise InputError(f"{path}: OpenCASCADE read the file but found no faces to draw")
    if approximated:
        warnings.append(
            f"{approximated} face{'s have' if approximated != 1 else ' has'} a surface OpenCASCADE could only "
            f"approximate (an offset of a free-form surface), up to {worst_approx / diagonal:.2g} of the model's "
            f"size off"
        )
    if untrimmed_reasons:
        n = len(untrimmed_reasons)
        warnings.append(
            f"{n} face{'s are' if n != 1 else ' is'} drawn untrimmed: {untrimmed_reasons[0]}"
            + (f" (and {n - 1} more)" if n > 1 else "")
        )
    if free_edges:
        skipped["edges not on any face (wireframe)"] = free_edges
    if all(c is None for c in colors):
        colors = []
    return Model(path, surfaces, names, skipped=skipped, warnings=warnings, untrimmed=len(untrimmed_reasons),
                 colors=colors)


# ---------------------------------------------------------------------------
# Reading the file: leaf parts with their placements and colours


@dataclass
class _Leaf:
    """One placed part: its shape (in the part's own frame), the TopLoc_Location
    to the world, a readable path, its colour and its sub-shapes' colours."""

    shape: object
    location: object
    name: str
    color: tuple | None
    face_colors: dict
    visible: bool = True


class _Key:
    """A dict key for a TopoDS shape that compares like IsSame (TShape and location)."""

    __slots__ = ("shape", "_hash")

    def __init__(self, shape):
        self.shape, self._hash = shape, hash(shape)

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        return isinstance(other, _Key) and self.shape.IsSame(other.shape)


class _FaceError(Exception):
    """A face that cannot become a surface at all."""


@contextmanager
def _captured_output():
    """Send what OpenCASCADE prints on stdout/stderr (at the C level) to a buffer.

    Yields a list that holds the captured text once the block ends (nothing
    is captured where the file descriptors 1 and 2 cannot be duplicated).
    """
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        fflush = ctypes.CDLL(None).fflush  # C stdio buffers (std::cout is synced with them)
    except (OSError, AttributeError, TypeError):
        fflush = None
    text: list[str] = []
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:
        yield text
        text.append("")
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        try:
            yield text
        finally:
            if fflush is not None:
                fflush(None)
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            sink.seek(0)
            text.append(sink.read().decode("utf-8", "replace"))


def _occt_complaint(text: str) -> str:
    """The first error line OpenCASCADE printed, without colour codes and stars."""
    import re

    for line in text.splitlines():
        line = re.sub(r"\x1b\[[0-9;]*m", "", line).strip(" *\t")
        if line and ("ERR" in line or "rror" in line or "Fail" in line):
            return line
    return ""


def _read_leaves(path: str, kind: str) -> list[_Leaf]:
    if kind == "brep":
        return _read_brep(path)
    return _read_xcaf(path, kind)


def _read_brep(path: str) -> list[_Leaf]:
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    with _captured_output() as out:
        try:
            ok = BRepTools.Read_s(shape, path, BRep_Builder())
        except Exception:  # OCP raises Standard_Failure subclasses for malformed files
            ok = False
    if not ok or shape.IsNull():
        why = _occt_complaint(out[0])
        raise InputError(f"{path}: OpenCASCADE cannot read this BREP file" + (f" ({why})" if why else ""))
    name = os.path.splitext(os.path.basename(path))[0]
    return [_Leaf(shape, TopLoc_Location(), name, None, {})]


def _read_xcaf(path: str, kind: str) -> list[_Leaf]:
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    app = XCAFApp_Application.GetApplication_s()
    doc = TDocStd_Document(TCollection_ExtendedString("MDTV-XCAF"))
    app.InitDocument(doc)
    if kind == "step":
        from OCP.STEPCAFControl import STEPCAFControl_Reader

        reader = STEPCAFControl_Reader()
    else:
        from OCP.IGESCAFControl import IGESCAFControl_Reader

        reader = IGESCAFControl_Reader()
    reader.SetColorMode(True)
    reader.SetNameMode(True)
    reader.SetLayerMode(False)
    label = "STEP" if kind == "step" else "IGES"
    with _captured_output() as out:
        try:
            status = reader.ReadFile(path)
            ok = status == IFSelect_RetDone and reader.Transfer(doc)
        except Exception:
            ok = False
    if not ok:
        why = _occt_complaint(out[0])
        raise InputError(f"{path}: OpenCASCADE cannot read this {label} file" + (f" ({why})" if why else ""))
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    return _leaves(doc, shape_tool)


def _label_name(label) -> str:
    from OCP.TDataStd import TDataStd_Name

    attr = TDataStd_Name()
    if label.FindAttribute(TDataStd_Name.GetID_s(), attr):
        name = attr.Get().ToExtString().strip()
        if name:
            return name.replace("/", "|")
    from OCP.TCollection import TCollection_AsciiString
    from OCP.TDF import TDF_Tool

    entry = TCollection_AsciiString()
    TDF_Tool.Entry_s(label, entry)
    return entry.ToCString()


def _rgb(style):
    if not style.IsSetColorSurf():
        return None
    c = style.GetColorSurf()  # Quantity_Color holds linear RGB
    return (float(c.Red()), float(c.Green()), float(c.Blue()))


def _leaves(doc, shape_tool) -> list[_Leaf]:
    """Every leaf part of the document's assembly tree, placed, with colours."""
    import OCP.collections as collections
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopLoc import TopLoc_Location
    from OCP.XCAFPrs import XCAFPrs, XCAFPrs_DocumentExplorer, XCAFPrs_DocumentExplorerFlags_None

    leaves: list[_Leaf] = []
    path: list[str] = []
    explorer = XCAFPrs_DocumentExplorer(doc, XCAFPrs_DocumentExplorerFlags_None)
    while explorer.More():
        node = explorer.Current()
        depth = explorer.CurrentDepth()
        del path[depth:]
        path.append(_label_name(node.Label))
        if not node.IsAssembly:
            shape = shape_tool.GetShape_s(node.RefLabel)
            if not shape.IsNull():
                styles = collections.IndexedDataMap_TopoDS_Shape_XCAFPrs_Style_TopTools_ShapeMapHasher()
                XCAFPrs.CollectStyleSettings_s(node.RefLabel, TopLoc_Location(), styles)
                entries = []
                for i in range(1, styles.Size() + 1):
                    sub, style = styles.FindKey(i), styles.FindFromIndex(i)
                    rgb = _rgb(style)
                    if rgb is not None and not sub.IsSame(shape):
                        entries.append((int(sub.ShapeType()), sub, rgb))
                face_colors = {}
                for _, sub, rgb in sorted(entries, key=lambda e: e[0]):  # compounds first, faces last
                    if int(sub.ShapeType()) == int(TopAbs_FACE):
                        face_colors[_Key(sub)] = rgb
                    else:
                        for face in _faces(sub):
                            face_colors[_Key(face)] = rgb
                leaves.append(_Leaf(shape, node.Location, "/".join(path), _rgb(node.Style), face_colors,
                                    bool(node.Style.IsVisible())))
        explorer.Next()
    return leaves


def _faces(shape):
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        yield _cast("Face", explorer.Current())
        explorer.Next()


def _count_free_edges(shape) -> int:
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    explorer = TopExp_Explorer(shape, TopAbs_EDGE, TopAbs_FACE)
    n = 0
    while explorer.More():
        n += 1
        explorer.Next()
    return n


def _cast(kind: str, shape):
    """TopoDS.Face(shape) (OCCT 8) or TopoDS.Face_s(shape) (OCCT 7)."""
    from OCP.TopoDS import TopoDS

    return (getattr(TopoDS, kind, None) or getattr(TopoDS, kind + "_s"))(shape)


def _diagonal(leaves) -> float:
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    for leaf in leaves:
        if leaf.visible:
            BRepBndLib.Add_s(leaf.shape.Moved(leaf.location), box)
    if box.IsVoid():
        return 1.0
    return max(float(np.sqrt(box.SquareExtent())), 1e-300)


# ---------------------------------------------------------------------------
# One face -> one trimmed B-spline surface


@dataclass
class FaceInfo:
    """What happened to a face: deviation is the largest distance (world units)
    between the converted surface and OpenCASCADE's at a grid of points;
    untrimmed_reason is "" when the trims were built."""

    deviation: float
    untrimmed_reason: str = ""
    identity: bool = True


def convert_face(face, diagonal: float) -> tuple[BSplineSurface, FaceInfo]:
    """A located TopoDS_Face -> (trimmed BSplineSurface, FaceInfo), in the frame
    the face's location maps to (the world's, for a face placed in it).

    diagonal: the model's size in that frame, the scale of the tolerances.
    """
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FORWARD
    from OCP.TopLoc import TopLoc_Location

    face = _cast("Face", face.Oriented(TopAbs_FORWARD))
    location = TopLoc_Location()
    original = BRep_Tool.Surface_s(face, location)
    if original is None:
        raise _FaceError("a face has no surface")
    trsf = location.Transformation()
    world_from_local = _matrix(trsf)
    scale = abs(float(trsf.ScaleFactor())) or 1.0
    local_size = diagonal / scale
    bounds = _face_bounds(face, original)
    local = _convert_surface(original, bounds, local_size)
    pmap = _ParamMap(original, local, bounds, local_size)
    info = FaceInfo(pmap.deviation * scale, identity=pmap.identity)
    try:
        # a face bounded by its surface's own bounds (NaturalRestriction) is the whole converted surface
        loops = [] if BRep_Tool.NaturalRestriction_s(face) else _face_loops(face, pmap, local_size)
        surface = local.with_trims(loops) if loops else local
    except (_TrimError, InputError) as e:
        info.untrimmed_reason = str(e)
        surface = local
    return surface.transformed(world_from_local), info


def _matrix(trsf) -> np.ndarray:
    """(4, 4) float64 of a gp_Trsf (its scale factor included)."""
    return np.array([[trsf.Value(r, c) for c in range(1, 5)] for r in range(1, 4)] + [[0.0, 0.0, 0.0, 1.0]])


def _face_bounds(face, surface) -> tuple[float, float, float, float]:
    """The face's (u, v) bounds, clipped to the surface's own bounds (and to one
    period in a periodic direction)."""
    from OCP.BRepTools import BRepTools

    umin, umax, vmin, vmax = BRepTools.UVBounds_s(face)
    su0, su1, sv0, sv1 = surface.Bounds()
    if not surface.IsUPeriodic():
        umin, umax = max(umin, su0), min(umax, su1)
    elif umax - umin > surface.UPeriod():
        umax = umin + surface.UPeriod()
    if not surface.IsVPeriodic():
        vmin, vmax = max(vmin, sv0), min(vmax, sv1)
    elif vmax - vmin > surface.VPeriod():
        vmax = vmin + surface.VPeriod()
    if not (np.isfinite([umin, umax, vmin, vmax]).all() and umin < umax and vmin < vmax):
        raise _FaceError("a face has an empty or infinite parameter range")
    return float(umin), float(umax), float(vmin), float(vmax)


def _convert_surface(surface, bounds, size: float) -> BSplineSurface:
    """The surface over ``bounds`` as an exact, non-periodic B-spline (local coordinates).

    A face that goes all the way round a periodic direction (a cylinder's
    side, a whole sphere) may have its seam anywhere, u = umin say.
    OpenCASCADE converts such a range by converting the whole period and
    cutting the periodic B-spline at umin, but in the B-spline's own
    parameter, which is not the angle: the cut would miss the seam. So
    the whole period is converted here, the B-spline parameter x0 of the
    seam's iso-line found by inverting a point of it, and the periodic
    B-spline cut at [x0, x0 + period].
    """
    from OCP.Geom import Geom_RectangularTrimmedSurface
    from OCP.GeomConvert import GeomConvert

    umin, umax, vmin, vmax = bounds
    full_u = surface.IsUPeriodic() and umax - umin >= surface.UPeriod() * (1 - 1e-12)
    full_v = surface.IsVPeriodic() and vmax - vmin >= surface.VPeriod() * (1 - 1e-12)
    su0, _, sv0, _ = surface.Bounds()
    window = [su0, su0 + surface.UPeriod()] if full_u else [umin, umax]
    window += [sv0, sv0 + surface.VPeriod()] if full_v else [vmin, vmax]
    try:
        bs = GeomConvert.SurfaceToBSplineSurface_s(Geom_RectangularTrimmedSurface(surface, *window))
    except Exception as e:
        raise _FaceError(f"OpenCASCADE cannot convert a {type(surface).__name__}: {e}") from None
    if full_u or full_v:
        whole = _extract(bs.Copy())
        u_mid, v_mid = 0.5 * (umin + umax), 0.5 * (vmin + vmax)
        seams = np.array([[umin, v_mid], [u_mid, vmin]])
        starts = seams.copy()
        for axis, (full, lo, period) in enumerate(((full_u, su0, window[1] - window[0]),
                                                   (full_v, sv0, window[3] - window[2]))):
            if full:
                starts[:, axis] = lo + np.mod(starts[:, axis] - lo, period)
        pts = np.array([[p.X(), p.Y(), p.Z()] for p in (surface.Value(*map(float, uv)) for uv in seams)])
        x, y = _invert(whole, pts, starts[:, 0], starts[:, 1], size)
        a0, a1 = (x[0], x[0] + window[1] - window[0]) if full_u else (window[0], window[1])
        b0, b1 = (y[1], y[1] + window[3] - window[2]) if full_v else (window[2], window[3])
        try:
            if full_u and not bs.IsUPeriodic():
                bs.SetUPeriodic()
            if full_v and not bs.IsVPeriodic():
                bs.SetVPeriodic()
            bs.Segment(float(a0), float(a1), float(b0), float(b1))
        except Exception as e:
            raise _FaceError(f"OpenCASCADE cannot cut a periodic {type(surface).__name__} at its seam: {e}") from None
    return _extract(bs)


def _extract(bs) -> BSplineSurface:
    """A Geom_BSplineSurface (made non-periodic, in place) as a BSplineSurface."""
    if bs.IsUPeriodic():
        bs.SetUNotPeriodic()
    if bs.IsVPeriodic():
        bs.SetVNotPeriodic()
    nu, nv = bs.NbUPoles(), bs.NbVPoles()
    points = np.empty((nu, nv, 3))
    weights = np.empty((nu, nv))
    for i in range(nu):
        for j in range(nv):
            p = bs.Pole(i + 1, j + 1)
            points[i, j] = p.X(), p.Y(), p.Z()
            weights[i, j] = bs.Weight(i + 1, j + 1)
    knots_u = _flat_knots(bs.UKnot, bs.UMultiplicity, bs.NbUKnots())
    knots_v = _flat_knots(bs.VKnot, bs.VMultiplicity, bs.NbVKnots())
    try:
        return make_surface((bs.UDegree(), bs.VDegree()), knots_u, knots_v, points,
                            None if np.all(weights == 1.0) else weights)
    except InputError as e:
        raise _FaceError(f"the converted surface is invalid ({e})") from None


def _flat_knots(knot, multiplicity, n) -> np.ndarray:
    return np.repeat([knot(i) for i in range(1, n + 1)], [multiplicity(i) for i in range(1, n + 1)]).astype(np.float64)


class _ParamMap:
    """The map from the original surface's (u, v) to the converted B-spline's.

    OpenCASCADE converts each direction on its own (circles to rational
    arcs, lines stay lines), so the map is u' = phi(u), v' = psi(v). phi is
    found by inverting the B-spline along the iso-line v = v_ref of the
    original surface (a regular one, mid-range), psi along u = u_ref. The
    map is checked on a 7 x 7 grid: ``deviation`` is the largest distance
    (local units) between S(u, v) and the B-spline at (phi(u), psi(v)).
    ``identity``: phi and psi are the identity (planes, B-splines).
    """

    def __init__(self, original, local: BSplineSurface, bounds, size: float):
        self.original, self.local, self.bounds, self.size = original, local, bounds, size
        umin, umax, vmin, vmax = bounds
        self.u_ref, self.v_ref = 0.5 * (umin + umax), 0.5 * (vmin + vmax)
        self.u_periodic = original.IsUPeriodic()
        self.v_periodic = original.IsVPeriodic()
        self.u_period = original.UPeriod() if self.u_periodic else 0.0
        self.v_period = original.VPeriod() if self.v_periodic else 0.0
        fractions = np.array([0.0, 0.137, 0.291, 0.5, 0.618, 0.853, 1.0])  # not symmetric: arcs map their middles to themselves
        gu, gv = umin + fractions * (umax - umin), vmin + fractions * (vmax - vmin)
        pu, pv = self.phi(gu), self.psi(gv)
        su = max(umax - umin, 1e-300)
        sv = max(vmax - vmin, 1e-300)
        self.identity = bool(np.all(np.abs(pu - gu) <= 1e-12 * su) and np.all(np.abs(pv - gv) <= 1e-12 * sv))
        uu, vv = np.meshgrid(gu, gv, indexing="ij")
        want = self.point(uu.ravel(), vv.ravel())
        uu2, vv2 = np.meshgrid(pu, pv, indexing="ij")
        got = evaluate(local, uu2.ravel(), vv2.ravel())[0]
        self.deviation = float(np.max(np.linalg.norm(got - want, axis=1)))
        self.separable = self.deviation <= _EXACT_TOLERANCE * size

    def point(self, u, v) -> np.ndarray:
        """(N, 3) points of the original surface (local coordinates)."""
        out = np.empty((len(u), 3))
        value = self.original.Value
        for k, (a, b) in enumerate(zip(np.asarray(u, float), np.asarray(v, float))):
            p = value(float(a), float(b))
            out[k] = p.X(), p.Y(), p.Z()
        return out

    def _guess(self, u, v):
        """Affine map of the original bounds onto the B-spline's domain: the Newton start."""
        umin, umax, vmin, vmax = self.bounds
        (a0, a1), (b0, b1) = self.local.domain_u, self.local.domain_v
        return a0 + (u - umin) / (umax - umin) * (a1 - a0), b0 + (v - vmin) / (vmax - vmin) * (b1 - b0)

    def phi(self, u) -> np.ndarray:
        u = np.atleast_1d(np.asarray(u, dtype=np.float64))
        if u.size == 0:
            return u.copy()
        v = np.full_like(u, self.v_ref)
        x0, y0 = self._guess(u, v)
        x, _ = _invert(self.local, self.point(u, v), x0, y0, self.size)
        return x

    def psi(self, v) -> np.ndarray:
        v = np.atleast_1d(np.asarray(v, dtype=np.float64))
        if v.size == 0:
            return v.copy()
        u = np.full_like(v, self.u_ref)
        x0, y0 = self._guess(u, v)
        _, y = _invert(self.local, self.point(u, v), x0, y0, self.size)
        return y

    def map(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) original (u, v) -> (N, 2) B-spline (u', v')."""
        if self.identity:
            return uv.copy()
        x, y = self.phi(uv[:, 0]), self.psi(uv[:, 1])
        if not self.separable:  # an approximated surface: the nearest point of the B-spline
            x, y = _invert(self.local, self.point(uv[:, 0], uv[:, 1]), x, y, self.size)
        return np.stack([x, y], axis=1)

    def inverse_u(self, x: float) -> float:
        """The u with phi(u) = x (phi is monotone)."""
        return self._inverse(self.phi, x, self.bounds[0], self.bounds[1])

    def inverse_v(self, y: float) -> float:
        return self._inverse(self.psi, y, self.bounds[2], self.bounds[3])

    @staticmethod
    def _inverse(f, target, lo, hi) -> float:
        grid = np.linspace(lo, hi, 33)
        values = f(grid) - target
        k = int(np.searchsorted(values, 0.0)) if values[-1] >= values[0] else int(np.searchsorted(-values, 0.0))
        k = min(max(k, 1), grid.size - 1)
        a, b, fa, fb = grid[k - 1], grid[k], values[k - 1], values[k]
        side = 0
        for _ in range(100):  # Illinois regula falsi
            if fb == fa:
                break
            c = b - fb * (b - a) / (fb - fa)
            fc = float(f(c)[0]) - target
            if fc * fb < 0:
                a, fa = b, fb
                if side == -1:
                    fa *= 0.5
                side = -1
            else:
                if side == 1:
                    fa *= 0.5
                side = 1
            b, fb = c, fc
            if abs(fc) == 0.0 or abs(b - a) <= 1e-15 * max(1.0, abs(b), hi - lo):
                break
        return float(b)


def _invert(surface: BSplineSurface, points: np.ndarray, x, y, size: float, iterations: int = 60):
    """(x, y) in the surface's domain with S(x, y) nearest ``points`` (N, 3), from the starts x, y.

    Damped Gauss-Newton (Levenberg-Marquardt), clamped to the domain; at a
    degenerate point (a pole) the free parameter stays at its start.
    """
    (a0, a1), (b0, b1) = surface.domain_u, surface.domain_v
    x = np.clip(np.array(x, dtype=np.float64), a0, a1)
    y = np.clip(np.array(y, dtype=np.float64), b0, b1)
    active = np.ones(x.shape, dtype=bool)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        s, su, sv = evaluate(surface, x[idx], y[idx])
        r = points[idx] - s
        a = np.einsum("ni,ni->n", su, su)
        b = np.einsum("ni,ni->n", su, sv)
        c = np.einsum("ni,ni->n", sv, sv)
        g0 = np.einsum("ni,ni->n", su, r)
        g1 = np.einsum("ni,ni->n", sv, r)
        damp = 1e-14 * (a + c) + 1e-300
        a, c = a + damp, c + damp
        det = a * c - b * b
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        dx = (c * g0 - b * g1) / det
        dy = (a * g1 - b * g0) / det
        nx = np.clip(x[idx] + dx, a0, a1)
        ny = np.clip(y[idx] + dy, b0, b1)
        step = np.hypot(nx - x[idx], ny - y[idx])
        x[idx], y[idx] = nx, ny
        scale = max(1.0, abs(a0), abs(a1), abs(b0), abs(b1))
        done = (step <= 1e-14 * scale) | (np.linalg.norm(r, axis=1) <= 1e-14 * size)  # rounding level
        active[idx[done]] = False
    return x, y


class _TrimError(Exception):
    """The face's wires do not make closed loops in the surface's domain."""


def _face_loops(face, pmap: _ParamMap, size: float) -> list[TrimLoop]:
    from OCP.TopAbs import TopAbs_WIRE
    from OCP.TopExp import TopExp_Explorer

    loops = []
    explorer = TopExp_Explorer(face, TopAbs_WIRE)
    while explorer.More():
        wire = _cast("Wire", explorer.Current())
        curves = [c for edge in _wire_edges(wire, face) for c in _edge_curves(edge, face, pmap, size)]
        if curves:
            loops.append(TrimLoop(tuple(_close(curves, pmap.local, size))))
        explorer.Next()
    return loops


def _wire_edges(wire, face) -> list:
    """The wire's edges in order along the wire, each with its orientation in the face."""
    from OCP.BRepTools import BRepTools_WireExplorer
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    edges = []
    try:
        walker = BRepTools_WireExplorer(wire, face)
        while walker.More():
            edges.append(_cast("Edge", walker.Current()))
            walker.Next()
    except Exception:
        edges = []
    count = 0
    explorer = TopExp_Explorer(wire, TopAbs_EDGE)
    stored = []
    while explorer.More():
        stored.append(_cast("Edge", explorer.Current()))
        count += 1
        explorer.Next()
    return edges if len(edges) == count else stored  # the walker skips edges of odd wires: take them all


def _edge_curves(edge, face, pmap: _ParamMap, size: float) -> list[TrimCurve]:
    """The edge's pcurve as trim curves in the converted surface's domain, in the edge's direction."""
    from OCP.BRep import BRep_Tool
    from OCP.Geom2d import Geom2d_TrimmedCurve
    from OCP.Geom2dConvert import Geom2dConvert
    from OCP.TopAbs import TopAbs_REVERSED

    pcurve = BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0)
    if pcurve is None:
        raise _TrimError("an edge has no curve on the face")
    first, last = BRep_Tool.Range_s(edge, face)
    if not first < last:
        return []
    try:
        bc = Geom2dConvert.CurveToBSplineCurve_s(Geom2d_TrimmedCurve(pcurve, first, last))
    except Exception as e:
        raise _TrimError(f"OpenCASCADE cannot convert a {type(pcurve).__name__} pcurve ({e})") from None
    if bc.IsPeriodic():
        bc.SetNotPeriodic()
    n = bc.NbPoles()
    points = np.array([[bc.Pole(i).X(), bc.Pole(i).Y()] for i in range(1, n + 1)])
    weights = np.array([bc.Weight(i) for i in range(1, n + 1)])
    knots = _flat_knots(bc.Knot, bc.Multiplicity, bc.NbKnots())
    if edge.Orientation() == TopAbs_REVERSED:
        points, weights, knots = points[::-1], weights[::-1], (knots[0] + knots[-1]) - knots[::-1]
    try:
        curve = make_trim_curve(bc.Degree(), knots, points, None if np.all(weights == 1.0) else weights)
    except InputError as e:
        raise _TrimError(f"a pcurve is invalid ({e})") from None
    curve = _into_period(curve, pmap)
    if pmap.identity:
        return [curve]
    return [_mapped(curve, pmap, size)]


def _into_period(curve: TrimCurve, pmap: _ParamMap) -> TrimCurve:
    """The curve shifted by whole periods so that it lies in the face's (u, v) bounds."""
    umin, umax, vmin, vmax = pmap.bounds
    pts = curve.evaluate(np.linspace(*curve.domain, 9))
    shift = np.zeros(2)
    for axis, (lo, hi, period) in enumerate(((umin, umax, pmap.u_period), (vmin, vmax, pmap.v_period))):
        if period > 0:
            mid = 0.5 * (pts[:, axis].min() + pts[:, axis].max())
            if not lo - 1e-9 * period <= mid <= hi + 1e-9 * period:
                shift[axis] = period * np.round((0.5 * (lo + hi) - mid) / period)
    if not shift.any():
        return curve
    return TrimCurve(curve.degree, curve.knots, curve.points + shift, curve.weights)


def _mapped(curve: TrimCurve, pmap: _ParamMap, size: float) -> TrimCurve:
    """The pcurve (in the original (u, v)) as a curve in the converted B-spline's (u', v')."""
    t0, t1 = curve.domain
    t = np.linspace(t0, t1, 17 + 8 * curve.points.shape[0])
    uv = curve.evaluate(t)
    spans = np.array([pmap.bounds[1] - pmap.bounds[0], pmap.bounds[3] - pmap.bounds[2]])
    for axis in (0, 1):  # an iso-line (axis fixed): a straight segment, exactly
        fixed, moving = uv[:, axis], uv[:, 1 - axis]
        if np.ptp(fixed) <= 1e-13 * spans[axis] and (np.all(np.diff(moving) >= 0) or np.all(np.diff(moving) <= 0)):
            ends = np.empty((2, 2))
            ends[:, axis] = fixed.mean()
            ends[:, 1 - axis] = moving[[0, -1]]
            return make_trim_curve(1, [0.0, 0.0, 1.0, 1.0], pmap.map(ends))
    breaks = {t0, t1}
    inner = np.unique(curve.knots[(curve.knots > t0) & (curve.knots < t1)])
    breaks.update(float(x) for x in inner)
    for axis, knots in ((0, pmap.local.knots_u), (1, pmap.local.knots_v)):
        lo, hi = (pmap.local.domain_u if axis == 0 else pmap.local.domain_v)
        for k in np.unique(knots[(knots > lo) & (knots < hi)]):
            value = pmap.inverse_u(k) if axis == 0 else pmap.inverse_v(k)
            breaks.update(_crossings(curve, axis, value, t, uv[:, axis]))
    return _fit(curve, pmap, sorted(breaks), size)


def _crossings(curve: TrimCurve, axis: int, value: float, t: np.ndarray, samples: np.ndarray) -> list[float]:
    """Parameters where the curve's coordinate ``axis`` equals ``value`` (sign changes on the samples)."""
    d = samples - value
    found = []
    for k in np.flatnonzero(d[:-1] * d[1:] < 0):
        a, b = t[k], t[k + 1]
        fa = d[k]
        for _ in range(200):
            c = 0.5 * (a + b)
            fc = curve.evaluate([c])[0, axis] - value
            if fc == 0 or b - a <= 1e-15 * max(1.0, abs(c)):
                break
            if (fc < 0) == (fa < 0):
                a, fa = c, fc
            else:
                b = c
        found.append(float(c))
    found.extend(float(x) for x in t[d == 0])  # a sample right on the value
    return found


def _fit(curve: TrimCurve, pmap: _ParamMap, breaks: list[float], size: float) -> TrimCurve:
    """Piecewise polynomial fit (degree 7, C0 at the breaks) of t -> map(curve(t))."""
    d = _FIT_DEGREE
    nodes = 0.5 - 0.5 * np.cos(np.pi * np.arange(d + 1) / d)  # Chebyshev-Lobatto on [0, 1]
    bern = _bernstein(d, nodes)
    checks = (np.arange(24) + 0.5) / 24
    bern_checks = _bernstein(d, checks)
    tol = _FIT_TOLERANCE * size
    pieces: list[tuple[float, float, np.ndarray]] = []
    todo = [(a, b) for a, b in zip(breaks[:-1], breaks[1:]) if b > a]
    splits = 0
    while todo:
        a, b = todo.pop(0)
        target = pmap.map(curve.evaluate(a + (b - a) * nodes))
        ctrl = np.linalg.solve(bern, target)
        want = pmap.map(curve.evaluate(a + (b - a) * checks))
        got = bern_checks @ ctrl
        error = np.max(np.linalg.norm(evaluate(pmap.local, got[:, 0], got[:, 1])[0]
                                      - evaluate(pmap.local, want[:, 0], want[:, 1])[0], axis=1))
        if error > tol and splits < _MAX_SPLITS and b - a > 1e-12 * (breaks[-1] - breaks[0]):
            splits += 1
            m = 0.5 * (a + b)
            todo[:0] = [(a, m), (m, b)]
            continue
        pieces.append((a, b, ctrl))
    pieces.sort(key=lambda p: p[0])
    points = [pieces[0][2][0]]
    knots = [pieces[0][0]] * (d + 1)
    for a, b, ctrl in pieces:
        points.extend(ctrl[1:])
        knots.extend([b] * d)
    knots.append(pieces[-1][1])
    return make_trim_curve(d, np.array(knots), np.array(points))


def _bernstein(d: int, s: np.ndarray) -> np.ndarray:
    from math import comb

    k = np.arange(d + 1)
    return np.array([comb(d, int(i)) for i in k])[None, :] * s[:, None] ** k[None, :] * (1 - s[:, None]) ** (d - k[None, :])


def _close(curves: list[TrimCurve], surface: BSplineSurface, size: float) -> list[TrimCurve]:
    """Chain the curves end to end (snapping ends that differ by at most the
    vertex tolerances) and cut off their excursions out of the domain."""
    ends = [c.ends() for c in curves]
    n = len(curves)
    gaps = [np.hypot(*(ends[i][1] - ends[(i + 1) % n][0])) for i in range(n)]
    (a0, a1), (b0, b1) = surface.domain_u, surface.domain_v
    scale = np.hypot(a1 - a0, b1 - b0)
    if max(gaps) > 1e-6 * scale:  # not in order along the wire: chain them greedily
        curves = _chain(curves, scale)
        ends = [c.ends() for c in curves]
    pts = [c.points.copy() for c in curves]
    worst = 0.0
    for i in range(n):
        j = (i + 1) % n
        a, b = ends[i][1], ends[j][0]
        s = evaluate(surface, np.array([a[0], b[0]]), np.array([a[1], b[1]]))[0]
        worst = max(worst, float(np.linalg.norm(s[0] - s[1])))
        mid = 0.5 * (a + b)
        pts[i][-1] = mid
        pts[j][0] = mid
    if worst > max(1e-3 * size, 1e-6):
        raise _TrimError(f"a wire does not close in the surface's domain (gap {worst:.3g})")
    return [_inside_domain(make_trim_curve(c.degree, c.knots, p, c.weights), (a0, a1, b0, b1)) for c, p in
            zip(curves, pts)]


def _inside_domain(curve: TrimCurve, domain) -> TrimCurve:
    """The curve with its excursions out of the surface's domain moved onto the domain's edge.

    A face's pcurves may leave the surface's parameter domain by about the
    edge tolerance (third-party files). Only the part inside the domain
    matters (the surface has nothing outside it), so each excursion is cut
    off exactly (its ends found by bisection, the curve split there by knot
    insertion) and its control points clipped onto the domain's edge; the
    rest of the curve is unchanged.
    """
    a0, a1, b0, b1 = domain
    lo, hi = curve.domain
    t = np.linspace(lo, hi, 64 * (curve.points.shape[0] + 1))
    eps = 1e-12 * np.hypot(a1 - a0, b1 - b0)  # a curve along the edge is inside, rounding aside

    def inside(x):
        uv = curve.evaluate(np.atleast_1d(x))
        return (uv[:, 0] >= a0 - eps) & (uv[:, 0] <= a1 + eps) & (uv[:, 1] >= b0 - eps) & (uv[:, 1] <= b1 + eps)

    state = inside(t)
    if state.all():
        return curve
    cuts = []
    for k in np.flatnonzero(state[:-1] != state[1:]):
        a, b, sa = t[k], t[k + 1], state[k]
        for _ in range(60):
            m = 0.5 * (a + b)
            if inside(m)[0] == sa:
                a = m
            else:
                b = m
        cuts.append(0.5 * (a + b))
    p = curve.degree
    knots, ctrl = curve.knots, curve.homogeneous()
    for x in cuts:
        for _ in range(p - int(np.count_nonzero(knots == x))):
            knots, ctrl = insert_knot(knots, ctrl, p, x)
    points = ctrl[:, :2] / ctrl[:, 2:3]
    weights = ctrl[:, 2]
    bounds = np.concatenate([[lo], cuts, [hi]])
    for a, b in zip(bounds[:-1], bounds[1:]):
        if not inside(0.5 * (a + b))[0]:  # an excursion: its control points onto the edge
            first = int(np.searchsorted(knots, a, side="right")) - 1 - p
            last = int(np.searchsorted(knots, b, side="left"))
            piece = points[max(first, 0): last]
            piece[:, 0] = np.clip(piece[:, 0], a0, a1)
            piece[:, 1] = np.clip(piece[:, 1], b0, b1)
    return make_trim_curve(p, knots, points, None if curve.weights is None else weights)


def _reversed(c: TrimCurve) -> TrimCurve:
    return TrimCurve(c.degree, (c.knots[0] + c.knots[-1]) - c.knots[::-1], c.points[::-1].copy(),
                     None if c.weights is None else c.weights[::-1].copy())


def _chain(curves: list[TrimCurve], scale: float) -> list[TrimCurve]:
    """Order (and reverse where needed) the curves so each starts where the previous ends."""
    left = list(curves[1:])
    out = [curves[0]]
    while left:
        end = out[-1].ends()[1]
        best, k, flip = np.inf, 0, False
        for i, c in enumerate(left):
            e = c.ends()
            for f, p in ((False, e[0]), (True, e[1])):
                d = np.hypot(*(p - end))
                if d < best:
                    best, k, flip = d, i, f
        c = left.pop(k)
        out.append(_reversed(c) if flip else c)
    if np.hypot(*(out[-1].ends()[1] - out[0].ends()[0])) > 1e-6 * scale:
        raise _TrimError("a wire does not close in the surface's parameter domain")
    return out
