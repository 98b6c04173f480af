"""Render progress on a terminal: a bar with percentage and time left, then one summary line.

``Progress`` is the ``progress(stage, fraction)`` callback of
:func:`bsrt.rendering.pipeline.render` (stage "map", "solve", "shade", "aov" or "done";
fraction 0..1 of the whole render; its callers report "setup" at 0 before
it starts, since loading the kernels can take a while, and ``bsrt render``
"write" at 1 while it writes the outputs). Before that, the
model load reports stage "load" with its own fraction, the faces converted
(:func:`load_reporter` adapts ``bsrt.io.load_model``'s ``progress(done,
total)``); the render's stages then start again from 0, and the time left
counts from there. The first run on a machine compiles the kernels before
the render, stage "compile", which is likewise a phase of its own (the
render's time left never counts it). On a terminal it redraws one line in place, at most ten
times a second::

    bsrt: [████████░░░░░░░░░░░░]  41% load 65/160 faces, 0.8 s, about 1.1 s left
    bsrt: [█████████░░░░░░░░░░░]  45% shade, 3.2 s, about 1.5 s left

and :meth:`Progress.finish` replaces it with a summary (``bsrt: rendered
out.png 512x512, 1 spp, newton, 2.7 s``) ending in a newline. Elsewhere
(``lines=True``: a pipe or a log, when asked for) it writes a plain line
when a stage first starts and at most once a second. Time left is
elapsed / fraction * (1 - fraction), shown once fraction > 0.

The bar owns the terminal line while it is drawn: :meth:`Progress.clear`
(or :func:`clear_active`, for an error handler that does not hold the
object) erases it, so an error message starts on a clean line. No ANSI
escapes are used (the line is erased by overwriting it with spaces), so it
also works on a dumb terminal.
"""

from __future__ import annotations

import os
import time

BAR_INTERVAL = 0.1  # seconds between redraws of the bar (at most 10 per second)
LINE_INTERVAL = 1.0  # seconds between progress lines when not on a terminal
BAR_CELLS = 20
LOAD = "load"  # the stage of the model load, before the render's own
COMPILE = "compile"  # the first run's kernel compile, before the render's own
BEFORE = (LOAD, COMPILE)  # stages with their own fraction, not counted in the render's time left

_active: Progress | None = None


def wanted(stream, flag: bool | None) -> Progress | None:
    """The progress display for ``stream`` and the command line's ``--progress`` /
    ``--no-progress`` (flag True / False; None: automatic).

    Automatic: a bar when the stream is a terminal and the environment is not
    CI (``CI`` set, as CI services do); nothing otherwise. Asked for on
    something that is not a terminal: plain lines.
    """
    tty = _isatty(stream)
    if flag is None:
        flag = tty and os.environ.get("CI", "").lower() in ("", "0", "false")
    return Progress(stream, lines=not tty) if flag else None


def load_reporter(progress):
    """A ``progress(done, total)`` callback for ``bsrt.io.load_model`` (faces converted) that
    reports stage "load" to a render's ``progress(stage, fraction)``; None for None. A
    :class:`Progress` also shows the counts ("load 65/160 faces")."""
    if progress is None:
        return None
    if isinstance(progress, Progress):
        return lambda done, total: progress(LOAD, done / total if total else 1.0, f"{done}/{total} faces")
    return lambda done, total: progress(LOAD, done / total if total else 1.0)


def clear_active() -> None:
    """Erase the bar being drawn, if any (before an error message is printed)."""
    if _active is not None:
        _active.clear()


class Progress:
    """A ``progress(stage, fraction)`` callback that draws on ``stream``.

    lines: write plain lines instead of redrawing a bar (not a terminal).
    clock: seconds (monotonic), replaceable in tests.
    """

    def __init__(self, stream, *, lines: bool = False, clock=time.monotonic):
        self.stream, self.lines, self.clock = stream, lines, clock
        self.start = clock()
        self.phase_start = self.start  # the render's start (after the load): the time left counts from here
        self.fraction = 0.0
        self.stage = ""
        self.detail = ""
        self._drawn_at: float | None = None  # when the line was last drawn
        self._width = 0  # characters of the bar currently on the terminal line
        self._last_line = ("", -1)
        self._stages: set[str] = set()  # stages that have had a line (lines mode)

    def elapsed(self) -> float:
        return self.clock() - self.start

    def __call__(self, stage: str, fraction: float = 0.0, detail: str = "") -> None:
        """Stage ``stage`` is ``fraction`` done; detail: shown after the stage's name."""
        global _active
        now = self.clock()
        if self.stage and stage != self.stage and (self.stage in BEFORE or stage in BEFORE):  # a new phase
            self.fraction, self.phase_start = 0.0, now  # (after a load or a compile the render starts from 0)
        self.fraction = max(self.fraction, min(1.0, max(0.0, float(fraction))))  # never backwards
        self.stage, self.detail = stage, detail
        first_of_stage = stage not in self._stages  # a stage change is always shown (a handful per render)
        if self.lines:
            percent = int(self.fraction * 100)
            due = self._drawn_at is None or now - self._drawn_at >= LINE_INTERVAL
            if (due or first_of_stage) and (stage, percent) != self._last_line and stage != "done":
                self._write(f"bsrt: {self._status(now)}\n")
                self._drawn_at, self._last_line = now, (stage, percent)
                self._stages.add(stage)
            return
        if not first_of_stage and self._drawn_at is not None and now - self._drawn_at < BAR_INTERVAL:
            return
        self._drawn_at = now
        self._stages.add(stage)
        _active = self
        self._draw(f"bsrt: {self._bar()} {self._status(now)}")

    def clear(self) -> None:
        """Erase the bar from its line (nothing in lines mode or when nothing is drawn)."""
        global _active
        if self._width:
            self._write("\r" + " " * self._width + "\r")
            self._width = 0
        if _active is self:
            _active = None

    def finish(self, summary: str) -> None:
        """Replace the bar by ``bsrt: <summary>`` and a newline."""
        self.clear()
        self._write(f"bsrt: {summary}\n")

    # -- drawing

    def _status(self, now: float) -> str:
        elapsed, phase = now - self.start, now - self.phase_start
        detail = f" {self.detail}" if self.detail else ""
        text = f"{self.fraction * 100:3.0f}% {self.stage}{detail}, {_duration(elapsed)}"
        if self.fraction > 0.0 and self.fraction < 1.0:
            text += f", about {_duration(phase / self.fraction * (1.0 - self.fraction))} left"
        return text

    def _bar(self) -> str:
        full, empty = ("█", "░") if _utf8(self.stream) else ("#", "-")
        n = int(self.fraction * BAR_CELLS)
        return "[" + full * n + empty * (BAR_CELLS - n) + "]"

    def _draw(self, text: str) -> None:
        text = text[: _columns(self.stream) - 1]  # a wrapped line cannot be redrawn with \r
        pad = max(0, self._width - len(text))
        self._write("\r" + text + " " * pad)
        self._width = len(text)

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed terminal must not fail the render
            pass


def _duration(seconds: float) -> str:
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, s = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {s:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def _columns(stream) -> int:
    try:
        columns = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, ValueError, OSError):
        columns = 0
    return columns if columns > 0 else 80


def _utf8(stream) -> bool:
    return (getattr(stream, "encoding", None) or "").lower().replace("-", "").replace("_", "") == "utf8"
