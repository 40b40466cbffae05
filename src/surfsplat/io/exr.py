"""OpenEXR images of float maps (depth, normals), through the ``OpenEXR`` package: the optional ``exr``
extra (``pip install "surfsplat[exr]"``).

Depth EXR (``--depth OUT.exr``): one float32 channel ``Z``, row 0 at the top: camera-space depth, the
distance from the eye along the view axis in scene (model) units, exactly :attr:`Frame.depth
<surfsplat.rendering.frame.Frame.depth>`; **+inf where empty** (no surface). The header attribute
``surfsplat:depth`` states the convention. Normal EXR (``--normals OUT.exr``): three float32 channels
``R``, ``G``, ``B`` = the unit normal's x, y, z (see :mod:`.image_maps`), NaN where empty.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np

from ..errors import InputError, file_reader
from .atomic import atomic_path, check_readable

#: The header attribute stating what the depth channel holds.
DEPTH_KEY = "surfsplat:depth"
DEPTH_CONVENTION = "camera-space depth along the view axis, scene units; +inf = empty"
#: The channel of a depth EXR (the usual name of depth in EXR files).
DEPTH_CHANNEL = "Z"


@file_reader
def check_exr(path: str | os.PathLike) -> Path:
    """``path`` as a Path; InputError naming the ``exr`` extra when the OpenEXR package is missing
    (checked before any rendering)."""
    path = Path(path)
    if importlib.util.find_spec("OpenEXR") is None:   # the optional `exr` extra
        raise InputError(f"{path}: writing OpenEXR needs the OpenEXR package: pip install \"surfsplat[exr]\" "
                         f"(or write .npy)")
    return path


def save_exr(channels: dict[str, np.ndarray], path: str | os.PathLike, *, attributes: dict[str, str] | None = None,
             overwrite: bool = True) -> Path:
    """Write float32 ``channels`` (name -> (H, W) array, or (H, W, 3) split into R, G, B when named
    ``"RGB"``) as a ZIP-compressed scanline EXR, row 0 at the top, atomically; returns the path."""
    import OpenEXR   # optional: the `exr` extra (checked by check_exr)

    out = check_exr(path)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **(attributes or {})}
    pixels = {name: np.ascontiguousarray(values, dtype=np.float32) for name, values in channels.items()}
    with atomic_path(out, overwrite=overwrite) as temp:
        with OpenEXR.File(header, pixels) as image:
            image.write(str(temp))
    return out


@file_reader
def load_exr(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], dict]:
    """The channels (name -> array) and header of an EXR file (InputError naming the file when it is
    not one)."""
    path = check_exr(check_readable(path))
    import OpenEXR   # optional: the `exr` extra (checked by check_exr)

    if not OpenEXR.isOpenExrFile(str(path)):
        raise InputError(f"{path}: not an OpenEXR file")
    try:
        with OpenEXR.File(str(path)) as image:
            return {name: np.asarray(c.pixels) for name, c in image.channels().items()}, dict(image.header())
    except Exception as exc:   # the binding raises plain RuntimeError/ValueError for damaged files
        raise InputError(f"{path}: cannot read the OpenEXR file: {exc}") from None


def save_depth_exr(depth: np.ndarray, path: str | os.PathLike, *, overwrite: bool = True) -> Path:
    """Write (H, W) camera-space depth (+inf where empty) as a one-channel float32 depth EXR (see the
    module docstring); returns the path."""
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise InputError(f"{path}: a depth map is (H, W), got shape {depth.shape}")
    return save_exr({DEPTH_CHANNEL: depth}, path, attributes={DEPTH_KEY: DEPTH_CONVENTION}, overwrite=overwrite)


@file_reader
def load_depth_exr(path: str | os.PathLike) -> np.ndarray:
    """(H, W) float32 depth of a depth EXR (channel ``Z``; +inf where empty)."""
    channels, _ = load_exr(path)
    if DEPTH_CHANNEL not in channels:
        raise InputError(f"{path}: no {DEPTH_CHANNEL!r} (depth) channel; it has {', '.join(sorted(channels))}")
    return channels[DEPTH_CHANNEL].astype(np.float32)
