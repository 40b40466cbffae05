"""Progress reporting for long steps (loading, preprocessing, Phong splats, sampling, hierarchy
builds, turntable and batch frames).

Long work is split into named stages (:func:`stage`). Progress is off unless enabled (the command
line enables it unless ``-q``; the API is quiet unless :func:`enable` is called). When enabled:

- every stage ends with one line on stderr: ``  NAME ... 1.23 s (45,678 points/s)``;
- when stderr is a terminal, a stage that runs longer than :data:`LIVE_DELAY` seconds also shows a
  live tqdm bar while it runs (cleared when it ends): with the rate and the time left when the
  stage reports its steps (``total`` and :meth:`Stage.update`), else the time elapsed;
- other lines (:func:`message`) and warnings raised inside a stage are printed above the bars
  (:func:`write`), never into them or into a half-written stage line.
"""

from __future__ import annotations

import sys
import threading
import time
import warnings
from contextlib import contextmanager
from typing import Any

from tqdm import tqdm

#: Seconds a stage runs before its live bar appears (shorter stages print their line only).
LIVE_DELAY = 2.0
#: Seconds between redraws of a live bar that reports no steps (its elapsed time).
TICK = 0.5

_enabled = False
_stages: list["Stage"] = []   # the running stages, outermost first
_open_line: "Stage | None" = None   # the stage whose "  NAME ..." line awaits its end (not a terminal)
_previous_showwarning: Any = None   # warnings.showwarning while a stage runs


def enable(on: bool = True) -> None:
    """Turn progress messages on stderr on or off."""
    global _enabled
    _enabled = on


def is_enabled() -> bool:
    """Whether progress messages are printed now."""
    return _enabled


@contextmanager
def enabled(on: bool | None):
    """Within the block, progress is on or off as ``on`` says (None: left as it is)."""
    global _enabled
    previous = _enabled
    if on is not None:
        _enabled = bool(on)
    try:
        yield
    finally:
        _enabled = previous


def is_terminal() -> bool:
    """Whether stderr is a terminal (live bars are drawn only there)."""
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):   # replaced or closed stderr
        return False


def _close_open_line() -> None:
    global _open_line
    if _open_line is not None:
        print(file=sys.stderr, flush=True)
        _open_line = None


def write(text: str) -> None:
    """Print one line on stderr (whether or not progress is enabled): above any live bars, after
    ending a stage line that awaits its time."""
    _close_open_line()
    if any(s.bar is not None for s in _stages):
        tqdm.write(text, file=sys.stderr)
    else:
        print(text, file=sys.stderr, flush=True)


def message(text: str) -> None:
    """Print one progress line on stderr if progress is enabled (see :func:`write`)."""
    if _enabled:
        write(text)


class _WarningLines:
    """A file for ``warnings.showwarning`` that sends each finished line through :func:`write`."""

    def __init__(self) -> None:
        self.pending = ""

    def write(self, text: str) -> None:
        self.pending += text
        *lines, self.pending = self.pending.split("\n")
        for line in lines:
            write(line)

    def flush(self) -> None:
        if self.pending:
            write(self.pending)
            self.pending = ""


#: Python's own warning display; recording (``catch_warnings(record=True)``, pytest) replaces the
#: implementation behind it, and then warnings are left to be recorded.
_DEFAULT_SHOWWARNING = warnings.showwarning
_DEFAULT_IMPL = getattr(warnings, "_showwarnmsg_impl", None)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    if _previous_showwarning is _DEFAULT_SHOWWARNING:
        if getattr(warnings, "_showwarnmsg_impl", None) is _DEFAULT_IMPL:   # printed, not recorded
            write(warnings.formatwarning(message, category, filename, lineno, line).rstrip("\n"))
        else:
            _previous_showwarning(message, category, filename, lineno, file, line)
        return
    lines = _WarningLines()   # a custom display (the command line's): its text goes through write()
    _previous_showwarning(message, category, filename, lineno, file=lines, line=line)
    lines.flush()


