"""Decoders that may crash, run in a child process.

Some decoders (the LAZ decompressor, libE57) abort the whole process on corrupt input. They run
as ``python -c SCRIPT PATH OUT [ARGS]`` in a child process that writes its arrays to ``OUT`` (an
``.npz``); a crash, an abort, a failure or a hang of the child becomes one InputError naming the
file, and the parent never unpickles anything.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import InputError


def _problem(done: subprocess.CompletedProcess) -> str:
    """What went wrong in a child that exited with ``done.returncode != 0``: its signal, or the last
    ``ERROR: `` line (else the last line) of its stderr."""
    if done.returncode < 0:
        try:
            name = signal.Signals(-done.returncode).name
        except ValueError:
            name = f"signal {-done.returncode}"
        return f"the decoder crashed ({name}); the file is corrupt"
    lines = done.stderr.decode("utf-8", "replace").strip().splitlines()
    errors = [line[len("ERROR: "):] for line in lines if line.startswith("ERROR: ")]
    if errors:
        return errors[-1]
    return lines[-1] if lines else f"the decoder failed (exit status {done.returncode})"


@contextmanager
def decoded_in_child(script: str, path: Path, source: str, what: str, args=(), hint=lambda problem: ""):
    """Run ``script`` on ``path`` in a child process and yield its output, an open ``np.load`` of the
    ``.npz`` it wrote (no pickles).

    Args:
        script: Python source run as ``python -c script PATH OUT *args``.
        path: the input file; the timeout is 60 s plus a second per megabyte of it.
        source: the file's name in messages.
        what: the kind of file in messages ("LAZ file").
        args: further command-line arguments (strings).
        hint: problem -> text appended to the message (e.g. the extra to install).

    Raises:
        InputError: ``"{source}: cannot read {what}: {problem}"`` when the child crashes, fails, hangs
            or cannot start, or its output cannot be read; errors raised by the caller's block
            while reading the output pass through, other OSError, ValueError and KeyError of the
            block become such InputErrors.
    """
    timeout = 60.0 + os.stat(path).st_size / 1e6   # generous: about a second per megabyte
    with tempfile.TemporaryDirectory(prefix="surfsplat-decode-") as folder:
        out = Path(folder) / "decoded.npz"
        try:
            done = subprocess.run([sys.executable, "-c", script, str(path), str(out), *map(str, args)],
                                  capture_output=True, timeout=timeout, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            raise InputError(f"{source}: cannot read {what}: decoding did not finish in {timeout:.0f} s") from None
        except OSError as exc:
            raise InputError(f"{source}: cannot read {what}: cannot start a decoder: {exc}") from exc
        if done.returncode != 0:
            problem = _problem(done)
            raise InputError(f"{source}: cannot read {what}: {problem}{hint(problem)}")
        try:
            with np.load(out, allow_pickle=False) as data:
                yield data
        except InputError:
            raise
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(f"{source}: cannot read {what}: {exc}") from exc
