"""Which signatures each compiled kernel gets: after the warm-up, and after real renders.

    python tests/kernel_signatures.py [--size 64] [--json FILE]

Runs ``bsrt.rendering.warm_up.warm_up`` (what ``bsrt doctor`` runs), then
renders every bundled scene (scenes/*.toml) and a trimmed IGES model with
every method (the scenes have shadows and mirrors), and prints, per numba
dispatcher in ``bsrt.kernels``, the signatures it compiled. Run it with an
empty cache (``NUMBA_CACHE_DIR`` set to a new folder): a kernel loaded from
the cache does not compile the kernels it calls, so their signatures show
only in a cold run. Each kernel should show exactly one signature, all of
them already after the warm-up (a first render then compiles nothing).

A helper of tests/test_compile.py (which runs it in a child process with an
empty cache and imports ``dispatchers``); it lives beside the tests because
they need it, and imports only the package.
"""

from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TRIMMED_MODEL = ROOT / "tests" / "data" / "iges" / "plane_circle_144.igs"


def dispatchers() -> dict:
    """{"module.name": dispatcher} for every numba dispatcher defined in bsrt.kernels."""
    from numba.core.registry import CPUDispatcher

    import bsrt.kernels

    found = {}
    for info in pkgutil.iter_modules(bsrt.kernels.__path__):
        module = importlib.import_module(f"bsrt.kernels.{info.name}")
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == module.__name__:
                found[f"{info.name}.{name}"] = value
    return found


def signatures() -> dict[str, list[str]]:
    return {name: [str(sig) for sig in d.signatures] for name, d in sorted(dispatchers().items())}


def render_everything(size: int) -> None:
    """Every bundled scene and a trimmed model, with every method, at size x size."""
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import render
    from bsrt.scene.loading import load_input
    from bsrt.settings import METHODS

    inputs = sorted((ROOT / "scenes").glob("*.toml")) + [TRIMMED_MODEL]
    for path in inputs:
        scene = load_input(path, width=size, height=size)
        for method in METHODS:
            render(scene, RenderOptions.resolve(scene, method=method, width=size, height=size))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64, help="film width and height (default 64)")
    parser.add_argument("--json", help="also write {warm_up, renders: {kernel: [signatures]}} here")
    args = parser.parse_args(argv)
    from bsrt.rendering.warm_up import warm_up

    clock = time.perf_counter()
    warm_up()
    after_warm_up = signatures()
    warm_seconds = time.perf_counter() - clock
    render_everything(args.size)
    after_renders = signatures()
    for name, sigs in after_renders.items():
        extra = [s for s in sigs if s not in after_warm_up[name]]
        flag = "" if len(sigs) <= 1 else f"  <-- {len(sigs)} signatures"
        flag += f"  (+{len(extra)} after the warm-up)" if extra else ""
        print(f"{name}: {len(sigs)}{flag}")
        if len(sigs) > 1 or extra:
            for s in sigs:
                print(f"    {s}")
    print(f"warm-up: {warm_seconds:.1f} s", file=sys.stderr)
    if args.json:
        Path(args.json).write_text(json.dumps({"warm_up": after_warm_up, "renders": after_renders}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
