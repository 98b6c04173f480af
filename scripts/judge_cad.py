"""Judge bsrt on real CAD parts against OpenCASCADE's exact ray intersector.

    python scripts/judge_cad.py FOLDER_OR_FILES... [--size 128] [--json out.json]
                                [--timeout 300] [--max-decide 2000] [--format auto]

For every STEP, IGES or BREP file (folders are searched recursively), in a
fresh process of its own (so that a crash or a hang costs one part, and each
load starts cold; ``--timeout`` seconds per part):

1. **bsrt** loads it the way users do, ``bsrt.io.load_model(path)`` (STEP and
   BREP through OpenCASCADE's XCAF reader, IGES through bsrt's own IGES
   reader; ``--format occt`` reads IGES through OpenCASCADE too), timed;
   ``Model.warnings``, ``Model.untrimmed`` and
   ``Model.skipped`` are reported.
2. **OpenCASCADE** reads the same file as one shape (``STEPControl_Reader``,
   ``IGESControl_Reader`` or ``BRepTools``; whole shape, every root).
   OpenCASCADE scales IGES to millimetres while bsrt's own IGES reader keeps
   the file's unit, so the IGES shape is scaled back by the Global section's
   unit flag. The diagonals of both boxes are compared: within a factor of 2
   (bsrt's box holds untrimmed surfaces' control points), else ``UNITS?``.
   A file OpenCASCADE makes no face of is an error row that says how many
   surfaces bsrt draws (nothing to compare).
3. The default camera (``scene_for_model``) shoots one primary ray per pixel
   of a SIZE x SIZE film; bsrt traces them (``render``) and OpenCASCADE's
   ``IntCurvesFace_ShapeIntersector`` traces the same rays on the shape.
4. Every pixel is one of: both miss, **agree** (both hit, |dt| <= 1e-6 of the
   diagonal), **extra** (bsrt hits, OpenCASCADE misses), **missed**
   (OpenCASCADE hits, bsrt misses), **wrong depth** (both hit, |dt| larger).
   A pixel is **at an edge** when its 3 x 3 neighbourhood sees more than one
   face (or a face and nothing) in bsrt's or in OpenCASCADE's labelling; those
   are counted apart from the interior ones.
5. For every disagreeing pixel (at most ``--max-decide`` per part, a seeded
   sample beyond), the hit points of both sides are measured against the
   shape (``BRepExtrema_DistShapeShape`` from a vertex): a hit farther than
   1e-6 of the diagonal from the shape is wrong. Extra: bsrt is right if its
   hit is on the shape, else OpenCASCADE. Missed: OpenCASCADE is right if its
   hit is on the shape, else bsrt. Wrong depth: the side whose hit alone is on
   the shape, or, both on it, the nearer hit (the other passed through a
   surface); neither on it: undecided.
   A ray OpenCASCADE's intersector raises on (``Standard_NullObject`` on some
   degenerate faces) is left out of the classes and reported as
   ``OCC-RAISED n``: of those, how many bsrt hits lie on the shape, how many
   off it, and how many bsrt misses (which cannot be judged).

Prints one table row per part; ``--json`` writes everything (per part: file,
size, authoring system from the header, faces, periodic faces, load seconds,
warnings, counts per class, decisions). Times are wall-clock on a possibly
shared machine: compare them only within one run.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

EXTENSIONS = (".step", ".stp", ".p21", ".igs", ".iges", ".brep", ".brp")
AGREE = 1e-6  # |dt| and the distance of a hit to the shape, as a fraction of the diagonal
CLASSES = ("agree", "extra", "missed", "wrong_depth")

# IGES Global section, parameter 14 (units flag) -> millimetres per unit
IGES_UNIT_MM = {1: 25.4, 2: 1.0, 4: 304.8, 5: 1609344.0, 6: 1000.0, 7: 1e6, 8: 0.0254, 9: 0.001, 10: 10.0, 11: 2.54e-5}
IGES_UNIT_NAMES = {
    "IN": 25.4,
    "INCH": 25.4,
    "MM": 1.0,
    "FT": 304.8,
    "MI": 1609344.0,
    "M": 1000.0,
    "KM": 1e6,
    "MIL": 0.0254,
    "UM": 0.001,
    "MICRON": 0.001,
    "CM": 10.0,
    "UIN": 2.54e-5,
}


# ---------------------------------------------------------------------------
# File headers: who wrote the file


def step_header(path: Path) -> dict:
    """FILE_NAME's preprocessor_version and originating_system (fields 5 and 6) of a STEP file."""
    text = path.read_bytes()[:20000].decode("latin-1")
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.DOTALL)
    m = re.search(r"FILE_NAME\s*\((.*?)\)\s*;", text, flags=re.DOTALL)
    if not m:
        return {}
    fields, depth, cur, quoted = [], 0, "", False
    body = m.group(1)
    i = 0
    while i < len(body):
        c = body[i]
        if quoted:
            if c == "'" and body[i + 1 : i + 2] == "'":
                cur += "'"
                i += 1
            elif c == "'":
                quoted = False
            else:
                cur += c
        elif c == "'":
            quoted = True
        elif c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif c == "," and depth == 0:
            fields.append(cur.strip())
            cur = ""
        elif depth == 0 and not c.isspace():
            cur += c
        i += 1
    fields.append(cur.strip())
    fields += [""] * (7 - len(fields))
    return {
        "name": " ".join(fields[0].split()),
        "preprocessor": " ".join(fields[4].split()),
        "system": " ".join(fields[5].split()),
    }


