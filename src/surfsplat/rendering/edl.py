"""Eye-dome lighting (EDL): shading from the depth buffer alone (Boucheny 2009).

C. Boucheny, "Visualisation scientifique de grands volumes de donnees: pour une approche
perceptive", PhD thesis, Universite Joseph Fourier, 2009 (chapter 5, eye-dome lighting), as
Potree (Schuetz 2016, ``edl.fs``) and CloudCompare use it. For each covered pixel p with linear
(camera-space) depth z_p, over 8 neighbours n at ``radius_px`` pixels (angles k 45 degrees,
offsets rounded to whole pixels)::

    obscurance(p) = sum_n max(0, log2 z_p - log2 z_n)          shade(p) = exp(-strength * obscurance(p))

A pixel darkens where neighbours lie nearer than it: the far side of a depth step next to a near
edge; the near side and a plane facing the camera (equal depths) keep their color. Background
neighbours (and those beyond the image) count as infinitely far: they add nothing. Background
pixels stay background. Only the surface's share of a pixel is shaded (``color = bg (1 - alpha) +
(color - bg (1 - alpha)) shade``), so antialiased silhouettes keep their background part.

Where it runs: on the assembled full-resolution Frame (``Renderer.render``), in NumPy, after
tiling. Every pixel then sees its neighbours whichever tile drew them, so tiled and untiled
images are identical without drawing tiles with margins, and any technique gets it (it reads
only the Frame's depth). It is applied at the output resolution, not to the sub-pixels: the
radius is in output pixels whatever ``supersample`` is (the look does not change with K), the
depth of an output pixel is its nearest sub-pixel's, and the cost is K^2 smaller. A window
drawing with ``Renderer.draw`` does not get it.
"""

from __future__ import annotations

import numpy as np

from .options import EdlOptions

#: Neighbours sampled around each pixel (Potree and Boucheny use 8; 4 is the cheaper variant).
NEIGHBOURS = 8


def neighbour_offsets(radius_px: float) -> list[tuple[int, int]]:
    """Whole-pixel offsets ``(dx, dy)`` of the neighbours: ``radius_px`` (cos, sin) of k 45 degrees, rounded."""
    angles = np.arange(NEIGHBOURS) * (2.0 * np.pi / NEIGHBOURS)
    return [(int(np.rint(radius_px * np.cos(a))), int(np.rint(radius_px * np.sin(a)))) for a in angles]


def obscurance(depth: np.ndarray, radius_px: float) -> np.ndarray:
    """``sum_n max(0, log2 z_p - log2 z_n)`` per pixel of ``depth`` (H, W; inf where empty); 0 on empty pixels."""
    covered = np.isfinite(depth) & (depth > 0)
    logz = np.full(depth.shape, np.inf)
    logz[covered] = np.log2(depth[covered].astype(np.float64))
    pad = max(max(abs(dx), abs(dy)) for dx, dy in neighbour_offsets(radius_px))
    padded = np.pad(logz, pad, constant_values=np.inf)
    h, w = depth.shape
    total = np.zeros(depth.shape)
    for dx, dy in neighbour_offsets(radius_px):
        nb = padded[pad + dy:pad + dy + h, pad + dx:pad + dx + w]
        with np.errstate(invalid="ignore"):
            total += np.where(covered & np.isfinite(nb), np.maximum(0.0, logz - nb), 0.0)
    return total


def eye_dome_shade(depth: np.ndarray, options: EdlOptions) -> np.ndarray:
    """The EDL factor ``exp(-strength * obscurance)`` in (0, 1] per pixel; 1 on empty pixels."""
    return np.exp(-options.strength * obscurance(depth, options.radius_px))


def apply_edl(color: np.ndarray, depth: np.ndarray, alpha: np.ndarray, background, options: EdlOptions) -> np.ndarray:
    """``color`` (H, W, 3) with the surface's share of each pixel (``alpha``) shaded by EDL; float32."""
    shade = eye_dome_shade(depth, options)[..., None]
    behind = np.asarray(background, np.float64) * (1.0 - alpha.astype(np.float64))[..., None]
    return (behind + (color - behind) * shade).astype("f4")
