"""The preview's refinement state machine: which level and map band comes
next, which solver results to show, and when the exact image is complete.
No window, no GL, no processes: the window feeds it the clock, the camera's
changes and the solver's outcomes, and does what it says.

A generation numbers the camera (and method and size): every change starts
a new one, forgets the levels and bands of the old one and restarts at the
coarsest level once the camera has been still for ``settle`` seconds; a
result of an older generation is stale and dropped.
"""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np

# Refinement levels: the framebuffer divided by these, coarse to fine. While
# the camera moves the fast GL view shows the shaded surfaces; once it stops
# the 1/4 level comes first: the exact surfaces, trims, shadows and mirrors
# within about a tenth of the exact level's time (7% of its CPU on water-lily
# at 800x600), solved while the window still rasterises the full level's map
# band by band, so it delays the exact image by little (measured with
# scripts/preview_latency.py, see docs/usage.md).
LEVELS = (4, 1)
SETTLE_SECONDS = 0.15  # the camera counts as stopped after this long without a change
# Live (the solver runs on a GPU, rendering/gpu.py): the exact level only, solved while the camera
# moves too; the window shows the newest exact image, of the camera a job or two ago.
LIVE_LEVELS = (1,)
# The window rasterises a level's map in bands of about this many pixels, one
# band per frame: a whole 800x600 map blocks the window for ~80 ms on llvmpipe.
MAP_BAND_PIXELS = 100_000


def level_size(fb_size: tuple[int, int], divisor: int) -> tuple[int, int]:
    """(width, height) of a level: the framebuffer divided, rounded up."""
    w, h = fb_size
    return max(1, -(-w // divisor)), max(1, -(-h // divisor))


def map_bands(width: int, height: int, band_pixels: int = MAP_BAND_PIXELS) -> list[tuple[int, int]]:
    """Film rows (first, stop) of the map's bands, top first: about band_pixels each."""
    count = max(1, min(height, round(width * height / band_pixels)))
    edges = np.linspace(0, height, count + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def stitch_maps(parts: list):
    """One PrelimMap from the maps of consecutive bands (top band first)."""
    from bsrt.rendering.prelim import PrelimMap

    if len(parts) == 1:
        return parts[0]
    return PrelimMap(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PrelimMap)))


class Refinement:
    """The refinement of one window's view, coarse to fine.

    levels: divisors of the framebuffer, coarse to fine (the last one 1: the
    exact image). The window asks :meth:`next_level` every frame, rasterises
    that level's map band by band (:meth:`next_band`, :meth:`add_band`),
    submits the job (:meth:`submitted`) and passes each solver outcome to
    :meth:`accept`.
    """

    def __init__(
        self, levels: tuple[int, ...] = LEVELS, settle: float = SETTLE_SECONDS, band_pixels: int = MAP_BAND_PIXELS
    ):
        self.levels, self.settle, self.band_pixels = tuple(levels), settle, band_pixels
        self.generation = 0
        self.last_change = -math.inf
        self.dead: str | None = None  # the solver is gone: every generation fails with this
        self.solve_seconds: float | None = None
        self._reset()

    def _reset(self) -> None:
        self.to_submit = 0  # index of the next level to hand to the solver
        self.parts: list = []  # its map's bands so far
        self.shown = -1  # index of the finest level shown for this generation
        self.failed: str | None = self.dead
        self.exact = None  # (H, W, 3) uint8: the exact image of this generation

    def restart(self, now: float, settle: bool = True) -> int:
        """The camera, method or size changed at time now: a new generation
        (returned); everything older is cancelled. settle=False: refine at
        once (a method switch, the camera did not move)."""
        self.generation += 1
        self.last_change = now if settle else -math.inf
        self._reset()
        return self.generation

    def go_live(self, now: float) -> int:
        """The solver runs on a GPU: from now on the exact level only, with no settling (a new
        generation, returned)."""
        self.levels, self.settle = LIVE_LEVELS, 0.0
        return self.restart(now, settle=False)

    def touch(self, now: float) -> None:
        """Still moving (a mouse button released): settle from now."""
        self.last_change = now

    def moving(self, now: float, held: bool = False) -> bool:
        """held: a mouse button is down (the user is dragging)."""
        return held or now - self.last_change < self.settle

    @property
    def complete(self) -> bool:
        return self.exact is not None

    def state(self, now: float, held: bool = False) -> str:
        """ "moving", "failed", "exact" or "refining" (the frame log's states)."""
        if self.moving(now, held):
            return "moving"
        if self.failed:
            return "failed"
        return "exact" if self.complete else "refining"

    def next_level(self, now: float, held: bool = False) -> int | None:
        """The level to work on now, or None (moving, failed, or all submitted)."""
        if self.failed or self.to_submit >= len(self.levels) or self.moving(now, held):
            return None
        return self.to_submit

    def size(self, level: int, fb_size: tuple[int, int]) -> tuple[int, int]:
        return level_size(fb_size, self.levels[level])

    def next_band(self, width: int, height: int) -> tuple[tuple[int, int] | None, int]:
        """(rows of the next map band or None for the whole map, band count)."""
        bands = map_bands(width, height, self.band_pixels)
        return (bands[len(self.parts)] if len(bands) > 1 else None), len(bands)

    def add_band(self, part, count: int):
        """A band's map is done: the stitched map once all count are, else None."""
        self.parts.append(part)
        if len(self.parts) < count:
            return None
        whole, self.parts = stitch_maps(self.parts), []
        return whole

    def submitted(self) -> None:
        """The next level's job went to the solver."""
        self.to_submit += 1

    def fail(self, message: str) -> None:
        self.failed = message

    def solver_died(self, message: str) -> None:
        self.dead = self.failed = message

    def accept(self, generation: int, level: int, pixels, error: str | None = None, seconds: float = 0.0) -> str:
        """A solver outcome: "stale" (an older generation: dropped), "failed"
        (error), "older" (a finer level is already shown), "shown" (show
        pixels, a coarse level) or "exact" (show pixels: the last level)."""
        if generation != self.generation:
            return "stale"
        if error is not None:
            self.failed = error
            return "failed"
        if level <= self.shown:
            return "older"
        self.shown = level
        self.solve_seconds = seconds
        if level == len(self.levels) - 1:
            self.exact = pixels
            return "exact"
        return "shown"

    def progress_text(self) -> str:
        """For the title: "refining 1/2 (1/4 shown)"."""
        shown = self.levels[self.shown] if self.shown >= 0 else None
        return f"refining {self.shown + 1}/{len(self.levels)}" + (f" (1/{shown} shown)" if shown and shown > 1 else "")