def iges_globals(path: Path) -> list[str]:
    """The IGES Global section's parameters (strings as their text)."""
    lines = path.read_bytes().decode("latin-1").splitlines()
    text = "".join(line[:72] for line in lines if len(line) >= 73 and line[72] == "G")
    pdelim, rdelim = ",", ";"
    if text.startswith("1H"):
        pdelim = text[2]
        rest = text[4:] if text[3:4] == pdelim else text[3:]
        if rest.startswith("1H"):
            rdelim = rest[2]
    elif text.startswith(","):
        pass
    fields, i = [], 0
    while i < len(text):
        m = re.match(r"\s*(\d+)H", text[i:])
        if m:
            n = int(m.group(1))
            start = i + m.end()
            fields.append(text[start : start + n])
            i = start + n
        else:
            ends = [k for k in (text.find(pdelim, i), text.find(rdelim, i)) if k >= 0]
            end = min(ends) if ends else len(text)
            fields.append(text[i:end].strip())
            i = end
        if i >= len(text) or text[i] == rdelim:
            break
        i += 1  # the delimiter
    return fields


def iges_header(path: Path) -> dict:
    g = iges_globals(path)
    g += [""] * (15 - len(g))
    return {
        "name": g[3].strip(),
        "system": g[4].strip(),
        "preprocessor": g[5].strip(),
        "unit_flag": g[13].strip(),
        "unit_name": g[14].strip(),
    }


def iges_mm_per_unit(header: dict) -> float:
    try:
        flag = int(float(header.get("unit_flag") or 1))
    except ValueError:
        flag = 1
    if flag == 3:
        return IGES_UNIT_NAMES.get(header.get("unit_name", "").upper().strip(), 1.0)
    return IGES_UNIT_MM.get(flag, 1.0)


def kind_of(path: Path) -> str:
    ext = path.suffix.lower()
    return "iges" if ext in (".igs", ".iges") else "brep" if ext in (".brep", ".brp") else "step"


def header(path: Path) -> dict:
    kind = kind_of(path)
    if kind == "step":
        return step_header(path)
    if kind == "iges":
        return iges_header(path)
    return {"system": "(BREP: none recorded)"}


# ---------------------------------------------------------------------------
# OpenCASCADE's side


#: an XSTEP selection (e.g. "iges-type(144)") that OpenCASCADE transfers instead of the file's roots: some IGES
#: files group their untrimmed base surfaces in 402 associativities, which OpenCASCADE draws (marsCapsule.igs)
OCC_SELECT = ""


