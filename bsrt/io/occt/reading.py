"""Reading a file through OpenCASCADE: the shapes, their placements and colours.

STEP and IGES go through the XCAF readers (``STEPCAFControl_Reader`` /
``IGESCAFControl_Reader``) into an XCAF document; ``XCAFPrs_DocumentExplorer``
walks its assembly tree and gives every leaf part its world placement and
inherited style, and ``XCAFPrs::CollectStyleSettings`` the colours set on the
part's sub-shapes (solids, shells, faces). A face's colour is its own, else
that of the smallest sub-shape holding it, else the part's (instance colours
override part colours). BREP files have no colours. What OpenCASCADE prints
while reading is captured, and its first error line goes into the message.
"""

from __future__ import annotations

import ctypes
import os
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from bsrt.errors import InputError


def read_leaves(path: str, kind: str) -> list[Leaf]:
    """Every leaf part of the file (kind "step", "iges" or "brep"), placed, with its colours."""
    if kind == "brep":
        return _read_brep(path)
    return _read_xcaf(path, kind)


@dataclass
class Leaf:
    """One placed part: its shape (in the part's own frame), the TopLoc_Location
    to the world, a readable path, its colour and its sub-shapes' colours."""

    shape: object
    location: object
    name: str
    color: tuple | None
    face_colors: dict
    visible: bool = True


class ShapeKey:
    """A dict key for a TopoDS shape that compares like IsSame (TShape and location)."""

    __slots__ = ("shape", "_hash")

    def __init__(self, shape):
        self.shape, self._hash = shape, hash(shape)

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        return isinstance(other, ShapeKey) and self.shape.IsSame(other.shape)


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


def _read_brep(path: str) -> list[Leaf]:
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
    return [Leaf(shape, TopLoc_Location(), name, None, {})]


def _read_xcaf(path: str, kind: str) -> list[Leaf]:
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


def _leaves(doc, shape_tool) -> list[Leaf]:
    """Every leaf part of the document's assembly tree, placed, with colours."""
    import OCP.collections as collections
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopLoc import TopLoc_Location
    from OCP.XCAFPrs import XCAFPrs, XCAFPrs_DocumentExplorer, XCAFPrs_DocumentExplorerFlags_None

    leaves: list[Leaf] = []
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
                        face_colors[ShapeKey(sub)] = rgb
                    else:
                        for face in faces(sub):
                            face_colors[ShapeKey(face)] = rgb
                leaves.append(
                    Leaf(
                        shape,
                        node.Location,
                        "/".join(path),
                        _rgb(node.Style),
                        face_colors,
                        bool(node.Style.IsVisible()),
                    )
                )
        explorer.Next()
    return _unique_names(leaves)


def _unique_names(leaves: list[Leaf]) -> list[Leaf]:
    """The leaves with the second, third, ... of equal paths named ``PATH@2``, ``PATH@3`` (an
    assembly may place an unnamed part twice under one parent: its faces need names of their own)."""
    seen: dict[str, int] = {}
    for leaf in leaves:
        n = seen.get(leaf.name, 0) + 1
        seen[leaf.name] = n
        if n > 1:
            leaf.name = f"{leaf.name}@{n}"
    return leaves


def faces(shape):
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        yield cast("Face", explorer.Current())
        explorer.Next()


def count_free_edges(shape) -> int:
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    explorer = TopExp_Explorer(shape, TopAbs_EDGE, TopAbs_FACE)
    n = 0
    while explorer.More():
        n += 1
        explorer.Next()
    return n


_CASTS: dict = {}


def cast(kind: str, shape):
    """TopoDS.Face(shape) (OCCT 8) or TopoDS.Face_s(shape) (OCCT 7)."""
    f = _CASTS.get(kind)
    if f is None:
        from OCP.TopoDS import TopoDS

        f = _CASTS[kind] = getattr(TopoDS, kind, None) or getattr(TopoDS, kind + "_s")
    return f(shape)


def diagonal(leaves) -> float:
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    for leaf in leaves:
        if leaf.visible:
            BRepBndLib.Add_s(leaf.shape.Moved(leaf.location), box)
    if box.IsVoid():
        return 1.0
    return max(float(np.sqrt(box.SquareExtent())), 1e-300)
