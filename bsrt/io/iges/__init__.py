"""IGES 5.x fixed-format ASCII files: B-spline, analytic and trimmed surfaces.

One module per concern: ``records.py`` (the file structure),
``bspline.py`` (exact B-spline curve algebra and conics), ``curves.py``
(curve entities), ``surfaces.py`` and ``analytic.py`` (surface entities as
exact NURBS), ``invert.py`` (model-space curves into a surface's parameters,
parameter maps on 2-D curves), ``loops.py`` (trim loops onto a surface's
B-spline), ``seams.py`` (loops across the seams of periodic surfaces) and
``topology.py`` (trimmed surfaces, bounded surfaces, B-rep faces, and what a
file draws).

Every record is 80 columns: data in 1-72, the section letter (S, G, D, P, T)
in 73 and a sequence number in 74-80. The reader checks the section order,
the sequence numbers and the Terminate record's counts, so truncated or
spliced files are reported rather than half-read.

* G: the parameter and record delimiters (default ``,`` ``;``) and parameter
  19, the minimum user-intended resolution (model-space gaps up to it do not
  open a trim loop).
* D: two records per entity; the directory entry number (DE) of an entity is
  the sequence number of its first record. Fields used: entity type, P
  pointer and P line count, transformation matrix pointer (field 7), blank
  status and subordinate switch (field 9), form, label (columns 57-64 of the
  2nd record) and subscript.
* P: columns 1-64 hold the parameters, 65-72 the DE back-pointer. Parameters
  after an entity's own ones (back pointers, properties) are ignored.

Entity 124 (transformation matrix) parameters are R11 R12 R13 T1 R21 ...
T3: x' = R x + T; a 124 may itself point to another 124, applied after it.
An entity's own matrix maps it into model space. The members of a composite
curve (102) are mapped by their own matrices and then by the composite's;
the curves, points and directions a surface entity is built from (118, 120,
122, 190-198) by theirs and then by the surface's. Boundary curves (142,
141, 504, a 108's boundary) are model-space curves: their own matrices only.
A parameter-space curve's matrix acts in the (u, v) plane (its x, y, z are
mapped and z is dropped: x -> u, y -> v).

What is drawn, in directory order: every trimmed surface (144), bounded
surface (143) and B-rep face (510), with its trim loops; every surface entity
no 144/143/510 refers to, whole (128, 114, 118, 120, 122, 196, 198; a 108
only when bounded by a curve or given a display size), unless it is
physically dependent (subordinate switch 01 or 11: part of another entity,
such as the surface of a 142 no trimmed surface uses, which OpenCASCADE does
not draw either); the solids (186) and
shells (514) only gather faces, which are drawn as faces. Subfigures: the
members of a definition (308; DEPTH NAME N and N pointers) -- surfaces,
trimmed surfaces, faces, and the faces of its solids and shells -- are drawn
only where a singular subfigure instance (408; DE X Y Z S) that is no
definition's member places them, nested instances within it: a definition
point p is drawn at M (S p + (X, Y, Z)), M the 408's own matrix, after the
308's own matrix (IGES 5.3: an entity's parameters are in its definition
space; OpenCASCADE adds (X, Y, Z) after M instead, which differs only when
both are there and M turns). A definition no instance places is not drawn
(counted skipped; OpenCASCADE draws it in place). Entities that take
part (curves, 124s, vertex and edge lists, ...) are used; every other one is
counted in ``Model.skipped`` by type, unless it is blanked (blank status 01:
hidden in the sending system). A trimmed surface whose boundary uses a curve
bsrt does not convert (130 offset curve, ...) is drawn whole, with a warning
and counted in ``Model.untrimmed``; an unbounded surface with nothing to bound
it is left out with a warning. Compressed (C) and binary IGES are refused.
"""

from __future__ import annotations

from bsrt.io import Model, fail
from bsrt.io.iges.records import IgesFile, entity_name
from bsrt.io.iges.surfaces import SURFACE_TYPES

__all__ = ["IgesFile", "read"]


def read(path: str) -> Model:
    from bsrt.io.iges.drawing import draw

    f = IgesFile(path)
    surfaces, names, warnings, untrimmed = draw(f)
    skipped: dict[str, int] = {}
    for entity in f.entities.values():
        if entity.type != 0 and entity.de not in f.used and not entity.blanked:
            key = entity_name(entity.type)
            skipped[key] = skipped.get(key, 0) + 1
    if not surfaces:
        if f.open_loops:  # every surface left out for loops that do not close: the first one says why
            raise f.open_loops[0]
        found = ", ".join(f"{n} x {k}" for k, n in skipped.items()) or "no entities"
        dependent = sum(e.dependent and e.type in SURFACE_TYPES and e.de not in f.used for e in f.entities.values())
        if dependent:  # pyIGES's 142-000.igs: the surface of a lone 142
            are = "is" if dependent == 1 else "are"
            found += (
                f"; {dependent} of those surfaces {are} physically dependent (part of another entity): not drawn alone"
            )
        raise fail(path, None, f"the file holds no surfaces bsrt can draw, only {found}")
    return Model(path, surfaces, names, skipped, warnings, untrimmed=untrimmed)
