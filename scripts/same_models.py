"""Whether two bsrt checkouts load the same models from the same files, bit for bit.

    python scripts/same_models.py BEFORE_PYTHONPATH AFTER_PYTHONPATH FILES_OR_FOLDERS...

For a change that should only make loading faster: each checkout loads every
STEP, IGES and BREP file (``bsrt.io.load_model(path, cache=False)``, one
process per checkout for all files), and every array of every surface (degree,
knots, points, weights, each trim curve's), the names, colours, warnings,
skipped counts and untrimmed count are compared exactly (floats by their
bits; every field of the Model but ``load``; a dataclass field that is None is
left out, so a new optional field, None throughout, does not count as a change). Prints one line per file that
differs, naming the fields and the first surface that differ, and exits 1 if
any does.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

EXTENSIONS = (".step", ".stp", ".p21", ".igs", ".iges", ".brep", ".brp")

DUMP = textwrap.dedent("""
    import pickle, sys
    import numpy as np
    from bsrt.io import load_model

    def plain(x):
        if isinstance(x, np.ndarray):
            return ("array", x.dtype.str, x.shape, x.tobytes())
        if isinstance(x, (list, tuple)):
            return (type(x).__name__, [plain(v) for v in x])
        if isinstance(x, dict):
            return ("dict", sorted((str(k), plain(v)) for k, v in x.items()))
        if hasattr(x, "__dataclass_fields__"):
            # (fields that are None are left out: a field added with default None compares as before)
            fields = [f for f in x.__dataclass_fields__ if f != "load" and getattr(x, f) is not None]
            return (type(x).__name__, [(f, plain(getattr(x, f))) for f in fields])
        if isinstance(x, float):
            return ("float", x.hex())
        return x

    out = {}
    for path in sys.argv[2:]:
        try:
            m = load_model(path, cache=False)
            out[path] = {f: plain(getattr(m, f)) for f in m.__dataclass_fields__ if f != "load"}  # every field
        except Exception as e:  # the same failure is the same result
            out[path] = {"error": repr(e)}
    with open(sys.argv[1], "wb") as f:
        pickle.dump(out, f)
""")


def collect(args: list[str]) -> list[str]:
    files = []
    for a in args:
        p = Path(a)
        if p.is_dir():
            files += sorted(str(q) for q in p.rglob("*") if q.is_file() and q.suffix.lower() in EXTENSIONS)
        else:
            files.append(str(p))
    return [os.path.abspath(f) for f in files]


def dump(pythonpath: str, files: list[str], where: str) -> dict:
    out = os.path.join(where, "models.pkl")
    env = dict(os.environ, PYTHONPATH=os.path.abspath(pythonpath))
    subprocess.run([sys.executable, "-c", DUMP, out, *files], check=True, env=env, cwd=where)
    with open(out, "rb") as f:
        return pickle.load(f)


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 3 or args[0] in ("-h", "--help"):
        print(__doc__)
        return 2
    files = collect(args[2:])
    with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
        before, after = dump(args[0], files, a), dump(args[1], files, b)
    differing = 0
    for path in files:
        x, y = before[path], after[path]
        fields = [k for k in sorted(set(x) | set(y)) if x.get(k) != y.get(k)]
        if not fields:
            continue
        differing += 1
        where = ""
        if "surfaces" in fields and "surfaces" in x and "surfaces" in y:
            pairs = list(zip(x["surfaces"][1], y["surfaces"][1]))
            first = next((i for i, (s, t) in enumerate(pairs) if s != t), len(pairs))
            where = f" (first at surface {first})"
        print(f"{path}: differs in {', '.join(fields)}{where}")
    print(f"{len(files)} files, {differing} differing")
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())
