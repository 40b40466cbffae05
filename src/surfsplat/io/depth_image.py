"""Depth and normal maps as PNG images.

Depth PNG (``--depth OUT.png``): one 16-bit grey channel, row 0 at the top. 0 means empty (no
surface); 1..65535 map camera-space depth (model units along the view axis) linearly from the
camera's near to its far plane: ``depth = near + (value - 1) / 65534 * (far - near)``. near and far
are stored in the PNG text chunks ``surfsplat:near`` and ``surfsplat:far`` (decimal, model units),
so :func:`load_depth_png` recovers depth within half a step, under 1/65535 of the range.

Normal PNG (``--normals OUT.png``): 8-bit RGB of camera-space unit normals (OpenGL camera axes: x
right, y up, z toward the viewer), ``RGB = 0.5 + 0.5 n``; (0, 0, 0) where empty.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image
from PIL.PngImagePlugin import PngInfo

from ..errors import InputError, file_reader
from .atomic import atomic_path

DEPTH_STEPS = 65534
NEAR_KEY, FAR_KEY = "surfsplat:near", "surfsplat:far"


def depth_to_png_values(depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """(H, W) uint16 of camera-space ``depth`` (inf: empty -> 0), near..far -> 1..65535 (clamped)."""
    if not (0 < near < far and np.isfinite(far)):
        raise InputError(f"a depth PNG needs 0 < near < far, got near={near}, far={far}")
    depth = np.asarray(depth, dtype=np.float64)
    finite = np.isfinite(depth)
    scaled = np.clip((np.where(finite, depth, near) - near) / (far - near), 0.0, 1.0)
    return np.where(finite, 1 + np.round(scaled * DEPTH_STEPS), 0).astype(np.uint16)


def save_depth_png(depth: np.ndarray, near: float, far: float, path: str | os.PathLike, *,
                   overwrite: bool = True) -> Path:
    """Write ``depth`` as a 16-bit depth PNG (see the module docstring), atomically; returns the path."""
    path = Path(path)
    values = depth_to_png_values(depth, near, far)
    info = PngInfo()
    info.add_text(NEAR_KEY, repr(float(near)))
    info.add_text(FAR_KEY, repr(float(far)))
    with atomic_path(path, overwrite=overwrite) as temp:
        Image.fromarray(values).save(temp, format="PNG", pnginfo=info)
    return path


@file_reader
def load_depth_png(path: str | os.PathLike) -> np.ndarray:
    """(H, W) float64 camera-space depth of a depth PNG (inf where empty)."""
    path = Path(path)
    try:
        with Image.open(path) as image:
            near, far = float(image.text[NEAR_KEY]), float(image.text[FAR_KEY])
            values = np.asarray(image, dtype=np.float64)
    except KeyError as exc:
        raise InputError(f"{path}: not a surfsplat depth PNG (no {exc.args[0]} text chunk)") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read a depth PNG: {exc}") from None
    return np.where(values > 0, near + (values - 1) / DEPTH_STEPS * (far - near), np.inf)


def save_normal_png(normals: np.ndarray, path: str | os.PathLike, *, overwrite: bool = True) -> Path:
    """Write (H, W, 3) camera-space normals (NaN or zero where empty) as an RGB PNG; returns the path."""
    path = Path(path)
    n = np.asarray(normals, dtype=np.float64)
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    valid = np.isfinite(length) & (length > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        rgb = np.where(valid, 0.5 + 0.5 * n / length, 0.0)
    pixels = np.round(np.clip(rgb, 0.0, 1.0) * 255).astype(np.uint8)
    with atomic_path(path, overwrite=overwrite) as temp:
        Image.fromarray(pixels).save(temp, format="PNG")
    return path
