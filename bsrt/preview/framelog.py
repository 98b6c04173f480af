"""The preview's ``--frame-log``: per-frame times, states and main-thread work,
and per refinement level the times it was started, submitted and shown (the
timeline ``scripts/preview_latency.py`` reads). Times are seconds since the
frame loop started."""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class FrameLog:
    """Per-frame times (seconds since the window opened) and states; ``levels``:
    one dict per refinement level started (generation, level, divisor, size,
    and the times "changed" (the camera's last change), "map" (its first map
    band), "submitted", "shown", with the solver's "waited" (submitted to
    solve start), "seconds" and "cpu_seconds" once it came back)."""

    times: list = field(default_factory=list)
    states: list = field(default_factory=list)
    work: list = field(default_factory=list)  # per frame: {step: milliseconds} of the main thread
    levels: list = field(default_factory=list)
    start: float = field(default_factory=time.perf_counter)

    def add(self, t: float, state: str, work: dict) -> None:
        self.times.append(t)
        self.states.append(state)
        self.work.append(work)

    def level(self, generation: int, level: int, divisor: int, size: tuple[int, int], changed=None) -> dict:
        """The entry of a level (made, with its "map" time, when first asked for).
        changed: time.perf_counter() of the generation's last camera change (None: not known)."""
        for entry in reversed(self.levels):
            if entry["generation"] == generation and entry["level"] == level:
                return entry
        entry = {"generation": generation, "level": level, "divisor": divisor, "size": list(size)}
        entry["map"] = self.now()
        if changed is not None and math.isfinite(changed):
            entry["changed"] = round(changed - self.start, 6)
        self.levels.append(entry)
        return entry

    def now(self) -> float:
        return round(time.perf_counter() - self.start, 6)

    def summary(self) -> dict:
        t = np.array(self.times)
        gaps = np.diff(t) if t.size > 1 else np.zeros(0)
        prev = np.array(self.states[:-1])
        refining = gaps[prev == "refining"] if gaps.size else gaps
        moving = gaps[prev == "moving"] if gaps.size else gaps
        return {
            "frames": int(t.size),
            "seconds": float(t[-1] - t[0]) if t.size > 1 else 0.0,
            "max_gap_ms": float(gaps.max() * 1e3) if gaps.size else 0.0,
            "max_gap_refining_ms": float(refining.max() * 1e3) if refining.size else 0.0,
            "p99_gap_refining_ms": float(np.percentile(refining, 99) * 1e3) if refining.size else 0.0,
            "refining_frames": int(refining.size),
            "fps_moving": float(moving.size / moving.sum()) if moving.size and moving.sum() > 0 else None,
            "moving_frames": int(moving.size),
        }

    def write(self, path: Path, extra: dict) -> None:
        doc = dict(extra)
        doc["summary"] = self.summary()
        doc["levels"] = self.levels
        doc["frames"] = [
            {"t": round(t, 6), "state": s, "ms": {k: round(v, 2) for k, v in w.items()}}
            for t, s, w in zip(self.times, self.states, self.work)
        ]
        path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
