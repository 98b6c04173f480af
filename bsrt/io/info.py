"""``bsrt info FILE``: a human-readable summary of a loaded :class:`~bsrt.io.Model`."""

from __future__ import annotations

from collections import Counter

import numpy as np

from bsrt.io import Model


def describe(model: Model) -> str:
    """Multi-line summary: surface count (with trimmed surfaces and their loops, e.g.
    "213 surfaces (213 trimmed, 427 loops)"), degrees, rational and trimmed counts,
    skipped entities, the bounding box of all control points, the load (time, from the
    model cache or read), and warnings."""
    surfaces = model.surfaces
    trimmed = [s for s in surfaces if s.is_trimmed]
    loops = sum(len(s.trims) for s in trimmed)
    head = f"{model.path}: {len(surfaces)} surface{'s' if len(surfaces) != 1 else ''}"
    if trimmed:
        head += f" ({len(trimmed)} trimmed, {loops} loop{'s' if loops != 1 else ''})"
    lines = [head]
    degrees = Counter(s.degree for s in surfaces)
    lines.append("  degrees (u,v): " + ", ".join(f"({p},{q}) x {n}" for (p, q), n in degrees.most_common()))
    shapes = Counter(s.shape for s in surfaces)
    lines.append(
        "  control nets:  "
        + ", ".join(f"{a}x{b} x {n}" for (a, b), n in shapes.most_common(5))
        + (f", ... ({len(shapes)} kinds)" if len(shapes) > 5 else "")
    )
    lines.append(f"  rational:      {sum(s.is_rational for s in surfaces)}")
    if trimmed:
        per = Counter(len(s.trims) for s in trimmed)
        lines.append(
            "  trim loops:    " + ", ".join(f"{k} loop{'s' if k != 1 else ''} x {n}" for k, n in sorted(per.items()))
        )
    lines.append(f"  rendered untrimmed although trimmed in the file: {model.untrimmed}")
    if model.load is not None:
        lines.append(load_line([model.load]))
    pts = np.concatenate([s.points.reshape(-1, 3) for s in surfaces]) if surfaces else np.zeros((1, 3))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    lines.append(
        f"  bounding box of the control points: min ({_xyz(lo)}), max ({_xyz(hi)}), "
        f"diagonal {np.linalg.norm(hi - lo):.6g}"
    )
    if model.skipped:
        lines.append(f"  skipped (not drawable), {sum(model.skipped.values())} in all:")
        lines.extend(f"    {n:6d}  {what}" for what, n in sorted(model.skipped.items(), key=lambda kv: -kv[1]))
    else:
        lines.append("  skipped: nothing")
    if model.warnings:
        lines.append("  warnings:")
        lines.extend(f"    {w}" for w in model.warnings)
    return "\n".join(lines)


def load_line(loads) -> str:
    """One line about how the model files were loaded (bsrt.io.LoadRecord), e.g.
    ``  loaded in 0.021 s (from the model cache)`` or ``  loaded in 1.67 s (read: 160 of 160
    faces converted)``."""
    seconds = sum(r.seconds for r in loads)
    cached = sum(r.cached for r in loads)
    if len(loads) > 1:
        return f"  {len(loads)} model files loaded in {seconds:.3g} s ({cached} from the model cache)"
    record = loads[0]
    if record.cached:
        how = "from the model cache"
    else:
        how = "read" + (f": {record.faces[0]} of {record.faces[1]} faces converted" if record.faces else "")
    return f"  loaded in {seconds:.3g} s ({how})"


def _xyz(v: np.ndarray) -> str:
    return ", ".join(f"{x:.6g}" for x in v)
