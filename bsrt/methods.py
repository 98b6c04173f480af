"""The root-finding methods: one declaration each.

:data:`METHODS` is the registry (name -> :class:`Method`), in the order the
preview's number keys and the docs list them. The CLI's ``--method``
choices, the scene's ``render.method``, the API's checks, the preview's keys
and the benchmark read it. The per-ray loops are in
:mod:`bsrt.kernels.roots` (seeded methods, by ``kernel_id``) and
:mod:`bsrt.rendering.trace` (the hierarchy).
"""

from __future__ import annotations

from dataclasses import dataclass

from bsrt.kernels.method_ids import FAST, GRADIENT, NEWTON


@dataclass(frozen=True)
class Method:
    """name: as users write it. seeded: started from the preliminary map (else
    the hierarchy finds every ray's start). kernel_id: the seeded solver's id in
    kernels/roots.py (None: not a seeded solver). help: one line.
    stops_on_growth: a seeded start gives up as soon as a step increases the
    residual (Martin et al.'s rule; the pixel is then re-solved as a suspect)."""

    name: str
    seeded: bool
    kernel_id: int | None
    help: str
    stops_on_growth: bool = False


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("gradient", True, GRADIENT, "the paper's gradient descent from the map's (u, v), steps in arc length"),
        Method(
            "fast", True, FAST, "the paper's fast variant: derivatives at every other step, the previous direction kept"
        ),
        Method(
            "newton",
            True,
            NEWTON,
            "Newton from the map's (u, v) (the default: fewest steps, exact)",
            stops_on_growth=True,
        ),
        Method("martin", False, None, "Martin et al. 2000: hierarchy + Newton for every ray, no map (the baseline)"),
    )
}

DEFAULT_METHOD = "newton"
#: the seeded method that repairs and checks the others (hard pixels, the benchmark's reference)
REFERENCE_METHOD = "newton"
MAP_METHODS = tuple(name for name, m in METHODS.items() if m.seeded)
