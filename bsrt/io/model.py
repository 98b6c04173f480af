"""What a model reader returns: :class:`Model` (the drawable content of one file) and
:class:`LoadRecord` (how its load went). Below every reader and the cache, so they import it
without importing :mod:`bsrt.io` itself."""

from __future__ import annotations

from dataclasses import dataclass, field

from bsrt.geometry.bspline import BSplineSurface


@dataclass(frozen=True)
class LoadRecord:
    """How one model file was loaded (``--stats``' ``load`` entry, ``bsrt info``).

    seconds: the whole :func:`load_model` call. cached: whether the model came
    from the converted-model cache. faces: (converted, total) as the reader
    last reported them through its progress callback, or None (a reader that
    does not report, or a cached load). framing_seconds: the automatic camera's fit to the
    model (``bsrt.scene.scene_for_model``), where it was framed.
    """

    path: str
    format: str
    seconds: float
    cached: bool
    faces: tuple[int, int] | None = None
    framing_seconds: float | None = None


@dataclass
class Model:
    """The drawable content of one model file.

    path: the file as given to :func:`load_model`.
    surfaces: the surfaces, in file order.
    names: one label per surface (``"teapot.bez#3"``, an IGES label, ...).
    skipped: description of something bsrt cannot draw -> how many there are.
    warnings: full sentences about approximations (e.g. trimming ignored).
    untrimmed: how many of the surfaces are trimmed in the file but drawn whole.
    colors: empty (the file gives no colours), or one per surface: a linear RGB
      colour (r, g, b), each in 0..1, or None where the file gives none.
    reversed: empty (every surface as parametrised), or one bool per surface:
      True where the outward normal is -(S_u x S_v) (a B-rep face whose
      orientation is REVERSED, or mirrored by its placement).
    load: how this load went (time, cache), set by :func:`load_model`; not
      part of the cached value nor of equality.
    """

    path: str
    surfaces: list[BSplineSurface]
    names: list[str]
    skipped: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    untrimmed: int = 0
    colors: list[tuple[float, float, float] | None] = field(default_factory=list)
    reversed: list[bool] = field(default_factory=list)
    load: LoadRecord | None = field(default=None, compare=False, repr=False)
