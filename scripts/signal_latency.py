"""How soon a long ``bsrt render`` ends after SIGTERM (or SIGINT) at a random moment, and what it leaves.

    python scripts/signal_latency.py [--scene SCENE] [--signals 10] [--seed 1] [--signal TERM] [-- RENDER ARGS ...]

Default: the column at 4096x4096 with --spp 4 (issue #28's long render).
First one render runs to its end, timed; then each of ``--signals`` renders
gets the signal at a moment drawn uniformly from [0.2 s, 90 % of that
time], and the script records how long the process took to end after it,
its exit code, and whether it left anything in its empty folder (an image,
an AOV file or a temporary: all or nothing means nothing, unless it had
finished first, exit 0 and the outputs whole). Prints one line per signal,
then the median and largest latency, with the load average before and
after (on a shared machine other jobs slow the exit too).
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _command(scene: str, extra: list[str]) -> list[str]:
    return [sys.executable, "-m", "bsrt", "render", scene, "-o", "out.png", "--aov", "out.npz", *extra]


def _run(command: list[str], delay: float | None, signum: int) -> dict:
    """One render in a fresh empty folder, signalled after ``delay`` seconds (None: not at all)."""
    with tempfile.TemporaryDirectory(prefix="bsrt-signal-") as folder:
        start = time.perf_counter()
        proc = subprocess.Popen(command, cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        sent = None
        if delay is not None:
            try:
                proc.wait(timeout=delay)
            except subprocess.TimeoutExpired:
                proc.send_signal(signum)
                sent = time.perf_counter()
        stderr = proc.communicate()[1]
        end = time.perf_counter()
        left = sorted(os.listdir(folder))
    return {
        "seconds": end - start,
        "latency": None if sent is None else end - sent,
        "code": proc.returncode,
        "left": left,
        "message": stderr.strip().splitlines()[-1] if stderr.strip() else "",
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=str(ROOT / "scenes" / "column.toml"), help="scene or model file")
    p.add_argument("--signals", type=int, default=10)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--signal", choices=("TERM", "INT"), default="TERM")
    p.add_argument("render_args", nargs="*", help="after --: bsrt render's options (default: 4096x4096, --spp 4)")
    a = p.parse_args()
    extra = a.render_args or ["--width", "4096", "--height", "4096", "--spp", "4"]
    command = _command(a.scene, extra)
    signum = getattr(signal, f"SIG{a.signal}")
    print(f"bsrt {' '.join(command[3:])}; load average before: {os.getloadavg()[0]:.2f}", flush=True)
    whole = _run(command, None, signum)
    if whole["code"] != 0:
        raise SystemExit(f"the uninterrupted render failed ({whole['code']}): {whole['message']}")
    print(f"uninterrupted: {whole['seconds']:.2f} s, left {whole['left']}", flush=True)
    draw = random.Random(a.seed)
    latencies, broken = [], 0
    for k in range(a.signals):
        delay = draw.uniform(0.2, 0.9 * whole["seconds"])
        r = _run(command, delay, signum)
        finished = r["latency"] is None or r["code"] == 0
        kept = (r["code"] == 0 and r["left"] == ["out.npz", "out.png"]) or (r["code"] != 0 and not r["left"])
        broken += not kept
        if r["latency"] is not None:
            latencies.append(r["latency"])
        latency = "-" if r["latency"] is None else f"{r['latency']:.3f} s"
        print(
            f"signal {k + 1:2d} at {delay:6.2f} s: ended {latency} later, exit {r['code']}, "
            f"{'finished first' if finished else 'interrupted'}, left {r['left'] or 'nothing'}"
            f"{'' if kept else '  <- NOT all or nothing'}; {r['message']}",
            flush=True,
        )
    if latencies:
        print(
            f"latency: median {statistics.median(latencies):.3f} s, largest {max(latencies):.3f} s, "
            f"over 1 s: {sum(t > 1.0 for t in latencies)} of {len(latencies)}; outputs broken: {broken}; "
            f"load average after: {os.getloadavg()[0]:.2f}"
        )
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
