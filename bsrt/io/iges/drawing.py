"""What an IGES file draws: every trimmed surface, bounded surface and face, and the surfaces
nothing trims, through subfigure instances, with the warnings' tallies (:func:`draw`)."""

from __future__ import annotations

import numpy as np

from bsrt.io.iges.curves import Unsupported
from bsrt.io.iges.loops import INVERSION_TOL, OpenLoop, Unbounded
from bsrt.io.iges.records import entity_name
from bsrt.io.iges.surfaces import SURFACE_TYPES
from bsrt.io.iges.topology import _TRIMMERS, _faces_under, _instance, _shells, _subfigure, _whole


class _Drawing:
    """What a file draws, entity by entity, with the warnings' tallies; a face drawn by several
    subfigure instances is converted once."""

    def __init__(self, f):
        self.f = f
        self.trimmed_targets = set()
        for e in f.entities.values():
            if e.type in _TRIMMERS:
                p = f.params(e)
                if e.type == 143:
                    p.int("TYPE")
                self.trimmed_targets.add(p.pointer("the surface pointer"))
        self.untrimmed, self.unsupported, self.unbounded, self.open_loops = [], {}, {}, []
        self.inverted = 0
        self.notes: list[str] = []  # faces drawn otherwise than written, one line each
        self.done: dict[int, object] = {}  # DE -> its surface (None: not drawn)

    def entity(self, e):
        """The surface an entity draws on its own (None if none), converted once."""
        if e.de not in self.done:
            self.done[e.de] = self._entity(e)
        return self.done[e.de]

    def _entity(self, e):
        f = self.f
        if e.type in _TRIMMERS:
            try:
                face = _TRIMMERS[e.type](f, e)
            except OpenLoop as err:  # named once, left out: never drawn with a wrong boundary
                where = str(err).split(": ", 1)[1] if str(err).startswith(f.path) else str(err)
                self.open_loops.append(f"{where}; the surface is left out")
                f.open_loops.append(err)
                return None
            except Unbounded:
                target = _target(f, e)
                kind = f.entities[target].type
                self.unbounded[kind] = self.unbounded.get(kind, 0) + 1
                f.used.discard(target)
                return None
            except Unsupported as u:
                target = f.entities.get(_target(f, e))
                try:
                    s = _whole(f, target) if target is not None and target.type in SURFACE_TYPES else None
                except (Unsupported, Unbounded):
                    s = None
                if s is None:  # the surface itself cannot be drawn: both are left out (skipped)
                    return None
                self.unsupported[u.entity.type] = self.unsupported.get(u.entity.type, 0) + 1
                self.untrimmed.append(e.de)
                f.used.add(e.de)
                return s
            self.inverted += face.inverted
            if face.note:
                self.notes.append(face.note)
            f.used.add(e.de)
            return face.surface
        if e.type in SURFACE_TYPES and e.de not in self.trimmed_targets:
            try:
                s = _whole(f, e)
            except Unsupported as u:  # named once with the reason, left out
                self.notes.append(f"{u}; the surface is left out")
                return None
            if s is None:
                self.unbounded[e.type] = self.unbounded.get(e.type, 0) + 1
                f.used.discard(e.de)
                return None
            f.used.add(e.de)
            return s
        return None

    def instance(self, e, outer: np.ndarray, chain: tuple) -> list:
        """[(surface, name)] a 408 places: its definition's members, nested instances included
        (named by the face and the chain of 408s, outermost first). outer: the enclosing
        instances' placement (4x4); chain: their DEs."""
        f = self.f
        if e.de in chain:
            raise f.fail(
                e,
                "the subfigure instances at DE "
                + ", ".join(map(str, chain + (e.de,)))
                + " contain each other in a loop",
            )
        definition, place = _instance(f, e)
        matrix, members = _subfigure(f, definition)
        place = outer @ place if matrix is None else outer @ place @ matrix
        f.used.update((e.de, definition.de))
        out = []
        for de in members:
            member = f.entities[de]
            if member.type == 408:
                out += self.instance(member, place, chain + (e.de,))
                continue
            faces: list[int] = []
            _faces_under(f, de, faces)
            if member.type in (186, 514):
                _shells(f, member)
            for face in faces:
                s = self.entity(f.entities[face])
                if s is not None:
                    where = " > ".join(f"#D{de}" for de in chain + (e.de,))
                    out.append((s.transformed(place), f"{f.name(f.entities[face])} in 408 {where}"))
        return out


def _subfigure_owned(f) -> tuple[set, set]:
    """(DEs drawn only through subfigure instances, the 408s that are members of a definition)."""
    owned, nested = set(), set()
    for e in f.entities.values():
        if e.type == 308:
            p = f.params(e)
            p.int("DEPTH")
            p.skip(1, "NAME")
            for _ in range(p.int("the member count N", 0)):
                de = f.get(p, p.pointer("a member pointer"), "member pointer").de
                if f.entities[de].type == 408:
                    nested.add(de)
                else:
                    owned.add(de)
                    faces: list[int] = []
                    _faces_under(f, de, faces)
                    owned.update(faces)
    return owned, nested


def draw(f):
    """(surfaces, names, warnings, untrimmed count) of an IgesFile.

    Subfigures: the members of a definition (308) -- and the faces of its solids and shells --
    are drawn only where an instance (408) that is itself no definition's member places them,
    nested instances within it."""
    d = _Drawing(f)
    owned, nested = _subfigure_owned(f)
    surfaces, names = [], []
    for e in f.entities.values():
        if e.type in (186, 514):
            if e.de not in owned:
                _shells(f, e)
        elif e.type == 408:
            if e.de not in nested:
                for s, name in d.instance(e, np.eye(4), ()):
                    surfaces.append(s)
                    names.append(name)
        elif e.de in owned or (e.type in SURFACE_TYPES and e.dependent):
            continue  # drawn by its instances, or part of another entity (a lone 142's surface)
        elif e.type in _TRIMMERS or e.type in SURFACE_TYPES:
            s = d.entity(e)
            if s is not None:
                surfaces.append(s)
                names.append(f.name(e))
    untrimmed, unsupported, unbounded = d.untrimmed, d.unsupported, d.unbounded
    warnings = list(d.open_loops) + d.notes
    if d.inverted:
        inverted = d.inverted
        warnings.append(
            f"{inverted} trim curve{'s were' if inverted != 1 else ' was'} given only in model space and "
            f"carried into the surface's (u, v) by point inversion, as degree-1 polylines within "
            f"{INVERSION_TOL:g} of the parameter domain's size"
        )
    if untrimmed:
        kinds = ", ".join(f"{n} x {entity_name(t)}" for t, n in sorted(unsupported.items()))
        are = "surface is drawn untrimmed: its" if len(untrimmed) == 1 else "surfaces are drawn untrimmed: their"
        warnings.append(f"{len(untrimmed)} {are} boundaries use entities bsrt does not convert ({kinds})")
    if unbounded:
        n = sum(unbounded.values())
        kinds = ", ".join(str(t) for t in sorted(unbounded))
        them = "them are" if n != 1 else "it is"
        warnings.append(
            f"{n} unbounded surface{'s' if n != 1 else ''} with nothing to bound {them} left out "
            f"(entit{'ies' if len(unbounded) > 1 else 'y'} {kinds})"
        )
    return surfaces, names, warnings, len(untrimmed)


def _target(f, e) -> int:
    p = f.params(e)
    if e.type == 143:
        p.int("TYPE")
    return p.pointer("the surface pointer")
