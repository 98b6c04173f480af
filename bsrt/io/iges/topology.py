"""Trimmed surfaces (144), bounded surfaces (143) and B-rep faces (510) as trim loops.

Entities (IGES 5.3):

* 144 trimmed surface: PTS N1 N2 PTO PTI(1..N2). N1 = 0: the outer boundary is
  the surface's own boundary (bsrt adds its domain rectangle as a loop, so
  that the even-odd rule keeps the surface minus the inner loops).
* 142 curve on a surface: CRTN SPTR BPTR CPTR PREF. The parameter-space curve
  BPTR is used when there is one; otherwise the model-space curve CPTR is
  carried into (u, v) (``pcurves``). When a 144's parameter-space loops do
  not close, or leave the surface's domain, and each of its 142s also has a
  model-space curve, the model-space curves trim it instead, with a warning (a
  writer's parameter-space curves in another parametrization of the surface, or
  in model x, y). PREF (the curve the writer prefers) is not used.
* 143 bounded surface: TYPE SPTR N and N pointers to 141s; 141 boundary:
  TYPE PREF SPTR N, then per curve CRVPT SENSE K PSCPT(1..K). The K
  parameter-space curves are used (the group reversed when SENSE = 2), else
  the model-space curve CRVPT.
* 186 manifold solid: SHELL SOF NVOID and (VOID, VOF) pairs; 514 shell: N and
  (FACE, OF) pairs. Solids and shells only gather faces; a face is drawn
  once, however many shells hold it, and its orientation is ignored (bsrt
  shades both sides).
* 510 face: SURF N OF LOOP(1..N). OF = 0 (no outer loop) on a bounded surface:
  its domain rectangle is added as the outer loop.
* 508 loop: N, then per edge TYPE EDGE NDX OF K and K (ISOP, CURV) pairs: the
  K parameter-space curves, reversed as a group when OF = 0, else the model
  curve of entry NDX (from 1) of the 504 edge list EDGE. A vertex edge
  (TYPE 1) without parameter-space curves becomes a straight segment in
  (u, v) between its neighbours (a pole or an apex).
* 504 edge list: N and per edge CURV SVP SV TVP TV; 502 vertex list: N and
  the points. They are checked and used, not drawn.

The loops themselves are assembled by ``loops.py``; ``drawing.py`` says what
a file draws (see the package docstring).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bsrt.errors import InputError
from bsrt.io.iges.bspline import reverse
from bsrt.io.iges.curves import Unsupported, mark_used
from bsrt.io.iges.loops import BRIDGE, Face, LoopBuilder, OffDomain, OpenLoop, Piece, RawLoop
from bsrt.io.iges.surfaces import SURFACE_TYPES, SurfaceDef, surface

# ---------------------------------------------------------------------------
# The entities


def _surface_of(f, params, what: str) -> SurfaceDef:
    target = f.get(params, params.pointer(what), what)
    if target.type not in SURFACE_TYPES:
        raise Unsupported(target, "as a surface")
    return surface(f, target)


def _curve_on_surface(b: LoopBuilder, params, de: int, what: str, model: bool = False) -> list[Piece]:
    """The pieces of a 142 (its parameter-space curve, else -- or with ``model`` -- its
    model-space curve)."""
    f = b.f
    e142 = f.get(params, de, what, {142})
    p = f.params(e142)
    p.int("CRTN")
    sptr = p.pointer("the surface pointer SPTR")
    if sptr != b.sd.entity.de:
        raise p.fail(
            f"the curve lies on surface DE {sptr}, but the trimmed surface DE {b.entity.de} "
            f"trims surface DE {b.sd.entity.de}"
        )
    bptr, cptr = p.pointer("the parameter-space curve BPTR"), p.pointer("the model-space curve CPTR")
    f.used.add(e142.de)
    if model and cptr:
        if bptr:
            mark_used(f, p, bptr, "parameter-space curve BPTR")
        return b.model_pieces(p, cptr, "model-space curve CPTR")
    if bptr:
        try:
            out = b.param_pieces(p, bptr, "parameter-space curve BPTR")
        except Unsupported:
            if not cptr:
                raise
        else:
            if cptr:
                mark_used(f, p, cptr, "model-space curve CPTR")
            return out
    if not cptr:
        raise p.fail("the curve has neither a parameter-space (BPTR) nor a model-space (CPTR) curve")
    return b.model_pieces(p, cptr, "model-space curve CPTR")


def _trimmed_surface(f, entity, model: bool = False) -> Face:
    """A 144's face. A boundary written in parameter space that does not close, where every
    boundary also has a model-space curve, is drawn with the model-space curves (carried
    into (u, v)) instead, with a note: a writer's parameter-space curves in another
    parametrization of the surface than IGES's (bug22566_test_Bad.igs: a 120's arc
    parameter counted from 0 at the arc's start, not from its start angle) close only
    where the surface collapses in theirs. Likewise for one that leaves the surface's domain
    (144-000.igs: a 100 arc in model x, y as the parameter-space curve)."""
    params = f.params(entity)
    sd = _surface_of(f, params, "surface pointer PTS")
    b = LoopBuilder(f, entity, sd)
    n1 = params.int("N1", 0)
    n2 = params.int("N2", 0)
    pto = params.pointer("the outer boundary pointer PTO")
    raw, boundaries = [], []
    if n1:
        items = _curve_on_surface(b, params, pto, "outer boundary PTO", model)
        raw.append(RawLoop(items, f"its outer boundary (DE {pto})"))
        boundaries.append(pto)
    for i in range(n2):
        de = params.pointer("an inner boundary pointer PTI")
        items = _curve_on_surface(b, params, de, "inner boundary PTI", model)
        raw.append(RawLoop(items, f"its inner boundary {i + 1} (DE {de})"))
        boundaries.append(de)
    try:
        return b.build(raw, outer_is_domain=not n1 and bool(raw))
    except (OpenLoop, OffDomain) as first:
        if model or not boundaries or not all(_has_both(f, de) for de in boundaries):
            raise
        try:
            face = _trimmed_surface(f, entity, model=True)
        except (InputError, Unsupported):
            raise first from None  # the parameter-space loop's own message
        if isinstance(first, OpenLoop):
            why = "does not close on the surface, its model-space boundary does"
        else:
            why = "leaves the surface's domain, its model-space boundary does not"
        return replace(
            face,
            note=(
                f"entity 144 (DE {entity.de}): its parameter-space boundary {why}: "
                f"the surface is trimmed by the model-space curves"
            ),
        )


def _has_both(f, de: int) -> bool:
    """Does the 142 at DE ``de`` have both a parameter-space and a model-space curve?"""
    e = f.entities.get(de)
    if e is None or e.type != 142:
        return False
    p = f.params(e)
    p.int("CRTN")
    p.pointer("SPTR")
    return bool(p.pointer("BPTR")) and bool(p.pointer("CPTR"))


def _bounded_surface(f, entity) -> Face:
    params = f.params(entity)
    params.int("TYPE")
    sd = _surface_of(f, params, "surface pointer SPTR")
    b = LoopBuilder(f, entity, sd)
    n = params.int("the boundary count N", 0)
    raw = []
    for i in range(n):
        e141 = f.get(params, params.pointer("a boundary pointer"), "boundary pointer", {141})
        p = f.params(e141)
        p.int("TYPE")
        p.int("PREF")
        if p.pointer("the surface pointer SPTR") != sd.entity.de:
            raise p.fail(f"the boundary lies on another surface than the bounded surface DE {entity.de}'s")
        items = []
        for _ in range(p.int("the curve count N", 1)):
            model = p.pointer("a model-space curve CRVPT")
            sense = p.int("SENSE")
            k = p.int("the parameter-space curve count K", 0)
            group = [
                x
                for _ in range(k)
                for x in b.param_pieces(p, p.pointer("a parameter-space curve"), "parameter-space curve pointer")
            ]
            if sense == 2:
                group = [replace(x, curve=reverse(x.curve)) for x in group[::-1]]
            if group and model:
                mark_used(f, p, model, "model-space curve CRVPT")
            if not group:
                group = b.model_pieces(p, model, "model-space curve CRVPT", backwards=sense == 2)
            items += group
        f.used.add(e141.de)
        raw.append(RawLoop(items, f"its boundary {i + 1} (141 at DE {e141.de})"))
    return b.build(raw)


def _face(f, entity) -> Face:
    params = f.params(entity)
    sd = _surface_of(f, params, "surface pointer SURF")
    b = LoopBuilder(f, entity, sd)
    n = params.int("the loop count N", 0)
    outer = params.int("the outer loop flag OF")
    raw = []
    for i in range(n):
        e508 = f.get(params, params.pointer("a loop pointer"), "loop pointer", {508})
        raw.append(RawLoop(_loop(b, e508), f"its loop {i + 1} (508 at DE {e508.de})"))
    return b.build(raw, outer_is_domain=not outer and sd.bounded and bool(raw))


def _loop(b: LoopBuilder, e508) -> list:
    f = b.f
    p = f.params(e508)
    items = []
    for _ in range(p.int("the edge count N", 1)):
        kind = p.int("the edge TYPE")
        lst = f.get(p, p.pointer("the edge or vertex list pointer EDGE"), "EDGE pointer", {502, 504})
        ndx = p.int("the list index NDX", 1)
        model = _list_entry(f, p, lst, ndx, kind)
        forward = p.int("the orientation flag OF") != 0
        k = p.int("the parameter-space curve count K", 0)
        group = []
        for _ in range(k):
            p.int("ISOP")
            group += b.param_pieces(p, p.pointer("a parameter-space curve CURV"), "parameter-space curve CURV")
        if not forward:
            group = [replace(x, curve=reverse(x.curve)) for x in group[::-1]]
        if group:
            items += group
            if model:
                mark_used(f, p, model, "edge curve")
        elif kind == 0:
            items += b.model_pieces(p, model, "edge curve", backwards=not forward)
        else:
            items.append(BRIDGE)
    f.used.add(e508.de)
    return items


def _list_entry(f, ref, lst, ndx: int, kind: int) -> int:
    """Check entry ``ndx`` of an edge (504) or vertex (502) list; the edge's curve DE (0 for a vertex)."""
    expected = 504 if kind == 0 else 502
    if lst.type != expected:
        raise ref.fail(f"an edge of TYPE {kind} must point to an entity {expected}, not {lst.type}")
    p = f.params(lst)
    n = p.int("the list length N", 1)
    if ndx > n:
        raise ref.fail(f"the index NDX = {ndx} is past the end of the {n}-entry list DE {lst.de}")
    f.used.add(lst.de)
    if lst.type == 502:
        return 0
    p.skip(5 * (ndx - 1), "an edge entry")
    de = p.pointer("an edge curve CURV")
    for _ in range(2):
        vl = f.get(p, p.pointer("a vertex list pointer"), "vertex list pointer", {502})
        f.used.add(vl.de)
        p.int("a vertex index")
    return de


