"""Fuzzing (issue #16): Hypothesis over scene documents and over each model
reader, and a short pass of tests/fuzz_cli.py (this module's helper) through the real command line.

The property everywhere: the input is either accepted, and then valid (every
surface within the limits, the render options resolve or are refused), or
refused with one InputError sentence that names the file; no other exception
and no Python warning (NumPy's floating-point warnings included).
"""

from __future__ import annotations

import copy
import re
import tomllib
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bsrt import validate
from bsrt.errors import InputError
from bsrt.io import load_model
from bsrt.rendering.options import RenderOptions
from bsrt.scene import parse_scene

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
QUAD = tomllib.loads((ROOT / "scenes" / "quad.toml").read_text())

EXTREME_TOKENS = [
    "1e308",
    "-1e308",
    "1e400",
    "5e-324",
    "0",
    "-0",
    "-1",
    "nan",
    "inf",
    "１",
    "٣",
    "true",
    "x",
    "",
    "99999999999999999999999999999",
    "1e15",
    "1e16",
    "1.7976931348623157e308",
    "2e-16",
    "0.5",
]

toml_scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([10**30, -(10**30), 1e308, 5e-324, 1e15, 1e16, 0, 1, 2, 3]),
    st.text(max_size=5),
    st.sampled_from(["１", "1", "newton", "martin", "float", "point", "ambient"]),
)
toml_values = st.recursive(
    toml_scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=5),
        st.dictionaries(st.sampled_from(["a", "eye", "scale", "kind", "x"]), inner, max_size=3),
    ),
    max_leaves=20,
)


def _nodes(value, path=()):
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in items:
        yield path + (key,)
        yield from _nodes(child, path + (key,))


@st.composite
def scene_documents(draw):
    """The quad scene with 1..4 nodes replaced by arbitrary TOML values, deleted or their lists grown."""
    doc = copy.deepcopy(QUAD)
    doc["surface"][0]["transform"] = {"scale": 1.0, "translate": [0.0, 0.0, 0.0], "rotate": [0.0, 0.0, 1.0, 0.0]}
    for _ in range(draw(st.integers(1, 4))):
        paths = list(_nodes(doc))
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "replace", "delete", "grow"]))
        if action == "delete":
            del parent[path[-1]]
        elif action == "grow" and isinstance(parent[path[-1]], list):
            parent[path[-1]].append(draw(toml_values))
        else:
            parent[path[-1]] = draw(toml_values)
    return doc


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scene_documents())
def test_scene_documents_are_valid_or_refused_naming_the_file(doc):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            scene = parse_scene(doc, "fuzz.toml")
        except InputError as exc:
            assert str(exc).startswith("fuzz.toml: ") and "\n" not in str(exc), str(exc)
            return
        for s in scene.surfaces:
            validate.surface(s.geometry)
        try:
            options = RenderOptions.resolve(scene)
        except InputError as exc:
            assert "\n" not in str(exc)
            return
        assert 1 <= options.spp <= validate.MAX_SPP and 1 <= options.width <= validate.MAX_FILM_SIDE


# ---------------------------------------------------------------------------
# Model readers: a small real file per format, tokens replaced, lines cut

MODEL_SEEDS = {
    ".bez": DATA / "models/bezier-teaset/qt3d/teapot-handle.bez",
    ".bpt": DATA / "patches.bpt",
    ".g2": DATA / "models/nurbs/splipy/sphere.g2",
    ".igs": DATA / "models/iges/pyIGES-benchmarks/128-000.igs",
    ".nurbs": DATA / "models/nurbs/glscene/duck2.nurbs",
    ".obj": DATA / "freeform.obj",
}
tokens = st.one_of(st.sampled_from(EXTREME_TOKENS), st.floats().map(repr), st.integers(-(10**30), 10**30).map(str))


@st.composite
def model_texts(draw, raw: str) -> str:
    spans = [m.span() for m in re.finditer(r"[^\s,;\[\]]+", raw)]
    edits = sorted(draw(st.lists(st.sampled_from(spans), min_size=1, max_size=4, unique=True)), reverse=True)
    for a, b in edits:
        raw = raw[:a] + draw(tokens) + raw[b:]
    lines = raw.split("\n")
    if draw(st.booleans()):
        i = draw(st.integers(0, len(lines) - 1))
        lines = lines[:i] + lines[i + draw(st.integers(1, 3)) :] if draw(st.booleans()) else lines[: i + 1] + lines[i:]
    return "\n".join(lines)


@pytest.mark.parametrize("suffix", sorted(MODEL_SEEDS))
def test_each_model_reader_gives_a_valid_model_or_an_input_error_naming_the_file(suffix, tmp_path_factory):
    raw = MODEL_SEEDS[suffix].read_text()
    path = tmp_path_factory.mktemp("fuzz") / f"fuzz{suffix}"

    @settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(model_texts(raw))
    def check(text):
        path.write_text(text, encoding="utf-8")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                model = load_model(path)
            except InputError as exc:
                assert str(exc).startswith(str(path)) and "\n" not in str(exc), str(exc)
                return
        assert len(model.surfaces) >= 1 and len(model.names) == len(model.surfaces)
        for s in model.surfaces:
            validate.surface(s)

    check()


# ---------------------------------------------------------------------------
# The command line, from the outside


def _fuzz_cli():
    import fuzz_cli  # tests/fuzz_cli.py: the mutations and the promises' checker

    return fuzz_cli


@pytest.mark.gl  # its cases render (a render failure, exit 1, would pass unmarked)
def test_short_cli_fuzz_pass_keeps_every_promise(tmp_path):
    """40 mutated scenes and model files through `bsrt render` at 64 x 64 (tests/fuzz_cli.py; the long
    run is `python tests/fuzz_cli.py --cases 2000 --seed 1`)."""
    fuzz = _fuzz_cli()
    result = fuzz.run(40, seed=16, jobs=1, timeout=120.0, memory_gb=8.0, keep=tmp_path / "broken", log=print)
    assert result["cases"] == 40 and sum(result["exits"].values()) == 40
    assert result["broken"] == [], result["broken"]


def test_the_fuzz_checks_catch_broken_promises(tmp_path):
    """The checker itself: each broken promise is named (a checker that passes everything proves nothing)."""
    fuzz = _fuzz_cli()
    out = tmp_path / "out"
    out.mkdir()
    case = fuzz.Case(
        0,
        "scenes/quad.toml",
        "test",
        code=1,
        stderr="Traceback (most recent call last):\nbsrt: internal error: KeyError\n",
    )
    (out / "image.png").write_bytes(b"not a png")
    assert fuzz.promises_broken(case, out, False, "quad.toml") == [
        "traceback",
        "internal error",
        "2 stderr lines",
        "files left: ['image.png']",
    ]
    case = fuzz.Case(0, "scenes/quad.toml", "test", code=0, stderr="x.py:1: RuntimeWarning: overflow\n")
    assert fuzz.promises_broken(case, out, False, "quad.toml") == [
        "Python warning on stderr",
        "exit 0 without a 64x64 PNG (found ['image.png'])",
        "exit 0 with a non-warning stderr line",
    ]
    case = fuzz.Case(0, "scenes/quad.toml", "test", code=2, stderr="bsrt: error: render.spp: too big\n")
    (out / "image.png").unlink()
    assert fuzz.promises_broken(case, out, False, "quad.toml") == ["message does not name the file"]
    case = fuzz.Case(0, "scenes/quad.toml", "test", code=-9, stderr="")
    assert fuzz.promises_broken(case, out, True, "quad.toml") == ["hang", "0 stderr lines"]