def occ_read(path: Path, keep_mm: bool = False):
    """(shape, seconds): the file as OpenCASCADE reads it, in bsrt's units (IGES scaled back to the file's
    unless keep_mm: bsrt reads IGES with format "occt" in OpenCASCADE's millimetres)."""
    from OCP.IFSelect import IFSelect_RetDone

    kind = kind_of(path)
    start = time.perf_counter()
    if kind == "brep":
        from OCP.BRep import BRep_Builder
        from OCP.BRepTools import BRepTools
        from OCP.TopoDS import TopoDS_Shape

        shape = TopoDS_Shape()
        if not BRepTools.Read_s(shape, str(path), BRep_Builder()):
            raise RuntimeError("OpenCASCADE cannot read this BREP file")
        return shape, time.perf_counter() - start
    if kind == "step":
        from OCP.STEPControl import STEPControl_Reader

        reader = STEPControl_Reader()
    else:
        from OCP.IGESControl import IGESControl_Reader
        from OCP.Interface import Interface_Static

        # blanked entities (status "blank": the 128 under a 144, construction geometry) are not drawn;
        # OpenCASCADE transfers them unless told to keep to the visible ones
        Interface_Static.SetIVal_s("read.iges.onlyvisible", 1)
        reader = IGESControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise RuntimeError(f"OpenCASCADE cannot read this {kind.upper()} file")
    if OCC_SELECT and kind == "iges":
        reader.TransferList(reader.GiveList(OCC_SELECT))
    else:
        reader.TransferRoots()
    shape = reader.OneShape()
    seconds = time.perf_counter() - start
    if kind == "iges" and not keep_mm:
        factor = iges_mm_per_unit(iges_header(path))
        if factor != 1.0:
            from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform
            from OCP.gp import gp_Pnt, gp_Trsf

            trsf = gp_Trsf()
            trsf.SetScale(gp_Pnt(0.0, 0.0, 0.0), 1.0 / factor)
            shape = BRepBuilderAPI_Transform(shape, trsf, True).Shape()
    return shape, seconds


def occ_faces(shape) -> list:
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    cast = getattr(TopoDS, "Face", None) or TopoDS.Face_s
    out = []
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        out.append(cast(explorer.Current()))
        explorer.Next()
    return out


def face_census(faces) -> dict:
    """Faces per surface type, and how many lie on a periodic surface."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    kinds, periodic = {}, 0
    for face in faces:
        surface = BRepAdaptor_Surface(face, False)
        kind = str(surface.GetType()).split(".")[-1].replace("GeomAbs_", "")
        kinds[kind] = kinds.get(kind, 0) + 1
        if surface.IsUPeriodic() or surface.IsVPeriodic():
            periodic += 1
    return {"faces": len(faces), "periodic_faces": periodic, "surface_types": kinds}


def tight_diagonal(faces) -> float:
    """The diagonal of OpenCASCADE's tight box of the faces (free wireframe edges left out)."""
    import numpy as np
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    for face in faces:
        BRepBndLib.AddOptimal_s(face, box, False, False)
    lo, hi = box.CornerMin(), box.CornerMax()
    return float(np.linalg.norm([hi.X() - lo.X(), hi.Y() - lo.Y(), hi.Z() - lo.Z()]))


def occ_hits(shape, faces, eye, directions, size):
    """(hit (N,) bool, t (N,) float64 NaN where no hit, face (N,) int64 index into faces, -1 where no hit,
    failed (N,) bool: OpenCASCADE raised on the ray, counted as no hit)."""
    import numpy as np
    from OCP.gp import gp_Dir, gp_Lin, gp_Pnt
    from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector

    index: dict[int, list[tuple[int, object]]] = {}
    for j, f in enumerate(faces):
        index.setdefault(hash(f), []).append((j, f))
    intersector = IntCurvesFace_ShapeIntersector()
    intersector.Load(shape, 1e-9 * size)
    n = len(directions)
    hit = np.zeros(n, dtype=bool)
    t = np.full(n, np.nan)
    face = np.full(n, -1, dtype=np.int64)
    failed = np.zeros(n, dtype=bool)
    origin = gp_Pnt(*map(float, eye))
    for k, d in enumerate(directions):
        try:
            intersector.Perform(gp_Lin(origin, gp_Dir(*map(float, d))), 0.0, math.inf)
        except Exception:  # e.g. Standard_NullObject on a degenerate face: this ray has no answer
            failed[k] = True
            continue
        if intersector.IsDone() and intersector.NbPnt() > 0:
            i = min(range(1, intersector.NbPnt() + 1), key=intersector.WParameter)
            hit[k], t[k] = True, intersector.WParameter(i)
            f = intersector.Face(i)
            face[k] = next((j for j, g in index.get(hash(f), ()) if g.IsSame(f)), -2)
            if face[k] == -2:  # hash and IsSame disagree: search them all
                face[k] = next((j for j, g in enumerate(faces) if g.IsSame(f)), len(faces))
    return hit, t, face, failed


