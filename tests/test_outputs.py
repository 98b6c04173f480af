"""Outputs all or nothing (bsrt/outputs.py) and the CLI's promises about them:
OS errors name the user's path, outputs never overwrite inputs, non-regular
input files are refused at once."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from bsrt.errors import OutputError
from bsrt.outputs import Outputs, write_file

ROOT = Path(__file__).resolve().parents[1]
QUAD = ROOT / "scenes" / "quad.toml"
CAMERA = "[camera]\neye = [0, -5, 2]\nlook_at = [0, 0, 0]\nup = [0, 0, 1]\nfov = 40\n"
TEACUP = ROOT / "tests" / "data" / "models" / "bezier-teaset" / "qt3d" / "teacup.bez"


def bsrt(*args, cwd, preexec_fn=None, timeout=300):
    return subprocess.run(
        [sys.executable, "-m", "bsrt", *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        preexec_fn=preexec_fn,
        timeout=timeout,
    )


def test_nothing_exists_before_commit_and_everything_after(tmp_path):
    with Outputs() as outputs:
        outputs.write(tmp_path / "a.bin", lambda f: f.write(b"alpha"))
        outputs.write(tmp_path / "b.bin", lambda f: f.write(b"beta"))
        assert sorted(os.listdir(tmp_path)) == []  # anonymous files: not even a temporary name
        outputs.commit()
    assert (tmp_path / "a.bin").read_bytes() == b"alpha"
    assert (tmp_path / "b.bin").read_bytes() == b"beta"
    assert sorted(os.listdir(tmp_path)) == ["a.bin", "b.bin"]


def test_a_failure_before_commit_leaves_nothing_and_keeps_the_old_file(tmp_path):
    (tmp_path / "a.bin").write_bytes(b"old")
    with pytest.raises(ZeroDivisionError):
        with Outputs() as outputs:
            outputs.write(tmp_path / "a.bin", lambda f: f.write(b"new"))
            outputs.write(tmp_path / "b.bin", lambda f: f.write(b"new"))
            1 / 0  # noqa: B018 (a failure inside the block)
    assert sorted(os.listdir(tmp_path)) == ["a.bin"]
    assert (tmp_path / "a.bin").read_bytes() == b"old"


SIGNAL_AT_COMMIT = """
import os, signal, sys
from bsrt import interrupts
from bsrt.outputs import outputs_at_safe_points
interrupts.install()
when = sys.argv[2]
try:
    with outputs_at_safe_points() as outputs:
        outputs.write(sys.argv[1], lambda f: f.write(b"whole"))
        if when == "before":
            os.kill(os.getpid(), signal.SIGTERM)  # waits for the commit's safe point
        outputs.commit()
        if when == "after":
            os.kill(os.getpid(), signal.SIGTERM)  # as if it came during the commit: taken as the block ends
    if when == "later":
        os.kill(os.getpid(), signal.SIGTERM)  # on the way out: the command's frames, arrays freed
    sum(range(1000))
    print("finished", flush=True)
except interrupts.Interrupted as exc:
    print("interrupted", exc.signum, flush=True)
