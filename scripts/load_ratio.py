"""How much longer bsrt takes to load a CAD file than OpenCASCADE takes to read it.

    python scripts/load_ratio.py FILES_OR_FOLDERS... [--repeat 3] [--warm] [--timeout 600] [--json out.json]
                                 [--variant NAME=PYTHONPATH ...]

For each STEP, IGES or BREP file, ``--repeat`` times, two fresh processes
back to back (``sys.executable -c ...``), each timing one call after its
imports are done:

* **occ**: OpenCASCADE's own read + transfer of the file, the whole shape:
  ``STEPControl_Reader.ReadFile`` + ``TransferRoots`` + ``OneShape`` (IGES:
  ``IGESControl_Reader``; BREP: ``BRepTools.Read``);
* **bsrt**: ``bsrt.io.load_model(path)``, the call users make (STEP and BREP
  through OpenCASCADE's XCAF reader plus bsrt's conversion of every face;
  IGES through bsrt's own reader). If ``load_model`` takes a ``cache``
  keyword (a converted-model cache), it is passed ``cache=False``. The
  OpenCASCADE modules bsrt's reader uses, and bsrt's reader modules, are
  imported before the clock starts (as OpenCASCADE's own are: with
  PYTHONDONTWRITEBYTECODE set, as on the development machines, importing
  bsrt's readers would otherwise compile their source on every run; every module of
  the ``bsrt.io`` package is imported, the IGES reader's helpers included, which
  ``bsrt.io.iges`` imports on its first read); compiled kernels are loaded from numba's cache inside the call,
  as they are for a user's first load. ``--warm`` also times a second call
  in the same process.

Prints the medians and the ratio bsrt / occ per file (the goal: at most 4),
with the load average (``os.getloadavg()``) before and after: on a shared
machine, compare ratios measured together, not seconds across runs. The
``cpu`` column is the same ratio of the processes' CPU time
(``time.process_time()``), which a loaded machine disturbs much less than the
wall clock (both readers run on one thread).

``--variant NAME=PYTHONPATH`` (repeatable) times the bsrt of each named
checkout (its PYTHONPATH set so) in every round, next to the same
OpenCASCADE run, interleaved: a before/after comparison sees the same load.
Each variant gets its own row per file.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

EXTENSIONS = (".step", ".stp", ".p21", ".igs", ".iges", ".brep", ".brp")

OCC_CHILD = textwrap.dedent("""
    import sys, time
    path = sys.argv[1]
    ext = path.rsplit(".", 1)[-1].lower()
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader
    from OCP.IGESControl import IGESControl_Reader
    from OCP.BRepTools import BRepTools
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Shape
    start, cpu = time.perf_counter(), time.process_time()
    if ext in ("brep", "brp"):
        shape = TopoDS_Shape()
        ok = BRepTools.Read_s(shape, path, BRep_Builder())
    else:
        reader = STEPControl_Reader() if ext in ("step", "stp", "p21") else IGESControl_Reader()
        ok = reader.ReadFile(path) == IFSelect_RetDone
        reader.TransferRoots()
        shape = reader.OneShape()
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    assert ok and not shape.IsNull(), "OpenCASCADE could not read the file"
    print("LOAD-SECONDS", seconds)
    print("CPU-SECONDS", cpu)