class Distance:
    """Distance of points to the shape (BRepExtrema_DistShapeShape from a vertex)."""

    def __init__(self, shape):
        from OCP.BRepExtrema import BRepExtrema_DistShapeShape

        self.tool = BRepExtrema_DistShapeShape()
        self.tool.LoadS2(shape)

    def __call__(self, point) -> float:
        from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
        from OCP.gp import gp_Pnt

        self.tool.LoadS1(BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, point))).Vertex())
        self.tool.Perform()
        return float(self.tool.Value()) if self.tool.IsDone() else math.inf


# ---------------------------------------------------------------------------
# The comparison


def interior(labels):
    """(H, W) bool: pixels whose 3 x 3 neighbourhood all see the same face (or all nothing)."""
    import numpy as np

    h, w = labels.shape
    pad = np.pad(labels, 1, constant_values=-2)
    same = np.ones((h, w), dtype=bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            same &= pad[1 + di : 1 + di + h, 1 + dj : 1 + dj + w] == labels
    return same


def classify(hit_b, t_b, hit_o, t_o, size):
    """(H, W) arrays of class names ("miss", "agree", "extra", "missed", "wrong_depth")."""
    import numpy as np

    out = np.full(hit_b.shape, "miss", dtype=object)
    both = hit_b & hit_o
    close = np.zeros_like(both)
    close[both] = np.abs(t_b[both] - t_o[both]) <= AGREE * size
    out[both & close] = "agree"
    out[both & ~close] = "wrong_depth"
    out[hit_b & ~hit_o] = "extra"
    out[~hit_b & hit_o] = "missed"
    return out


def decide(kind, d_b, d_o, t_b, t_o, tol):
    """ "bsrt", "occ" or "undecided" for one disagreeing pixel (distances to the shape, NaN where no hit)."""
    on_b, on_o = d_b <= tol, d_o <= tol
    if kind == "extra":
        return "bsrt" if on_b else "occ"
    if kind == "missed":
        return "occ" if on_o else "bsrt"
    if on_b and not on_o:
        return "bsrt"
    if on_o and not on_b:
        return "occ"
    if on_b and on_o:
        return "bsrt" if t_b < t_o else "occ"
    return "undecided"


def judge_one(path: Path, size: int, max_decide: int, format: str = "auto") -> dict:
    import numpy as np

    from bsrt.io import load_model
    from bsrt.rendering.pipeline import render
    from bsrt.scene import model_box, scene_for_model
    from bsrt.scene.camera import pixel_rays

    out: dict = {"file": str(path), "bytes": path.stat().st_size, "kind": kind_of(path), "size": size, "format": format}
    out["header"] = header(path)
    start = time.perf_counter()
    model = load_model(path, format)
    out["load_s"] = time.perf_counter() - start
    out["surfaces"] = len(model.surfaces)
    out["untrimmed"] = int(model.untrimmed)
    out["skipped"] = dict(model.skipped)
    out["warnings"] = list(model.warnings)
    shape, occ_s = occ_read(path, keep_mm=format == "occt")
    out["occ_read_s"] = occ_s
    faces = occ_faces(shape)
    out.update(face_census(faces))
    if not faces:  # nothing to trace rays on (and no box): bsrt's surfaces are all the news
        out["error"] = f"OpenCASCADE made no face from the file, bsrt draws {len(model.surfaces)} surfaces"
        return out
    diag = tight_diagonal(faces)
    lo, hi = model_box(model.surfaces)
    ours = float(np.linalg.norm(hi - lo))
    out["diagonal"] = diag
    out["bsrt_box_diagonal"] = ours
    out["units_ok"] = bool(0.5 * diag <= ours <= 2.0 * diag)  # a unit mix-up is a factor of 10 or more

    scene = scene_for_model(model, size, size)
    start = time.perf_counter()
    result = render(scene)
    out["render_s"] = time.perf_counter() - start
    aovs = result.aovs()
    hit_b, t_b, surf_b = aovs["hit"], aovs["t"], aovs["surface"]
    directions = pixel_rays(scene.camera, size, size)
    start = time.perf_counter()
    hit_o, t_o, face_o, failed = occ_hits(shape, faces, scene.camera.eye, directions, diag)
    out["occ_trace_s"] = time.perf_counter() - start
    hit_o, t_o, face_o = hit_o.reshape(size, size), t_o.reshape(size, size), face_o.reshape(size, size)
    failed = failed.reshape(size, size)

    labels_b = np.where(hit_b, surf_b, -1)
    labels_o = np.where(hit_o, face_o, -1)
    inner = interior(labels_b) & interior(labels_o)
    cls = classify(hit_b, t_b, hit_o, t_o, diag)
    cls[failed] = "occ_error"  # judged below by bsrt's hit alone
    counts = {"both_miss": int((cls == "miss").sum())}
    for c in CLASSES:
        counts[c] = int(((cls == c) & inner).sum())
        counts[c + "_at_edges"] = int(((cls == c) & ~inner).sum())
    out["counts"] = counts

    # who is right where they disagree
    bad = np.argwhere(np.isin(cls, CLASSES[1:]))
    out["disagreements"] = len(bad)
    if len(bad) > max_decide:
        bad = bad[np.sort(np.random.default_rng(0).choice(len(bad), max_decide, replace=False))]
    out["decided_sample"] = len(bad)
    distance = Distance(shape)
    eye = np.asarray(scene.camera.eye, dtype=np.float64)
    dirs = directions.reshape(size, size, 3)
    tol = AGREE * diag
    decisions = {
        c: {"bsrt": 0, "occ": 0, "undecided": 0, "at_edges": {"bsrt": 0, "occ": 0, "undecided": 0}} for c in CLASSES[1:]
    }
    examples = []
    start = time.perf_counter()
    for i, j in bad:
        kind = cls[i, j]
        d_b = distance(eye + t_b[i, j] * dirs[i, j]) if hit_b[i, j] else math.nan
        d_o = distance(eye + t_o[i, j] * dirs[i, j]) if hit_o[i, j] else math.nan
        who = decide(kind, d_b, d_o, t_b[i, j], t_o[i, j], tol)
        (decisions[kind] if inner[i, j] else decisions[kind]["at_edges"])[who] += 1
        if len(examples) < 20 and inner[i, j]:
            examples.append(
                {
                    "pixel": [int(i), int(j)],
                    "class": kind,
                    "winner": who,
                    "bsrt_t": None if not hit_b[i, j] else float(t_b[i, j]),
                    "occ_t": None if not hit_o[i, j] else float(t_o[i, j]),
                    "bsrt_distance": None if math.isnan(d_b) else d_b / diag,
                    "occ_distance": None if math.isnan(d_o) else d_o / diag,
                    "bsrt_surface": None if not hit_b[i, j] else model.names[int(surf_b[i, j])],
                    "occ_face": None if not hit_o[i, j] else int(face_o[i, j]),
                }
            )
    # rays OpenCASCADE raised on: bsrt's hit is on the shape or not; a miss cannot be judged
    on, off = 0, 0
    for i, j in np.argwhere(failed & hit_b):
        if distance(eye + t_b[i, j] * dirs[i, j]) <= tol:
            on += 1
        else:
            off += 1
    out["occ_error"] = {"rays": int(failed.sum()), "bsrt_on_shape": on, "bsrt_off_shape": off}
    out["decide_s"] = time.perf_counter() - start
    out["decisions"] = decisions
    out["examples"] = examples  # interior disagreements; distances as fractions of the diagonal
    totals = {"bsrt": 0, "occ": 0, "undecided": 0}
    for c in decisions.values():
        for k in totals:
            totals[k] += c[k] + c["at_edges"][k]
    out["decided"] = totals
    return out


# ---------------------------------------------------------------------------
# Driver: one fresh process per part


def collect(args: list[str]) -> list[Path]:
    files = []
    for a in args:
        p = Path(a)
        if p.is_dir():
            files += sorted(q for q in p.rglob("*") if q.is_file() and q.suffix.lower() in EXTENSIONS)
        else:
            files.append(p)
    return files


def run_child(path: Path, size: int, max_decide: int, timeout: float, format: str = "auto") -> dict:
    cmd = [
        sys.executable,
        os.path.abspath(__file__),
        "--one",
        str(path),
        "--size",
        str(size),
        "--max-decide",
        str(max_decide),
        "--format",
        format,
        "--occ-select",
        OCC_SELECT,
    ]
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"file": str(path), "error": f"timed out after {timeout:g} s"}
    for line in reversed(proc.stdout.splitlines()):
        if line.startswith("JUDGE-RESULT "):
            result = json.loads(line[len("JUDGE-RESULT ") :])
            result["process_s"] = time.perf_counter() - start
            return result
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    return {"file": str(path), "error": f"exit status {proc.returncode}: " + " | ".join(tail)}