def _shells(f, entity) -> None:
    """Check a 186 or 514 and mark it (and its shells) used; faces are drawn on their own."""
    p = f.params(entity)
    if entity.type == 186:
        shells = [f.get(p, p.pointer("the shell pointer"), "shell pointer", {514})]
        p.int("SOF")
        for _ in range(p.int("the void count NVOID", 0)):
            shells.append(f.get(p, p.pointer("a void shell pointer"), "void shell pointer", {514}))
            p.int("VOF")
        for s in shells:
            _shells(f, s)
    else:
        for _ in range(p.int("the face count N", 0)):
            f.get(p, p.pointer("a face pointer"), "face pointer", {510})
            p.int("OF")
    f.used.add(entity.de)


# ---------------------------------------------------------------------------
# What a file draws


def _whole(f, entity) -> object:
    """A surface entity drawn alone, over its natural range (InputError-free None if unbounded)."""
    sd = surface(f, entity)
    if entity.type == 108:
        return _plane_alone(f, entity, sd)
    if not sd.bounded:
        return None
    return sd.place(None)[0]


def _plane_alone(f, entity, sd):
    params = f.params(entity)
    params.skip(4, "a plane coefficient")
    ptr = params.pointer("the boundary pointer PTR")
    centre = params.reals(3, "a display symbol coordinate")
    size = params.real("the display symbol size SIZE")
    if ptr and entity.form == 1:
        b = LoopBuilder(f, entity, sd)
        raw = [RawLoop(b.model_pieces(params, ptr, "boundary pointer PTR"), f"its boundary (DE {ptr})")]
        return b.build(raw).surface
    if size > 0:
        m = f.matrix(entity)
        if m is not None:
            centre = m[:3, :3] @ centre + m[:3, 3]
        u, v = sd.invert(centre[None])[0]
        return sd.place((u - size / 2, u + size / 2, v - size / 2, v + size / 2))[0]
    return None