"""


@pytest.mark.parametrize("when", ["before", "after", "later"])
def test_a_signal_during_the_commit_ends_the_command_as_finished_one_before_it_leaves_nothing(tmp_path, when):
    """outputs_at_safe_points (the render and map commands): a signal before the commit's safe
    point interrupts, leaving nothing; one that arrives after it (during the commit) is taken at
    the block's end, when the outputs are whole, and one after the block (the command returning)
    is too late as well: the command ends as finished, its file in place (CI once saw ``bsrt map``
    report SIGTERM and leave map.png; this project's README run saw it again after the block)."""
    out = tmp_path / "out.bin"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run(
        [sys.executable, "-c", SIGNAL_AT_COMMIT, str(out), when], capture_output=True, text=True, env=env, timeout=120
    )
    if when == "before":
        assert run.stdout.split() == ["interrupted", str(int(signal.SIGTERM))], run.stderr
        assert sorted(os.listdir(tmp_path)) == []
    else:
        assert run.stdout.split() == ["finished"], run.stderr
        assert out.read_bytes() == b"whole"


SIGNAL_DURING_AOVS = """
import os, signal, sys
from bsrt import interrupts
interrupts.install()
with interrupts.at_safe_points():  # as bsrt/__main__.py: numpy's threads start with the signals blocked
    import numpy as np
    from bsrt.outputs import outputs_at_safe_points
    from bsrt import npz
npz.PIECE = 1 << 12

class SignalOnSecond(dict):
    def items(self):
        for i, item in enumerate(super().items()):
            if i == 1:
                os.kill(os.getpid(), signal.SIGTERM)  # while the archive is being written
            if i == 2:
                print("went on", flush=True)  # only if the second array was written whole
            yield item

try:
    with outputs_at_safe_points() as outputs:
        arrays = SignalOnSecond(a=np.zeros(10), b=np.ones((64, 64, 3)), c=np.zeros(10))
        outputs.write(sys.argv[1], npz.writer(arrays))
        outputs.commit()
    print("finished", flush=True)
except interrupts.Interrupted as exc:
    print("interrupted", exc.signum, flush=True)
"""


def test_a_signal_while_the_aovs_are_written_is_taken_within_a_piece(tmp_path):
    """The AOV archive is written with safe points between pieces of each array: a signal that
    comes while the second array is written ends the command there (numpy.savez_compressed held
    it until the whole 1.5 GB of a 4096x4096 film's AOVs were compressed: 2.5 s at 2048x2048
    here), leaving nothing."""
    out = tmp_path / "out.npz"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run(
        [sys.executable, "-c", SIGNAL_DURING_AOVS, str(out)], capture_output=True, text=True, env=env, timeout=120
    )
    assert run.stdout.split() == ["interrupted", str(int(signal.SIGTERM))], run.stderr
    assert sorted(os.listdir(tmp_path)) == []


def test_a_file_is_created_with_the_usual_mode(tmp_path):
    old = os.umask(0o022)
    try:
        write_file(tmp_path / "a.bin", lambda f: f.write(b"x"))
    finally:
        os.umask(old)
    assert (tmp_path / "a.bin").stat().st_mode & 0o777 == 0o644


def test_an_os_error_names_the_users_path_not_a_temporary_one(tmp_path):
    with pytest.raises(OutputError) as caught:
        write_file(tmp_path / "missing" / "a.png", lambda f: f.write(b"x"))
    assert str(caught.value) == f"{tmp_path / 'missing' / 'a.png'}: No such file or directory"


def _file_size_limit(limit):
    def apply():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


@pytest.mark.gl
def test_a_full_disk_is_one_message_naming_the_output_and_leaves_nothing(tmp_path):
    run = bsrt(
        "render",
        QUAD,
        "-o",
        "out.png",
        "--width",
        64,
        "--height",
        64,
        "--aov",
        "out.npz",
        "--no-cache",  # the geometry cache would say it cannot write too, were the quad not cached yet
        cwd=tmp_path,
        preexec_fn=_file_size_limit(300),
    )
    assert run.returncode == 1
    assert run.stderr.splitlines() == ["bsrt: error: out.png: File too large"]
    assert os.listdir(tmp_path) == []


@pytest.mark.gl
def test_stats_on_a_failing_stdout_leaves_no_image(tmp_path):
    with open("/dev/full", "w") as full:
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "bsrt",
                "render",
                str(QUAD),
                "-o",
                "out.png",
                "--width",
                "16",
                "--height",
                "16",
                "--stats",
            ],
            cwd=tmp_path,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=300,
        )
    assert run.returncode == 1
    assert run.stderr.splitlines() == ["bsrt: error: <stdout>: No space left on device"]
    assert os.listdir(tmp_path) == []


