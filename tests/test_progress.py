"""Progress of `bsrt render` (bsrt/progress.py): a bar on a terminal, nothing on a
pipe unless asked, a summary line at the end, and a clean line for errors."""

from __future__ import annotations

import io
import os
import pty
import re
import resource
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bsrt import progress as progress_module
from bsrt.progress import Progress, clear_active, wanted

SCENES = Path(__file__).resolve().parents[1] / "scenes"
CLI = [sys.executable, "-c", "import sys; from bsrt.cli import main; sys.exit(main())"]
SUMMARY = re.compile(r"^bsrt: rendered (\S+) 40x30, 1 spp, newton, \d+\.\d s$")


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class Terminal(io.StringIO):
    encoding = "utf-8"

    def isatty(self):
        return True


def test_the_bar_shows_percentage_stage_and_time_left():
    clock, out = Clock(), Terminal()
    bar = Progress(out, clock=clock)
    bar("map", 0.0)
    assert out.getvalue() == "\rbsrt: [░░░░░░░░░░░░░░░░░░░░]   0% map, 0.0 s"
    clock.now += 2.0
    bar("shade", 0.25)  # time left = elapsed / fraction * (1 - fraction) = 2 / 0.25 * 0.75
    assert out.getvalue().split("\r")[-1] == "bsrt: [█████░░░░░░░░░░░░░░░]  25% shade, 2.0 s, about 6.0 s left"
    clock.now += 60.0
    bar("shade", 0.5)
    assert (
        out.getvalue().split("\r")[-1] == "bsrt: [██████████░░░░░░░░░░]  50% shade, 1 min 02 s, about 1 min 02 s left"
    )


def test_the_bar_redraws_at_most_ten_times_a_second():
    clock, out = Clock(), Terminal()
    bar = Progress(out, clock=clock)
    bar("map", 0.0)
    clock.now += 0.001
    bar("solve", 0.001)  # a new stage is shown at once
    assert out.getvalue().count("\r") == 2
    for i in range(2, 101):  # 99 reports within 0.099 s of that: no redraw
        clock.now += 0.001
        bar("solve", i / 1000)
    assert out.getvalue().count("\r") == 2
    clock.now += 0.002
    bar("solve", 0.1)
    assert out.getvalue().count("\r") == 3 and out.getvalue().endswith("10% solve, 0.1 s, about 0.9 s left")


def test_the_bar_never_goes_back_and_a_shorter_line_erases_the_longer():
    clock, out = Clock(), Terminal()
    bar = Progress(out, clock=clock)
    clock.now += 20.0
    bar("shade", 0.5)
    long = out.getvalue().split("\r")[-1]
    clock.now += 1.0
    bar("aov", 0.4)  # reports never move the bar backwards
    last = out.getvalue().split("\r")[-1]
    assert "50% aov, 21 s, about 21 s left" in last and len(last) == len(long)


def test_finish_replaces_the_bar_by_one_summary_line():
    clock, out = Clock(), Terminal()
    bar = Progress(out, clock=clock)
    bar("map", 0.0)
    drawn = len(out.getvalue()) - 1
    bar.finish("rendered out.png 64x64, 1 spp, newton, 0.0 s")
    summary = "bsrt: rendered out.png 64x64, 1 spp, newton, 0.0 s\n"
    assert out.getvalue()[drawn + 1 :] == "\r" + " " * drawn + "\r" + summary


def test_clear_erases_the_bar_and_only_once():
    out = Terminal()
    bar = Progress(out, clock=Clock())
    bar("map", 0.0)
    width = len(out.getvalue()) - 1
    clear_active()
    assert out.getvalue().endswith("\r" + " " * width + "\r")
    before = out.getvalue()
    bar.clear()
    clear_active()
    assert out.getvalue() == before and progress_module._active is None


def test_ascii_bar_where_the_terminal_is_not_utf8():
    out = Terminal()
    out.encoding = "ascii"
    Progress(out, clock=Clock())("shade", 0.5)
    assert out.getvalue() == "\rbsrt: [##########----------]  50% shade, 0.0 s, about 0.0 s left"


def test_lines_mode_writes_a_line_per_new_stage_and_at_most_one_a_second():
    clock, out = Clock(), io.StringIO()
    lines = Progress(out, lines=True, clock=clock)
    lines("map", 0.0)
    clock.now += 0.2
    lines("solve", 0.1)
    clock.now += 0.2
    lines("solve", 0.3)  # same stage, within a second: no line
    clock.now += 0.2
    lines("map", 0.4)  # a stage seen before, within a second: no line
    clock.now += 1.0
    lines("shade", 0.5)
    clock.now += 1.0
    lines("shade", 0.8)
    lines("done", 1.0)
    lines.finish("rendered x.png")
    assert out.getvalue() == (
        "bsrt:   0% map, 0.0 s\n"
        "bsrt:  10% solve, 0.2 s, about 1.8 s left\n"
        "bsrt:  50% shade, 1.6 s, about 1.6 s left\n"
        "bsrt:  80% shade, 2.6 s, about 0.7 s left\n"
        "bsrt: rendered x.png\n"
    )


def test_durations():
    d = progress_module._duration
    assert [d(0.04), d(9.94), d(10.4), d(59.4), d(61), d(3599), d(3600 * 2 + 61)] == [
        "0.0 s",
        "9.9 s",
        "10 s",
        "59 s",
        "1 min 01 s",
        "59 min 59 s",
        "2 h 01 min",
    ]


