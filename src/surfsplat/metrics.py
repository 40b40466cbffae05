"""Image quality of a splat rendering against its ground truth (DESIGN.md, "How we know it works").

Pure NumPy/SciPy, for tests and benchmarks. Images are float arrays with
values in [0, 1] (``Frame.color``), (H, W) grayscale or (H, W, C) color;
masks are (H, W) bool arrays or anything ``numpy.asarray(..., bool)`` takes.
A *silhouette* is the set of pixels a rendering covers (``Frame.mask``:
weight > 0). Erosion and dilation count pixels of 4-connected steps (SciPy's
default cross structure, repeated ``px`` times); erosion treats the outside of
the image as covered, so a silhouette cut by the image border is not eroded
there.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .errors import InputError

#: Standard deviation in pixels of SSIM's Gaussian window (Wang et al. 2004).
SSIM_SIGMA = 1.5
#: SSIM's stabilizing constants, as fractions of the peak value.
SSIM_K1, SSIM_K2 = 0.01, 0.03


def _pair(image, reference) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(image, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"image shape {a.shape} differs from the reference's {b.shape}")
    if a.ndim not in (2, 3):
        raise InputError(f"images must be (H, W) or (H, W, C), got shape {a.shape}")
    return a, b


def _mask(mask, shape: tuple[int, ...], name: str = "mask") -> np.ndarray:
    """``mask`` as an (H, W) bool array for images of ``shape``; all True for None."""
    if mask is None:
        return np.ones(shape[:2], dtype=bool)
    m = np.asarray(mask, dtype=bool)
    if m.shape != tuple(shape[:2]):
        raise InputError(f"{name} shape {m.shape} differs from the image's {tuple(shape[:2])}")
    return m


def _coverage(frame_or_weight, name: str) -> np.ndarray:
    """(H, W) bool: covered pixels of a Frame (its mask) or of a weight/coverage array (> 0)."""
    weight = getattr(frame_or_weight, "weight", frame_or_weight)
    w = np.asarray(weight)
    if w.ndim != 2:
        raise InputError(f"{name} must be a Frame or an (H, W) weight array, got shape {w.shape}")
    return w > 0


def erode(mask, px: int) -> np.ndarray:
    """``mask`` shrunk by ``px`` pixels (4-connected steps; the image's outside counts as inside)."""
    m = np.asarray(mask, dtype=bool)
    if px <= 0:
        return m.copy()
    return ndimage.binary_erosion(m, iterations=int(px), border_value=1)


def dilate(mask, px: int) -> np.ndarray:
    """``mask`` grown by ``px`` pixels (4-connected steps)."""
    m = np.asarray(mask, dtype=bool)
    if px <= 0:
        return m.copy()
    return ndimage.binary_dilation(m, iterations=int(px))


def psnr(image, reference, mask=None, peak: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB: ``10 log10(peak^2 / MSE)``.

    The mean squared error runs over the pixels where ``mask`` is True (all
    pixels when None) and over all channels. Returns ``inf`` when the images
    are equal there.

    Raises:
        InputError: shapes differ, or the mask selects no pixel.
    """
    a, b = _pair(image, reference)
    m = _mask(mask, a.shape)
    if not m.any():
        raise InputError("psnr: the mask selects no pixel")
    mse = float(np.mean((a[m] - b[m]) ** 2))
    if mse == 0.0:
        return float("inf")
    return float(10.0 * np.log10(peak * peak / mse))


def ssim_map(image, reference, peak: float = 1.0, luma: bool = False) -> np.ndarray:
    """(H, W) local structural similarity (Wang et al. 2004), each in [-1, 1].

    Single scale, Gaussian window of standard deviation ``SSIM_SIGMA`` = 1.5 px
    (cut at 3.5 sigma: 11 x 11), ``C1 = (0.01 peak)^2``, ``C2 = (0.03 peak)^2``,
    borders reflected. Color images: the mean of the channels' maps, or with
    ``luma`` the map of the Rec. 601 luma ``0.299 R + 0.587 G + 0.114 B``.
    """
    a, b = _pair(image, reference)
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    elif luma:
        if a.shape[2] != 3:
            raise InputError(f"ssim: luma needs RGB images, got {a.shape[2]} channels")
        weights = np.array([0.299, 0.587, 0.114])
        a, b = (a @ weights)[..., None], (b @ weights)[..., None]
    c1, c2 = (SSIM_K1 * peak) ** 2, (SSIM_K2 * peak) ** 2

    def blur(x):
        return ndimage.gaussian_filter(x, sigma=(SSIM_SIGMA, SSIM_SIGMA, 0), truncate=3.5, mode="reflect")

    mu_a, mu_b = blur(a), blur(b)
    var_a = blur(a * a) - mu_a**2
    var_b = blur(b * b) - mu_b**2
    cov = blur(a * b) - mu_a * mu_b
    local = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2))
    return local.mean(axis=2)


def ssim(image, reference, mask=None, peak: float = 1.0, luma: bool = False) -> float:
    """Mean structural similarity (unitless, 1 for equal images) over ``mask`` (all pixels when None).

    The local map is :func:`ssim_map` of the whole images (windows reach
    across the mask's edge); only its average is restricted to the mask.

    Raises:
        InputError: shapes differ, or the mask selects no pixel.
    """
    local = ssim_map(image, reference, peak, luma)
    m = _mask(mask, local.shape)
    if not m.any():
        raise InputError("ssim: the mask selects no pixel")
    return float(local[m].mean())


def holes(frame_or_weight, reference_mask, erode_px: int = 2) -> int:
    """Number of pixels inside the reference silhouette, shrunk by ``erode_px``
    pixels, that the rendering does not cover (its weight is 0 there).

    Args:
        frame_or_weight: a Frame (its ``mask``) or an (H, W) weight array
            (covered where > 0).
        reference_mask: (H, W) bool silhouette of the ground truth, e.g.
            ``render_mesh(...).mask``.
        erode_px: pixels of the silhouette's rim left out (partly covered edge
            pixels and one-pixel silhouette jitter are not holes).
    """
    covered = _coverage(frame_or_weight, "holes: frame_or_weight")
    inner = erode(_mask(reference_mask, covered.shape, "reference_mask"), erode_px)
    return int(np.count_nonzero(inner & ~covered))


def leaks(weight, reference_mask, dilate_px: int = 2) -> int:
    """Number of pixels the rendering covers (weight > 0) outside the reference
    silhouette grown by ``dilate_px`` pixels: splats leaking past the surface's outline.

    Args:
        weight: a Frame or an (H, W) weight array.
        reference_mask: (H, W) bool silhouette of the ground truth.
        dilate_px: tolerance in pixels around the silhouette.
    """
    covered = _coverage(weight, "leaks: weight")
    outer = dilate(_mask(reference_mask, covered.shape, "reference_mask"), dilate_px)
    return int(np.count_nonzero(covered & ~outer))


def compare(frame, reference_frame, erode_px: int = 2) -> dict:
    """Quality of ``frame`` (a splat rendering) against ``reference_frame`` (e.g. :func:`render_mesh`).

    Masks: ``inner`` is the reference's silhouette (weight > 0) eroded by
    ``erode_px`` pixels; ``either`` is ``inner`` or the frame's own mask
    (pixels either rendering covers, so leaks and missing rims both count).

    Returns:
        dict with
        ``psnr``: dB of the colors over ``either``;
        ``psnr_inner``: dB over ``inner`` only;
        ``ssim``: mean SSIM over ``either``;
        ``holes``: :func:`holes` with ``erode_px``;
        ``leaks``: :func:`leaks` with ``dilate_px = erode_px``;
        ``pixels``: the size of ``either`` and ``inner`` as ``(either, inner)``.

    Raises:
        InputError: the frames differ in size, or the reference covers nothing.
    """
    if frame.color.shape != reference_frame.color.shape:
        raise InputError(f"compare: frame size {frame.color.shape[:2]} differs from the "
                         f"reference's {reference_frame.color.shape[:2]}")
    ref_mask = reference_frame.mask
    if not ref_mask.any():
        raise InputError("compare: the reference frame covers no pixel")
    inner = erode(ref_mask, erode_px)
    either = inner | frame.mask
    return {
        "psnr": psnr(frame.color, reference_frame.color, either),
        "psnr_inner": psnr(frame.color, reference_frame.color, inner) if inner.any() else float("nan"),
        "ssim": ssim(frame.color, reference_frame.color, either),
        "holes": holes(frame, ref_mask, erode_px),
        "leaks": leaks(frame, ref_mask, erode_px),
        "pixels": (int(either.sum()), int(inner.sum())),
    }
