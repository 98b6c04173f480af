"""One compiled signature per kernel: no duplicate specialisations creep back into the cold compile.

A kernel called with a read-only array here and a writable one there, or
with a literal argument at one call site and a variable at another, is
compiled (and cached) once per variant. ``tests/kernel_signatures.py``
runs the warm-up (``bsrt doctor``'s) and then renders every bundled scene
(shadows, mirrors) and a trimmed IGES model with every method; it runs here
in a new process with an empty numba cache, so that every kernel, called
from Python or from another kernel, is compiled in front of us (a kernel
loaded from the cache compiles none of the kernels it calls). The signatures
recorded for the parallel first-run compile (``bsrt/kernels/signatures.pickle``)
must be the ones renders compile.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bsrt.kernels import compile as kernels
from bsrt.methods import METHODS

pytestmark = pytest.mark.gl  # every test here needs it (tests/conftest.py checks)

ROOT = Path(__file__).resolve().parent.parent
INLINED = {
    "patches._horner",
    "roots.solve_one",
    "prelim._decode",
    "nets.leaf_net",
    "nets._split_cubic",
    "hulls._point",
}  # inline="always": copied into their callers, never compiled alone


def test_every_kernel_compiles_exactly_one_signature_and_the_warm_up_all_of_them(tmp_path):
    assert tuple(METHODS) == ("gradient", "fast", "newton", "martin")  # the script renders with each of these
    out = tmp_path / "signatures.json"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    subprocess.run(
        [sys.executable, str(ROOT / "tests" / "kernel_signatures.py"), "--size", "32", "--json", str(out)],
        env=env,
        check=True,
        capture_output=True,
        timeout=1800,
    )
    found = json.loads(out.read_text())
    renders, warm_up = found["renders"], found["warm_up"]
    entry = {f"{k.py_func.__module__.rsplit('.', 1)[1]}.{k.py_func.__name__}" for k in kernels.ENTRY_KERNELS}
    assert entry <= set(renders)
    assert {name for name, d in _dispatchers().items() if d.targetoptions.get("inline") == "always"} == INLINED
    counts = {name: len(sigs) for name, sigs in renders.items()}
    assert counts == {name: 0 if name in INLINED else 1 for name in renders}, {
        name: renders[name] for name, n in counts.items() if n != (0 if name in INLINED else 1)
    }
    assert warm_up == renders  # the warm-up compiled everything: a first render compiles nothing more
    record = kernels.recorded()  # the parallel first-run compile works from these (bsrt/kernels/compile.py)
    assert record is not None, "bsrt/kernels/signatures.pickle unreadable: run scripts/record_kernel_signatures.py"
    recorded = {name: [str(sig) for sig in sigs] for name, sigs in record["signatures"].items()}
    assert recorded == {name: renders[name] for name in recorded}, "run scripts/record_kernel_signatures.py"


def _dispatchers():
    from kernel_signatures import dispatchers  # tests/kernel_signatures.py, this test's helper

    return dispatchers()
