"""Time bsrt's IGES reader against OpenCASCADE's on real files.

    python scripts/iges_load_ratio.py [--repeat 3] [--variant NAME=PYTHONPATH ...] FILES...

For each file, ``--repeat`` rounds of two fresh subprocesses back to back: one
times ``bsrt.io.load_model(path)`` (bsrt's own reader, its modules imported
before the clock starts), the other OpenCASCADE's ``IGESControl_Reader``
``ReadFile`` + ``TransferRoots`` + ``OneShape`` (OCP imported before the clock
starts). Prints the medians, their ratio (bsrt / OpenCASCADE; the issue asks
for at most 4) and the load average before and after (the machine may be
shared: compare ratios, not seconds). With ``--variant`` (repeatable), each
round times every variant's bsrt (PYTHONPATH set to its checkout) next to
the same OpenCASCADE run, interleaved, so that a before/after comparison
sees the same load.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile

_BSRT = """
import sys, time
import bsrt.io, bsrt.io.iges, bsrt.io.iges.topology, bsrt.io.iges.seams
path = sys.argv[1]
t = time.perf_counter()
m = bsrt.io.load_model(path)
print(bsrt.__file__, time.perf_counter() - t, len(m.surfaces))
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


def _run(code: str, path: str, pythonpath: str | None = None) -> tuple[float, int]:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    # run outside any checkout: ``python -c`` puts the working directory first on sys.path
    out = subprocess.run(
        [sys.executable, "-c", code, os.path.abspath(path)],
        capture_output=True,
        text=True,
        check=True,
        env=env,
        cwd=tempfile.gettempdir(),
    )
    seconds, faces = out.stdout.split()[-2:]
    return float(seconds), int(faces), out.stdout.split()[-3]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="NAME=PYTHONPATH",
        help="a bsrt checkout to time (repeatable; default: the current environment's)",
    )
    args = parser.parse_args(argv)
    variants = [tuple(v.split("=", 1)) for v in args.variant] or [("bsrt", None)]
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'file':32s} {'variant':8s} {'bsrt s':>8s} {'OCC s':>8s} {'ratio':>6s} {'faces':>11s}")
    for path in args.files:
        ours = {name: [] for name, _ in variants}
        faces, where = {}, {}
        theirs = []
        for _ in range(args.repeat):
            for name, pp in variants:
                a, faces[name], where[name] = _run(_BSRT, path, pp)
                ours[name].append(a)
            b, nb, _ = _run(_OCC, path)
            theirs.append(b)
        mt = statistics.median(theirs)
        for name, _ in variants:
            mo = statistics.median(ours[name])
            print(
                f"{os.path.basename(path):32s} {name:8s} {mo:8.3f} {mt:8.3f} {mo / mt:6.2f} "
                f"{faces[name]:5d}/{nb:<5d} {os.path.dirname(os.path.dirname(where[name]))}",
                flush=True,
            )
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
