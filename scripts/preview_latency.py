"""Time from "the camera stops" to "the exact image is shown" in ``bsrt preview``.

Runs the preview (in a subprocess, on $DISPLAY) with a script that orbits,
waits for the exact image, and repeats; reads its ``--frame-log`` and prints,
per run, each settle-to-exact latency (the first "exact" frame's time minus
the last "moving" frame's time before it) and the frame gaps while refining
(median and max, ms); from the log's refinement timeline, per stop, the time
to the first (coarse) exact image and the solver's wall and CPU seconds per
level (bsrt.rendering.bench.preview_timeline, also behind ``bsrt bench
--preview``); and the load average and the CPU seconds of each whole run (the
window and its solver processes). Usage:

    python scripts/preview_latency.py [SCENE] [--size 800x600] [--runs 3] [--moves 2]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bsrt.rendering.bench import preview_timeline  # noqa: E402


def latencies(log: dict) -> list[float]:
    """Seconds from each last "moving" frame to the next "exact" frame."""
    out, last_moving = [], None
    for frame in log["frames"]:
        if frame["state"] == "moving":
            last_moving = frame["t"]
        elif frame["state"] == "exact" and last_moving is not None:
            out.append(frame["t"] - last_moving)
            last_moving = None
    return out


def gaps_ms(log: dict) -> list[float]:
    """Gaps (ms) after each frame drawn in the "refining" state."""
    frames = log["frames"]
    return [(b["t"] - a["t"]) * 1e3 for a, b in zip(frames, frames[1:]) if a["state"] == "refining"]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=str(ROOT / "scenes" / "water-lily.toml"))
    p.add_argument("--size", default="800x600")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--moves", type=int, default=2)
    a = p.parse_args()
    width, height = a.size.split("x")
    events = "wait; " + "; ".join(["orbit 15 0 5; wait"] * a.moves) + "; quit"
    all_lat, all_gaps, all_steps = [], [], []
    print(f"load average at start: {Path('/proc/loadavg').read_text().split()[:3]}", flush=True)
    for run in range(a.runs):
        cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
        with tempfile.TemporaryDirectory() as tmp:
            log_path = Path(tmp) / "log.json"
            cmd = [
                sys.executable,
                "-m",
                "bsrt",
                "preview",
                a.scene,
                "--width",
                width,
                "--height",
                height,
                "--events",
                events,
                "--frame-log",
                str(log_path),
            ]
            result = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
            if result.returncode != 0:
                print(result.stderr, file=sys.stderr)
                return 1
            log = json.loads(log_path.read_text())
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        run_cpu = after.ru_utime + after.ru_stime - cpu.ru_utime - cpu.ru_stime
        lat = latencies(log)[1:]  # the first "exact" follows start-up, not a camera stop
        gaps = gaps_ms(log)
        steps = preview_timeline(log)
        all_lat += lat
        all_gaps += gaps
        all_steps += steps
        print(
            f"run {run + 1}: settle-to-exact {[round(x, 3) for x in lat]} s; refining gaps median "
            f"{statistics.median(gaps):.1f} ms, max {max(gaps):.1f} ms ({len(gaps)} frames); "
            f"CPU of the whole run {run_cpu:.1f} s",
            flush=True,
        )
        for step in steps:
            solves = ", ".join(f"1/{d} {w:.3f} s ({c:.3f} s CPU)" for d, (w, c) in step["solve"].items())
            print(
                f"  first image {step['first']:.3f} s, exact {step['exact']:.3f} s (from the last change "
                f"{step['changed_first']:.3f}, {step['changed_exact']:.3f}); exact level: map {step['map']:.3f} s, "
                f"waited {step['waited']:.3f} s, back {step['back']:.3f} s; solves {solves}",
                flush=True,
            )
    print(
        f"median settle-to-exact {statistics.median(all_lat):.3f} s over {len(all_lat)}; "
        f"refining gaps median {statistics.median(all_gaps):.1f} ms, max {max(all_gaps):.1f} ms"
    )
    if all_steps:

        def median(key):
            return statistics.median(s[key] for s in all_steps)

        cpu_exact = statistics.median(s["solve"][1][1] for s in all_steps)
        print(
            f"medians: settle-to-first-image {median('first'):.3f} s, settle-to-exact {median('exact'):.3f} s; "
            f"from the last change {median('changed_first'):.3f} s and {median('changed_exact'):.3f} s; "
            f"exact level map {median('map'):.3f} s, waited {median('waited'):.3f} s, back {median('back'):.3f} s, "
            f"solver CPU {cpu_exact:.3f} s"
        )
    print(f"load average at end: {Path('/proc/loadavg').read_text().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