""")

BSRT_CHILD = textwrap.dedent("""
    import inspect, sys, time
    path, warm = sys.argv[1], sys.argv[2] == "1"
    import bsrt.io
    from bsrt.io import load_model
    import bsrt.io.iges, bsrt.io.cache  # the readers' modules: imported, not timed (as OpenCASCADE's are)
    import importlib, pkgutil
    for info in pkgutil.walk_packages(bsrt.io.__path__, "bsrt.io."):  # their helpers too (bsrt.io.iges.topology, ...)
        try:
            importlib.import_module(info.name)
        except ImportError:
            pass
    try:
        import bsrt.io.occt
        # every OpenCASCADE module bsrt/io/occt imports (grep for "OCP." there when it changes)
        import OCP.STEPCAFControl, OCP.IGESCAFControl, OCP.XCAFPrs, OCP.XCAFDoc, OCP.XCAFApp, OCP.TDocStd
        import OCP.BRepTools, OCP.GeomConvert, OCP.Geom2dConvert, OCP.BRep, OCP.TopExp, OCP.GeomAbs
        import OCP.BRepBndLib, OCP.Bnd, OCP.TDataStd, OCP.TDF, OCP.Geom, OCP.Geom2d, OCP.ShapeAnalysis
        import OCP.IFSelect, OCP.TCollection, OCP.TopAbs, OCP.TopLoc, OCP.TopoDS, OCP.collections, OCP.gp
    except ImportError:
        pass
    kwargs = {"cache": False} if "cache" in inspect.signature(load_model).parameters else {}
    start, cpu = time.perf_counter(), time.process_time()
    model = load_model(path, **kwargs)
    print("LOAD-SECONDS", time.perf_counter() - start)
    print("CPU-SECONDS", time.process_time() - cpu)
    if warm:
        start = time.perf_counter()
        load_model(path, **kwargs)
        print("WARM-SECONDS", time.perf_counter() - start)
    print("SURFACES", len(model.surfaces), "UNTRIMMED", model.untrimmed, "CACHE-KEYWORD", bool(kwargs))