def short_system(h: dict) -> str:
    s = h.get("system") or h.get("preprocessor") or "?"
    return s[:28]


def row(r: dict) -> str:
    name = Path(r["file"]).name[:34]
    if "error" in r:
        return f"{name:34} ERROR {r['error'][:150]}"
    c, d = r["counts"], r["decided"]
    edges = sum(c[k + "_at_edges"] for k in CLASSES[1:])
    skipped = sum(r["skipped"].values())
    return (
        f"{name:34} {short_system(r['header']):28} {r['faces']:5d} {r['periodic_faces']:5d} "
        f"{r['load_s']:7.2f} {r['occ_read_s']:6.2f} {r['untrimmed']:4d} {skipped:4d} {len(r['warnings']):3d} "
        f"{c['agree']:6d} {c['extra']:5d} {c['missed']:5d} {c['wrong_depth']:5d} {edges:6d} "
        f"{d['bsrt']:5d} {d['occ']:5d} {d['undecided']:5d}{'' if r['units_ok'] else '  UNITS?'}{occ_errors(r)}"
    )


def occ_errors(r: dict) -> str:
    """'' or a note of the rays OpenCASCADE's intersector raised on, with bsrt's hits judged alone."""
    e = r.get("occ_error") or {"rays": 0}
    if not e["rays"]:
        return ""
    missed = e["rays"] - e["bsrt_on_shape"] - e["bsrt_off_shape"]
    return (
        f"  OCC-RAISED {e['rays']} (bsrt hit on shape {e['bsrt_on_shape']}, off {e['bsrt_off_shape']}, no hit {missed})"
    )


