"""``bsrt bench --devices``: each method timed on the CPU and on the GPU path side by side
(the GPU path on Mesa's llvmpipe here and in CI), the cores used, the JSON. Tiny renders of
the bundled plane; speed is never asserted here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bsrt.cli import main
from bsrt.errors import InputError
from bsrt.kernels.threads import workers
from bsrt.rendering import bench

QUAD = Path(__file__).resolve().parents[1] / "scenes" / "quad.toml"


@pytest.mark.gl
def test_both_devices_side_by_side_in_the_tables_and_the_json(tmp_path, capsys):
    out = tmp_path / "bench.json"
    argv = ["bench", "--scenes", str(QUAD), "--methods", "newton", "--devices", "cpu,gpu", "--size", "16"]
    argv += ["--repeat", "1", "--no-startup", "--no-memory", "--no-embree", "--json", str(out)]
    assert main(argv) == 0
    results = json.loads(out.read_text())
    assert results["devices"] == ["cpu", "gpu"] and results["cores"] == workers()
    rows = results["scenes"]["quad"]["methods"]
    assert list(rows) == ["newton", "newton@gpu"]
    assert rows["newton"]["device"] == "cpu"
    assert rows["newton"]["stages"]["solve"] == rows["newton"]["stages"]["shade"] == "cpu"
    assert rows["newton@gpu"]["device"] == "gpu"
    assert rows["newton@gpu"]["stages"]["solve"] == rows["newton@gpu"]["stages"]["shade"] == "gpu"
    assert rows["newton@gpu"]["disagree"] == {"hit": 0, "surface": 0, "t": 0}  # against newton on the CPU
    assert rows["newton@gpu"]["hits"] == rows["newton"]["hits"] > 0
    table = capsys.readouterr().out
    assert "newton@gpu" in table and f"{workers()} cores" in table


@pytest.mark.gl  # the default probes the context (gpu.choose_device)
def test_the_devices_option():
    assert bench.bench_devices("gpu, cpu,gpu") == ("gpu", "cpu")
    assert bench.bench_devices(None)[0] == "cpu"
    for bad, message in (("cpu,tpu", "unknown device 'tpu'"), (" , ", "names no device"), ("auto", "unknown")):
        with pytest.raises(InputError, match=message):
            bench.bench_devices(bad)


def test_an_unknown_device_is_one_line_and_exit_2(tmp_path, capsys):
    out = tmp_path / "bench.json"
    assert main(["bench", "--scenes", str(QUAD), "--devices", "tpu", "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--devices: unknown device 'tpu'" in err and err.count("\n") == 0
    assert not out.exists()