@pytest.mark.gl
def test_render_png_aov_and_stats_together(tmp_path):
    run = bsrt(
        "render", QUAD, "-o", "out.png", "--width", 24, "--height", 16, "--aov", "out.npz", "--stats", cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr
    assert sorted(os.listdir(tmp_path)) == ["out.npz", "out.png"]
    assert Image.open(tmp_path / "out.png").size == (24, 16)
    assert np.load(tmp_path / "out.npz")["hit"].shape == (16, 24)
    assert '"seconds"' in run.stdout


@pytest.mark.gl
def test_a_legal_long_output_name_is_written(tmp_path):
    name = "x" * 251 + ".png"  # 255 bytes: the longest legal name; the temporary name must not grow from it
    run = bsrt("render", QUAD, "-o", name, "--width", 8, "--height", 8, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert os.listdir(tmp_path) == [name]


def test_the_output_may_not_be_the_model_it_renders(tmp_path):
    model = tmp_path / "m.png"
    model.write_bytes(TEACUP.read_bytes())
    run = bsrt("render", "m.png", "--format", "bez", "-o", "m.png", "--width", 8, "--height", 8, cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [
        "bsrt: error: m.png: is an input of this render (m.png); choose another output name"
    ]
    assert model.read_bytes() == TEACUP.read_bytes()


def test_the_output_may_not_be_a_file_the_scene_imports(tmp_path):
    (tmp_path / "cup.png").write_bytes(TEACUP.read_bytes())
    light = '[[light]]\nkind = "ambient"\ncolor = [1.0, 1.0, 1.0]\nintensity = 1.0\n'
    (tmp_path / "s.toml").write_text(CAMERA + light + '[[import]]\nfile = "cup.png"\nformat = "bez"\n')
    run = bsrt("render", "s.toml", "-o", "./cup.png", "--width", 8, "--height", 8, cwd=tmp_path)
    assert run.returncode == 2
    assert "cup.png: is an input of this render" in run.stderr and len(run.stderr.splitlines()) == 1
    assert (tmp_path / "cup.png").read_bytes() == TEACUP.read_bytes()


def test_the_image_and_the_aovs_may_not_be_one_file(tmp_path):
    run = bsrt("render", QUAD, "-o", "a.png", "--aov", "a.png", cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr.splitlines() == ["bsrt: error: a.png: the output file name must end in .npz"]
    os.symlink("a.npz", tmp_path / "b.png")
    run = bsrt("render", QUAD, "-o", "b.png", "--aov", "a.npz", cwd=tmp_path)
    assert run.stderr.splitlines() == ["bsrt: error: a.npz: given as two outputs (b.png)"]


@pytest.mark.parametrize(
    "make, kind",
    [
        (lambda p: os.mkfifo(p), "a named pipe (FIFO)"),
        (lambda p: os.symlink("/dev/zero", p), "a character device"),
        (lambda p: os.mkdir(p), "a folder"),
    ],
)
@pytest.mark.parametrize("name", ["in.toml", "in.bez"])
def test_non_regular_inputs_are_refused_at_once(tmp_path, make, kind, name):
    make(tmp_path / name)
    run = bsrt("render", name, "-o", "out.png", cwd=tmp_path, timeout=60)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [f"bsrt: error: {name}: is {kind}, not a scene or model file"]


def test_info_and_load_model_refuse_a_fifo_at_once(tmp_path):
    os.mkfifo(tmp_path / "cup.bez")
    run = bsrt("info", "cup.bez", cwd=tmp_path, timeout=60)
    assert run.returncode == 2
    assert run.stderr.splitlines() == ["bsrt: error: cup.bez: is a named pipe (FIFO), not a model file"]
    from bsrt.errors import InputError
    from bsrt.io import load_model

    with pytest.raises(InputError, match=r"cup.bez: is a named pipe \(FIFO\), not a model file$"):
        load_model(tmp_path / "cup.bez")


def test_an_import_that_is_a_fifo_is_refused(tmp_path):
    os.mkfifo(tmp_path / "cup.bez")
    (tmp_path / "s.toml").write_text(CAMERA + '[[import]]\nfile = "cup.bez"\n')
    run = bsrt("render", "s.toml", "-o", "out.png", cwd=tmp_path, timeout=60)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [
        "bsrt: error: s.toml: import[0].file: cup.bez: is a named pipe (FIFO), not a model file"
    ]


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["render", "q.toml", "-o", "q.png", "--width", "0"],
            "bsrt render: error: argument --width: expected a whole number >= 1, got 0",
        ),
        (["render"], "bsrt render: error: the following arguments are required: scene"),
        (
            ["render", "q.toml", "-o", "q.png", "--method", "euler"],
            "bsrt render: error: argument --method: invalid choice: 'euler' (choose from 'gradient', 'fast', 'newton', "
            "'martin')",
        ),
    ],
)
def test_a_usage_error_is_one_line(tmp_path, args, message):
    run = bsrt(*args, cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [message]
    assert os.listdir(tmp_path) == []
