"""STEP, BREP and IGES B-reps through OpenCASCADE (the optional extra ``bsrt[cad]``).

This package is the only code that imports OpenCASCADE (the ``OCP``
bindings of ``cadquery-ocp-novtk``), and it does so inside functions (its
modules import without it), so the rest of bsrt never needs it. ``read(path, format)`` turns every face of the
file into one trimmed :class:`~bsrt.geometry.bspline.BSplineSurface`. One module per
concern:

- :mod:`.reading`: the file, its assembly tree, placements and colours;
- :mod:`.surfaces`: a face's surface as an exact, non-periodic B-spline cut
  to the face's bounds (rotated to the face's own seam), and the closed-form
  map of its parameters;
- :mod:`.curves`: pcurves as OpenCASCADE gives them, mapped into the
  B-spline's domain (exactly where the map allows, else fitted all at once);
- :mod:`.topology`: wires to closed trim loops across seams and poles.

The faces are read FORWARD (bsrt shades both sides, so a reversed face looks
the same); ``Model.reversed`` keeps each face's orientation (REVERSED, or
mirrored by a placement) for the outward normals of ray queries. A part placed several times is converted once. A face whose
wires cannot be made into closed loops is drawn over its (u, v) bounds and
named in a warning with the reason; a face OpenCASCADE cannot convert is
named in a warning and left out.
"""

from __future__ import annotations

import importlib.util
import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bsrt.errors import InputError
from bsrt.files import check_input_file
from bsrt.geometry.bspline import BSplineSurface
from bsrt.io.formats import READERS
from bsrt.io.occt.curves import TrimError
from bsrt.io.occt.reading import ShapeKey, cast, count_free_edges, diagonal, faces, read_leaves
from bsrt.io.occt.surfaces import EXACT_TOLERANCE, FaceError, convert_surface
from bsrt.io.occt.topology import face_loops

#: kind -> the extensions OpenCASCADE reads it from (the reader registry's; IGES is bsrt's own "iges" format)
EXTENSIONS = {kind: READERS[kind].extensions for kind in ("step", "brep", "iges")}

_WHAT = {"step": "STEP", "brep": "BREP", "iges": "IGES with format 'occt'"}


def available() -> bool:
    """Whether OpenCASCADE's Python bindings (``OCP``) are installed."""
    return importlib.util.find_spec("OCP") is not None


def needs_message(path: str, kind: str) -> str:
    """The one-line message for a file of ``kind`` ("step", "brep", "iges") when OpenCASCADE is missing."""
    return f"{path}: reading {_WHAT[kind]} needs OpenCASCADE: pip install 'bsrt[cad]'"


def kind_of(path: str, format: str) -> str:
    """ "step", "brep" or "iges": which OpenCASCADE reader ``format`` ("step", "brep" or "occt") uses."""
    if format in ("step", "brep"):
        return format
    ext = os.path.splitext(path)[1].lower()
    for kind, exts in EXTENSIONS.items():
        if ext in exts:
            return kind
    known = ", ".join(e for exts in EXTENSIONS.values() for e in exts)
    raise InputError(
        f"{path}: format 'occt' reads STEP, BREP and IGES files by their extension ({known}), not {ext or '(none)'!r}"
    )


@dataclass
class FaceInfo:
    """What happened to a face: deviation is the largest distance (world units) between the converted
    surface and OpenCASCADE's on a grid; approximated: an offset of a free-form surface, approximated;
    untrimmed_reason is "" when the trims were built."""

    deviation: float
    approximated: bool = False
    untrimmed_reason: str = ""
    mirrored: bool = False  # the face's own location reverses orientation (a negative determinant)


def convert_face(face, diagonal: float) -> tuple[BSplineSurface, FaceInfo]:
    """A located TopoDS_Face -> (trimmed BSplineSurface, FaceInfo), in the frame the face's location maps to.

    diagonal: the model's size in that frame, the scale of the tolerances.
    Raises :class:`~bsrt.io.occt.surfaces.FaceError` for a face with no
    usable surface.
    """
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FORWARD
    from OCP.TopLoc import TopLoc_Location

    face = cast("Face", face.Oriented(TopAbs_FORWARD))
    location = TopLoc_Location()
    original = BRep_Tool.Surface_s(face, location)
    if original is None:
        raise FaceError("a face has no surface")
    trsf = location.Transformation()
    scale = abs(float(trsf.ScaleFactor())) or 1.0
    local_size = diagonal / scale
    bounds = _face_bounds(face, original)
    local, pmap = convert_surface(original, bounds, local_size)
    info = FaceInfo(pmap.deviation * scale, approximated=pmap.approximated, mirrored=bool(trsf.IsNegative()))
    try:
        # a face bounded by its surface's own bounds (NaturalRestriction) is the whole converted surface
        loops = [] if BRep_Tool.NaturalRestriction_s(face) else face_loops(face, original, pmap, local, local_size)
        surface = local.with_trims(loops) if loops else local
    except (TrimError, InputError) as e:
        info.untrimmed_reason = str(e)
        surface = local
    if trsf.Form() == _identity_form():  # (a no-op: skipped)
        return surface, info
    return surface.transformed(matrix(trsf)), info