class Stage:
    """A running stage (yielded by :func:`stage`): :meth:`update` reports finished steps."""

    def __init__(self, name: str, count: int | None, unit: str, total: int | None, live: bool,
                 report: bool = True):
        self.name, self.count, self.unit, self.total = name, count, unit, total
        self.done, self.report = 0, report
        self.start = time.perf_counter()
        self.bar: tqdm | None = None
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None
        if live:
            steps = total is not None
            self.bar = tqdm(total=total, desc=f"  {name}", unit=unit, file=sys.stderr, leave=False,
                            delay=LIVE_DELAY, position=len(_stages), dynamic_ncols=True, mininterval=TICK,
                            bar_format=None if steps else "{desc} ... {elapsed}")
            if total is None:   # no steps to show: redraw the elapsed time until the stage ends
                self._ticker = threading.Thread(target=self._tick, daemon=True)
                self._ticker.start()

    def _tick(self) -> None:
        while not self._stop.wait(TICK):
            if self.bar is not None:
                self.bar.update(0)   # redraws (after LIVE_DELAY) and records the draw, so close() clears it

    def update(self, n: int = 1) -> None:
        """``n`` more steps of the stage's ``total`` are done: the live bar moves; without a terminal
        a line is printed every tenth of the total (steps done, time per step, time left)."""
        before, self.done = self.done, self.done + n
        if self.bar is not None:
            self.bar.update(n)
        elif self.report and self.total:
            tenth = max(1, self.total // 10)
            if self.done // tenth > before // tenth or self.done == self.total:
                each = (time.perf_counter() - self.start) / max(self.done, 1)
                write(f"  {self.name}: {self.done:,}/{self.total:,} {self.unit}, {each:.2f} s each, "
                      f"{each * max(self.total - self.done, 0):.0f} s to go")

    def close(self) -> float:
        """End the live bar (if any); returns the seconds the stage ran."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        if self.bar is not None:
            self.bar.close()
        return time.perf_counter() - self.start


@contextmanager
def stage(name: str, count: int | None = None, unit: str = "points", *, total: int | None = None,
          show: bool = True):
    """Report a named stage while the block runs; yields a :class:`Stage`.

    ``count``: the amount of work (``unit``), for the rate in the stage's closing line. ``total``:
    the number of steps the block reports through :meth:`Stage.update`, for a live bar with the rate
    and the time left (otherwise the bar shows the time elapsed). ``show=False``: a silent stage
    (for a loop of one step, say). See the module docstring.
    """
    global _open_line, _previous_showwarning
    if not (_enabled and show):
        yield Stage(name, count, unit, total, live=False, report=False)
        return
    live = is_terminal()
    _close_open_line()
    if not _stages:   # warnings raised inside stages go above the bars / after the open line
        _previous_showwarning, warnings.showwarning = warnings.showwarning, _show_warning
    current = Stage(name, count, unit, total, live)
    _stages.append(current)
    if not live:
        print(f"  {name} ...", end="", file=sys.stderr, flush=True)
        _open_line = current
    try:
        yield current
    except BaseException:
        current.close()
        _end(current)
        _close_open_line()   # the error is reported by the caller, on a line of its own
        raise
    elapsed = current.close()
    _end(current)
    amount = count if count is not None else total
    rate = f" ({_number(amount / elapsed)} {unit}/s)" if amount and elapsed > 0 else ""
    if _open_line is current:
        print(f" {elapsed:.2f} s{rate}", file=sys.stderr, flush=True)
        _open_line = None
    else:
        write(f"  {name} ... {elapsed:.2f} s{rate}")


def _number(value: float) -> str:
    """A rate as people read it: 45,678 or 2.35."""
    return f"{value:,.0f}" if value >= 100 else f"{value:.3g}"


def _end(current: Stage) -> None:
    _stages.remove(current)
    if not _stages:
        warnings.showwarning = _previous_showwarning
