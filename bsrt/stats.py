"""Timings and counters of one render: one timing helper, merged into one record."""

from __future__ import annotations

import time
from contextlib import contextmanager

from . import interrupts

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

    def as_dict(self) -> dict:
        """JSON-serialisable: the fields, then the counters, then "seconds"."""
        return {**self.fields, **self.counts, "seconds": dict(self.seconds)}
