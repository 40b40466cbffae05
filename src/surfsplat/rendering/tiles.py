"""Tiles and supersampling: images larger than the GL limits, and antialiased edges.

An image of W x H pixels supersampled K times is drawn as a (K W) x (K H) image of sub-pixels,
cut into tiles that fit the GL limits (a tile's side is a multiple of K, so every output pixel's
K x K sub-pixels lie in one tile). Each tile is drawn with the full image's camera and an offset
(``u_tile`` in ``camera.glsl``), so tiles meet without seams. The sub-pixels are then reduced
per output pixel with a box filter: the output pixel is the mean of its K x K sub-pixels, the
same reconstruction as the mesh ground truth's (``render_mesh``) and as an area-coverage alpha,
so coverage, color and alpha stay consistent; a wider filter (tent, Lanczos) would blur edges
and ring on silhouettes.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from ..defaults import MAX_SUPERSAMPLE
from ..errors import InputError

#: Largest tile side in sub-pixels: bounds GPU memory (64 bytes per sub-pixel of targets, 20 of read-back).
MAX_TILE = 2048


def check_supersample(supersample) -> int:
    """``supersample`` as an integer K in 1..:data:`~surfsplat.defaults.MAX_SUPERSAMPLE` (K x K
    sub-pixels a pixel); InputError otherwise. The one rule of splats and of the mesh ground truth."""
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) \
            or not 1 <= supersample <= MAX_SUPERSAMPLE:
        raise InputError(f"supersample must be an integer in 1..{MAX_SUPERSAMPLE}, got {supersample!r}")
    return int(supersample)


def tile_side(ctx: moderngl.Context, supersample: int, limit: int = MAX_TILE, margin: int = 0) -> int:
    """Largest tile side (sub-pixels) the context allows with ``margin`` pixels drawn on every side,
    at most ``limit``, a multiple of ``supersample``."""
    side = min(limit, int(ctx.info["GL_MAX_TEXTURE_SIZE"]) - 2 * margin,
               int(ctx.info["GL_MAX_RENDERBUFFER_SIZE"]) - 2 * margin,
               *(int(d) - 2 * margin for d in ctx.info["GL_MAX_VIEWPORT_DIMS"]))
    return max(supersample, side - side % supersample)


def tile_rects(width: int, height: int, side: int) -> list[tuple[int, int, int, int]]:
    """``(x0, y0, w, h)`` tiles of at most ``side`` covering a ``width`` x ``height`` image, window
    pixels (y up), row by row from the bottom."""
    return [(x0, y0, min(side, width - x0), min(side, height - y0))
            for y0 in range(0, height, side) for x0 in range(0, width, side)]


@dataclass
class SubPixels:
    """What the passes leave in a tile's targets, window orientation (row 0 at the bottom).

    Attributes:
        color: (h, w, 3) normalized color, the background where nothing was drawn.
        weight: (h, w) accumulated splat weight (0: empty).
        depth: (h, w) weighted camera-space depth, inf where empty.
        alpha: (h, w) the fraction of the sub-pixel the surface covers (0 where empty; on the rim
            of a silhouette the splats' analytic coverage, normalize.frag), None: weight > 0.
    """

    color: np.ndarray
    weight: np.ndarray
    depth: np.ndarray
    alpha: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.alpha is None:
            self.alpha = (self.weight > 0).astype("f4")

    def cropped(self, margin: int) -> "SubPixels":
        """The sub-pixels without ``margin`` pixels on every side."""
        if margin == 0:
            return self
        inner = np.s_[margin:-margin, margin:-margin]
        return SubPixels(self.color[inner], self.weight[inner], self.depth[inner], self.alpha[inner])


def box_reduce(sub: SubPixels, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per output pixel of K x K sub-pixels: (color: mean, over the background where uncovered;
    weight: mean sub-pixel weight; depth: the nearest sub-pixel's, inf where none is covered;
    alpha: the mean sub-pixel coverage). Window orientation kept."""
    if k == 1:   # views: the caller copies them into its image
        return sub.color, sub.weight, sub.depth, sub.alpha
    h, w = sub.weight.shape
    shape = (h // k, k, w // k, k)
    color = sub.color.reshape(*shape, 3).mean(axis=(1, 3), dtype=np.float64)
    weight = sub.weight.reshape(shape).mean(axis=(1, 3), dtype=np.float64)
    depth = sub.depth.reshape(shape).min(axis=(1, 3))
    alpha = sub.alpha.reshape(shape).mean(axis=(1, 3), dtype=np.float64)
    return color.astype("f4"), weight.astype("f4"), depth.astype("f4"), alpha.astype("f4")