""")


def collect(args: list[str]) -> list[Path]:
    files = []
    for a in args:
        p = Path(a)
        if p.is_dir():
            files += sorted(q for q in p.rglob("*") if q.is_file() and q.suffix.lower() in EXTENSIONS)
        else:
            files.append(p)
    return files


def child(code: str, args: list[str], timeout: float, pythonpath: str | None = None) -> dict:
    env = None
    if pythonpath is not None:
        env = dict(os.environ, PYTHONPATH=pythonpath)
    try:
        # run outside any checkout: ``python -c`` puts the working directory first on sys.path
        proc = subprocess.run(
            [sys.executable, "-c", code, *args],
            check=False,
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
            cwd=tempfile.gettempdir() if pythonpath is not None else None,
        )
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:g} s"}
    out = {}
    for line in proc.stdout.splitlines():
        words = line.split()
        if words and words[0] == "LOAD-SECONDS":
            out["seconds"] = float(words[1])
        elif words and words[0] == "CPU-SECONDS":
            out["cpu"] = float(words[1])
        elif words and words[0] == "WARM-SECONDS":
            out["warm"] = float(words[1])
        elif words and words[0] == "SURFACES":
            out["surfaces"], out["untrimmed"], out["cache_keyword"] = int(words[1]), int(words[3]), words[5]
    if "seconds" not in out:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-2:]
        out["error"] = f"exit status {proc.returncode}: " + " | ".join(tail)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("paths", nargs="+", help="STEP/IGES/BREP files or folders (searched recursively)")
    parser.add_argument("--repeat", type=int, default=3, help="fresh-process pairs per file (default 3)")
    parser.add_argument("--warm", action="store_true", help="also time a second load_model in the same process")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per process (default 600)")
    parser.add_argument("--json", help="write the measurements to this JSON file")
    parser.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="NAME=PYTHONPATH",
        help="a bsrt checkout to time, interleaved with the others (repeatable; default: this environment's)",
    )
    args = parser.parse_args(argv)
    variants = [tuple(v.split("=", 1)) for v in args.variant]
    if any(len(v) != 2 or not v[0] for v in variants):
        parser.error("--variant takes NAME=PYTHONPATH")
    variants = variants or [("", None)]
    files = collect(args.paths)
    before = os.getloadavg()
    print(f"load average before: {before[0]:.2f} {before[1]:.2f} {before[2]:.2f} ({os.cpu_count()} CPUs)")
    print(
        f"{'file':40} {'occ s':>8} {'bsrt s':>8} {'ratio':>7} {'cpu':>7}"
        + (f" {'warm s':>8}" if args.warm else "")
        + "  surfaces"
    )
    results = []
    for path in files:
        occ, occ_cpu, occ_errors = [], [], []
        ours = {name: {"s": [], "cpu": [], "warm": [], "info": {}, "errors": []} for name, _ in variants}
        for _ in range(args.repeat):
            a = child(OCC_CHILD, [str(path)], args.timeout)
            if "error" in a:
                occ_errors.append(a["error"])
            for name, pythonpath in variants:
                b = child(BSRT_CHILD, [str(os.path.abspath(path)), "1" if args.warm else "0"], args.timeout, pythonpath)
                mine = ours[name]
                if "error" in b:
                    mine["errors"].append(b["error"])
                    continue
                mine["s"].append(b["seconds"])
                if "cpu" in a and "cpu" in b:
                    mine["cpu"].append(b["cpu"])
                if "warm" in b:
                    mine["warm"].append(b["warm"])
                mine["info"] = {k: b[k] for k in ("surfaces", "untrimmed", "cache_keyword") if k in b} or mine["info"]
            if "error" not in a:
                occ.append(a["seconds"])
                occ_cpu.append(a["cpu"])
        for name, _ in variants:
            mine = ours[name]
            r = {
                "file": str(path),
                "occ_s": occ,
                "bsrt_s": mine["s"],
                "warm_s": mine["warm"],
                "occ_cpu_s": occ_cpu,
                "bsrt_cpu_s": mine["cpu"],
                **mine["info"],
            }
            if name:
                r["variant"] = name
            errors = occ_errors + mine["errors"]
            if errors:
                r["errors"] = errors
            label = (f"{name}: " if name else "") + path.name
            label = label[:40]
            if occ and mine["s"]:
                r["occ_median"], r["bsrt_median"] = statistics.median(occ), statistics.median(mine["s"])
                r["ratio"] = r["bsrt_median"] / max(r["occ_median"], 1e-9)
                line = f"{label:40} {r['occ_median']:8.3f} {r['bsrt_median']:8.3f} {r['ratio']:7.1f}"
                if mine["cpu"] and occ_cpu:
                    r["occ_cpu_median"] = statistics.median(occ_cpu)
                    r["bsrt_cpu_median"] = statistics.median(mine["cpu"])
                    r["cpu_ratio"] = r["bsrt_cpu_median"] / max(r["occ_cpu_median"], 1e-9)
                    line += f" {r['cpu_ratio']:7.1f}"
                else:
                    line += f" {'-':>7}"
                if args.warm:
                    line += f" {statistics.median(mine['warm']):8.3f}" if mine["warm"] else f" {'-':>8}"
                print(line + f"  {mine['info'].get('surfaces', '?')}", flush=True)
            else:
                print(f"{label:40} ERROR {errors[0][:150] if errors else '?'}", flush=True)
            results.append(r)
    after = os.getloadavg()
    print(f"load average after: {after[0]:.2f} {after[1]:.2f} {after[2]:.2f}")
    for name, _ in variants:
        mine = [r for r in results if r.get("variant", "") == name]
        ratios = [r["ratio"] for r in mine if "ratio" in r]
        if not ratios:
            continue
        head = f"{name}: " if name else ""
        over = [Path(r["file"]).name for r in mine if r.get("ratio", 0) > 4]
        print(
            f"{head}ratio median {statistics.median(ratios):.1f}, max {max(ratios):.1f}; over 4x: "
            f"{len(over)} of {len(ratios)}" + (f" ({', '.join(over)})" if over else "")
        )
        cpus = [r["cpu_ratio"] for r in mine if "cpu_ratio" in r]
        if cpus:
            over = [Path(r["file"]).name for r in mine if r.get("cpu_ratio", 0) > 4]
            print(
                f"{head}cpu ratio median {statistics.median(cpus):.1f}, max {max(cpus):.1f}; over 4x: "
                f"{len(over)} of {len(cpus)}" + (f" ({', '.join(over)})" if over else "")
            )
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                {"load_average_before": before, "load_average_after": after, "repeat": args.repeat, "files": results},
                indent=1,
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
