"""Frame: a rendered image as NumPy arrays, with saving and notebook display."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import png
from PIL import Image

from ..camera import Camera
from ..errors import InputError
from ..io.atomic import atomic_path


#: Image formats :meth:`Frame.save` (and the viewer's screenshots) write, by suffix.
IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"})
#: Of those, the formats with an alpha channel (``transparent``).
ALPHA_SUFFIXES = frozenset({".png", ".tif", ".tiff", ".webp"})


def check_background(background) -> tuple[float, float, float]:
    """``background`` as 3 floats in [0, 1] (an RGB colour); InputError otherwise. The one rule of
    every renderer (splats and the mesh ground truth alike)."""
    try:
        values = tuple(float(x) for x in np.asarray(background, dtype=float).reshape(-1))
    except (TypeError, ValueError):
        values = ()
    if len(values) != 3 or not all(0.0 <= x <= 1.0 for x in values):
        raise InputError(f"background must be 3 numbers in [0, 1], got {background!r}")
    return values


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


#: Bit depths :meth:`Frame.save` writes PNG files in.
BIT_DEPTHS = (8, 16)


@dataclass
class Frame:
    """One rendered view. Row 0 of every array is the top of the image.

    Attributes:
        color: (H, W, 3) float32 in [0, 1], composited over the background.
        depth: (H, W) float32 camera-space depth (model units along the view
            axis), weight-averaged over the blended splats; supersampled, the
            nearest sub-pixel's; inf where empty.
        weight: (H, W) float32 accumulated splat weight (supersampled: the mean
            of the sub-pixels'); 0 where empty.
        camera: the camera it was rendered with.
        alpha: (H, W) float32 coverage in [0, 1]: the fraction of the pixel's
            area the surface covers: the mean over its sub-pixels (antialiased when
            supersampled) of 1 where covered, or with
            ``VisibilityOptions.edge_coverage`` of the area the splats' disks cover
            on a silhouette's rim (antialiased at one sample); None: 1 where
            ``weight > 0``, else 0.
        background: the RGB color composited where the surface does not cover.
    """

    color: np.ndarray
    depth: np.ndarray
    weight: np.ndarray
    camera: Camera
    alpha: np.ndarray = None  # type: ignore[assignment]  # None given: 1 where weight > 0 (__post_init__)
    background: tuple = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        if self.alpha is None:
            self.alpha = (self.weight > 0).astype(np.float32)

    @classmethod
    def empty(cls, camera: Camera, background=(1.0, 1.0, 1.0)) -> "Frame":
        """A frame with nothing drawn: the background color, depth inf, weight 0."""
        h, w = camera.height, camera.width
        color = np.empty((h, w, 3), dtype=np.float32)
        color[:] = np.asarray(background, dtype=np.float32)
        return cls(color, np.full((h, w), np.inf, dtype=np.float32), np.zeros((h, w), dtype=np.float32), camera,
                   background=tuple(map(float, background)))

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool: pixels covered by at least one splat (in any sub-pixel)."""
        return self.weight > 0

    def rgba(self) -> np.ndarray:
        """(H, W, 4) float32 straight (not premultiplied) color and alpha: the surface's own color
        where it covers, un-composited from the background; (0, 0, 0, 0) where it does not."""
        alpha = np.clip(self.alpha, 0.0, 1.0)[..., None]
        background = np.asarray(self.background, dtype=np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            straight = np.where(alpha > 0, (self.color - (1.0 - alpha) * background) / alpha, 0.0)
        return np.concatenate([np.clip(straight, 0.0, 1.0), alpha], axis=-1).astype(np.float32)

    def image(self, *, transparent: bool = False, bit_depth: int = 8) -> np.ndarray:
        """The picture as integers: (H, W, 3) color, or (H, W, 4) straight color and alpha with
        ``transparent``; uint8 (``bit_depth`` 8) or uint16 (16), values clamped and rounded."""
        if bit_depth not in BIT_DEPTHS:
            raise InputError(f"bit depth must be 8 or 16, got {bit_depth!r}")
        values = self.rgba() if transparent else np.clip(self.color, 0.0, 1.0)
        top = 255.0 if bit_depth == 8 else 65535.0
        return np.round(values * top).astype(np.uint8 if bit_depth == 8 else np.uint16)

    def save(self, path, *, overwrite: bool = True, transparent: bool = False, bit_depth: int = 8) -> Path:
        """Write the image as PNG (or JPEG, BMP, TIFF, WebP by the suffix); returns the path.

        ``transparent``: RGBA whose alpha is the surface's coverage (:meth:`rgba`), so the
        render composites over any background (PNG, TIFF, WebP). ``bit_depth`` 16: a 16-bit
        PNG. The image is written to a temporary file that then replaces ``path``, so a
        failed write never leaves a partial file or touches an existing one;
        ``overwrite=False`` refuses an existing file.
        """
        path = check_image_path(path)
        suffix = path.suffix.lower()
        if transparent and suffix not in ALPHA_SUFFIXES:
            raise InputError(f"{path}: {suffix} has no alpha channel; use .png for a transparent image")
        if bit_depth == 16 and suffix != ".png":
            raise InputError(f"{path}: 16-bit images are written as PNG; name the file .png")
        pixels = self.image(transparent=transparent, bit_depth=bit_depth)
        with atomic_path(path, overwrite=overwrite) as temp:
            if bit_depth == 16:
                h, w, c = pixels.shape
                writer = png.Writer(w, h, greyscale=False, alpha=c == 4, bitdepth=16)
                with open(temp, "wb") as handle:
                    writer.write(handle, pixels.reshape(h, w * c))
            else:
                Image.fromarray(pixels).save(temp, format=Image.registered_extensions()[suffix])
        return path

    def _repr_png_(self) -> bytes:
        buffer = io.BytesIO()
        Image.fromarray(self.image()).save(buffer, format="PNG")
        return buffer.getvalue()
