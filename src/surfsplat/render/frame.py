"""Frame: a rendered image as NumPy arrays, with saving and notebook display."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from ..camera import Camera
from ..errors import InputError
from ..io.atomic import atomic_path


#: Image formats :meth:`Frame.save` (and the viewer's screenshots) write, by suffix.
IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"})


def check_image_path(path) -> Path:
    """``path`` as a Path; InputError for an image suffix :meth:`Frame.save` does not write or a
    missing folder."""
    path = Path(path)
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise InputError(f"{path}: unsupported image format {path.suffix!r}; use .png")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{path}: folder {folder} does not exist")
    return path


@dataclass
class Frame:
    """One rendered view. Row 0 of every array is the top of the image.

    Attributes:
        color: (H, W, 3) float32 in [0, 1], background included.
        depth: (H, W) float32 camera-space depth (model units along the view
            axis), weight-averaged over the blended splats; inf where empty.
        weight: (H, W) float32 accumulated splat weight; 0 where empty.
        camera: the camera it was rendered with.
    """

    color: np.ndarray
    depth: np.ndarray
    weight: np.ndarray
    camera: Camera

    @classmethod
    def empty(cls, camera: Camera, background=(1.0, 1.0, 1.0)) -> "Frame":
        """A frame with nothing drawn: the background color, depth inf, weight 0."""
        h, w = camera.height, camera.width
        color = np.empty((h, w, 3), dtype=np.float32)
        color[:] = np.asarray(background, dtype=np.float32)
        return cls(color, np.full((h, w), np.inf, dtype=np.float32), np.zeros((h, w), dtype=np.float32), camera)

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool: pixels covered by at least one splat."""
        return self.weight > 0

    def image(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB-agnostic 8-bit image (values clamped, rounded)."""
        return np.round(np.clip(self.color, 0.0, 1.0) * 255.0).astype(np.uint8)

    def save(self, path, *, overwrite: bool = True) -> Path:
        """Write the color image as PNG (or JPEG, BMP, TIFF, WebP by the suffix); returns the path.

        The image is written to a temporary file that then replaces ``path``, so a failed write
        never leaves a partial file or touches an existing one; ``overwrite=False`` refuses an
        existing file.
        """
        path = check_image_path(path)
        with atomic_path(path, overwrite=overwrite) as temp:
            Image.fromarray(self.image()).save(temp, format=Image.registered_extensions()[path.suffix.lower()])
        return path

    def _repr_png_(self) -> bytes:
        buffer = io.BytesIO()
        Image.fromarray(self.image()).save(buffer, format="PNG")
        return buffer.getvalue()