def _identity_form():
    from OCP.gp import gp_TrsfForm

    return gp_TrsfForm.gp_Identity


def matrix(trsf) -> np.ndarray:
    """(4, 4) float64 of a gp_Trsf (its scale factor included)."""
    return np.array([[trsf.Value(r, c) for c in range(1, 5)] for r in range(1, 4)] + [[0.0, 0.0, 0.0, 1.0]])


def _face_bounds(face, surface) -> tuple[float, float, float, float]:
    """The face's (u, v) bounds, clipped to the surface's own bounds (and to one period in a periodic direction)."""
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
    if not (all(map(math.isfinite, (umin, umax, vmin, vmax))) and umin < umax and vmin < vmax):
        raise FaceError("a face has an empty or infinite parameter range")
    return float(umin), float(umax), float(vmin), float(vmax)


def read(path, format: str = "occt", progress: Callable[[int, int], None] | None = None):
    """Read a STEP, BREP or IGES file through OpenCASCADE into a :class:`~bsrt.io.Model`.

    format: "step", "brep", or "occt" (the reader is chosen by the extension,
    IGES included). Every face becomes one trimmed surface, in the file's
    assembly order, named ``FILE:ASSEMBLY/.../PART#k`` (k counts the faces of
    the part). ``Model.colors`` holds one linear RGB colour per surface (None
    where the file gives none) or is empty when the file has no colours.
    progress: called as progress(faces done, faces in all) while faces are
    converted. Raises InputError (one sentence naming the file) if OpenCASCADE
    is missing or cannot read the file.
    """
    from bsrt.io.model import Model

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
    leaves = read_leaves(path, kind)
    size = diagonal(leaves)
    visible = [leaf for leaf in leaves if leaf.visible]
    placed = [(leaf, list(faces(leaf.shape))) for leaf in visible]
    total = sum(len(f) for _, f in placed)
    from OCP.TopAbs import TopAbs_REVERSED

    surfaces, names, colors, warnings, reversed_ = [], [], [], [], []
    untrimmed: list[str] = []
    not_converted: list[str] = []
    approximated, worst_approx = 0, 0.0
    skipped: dict[str, int] = {}
    hidden = len(leaves) - len(visible)
    if hidden:
        skipped["parts the file marks invisible"] = hidden
    free_edges = 0
    base = os.path.basename(path)
    converted: dict = {}  # a part placed several times is converted once, in its own frame
    done = 0
    if progress is not None:
        progress(0, total)
    for leaf, leaf_faces in placed:
        free_edges += count_free_edges(leaf.shape)
        trsf = leaf.location.Transformation()
        scale = abs(float(trsf.ScaleFactor())) or 1.0
        moved = not leaf.location.IsIdentity()
        mirrored = bool(trsf.IsNegative())
        for k, face in enumerate(leaf_faces):
            key = ShapeKey(face)
            if key not in converted:
                try:
                    converted[key] = convert_face(face, size / scale)
                except FaceError as e:
                    converted[key] = e
            done += 1
            if progress is not None:
                progress(done, total)
            result = converted[key]
            name = f"{leaf.name}#{k}"
            if isinstance(result, FaceError):
                not_converted.append(f"{name}: {result}")
                continue
            surface, info = result
            if info.untrimmed_reason:
                untrimmed.append(f"{name}: {info.untrimmed_reason}")
            if info.approximated:
                approximated += 1
                worst_approx = max(worst_approx, info.deviation * scale)
            surfaces.append(surface.transformed(matrix(trsf)) if moved else surface)
            names.append(f"{base}:{name}")
            reversed_.append((face.Orientation() == TopAbs_REVERSED) ^ mirrored ^ info.mirrored)
            colors.append(leaf.face_colors.get(key, leaf.color))
    if not surfaces:
        raise InputError(
            f"{path}: OpenCASCADE read the file but found no faces to draw"
            + (f" ({not_converted[0]})" if not_converted else "")
        )
    if approximated:
        warnings.append(
            f"{approximated} face{'s have' if approximated != 1 else ' has'} an offset of a free-form surface, "
            f"approximated to within {max(worst_approx / size, EXACT_TOLERANCE):.2g} of the model's size"
        )
    for what, items in (
        ("drawn over its (u, v) bounds, untrimmed", untrimmed),
        ("left out: OpenCASCADE cannot convert it", not_converted),
    ):
        if items:
            n = len(items)
            warnings.append(
                f"{n} face{'s are' if n != 1 else ' is'} {what.replace('its', 'their') if n != 1 else what}"
                f": {items[0]}" + (f" (and {n - 1} more)" if n > 1 else "")
            )
    if not_converted:
        skipped["faces OpenCASCADE could not convert"] = len(not_converted)
    if free_edges:
        skipped["edges not on any face (wireframe)"] = free_edges
    if all(c is None for c in colors):
        colors = []
    return Model(
        path,
        surfaces,
        names,
        skipped=skipped,
        warnings=warnings,
        untrimmed=len(untrimmed),
        colors=colors,
        reversed=reversed_ if any(reversed_) else [],
    )