_TRIMMERS = {144: _trimmed_surface, 143: _bounded_surface, 510: _face}


# ---------------------------------------------------------------------------
# Subfigures (308 definitions, 408 instances)


def _subfigure(f, entity):
    """A 308's (matrix or None, member DEs): DEPTH NAME N and N member pointers."""
    p = f.params(entity)
    p.int("DEPTH")
    p.skip(1, "NAME")
    members = [
        f.get(p, p.pointer("a member pointer"), "member pointer").de for _ in range(p.int("the member count N", 0))
    ]
    return f.matrix(entity), members


def _instance(f, entity):
    """A 408's (definition DE, 4x4 placement model-from-definition): DE X Y Z S, where a
    definition point p goes to M (S p + (X, Y, Z)), M the 408's own matrix (S defaults to 1)."""
    p = f.params(entity)
    definition = f.get(p, p.pointer("the subfigure definition pointer DE"), "subfigure definition pointer", {308})
    place = np.eye(4)
    given = len(p.texts) - 1
    place[:3, 3] = [p.real("a translation") if k < given else 0.0 for k in range(1, 4)]
    scale = p.real("the scale S") if given >= 5 and p.texts[5] != "" else 1.0
    if not scale > 0:
        raise p.fail(f"the scale S must be positive, got {scale:g}")
    place[:3, :3] *= scale
    m = f.matrix(entity)
    return definition, place if m is None else m @ place


def _faces_under(f, de: int, out: list) -> None:
    """The DEs of what draws below a subfigure member (its faces, or the member itself), in order."""
    e = f.entities[de]
    if e.type in _TRIMMERS or e.type in SURFACE_TYPES:
        out.append(de)
    elif e.type in (186, 514):
        p = f.params(e)
        if e.type == 186:
            shells = [p.pointer("the shell pointer")]
            p.int("SOF")
            for _ in range(p.int("the void count NVOID", 0)):
                shells.append(p.pointer("a void shell pointer"))
                p.int("VOF")
            for s in shells:
                _faces_under(f, s, out)
        else:
            for _ in range(p.int("the face count N", 0)):
                out.append(p.pointer("a face pointer"))
                p.int("OF")
