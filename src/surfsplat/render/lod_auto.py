"""``lod_tolerance="auto"``: the level of detail the output resolution asks for.

A hierarchy's cut at screen tolerance tau draws one splat for every node whose projected extent is at
most tau pixels (Pajarola, Sainz & Guidotti 2003, sec. 5.1): at tau = one pixel of the drawn grid
(1/K output pixels when supersampled K times), the points that fall within a pixel are merged into one
splat, which the pixel cannot tell apart anyway. A hierarchy is cut so. A point cloud is first given a
hierarchy (``api.as_hierarchy``: about a second per million points on 2 cores, once) only where the
view holds at least :data:`AUTO_MIN_DENSITY` points per pixel they cover: there the cut removes most
splats; a sparser view draws every splat as it is (the build would cost more than it saves, and the
picture would not change). The density is counted, not guessed: the points' centres are projected and
the distinct pixels they land in counted (a strided sample for large clouds).
"""

from __future__ import annotations

import numpy as np

from ..camera import Camera

#: The value of ``lod_tolerance`` that selects the tolerance from the output resolution.
AUTO = "auto"
#: The tolerance "auto" cuts at, in pixels of the drawn grid (one sub-pixel when supersampled).
AUTO_LOD_PX = 1.0
#: Points per covered pixel from which a point cloud gets a hierarchy and is cut.
AUTO_MIN_DENSITY = 8.0
#: Most points projected to count the covered pixels (a strided sample beyond).
DENSITY_SAMPLE = 1 << 21


def points_per_pixel(positions: np.ndarray, camera: Camera, supersample: int = 1) -> float:
    """Mean number of splat centres per covered pixel of ``camera``'s image drawn ``supersample``
    times larger: centres in front of the near plane and inside the image, over the distinct pixels
    they land in (``positions`` (N, 3) in the camera's frame; 0 when none is in view)."""
    positions = np.asarray(positions)
    n = len(positions)
    step = max(1, -(-n // DENSITY_SAMPLE))
    sample = positions[::step]
    view = camera.view_matrix
    p = sample @ view[:3, :3].T.astype(np.float32) + view[:3, 3].astype(np.float32)
    z = -p[:, 2]
    near = camera.near if camera.near is not None else 0.0
    front = z > max(near, 1e-30)
    k = int(supersample)
    width, height = camera.width * k, camera.height * k
    f = np.float32(camera.focal_px * k)
    x = np.floor(f * p[front, 0] / z[front] + np.float32(0.5 * width))
    y = np.floor(f * p[front, 1] / z[front] + np.float32(0.5 * height))
    inside = (x >= 0) & (x < width) & (y >= 0) & (y < height)
    keys = y[inside].astype(np.int64) * width + x[inside].astype(np.int64)
    if len(keys) == 0:
        return 0.0
    return float(len(keys) * step) / float(len(np.unique(keys)))


def auto_lod_tolerance(positions: np.ndarray | None, camera: Camera | None, supersample: int = 1, *,
                       hierarchy: bool = False) -> float | None:
    """The LOD tolerance (output pixels) ``lod_tolerance="auto"`` stands for: :data:`AUTO_LOD_PX`
    sub-pixels for a hierarchy, or for a point cloud whose view holds at least
    :data:`AUTO_MIN_DENSITY` points per covered pixel (:func:`points_per_pixel`); None (every splat
    drawn, no hierarchy) for a sparser cloud. ``positions`` are in ``camera``'s frame (unused for a
    hierarchy)."""
    tolerance = AUTO_LOD_PX / int(supersample)
    if hierarchy:
        return tolerance
    return tolerance if points_per_pixel(positions, camera, supersample) >= AUTO_MIN_DENSITY else None
