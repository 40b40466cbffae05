"""Progress reporting for long steps (preprocessing, hierarchy builds, turntables).

Long work is split into named stages; each stage reports its start and its
duration on stderr when progress is enabled (the CLI enables it, the API is
quiet unless ``surfsplat.progress.enable()`` is called).
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

_enabled = False


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


def message(text: str) -> None:
    """Print one progress line on stderr if progress is enabled."""
    if _enabled:
        print(text, file=sys.stderr, flush=True)


@contextmanager
def stage(name: str, count: int | None = None, unit: str = "points"):
    """Report a named stage: its start, its duration and, with ``count``, its rate."""
    if not _enabled:
        yield
        return
    print(f"  {name} ...", end="", file=sys.stderr, flush=True)
    start = time.perf_counter()
    yield
    elapsed = time.perf_counter() - start
    rate = f" ({count / elapsed:,.0f} {unit}/s)" if count and elapsed > 0 else ""
    print(f" {elapsed:.2f} s{rate}", file=sys.stderr, flush=True)
