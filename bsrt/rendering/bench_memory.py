"""``bsrt bench --memory``: the memory a render holds per pixel.

Two CLI renders of one scene in new processes, a small and a large film; the
peak resident memory of each (its ``ru_maxrss``, reported by a small process
that starts it: peak_rss) and the difference per added pixel: what a bigger
film costs, the process's fixed part (Python, NumPy, numba, the GL context,
the scene) taken out. A streamed film (bsrt/rendering/film.py) holds the
8-bit image, a 2-byte sample count per pixel and the band being traced (at
most pipeline.MAX_BAND_SAMPLES, twice a 512x512 film's pixels), so the figure
falls as the large film grows (column and water-lily: 53-59 bytes from 512
to 2048, 16.5 from 512 to 4096).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from bsrt.errors import InputError

DEFAULT_SIZES = (512, 2048)

# Linux counts in a child's peak the memory of the process it was started from (at exec, the
# copied or borrowed address space's high-water mark: a bench process holding 2.4 GB of Embree
# scenes made every child's "peak" 2.4 GB). So the child is started from a small Python process of
# its own, which reports its children's peak.
_PROBE = """
import json, resource, subprocess, sys
run = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(json.dumps({"code": run.returncode, "peak_kb": peak, "stderr": run.stderr.decode(errors="replace")[-2000:]}))
"""


def peak_rss(argv: list[str], env: dict, cwd=None) -> int:
    """Run ``argv`` in a child process (in folder ``cwd``); its peak resident memory in bytes, not
    counting this process's (_PROBE). A failure is an InputError."""
    probe = subprocess.run([sys.executable, "-c", _PROBE, *argv], env=env, capture_output=True, text=True, cwd=cwd)
    try:
        result = json.loads(probe.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        raise InputError(f"{' '.join(argv)}: could not be run ({probe.stderr.strip()[-300:]})") from None
    if result["code"] != 0:
        raise InputError(f"{' '.join(argv)}: failed ({result['code']}): {result['stderr'].strip()[-300:]}")
    return int(result["peak_kb"]) * 1024  # kB on Linux


def per_pixel(render_argv, env: dict, sizes=DEFAULT_SIZES, cwd=None) -> dict:
    """``render_argv(out_path)``: the argv of a CLI render writing out_path (width and height are
    added), run in folder ``cwd``. Peak memory at each size of ``sizes`` (small, large) and bytes per
    added pixel."""
    small, large = sizes
    peaks = {}
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            argv = render_argv(Path(tmp) / f"memory-{n}.png") + ["--width", str(n), "--height", str(n)]
            peaks[n] = peak_rss(argv, env, cwd)
    return {
        "sizes": list(sizes),
        "peak_mb": {str(n): peaks[n] / 2**20 for n in sizes},
        "bytes_per_pixel": (peaks[large] - peaks[small]) / (large * large - small * small),
        "load_average": [load, os.getloadavg()[0]],
    }


def format_row(memory: dict) -> str:
    """One line: the peaks and bytes per pixel."""
    small, large = memory["sizes"]
    return (
        f"memory: peak {memory['peak_mb'][str(small)]:.0f} MB at {small}x{small}, "
        f"{memory['peak_mb'][str(large)]:.0f} MB at {large}x{large}: "
        f"{memory['bytes_per_pixel']:.1f} bytes per added pixel, "
        f"load {memory['load_average'][0]:.1f}-{memory['load_average'][1]:.1f}"
    )
