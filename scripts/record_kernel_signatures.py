"""Write bsrt/kernels/signatures.pickle: each entry kernel's signatures and its compile seconds.

    python scripts/record_kernel_signatures.py

Run after changing a kernel's arguments (tests/test_compile.py fails until
then). In a child with an empty numba cache, the warm-up (``bsrt doctor``'s)
compiles every kernel and its signatures are taken; a second child with
another empty cache compiles them one by one from those signatures, timed
(CPU seconds; a kernel's callees count for the first kernel that needs
them). ``bsrt.kernels.compile.compile_all`` deals the kernels to its
workers by these seconds, longest first.
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

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
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
    with open(kernels.SIGNATURES, "wb") as f:
        pickle.dump(record, f, protocol=4)
    total = sum(record["seconds"].values())
    print(f"wrote {kernels.SIGNATURES}: {len(names)} kernels, {total:.1f} s of compiling on one core")
    return 0


if __name__ == "__main__":
    sys.exit(main())
