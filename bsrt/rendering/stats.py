"""Timings and counters of one render: one timing helper, merged into one record."""

from __future__ import annotations

import time
from contextlib import contextmanager

from bsrt import interrupts

STAGES = ("setup", "map", "solve", "shade", "secondary")


class Stats:
    """seconds: stage -> seconds (``secondary`` is part of ``shade``); counts: name -> int."""

    def __init__(self, **fields):
        self.fields = dict(fields)
        self.seconds = {stage: 0.0 for stage in STAGES}
        self.counts: dict[str, int] = {}

    @contextmanager
    def timer(self, stage: str):
        interrupts.safe_point()  # between stages and bands: a signal may end the run here
        clock = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[stage] = self.seconds.get(stage, 0.0) + time.perf_counter() - clock

    def add(self, name: str, value) -> None:
        self.counts[name] = self.counts.get(name, 0) + int(value)

    def loaded(self, loads) -> None:
        """Record the scene's model loads (``Scene.loads``, bsrt.io.LoadRecord) as the field "load"."""
        entry = load_entry(loads)
        if entry is not None:
            self.fields["load"] = entry

    def as_dict(self) -> dict:
        """JSON-serialisable: the fields, then the counters, then "seconds"."""
        return {**self.fields, **self.counts, "seconds": dict(self.seconds)}


def load_entry(loads) -> dict | None:
    """--stats' "load" for the model files a scene was made from (None: it loaded none):
    seconds (all of them), files, cached (every one came from the model cache), and
    faces_converted / faces_total where the readers reported them (OpenCASCADE, not cached),
    framing_seconds where the automatic camera was fitted to a model."""
    loads = [r for r in loads if r is not None]
    if not loads:
        return None
    entry = {"seconds": sum(r.seconds for r in loads), "files": len(loads), "cached": all(r.cached for r in loads)}
    counted = [r.faces for r in loads if r.faces is not None]
    if counted:
        entry["faces_converted"] = sum(done for done, _ in counted)
        entry["faces_total"] = sum(total for _, total in counted)
    framed = [r.framing_seconds for r in loads if r.framing_seconds is not None]
    if framed:
        entry["framing_seconds"] = sum(framed)
    return entry
