"""Time bsrt's IGES reader against OpenCASCADE's on real files.

    python scripts/iges_load_ratio.py [--repeat 3] FILES...

For each file, ``--repeat`` rounds of two fresh subprocesses back to back: one
times ``bsrt.io.load_model(path)`` (bsrt's own reader, its modules imported
before the clock starts), the other OpenCASCADE's ``IGESControl_Reader``
``ReadFile`` + ``TransferRoots`` + ``OneShape`` (OCP imported before the clock
starts). Prints the medians, their ratio (bsrt / OpenCASCADE; the issue asks
for at most 4) and the load average before and after (the machine may be
shared: compare ratios, not seconds).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys

_BSRT = """
import sys, time
import bsrt.io, bsrt.io.iges, bsrt.io.iges_topology, bsrt.io.iges_seams
path = sys.argv[1]
t = time.perf_counter()
m = bsrt.io.load_model(path)
print(time.perf_counter() - t, len(m.surfaces))
"""

_OCC = """
import sys, time
from OCP.IGESControl import IGESControl_Reader
from OCP.TopExp import TopExp_Explorer
from OCP.TopAbs import TopAbs_FACE
path = sys.argv[1]
t = time.perf_counter()
r = IGESControl_Reader()
r.ReadFile(path)
r.TransferRoots()
shape = r.OneShape()
dt = time.perf_counter() - t
n, e = 0, TopExp_Explorer(shape, TopAbs_FACE)
while e.More():
    n += 1
    e.Next()
print(dt, n)
"""


def _run(code: str, path: str) -> tuple[float, int]:
    out = subprocess.run([sys.executable, "-c", code, path], capture_output=True, text=True, check=True)
    seconds, faces = out.stdout.split()[-2:]
    return float(seconds), int(faces)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'file':40s} {'bsrt s':>8s} {'OCC s':>8s} {'ratio':>6s} {'faces':>11s}")
    for path in args.files:
        ours, theirs = [], []
        for _ in range(args.repeat):
            a, na = _run(_BSRT, path)
            b, nb = _run(_OCC, path)
            ours.append(a)
            theirs.append(b)
        mo, mt = statistics.median(ours), statistics.median(theirs)
        print(f"{os.path.basename(path):40s} {mo:8.3f} {mt:8.3f} {mo / mt:6.2f} {na:5d}/{nb:<5d}", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
