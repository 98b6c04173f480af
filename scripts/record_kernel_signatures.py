"""Write bsrt/kernels/signatures.pickle: each entry kernel's signatures and its compile seconds.

    python scripts/record_kernel_signatures.py

Run after changing a kernel's arguments (tests/test_compile.py fails until
then). In a child with an empty numba cache, the warm-up (``bsrt doctor``'s)
compiles every kernel and its signatures are taken; a second child with
another empty cache compiles them one by one from those signatures, timed
(CPU seconds; a kernel's callees count for the first kernel that needs
them); then each kernel is compiled alone, in a child of its own with an
empty cache ("solo": its callees included), as many children at once as
there are cores (CPU seconds do not depend on that much).
``bsrt.kernels.compile.compile_all`` deals the kernels to its workers by
these seconds (compile._plan).
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

_SIGNATURES = """
import pickle, sys
from bsrt.kernels import compile as kernels
from bsrt.rendering.warm_up import warm_up
warm_up()
with open(sys.argv[1], "wb") as f:
    pickle.dump({"signatures": kernels.signatures_now()}, f, protocol=4)
"""


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from bsrt.kernels import compile as kernels

    env = kernels.worker_env()  # compiled as the first run's workers compile (NUMBA_OPT)
    with tempfile.TemporaryDirectory() as tmp:
        found = Path(tmp) / "signatures.pickle"
        env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "a")
        subprocess.run([sys.executable, "-c", _SIGNATURES, str(found)], env=env, check=True)
        env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "b")
        names = [kernels.name_of(k) for k in kernels.ENTRY_KERNELS]
        out = subprocess.run(
            [sys.executable, "-m", "bsrt.kernels.compile", "--record", str(found), *names],
            env=env,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        record = pickle.loads(found.read_bytes())
        record["seconds"] = json.loads(out.strip().splitlines()[-1])
        record["solo"] = _solo(names, found, env, Path(tmp))
    with open(kernels.SIGNATURES, "wb") as f:
        pickle.dump(record, f, protocol=4)
    total = sum(record["seconds"].values())
    print(f"wrote {kernels.SIGNATURES}: {len(names)} kernels, {total:.1f} s of compiling on one core")
    for workers in (2, 4):
        print(f"  {workers} workers: {kernels._plan(record, workers)[1]:.1f} s for the longest share")
    return 0


def _solo(names: list[str], found: Path, env: dict, tmp: Path) -> dict:
    """{name: CPU seconds} of each kernel compiled alone, in a child with an empty cache."""
    pending, running, seconds = list(names), [], {}
    while pending or running:
        while pending and len(running) < (os.cpu_count() or 1):
            name = pending.pop(0)
            child_env = {**env, "NUMBA_CACHE_DIR": str(tmp / f"solo-{name}")}
            command = [sys.executable, "-m", "bsrt.kernels.compile", "--record", str(found), name]
            running.append(subprocess.Popen(command, env=child_env, stdout=subprocess.PIPE, text=True))
        child = running.pop(0)
        out, _ = child.communicate()
        if child.returncode:
            raise SystemExit(f"compiling {child.args[-1]} alone failed ({child.returncode})")
        seconds |= json.loads(out.strip().splitlines()[-1])
    return seconds


if __name__ == "__main__":
    sys.exit(main())