def test_wanted(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    assert wanted(io.StringIO(), None) is None
    assert wanted(io.StringIO(), False) is None
    assert wanted(Terminal(), False) is None
    assert wanted(io.StringIO(), True).lines is True
    assert wanted(Terminal(), None).lines is False
    monkeypatch.setenv("CI", "true")
    assert wanted(Terminal(), None) is None
    assert wanted(Terminal(), True).lines is False
    monkeypatch.setenv("CI", "false")
    assert wanted(Terminal(), None).lines is False


# ---------------------------------------------------------------------------
# the command line


def _env():
    env = dict(os.environ)
    env.pop("CI", None)
    return env


def run_on_a_terminal(args, timeout=300.0, preexec_fn=None):
    """Run `bsrt ARGS` with stderr on a pseudo-terminal; (exit code, what the terminal got)."""
    master, slave = pty.openpty()
    try:
        proc = subprocess.Popen(
            CLI + args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=slave,
            env=_env(),
            preexec_fn=preexec_fn,
        )
    finally:
        os.close(slave)
    received = b""
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.5)
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # EIO: the last writer closed the terminal
                    break
                if not chunk:
                    break
                received += chunk
            elif proc.poll() is not None:
                break
        proc.communicate(timeout=max(1.0, deadline - time.monotonic()))
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, received.decode("utf-8").replace("\r\n", "\n")


@pytest.mark.gl
def test_render_on_a_terminal_shows_the_bar_then_the_summary(tmp_path):
    out = tmp_path / "out.png"
    code, text = run_on_a_terminal(
        ["render", str(SCENES / "column.toml"), "-o", str(out), "--width", "40", "--height", "30"]
    )
    assert code == 0 and out.exists()
    assert re.search(r"\rbsrt: \[[█░]{20}\] +\d+% (setup|map|solve|shade)", text), text
    assert "% shade" in text
    assert text.endswith("\n") and text.count("\n") <= 2  # the compile notice, if any, and the summary
    summary = text.rstrip("\n").split("\n")[-1].split("\r")[-1]  # what stays on the terminal's last line
    match = SUMMARY.match(summary)
    assert match and match.group(1) == str(out), repr(text)
    bar = text.rstrip("\n").split("\n")[-1].split("\r")[-2]
    assert bar.strip() == ""  # the bar was erased before the summary


@pytest.mark.gl
def test_no_progress_on_a_terminal(tmp_path):
    code, text = run_on_a_terminal(
        ["render", str(SCENES / "quad.toml"), "-o", str(tmp_path / "q.png"), "--no-progress"]
    )
    assert code == 0 and "%" not in text and "rendered" not in text


@pytest.mark.gl
def test_a_failure_after_the_bar_started_gets_a_clean_line(tmp_path):
    out = tmp_path / "out.png"

    def full_disk():  # a file-size limit: the render succeeds, writing the PNG fails (EFBIG)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (100, 100))

    code, text = run_on_a_terminal(["render", str(SCENES / "quad.toml"), "-o", str(out)], preexec_fn=full_disk)
    assert code == 1 and "%" in text
    last = text.rstrip("\n").split("\n")[-1]
    before, error = last.rsplit("\r", 1)
    assert error == f"bsrt: error: {out}: File too large" and "rendered" not in text
    assert before.split("\r")[-1].strip() == ""  # the bar's line was blanked before the message


@pytest.mark.gl
def test_nothing_on_a_pipe(tmp_path):
    out = tmp_path / "q.png"
    done = subprocess.run(
        CLI + ["render", str(SCENES / "quad.toml"), "-o", str(out)], capture_output=True, text=True, env=_env()
    )
    assert done.returncode == 0 and out.exists()
    assert done.stderr == "" and done.stdout == ""


@pytest.mark.gl
def test_progress_on_a_pipe_writes_lines(tmp_path):
    out = tmp_path / "q.png"
    done = subprocess.run(
        CLI + ["render", str(SCENES / "column.toml"), "-o", str(out), "--width", "40", "--height", "30", "--progress"],
        capture_output=True,
        text=True,
        env=_env(),
    )
    assert done.returncode == 0 and done.stdout == ""
    lines = done.stderr.splitlines()
    assert "\r" not in done.stderr and done.stderr.endswith("\n")
    assert re.fullmatch(r"bsrt:   0% setup, \d\.\d s", lines[0])  # the clock runs from before the scene's load
    assert all(
        re.fullmatch(r"bsrt: +\d+% (setup|map|solve|shade|aov|write), \d+(\.\d)? s(, about .* left)?", line)
        for line in lines[:-1]
    ), lines
    assert {"map", "solve", "shade"} <= {line.split()[2].rstrip(",") for line in lines[:-1]}
    assert re.fullmatch(r"bsrt: 100% write, \d+\.\d s", lines[-2])  # the outputs, last
    assert SUMMARY.match(lines[-1]) and SUMMARY.match(lines[-1]).group(1) == str(out)


@pytest.mark.gl
def test_progress_with_aov_names_both_files(tmp_path):
    out, aov = tmp_path / "q.png", tmp_path / "q.npz"
    done = subprocess.run(
        CLI + ["render", str(SCENES / "quad.toml"), "-o", str(out), "--aov", str(aov), "--progress"],
        capture_output=True,
        text=True,
        env=_env(),
    )
    assert done.returncode == 0
    assert re.fullmatch(
        rf"bsrt: rendered {re.escape(str(out))} \(AOVs: {re.escape(str(aov))}\) 64x64, 1 spp, "
        rf"newton, \d+\.\d s",
        done.stderr.splitlines()[-1],
    )


@pytest.mark.parametrize("flag", ["--progress", "--no-progress"])
def test_progress_flags_in_help(flag, capsys):
    from bsrt.cli import main

    with pytest.raises(SystemExit):
        main(["render", "--help"])
    assert flag in capsys.readouterr().out
