"""scripts/judge_cad.py on a part where OpenCASCADE makes no face.

Found on the IGES 5.x sample ``142-000.igs`` (SOURCES.md): bsrt draws the 114
surface a lone 142 curve references, OpenCASCADE's reader makes no face, and
the judge crashed on the empty box (``Standard_ConstructionError: Bnd_Box is
void``) instead of naming the difference. Here OpenCASCADE's read is replaced by
a real empty compound (no faces), the rest is the script as it runs.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from conftest import MODELS
from OCP.TopoDS import TopoDS_Compound

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "judge_cad.py"
_spec = importlib.util.spec_from_file_location("judge_cad", SCRIPT)
judge_cad = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(judge_cad)

PART = MODELS / "step" / "SkyentificGit-SmallRobotArm" / "Axis1tube.step"  # 8 faces


def test_a_part_opencascade_makes_no_face_of_is_an_error_row_not_a_crash(monkeypatch):
    monkeypatch.setattr(judge_cad, "occ_read", lambda path, keep_mm=False: (TopoDS_Compound(), 0.0))
    result = judge_cad.judge_one(PART, 16, 10)
    assert result["error"] == "OpenCASCADE made no face from the file, bsrt draws 8 surfaces"
    assert result["faces"] == 0 and result["surfaces"] == 8
    assert judge_cad.row(result).split()[1:3] == ["ERROR", "OpenCASCADE"]
