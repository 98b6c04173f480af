"""How a whole render scales with cores: the same render pinned to 1, 2, ... cores with taskset.

For each core set (``--cores 0 0,1`` by default) a fresh child process is
pinned with ``taskset -c SET`` (bsrt's thread pool sizes itself to the
affinity), renders the scene once untimed (kernels, GL context, hierarchy),
then ``--rounds`` times, in process (as ``bsrt bench``, with the program's
allocator settings: bsrt/allocator.py); it reports each
set's median wall and CPU seconds and the speed-up of the wall time against
the first set, with the load average before and after (on a shared machine
other jobs take the same cores: read the speed-ups with the load). Usage:

    python scripts/core_scaling.py [SCENE] [--size 512] [--rounds 5] [--cores 0 0,1] [--device cpu]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bsrt.settings import DEVICES  # noqa: E402

CHILD = """
import json, os, sys, time
from bsrt.allocator import keep_freed_memory
keep_freed_memory()  # as the bsrt program (bench) does
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import load_scene
scene = load_scene(sys.argv[1])
size, rounds, device = int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
geometry = Geometry(scene)
options = RenderOptions.resolve(scene, width=size, height=size, device=device)
result = render(scene, options, geometry=geometry)  # warm-up
wall, cpu, stages = [], [], []
for _ in range(rounds):
    clock, used = time.perf_counter(), time.process_time()
    result = render(scene, options, geometry=geometry)
    wall.append(time.perf_counter() - clock)
    cpu.append(time.process_time() - used)
    stages.append(result.stats["seconds"])
print(json.dumps({"wall": wall, "cpu": cpu, "stages": stages, "devices": result.stats["devices"],
                  "cores": len(os.sched_getaffinity(0))}))
"""


def pinned(cores: str, scene: Path, size: int, rounds: int, device: str) -> dict:
    """Wall and CPU seconds and the stages' seconds per round of the render in a child pinned to
    ``cores`` (taskset -c), with the ``device`` setting, and the devices its stages ran on."""
    cmd = ["taskset", "-c", cores, sys.executable, "-c", CHILD, str(scene), str(size), str(rounds), device]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"the render on cores {cores} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=str(ROOT / "scenes" / "water-lily.toml"))
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--cores", nargs="+", default=["0", "0,1"], help="taskset core lists, the first the baseline")
    p.add_argument(
        "--device",
        choices=DEVICES,
        default="cpu",
        help="the device setting (default cpu: the CPU kernels' cores are what is measured)",
    )
    a = p.parse_args()
    if shutil.which("taskset") is None:
        raise SystemExit("taskset (util-linux) is not installed")
    scene = Path(a.scene)
    print(
        f"{scene.name} {a.size}x{a.size}, {a.rounds} rounds, device {a.device}; load average before: {os.getloadavg()}",
        flush=True,
    )
    base = None
    for cores in a.cores:
        r = pinned(cores, scene, a.size, a.rounds, a.device)
        wall, cpu = statistics.median(r["wall"]), statistics.median(r["cpu"])
        base = base or wall
        print(
            f"cores {cores:8s} ({r['cores']}): wall {wall:.3f} s (rounds {', '.join(f'{w:.2f}' for w in r['wall'])}), "
            f"CPU {cpu:.3f} s, speed-up {base / wall:.2f}x",
            flush=True,
        )
        stages = {k: statistics.median(s[k] for s in r["stages"]) for k in r["stages"][0]}
        print("    stages: " + ", ".join(f"{k} {v:.3f}" for k, v in stages.items()) + f"; devices {r['devices']}")
    print(f"load average after: {os.getloadavg()}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
