"""Progress: live tqdm bars with rate and time left on a terminal (a fake tty here), one line per
stage otherwise, nothing under -q; warnings and messages never inside a bar or a stage line."""

from __future__ import annotations

import io
import re
import sys
import time
import warnings
from contextlib import redirect_stderr

import pytest

from surfsplat import progress
from surfsplat.cli import main


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class FakeFile(io.StringIO):
    def isatty(self) -> bool:
        return False


@pytest.fixture(autouse=True)
def quick_bars(monkeypatch):
    monkeypatch.setattr(progress, "LIVE_DELAY", 0.0)
    monkeypatch.setattr(progress, "TICK", 0.01)


# sys.stderr is replaced inside each test: pytest puts its own capture back between setup and call


def visible_lines(text: str) -> list[str]:
    """What stays on screen: each line's text after its last carriage return, blanks dropped."""
    return [line.split("\r")[-1].rstrip() for line in text.split("\n") if line.split("\r")[-1].strip()]


def test_a_terminal_shows_a_bar_with_rate_and_time_left_then_one_line():
    with redirect_stderr(FakeTerminal()) as terminal, progress.enabled(True):
        with progress.stage("rendering 4 frames", unit="frames", total=4) as frames:
            for _ in range(4):
                time.sleep(0.02)
                frames.update()
    text = terminal.getvalue()
    bars = [part for part in text.split("\r") if "%|" in part]
    assert bars, text
    assert any(re.search(r"\d/4 \[\d\d:\d\d<\d\d:\d\d, +[\d.]+(frames/s|s/frames)\]", bar) for bar in bars), bars
    assert visible_lines(text) == [visible_lines(text)[-1]]   # the bar is cleared; its line stays
    assert re.fullmatch(r"  rendering 4 frames \.\.\. \d+\.\d\d s \([\d.,]+ frames/s\)", visible_lines(text)[-1])


def test_a_stage_without_steps_shows_its_elapsed_time():
    with redirect_stderr(FakeTerminal()) as terminal, progress.enabled(True):
        with progress.stage("octree", 1000):
            time.sleep(0.1)
    text = terminal.getvalue()
    assert "\r  octree ... 00:00" in text   # the live line, redrawn while the stage runs
    assert visible_lines(text) == [visible_lines(text)[-1]] and visible_lines(text)[-1].endswith("points/s)")


def show(message, category, filename, lineno, file=None, line=None):
    """A warning display as the warnings module calls it (pytest records warnings; this prints them)."""
    (file or sys.stderr).write(f"{category.__name__}: {message}\n")


def test_warnings_and_messages_print_above_the_bar():
    with redirect_stderr(FakeTerminal()) as terminal, progress.enabled(True), warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        with progress.stage("outer", total=3, unit="steps") as outer:
            outer.update()
            time.sleep(0.02)
            warnings.warn("careful now", stacklevel=1)
            progress.message("a note")
            with progress.stage("inner"):
                time.sleep(0.02)
            outer.update(2)
        assert warnings.showwarning is show   # restored after the stages
    text = terminal.getvalue()
    assert "%|" in text   # there were bars
    # each line is printed after the bars are cleared (a carriage return, blanks, a carriage return)
    for line in ("UserWarning: careful now", "a note", r"  inner \.\.\. \d\.\d\d s"):
        assert re.search(r"\r +\r" + line + "\n", text), (line, text)
    assert re.search(r"\r +\r  outer \.\.\. \d\.\d\d s \([\d.]+ steps/s\)\n$", text)


def test_without_a_terminal_one_line_a_stage_and_no_bar():
    with redirect_stderr(FakeFile()) as pipe, progress.enabled(True), warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        with progress.stage("loading", 10):
            pass
        with progress.stage("outer", 5):
            with progress.stage("inner", 5):
                warnings.warn("careful", stacklevel=1)
        with progress.stage("frames", unit="frames", total=20) as frames:
            frames.update(20)
        with pytest.raises(ValueError):
            with progress.stage("failing"):
                raise ValueError
        progress.message("after")
    text = pipe.getvalue()
    assert "\r" not in text and "%|" not in text
    lines = text.splitlines()
    assert re.fullmatch(r"  loading \.\.\. \d\.\d\d s \([\d.,]+ points/s\)", lines[0])
    assert lines[1] == "  outer ..." and lines[2] == "  inner ..."   # a nested stage starts a new line
    assert lines[3].endswith("UserWarning: careful") and lines[4].startswith("  inner ... ")
    assert lines[5].startswith("  outer ... ") and lines[6].startswith("  frames ...")
    assert lines[7].startswith("  frames: 20/20 frames,") and lines[8].startswith("  frames ... ")
    assert lines[9:] == ["  failing ...", "after"]   # a failed stage ends its line, with no time


def test_quiet_prints_nothing():
    for stream in (FakeTerminal(), FakeFile()):
        with redirect_stderr(stream):
            with progress.enabled(False):
                with progress.stage("x", total=2) as stage:
                    stage.update(2)
                progress.message("hidden")
            with progress.enabled(True):
                with progress.stage("silent", show=False) as stage:
                    stage.update()
        assert stream.getvalue() == ""


@pytest.mark.gl
def test_cli_quiet_and_batch_progress(tmp_path, capsys):
    outputs = str(tmp_path / "{stem}.png")
    assert main(["-q", "render", "demo:sphere", "demo:cube", "-o", outputs, "--width", "24", "--height", "24"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["render", "demo:sphere", "demo:cube", "-o", outputs, "--width", "24", "--height", "24",
                 "--force"]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err   # not a terminal: lines only
    assert re.search(r"^  rendering 2 inputs: 2/2 images, [\d.]+ s each, 0 s to go$", err, re.M)
    assert re.search(r"^  rendering 2 inputs \.\.\. [\d.]+ s \([\d.]+ images/s\)$", err, re.M)
