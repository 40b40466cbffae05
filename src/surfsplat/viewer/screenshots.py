"""Screenshots of the viewer: unique names (files never overwritten) for key S, a named file (replaced
atomically) for ``--screenshot``, checked paths."""

from __future__ import annotations

import itertools
import time
from pathlib import Path

import numpy as np
from PIL import Image

from ..errors import InputError
from ..io.atomic import atomic_path


def unique_screenshot_path(folder: Path | None = None, now: float | None = None) -> Path:
    """``surfsplat-YYYYmmdd-HHMMSS.png`` in ``folder`` (default: the current folder), with ``-1``,
    ``-2``, ... appended while that name exists. :func:`save_image` with ``exclusive``
    re-checks atomically."""
    folder = Path.cwd() if folder is None else Path(folder)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
    for i in itertools.count():
        path = folder / f"surfsplat-{stamp}{'' if i == 0 else f'-{i}'}.png"
        if not path.exists():
            return path
    raise AssertionError("unreachable")


def save_image(image: np.ndarray, path: Path, exclusive: bool = False) -> Path:
    """Write an (H, W, 3) uint8 image. ``exclusive``: never overwrite; the name gets ``-1``,
    ``-2``, ... until a new file can be created (opened with O_EXCL, so no race). Returns the path."""
    path = Path(path)
    picture = Image.fromarray(image)
    if not exclusive:   # replaced atomically: a failed write leaves the old file as it was
        kind = Image.registered_extensions().get(path.suffix.lower())
        if kind is None:
            raise InputError(f"{path}: unknown image type {path.suffix!r}; name it .png")
        with atomic_path(path) as temp:
            picture.save(temp, format=kind)
        return path
    stem, suffix = path.stem, path.suffix
    for i in itertools.count():
        candidate = path.with_name(f"{stem}{'' if i == 0 else f'-{i}'}{suffix}")
        try:
            with open(candidate, "xb") as handle:
                picture.save(handle, format="PNG")
            return candidate
        except FileExistsError:
            continue
    raise AssertionError("unreachable")