HEAD = (
    f"{'part':34} {'system':28} {'faces':>5} {'perio':>5} {'load s':>7} {'occ s':>6} {'untr':>4} {'skip':>4} "
    f"{'wrn':>3} {'agree':>6} {'extra':>5} {'missd':>5} {'depth':>5} {'edges':>6} {'bsrt':>5} {'occ':>5} {'?':>5}"
)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("paths", nargs="*", help="STEP/IGES/BREP files or folders (searched recursively)")
    parser.add_argument("--size", type=int, default=128, help="film width and height in pixels (default 128)")
    parser.add_argument("--json", help="write every result to this JSON file")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per part (default 300)")
    parser.add_argument(
        "--max-decide",
        type=int,
        default=2000,
        help="disagreeing pixels measured per part; a seeded sample beyond (default 2000)",
    )
    parser.add_argument(
        "--format",
        default="auto",
        help='load_model\'s format: "auto" (by extension, as users do) or "occt" (IGES too through OpenCASCADE)',
    )
    parser.add_argument(
        "--occ-select",
        default="",
        help="IGES: the entities OpenCASCADE transfers, as an XSTEP selection such as "
        '"iges-type(144)" (default: the file\'s roots)',
    )
    parser.add_argument("--one", help=argparse.SUPPRESS)  # the child process: judge one file, print JSON
    args = parser.parse_args(argv)
    global OCC_SELECT
    OCC_SELECT = args.occ_select
    if args.one:
        result = judge_one(Path(args.one), args.size, args.max_decide, args.format)
        print("JUDGE-RESULT " + json.dumps(result))
        return 0
    files = collect(args.paths)
    if not files:
        parser.error("no STEP, IGES or BREP files given")
    print(
        f"{len(files)} parts, {args.size}x{args.size} rays each; counts away from edges, 'edges' = all "
        f"disagreements at edges; bsrt/occ/? = disagreements decided by distance to the shape",
        flush=True,
    )
    print(HEAD, flush=True)
    results = []
    for path in files:
        r = run_child(path, args.size, args.max_decide, args.timeout, args.format)
        results.append(r)
        print(row(r), flush=True)
    problems = [r for r in results if "error" not in r and (r["untrimmed"] or r["warnings"])]
    if problems:
        print("\nwarnings:")
        for r in problems:
            for w in r["warnings"]:
                print(f"  {Path(r['file']).name}: {w}")
    skipped = [r for r in results if "error" not in r and r["skipped"]]
    if skipped:
        print("\nskipped:")
        for r in skipped:
            print(f"  {Path(r['file']).name}: {r['skipped']}")
    if args.json:
        Path(args.json).write_text(
            json.dumps({"size": args.size, "load_average": os.getloadavg(), "parts": results}, indent=1)
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
