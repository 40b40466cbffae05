"""``lod_tolerance="auto"``: the level of detail the output resolution asks for.

A hierarchy's cut at screen tolerance tau draws one splat for every node whose projected extent is at
most tau pixels (Pajarola, Sainz & Guidotti 2003, sec. 5.1): at tau = one pixel of the drawn grid
(1/K output pixels when supersampled K times), the points that fall within a pixel are merged into one
splat, which the pixel cannot tell apart anyway. A hierarchy is cut so. A point cloud gets no
hierarchy (building one costs 1-2 s per million points, more than the frame it would save): where the
view holds at least :data:`AUTO_MIN_DENSITY` points per pixel they cover, its points are merged per
half-pixel bin for this view (:func:`merge_in_pixels`); a sparser view draws every splat as it is. The
density is counted, not guessed: the points' centres are projected and the distinct pixels they land
in counted (a strided sample for large clouds).
"""
from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..frames import tangent_frame64

#: The value of ``lod_tolerance`` that selects the tolerance from the output resolution.
AUTO = "auto"
#: The tolerance "auto" cuts at, in pixels of the drawn grid (one sub-pixel when supersampled).
AUTO_LOD_PX = 1.0
#: Points per covered pixel from which a point cloud gets a hierarchy and is cut.
AUTO_MIN_DENSITY = 8.0
#: Most points projected to count the covered pixels (a strided sample beyond).
DENSITY_SAMPLE = 1 << 21


def _pixels(positions: np.ndarray, camera: Camera, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Which of ``positions`` ((N, 3), ``camera``'s frame) lie in front of the near plane and inside the
    image drawn ``scale`` times larger: their indices, row-major pixel numbers and view depths, and the
    drawn width."""
    width, height = int(round(camera.width * scale)), int(round(camera.height * scale))
    f = np.float32(camera.focal_px * scale)
    view = camera.view_matrix
    rows3, shift = view[:3, :3].astype(np.float32), view[:3, 3].astype(np.float32)
    # one matrix-vector product per axis: NumPy's (N, 3) @ (3, 3) in float32 is 100x slower
    px, py, pz = (positions @ rows3[i] + shift[i] for i in range(3))
    z = -pz
    near = max(float(camera.near or 0.0), 1e-30)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        x = np.floor(f * px / z + np.float32(0.5 * width))
        y = np.floor(f * py / z + np.float32(0.5 * height))
    inside = np.flatnonzero((z > near) & (x >= 0) & (x < width) & (y >= 0) & (y < height))
    pixel = y[inside].astype(np.int64) * width + x[inside].astype(np.int64)
    return inside, pixel, z[inside], width


def points_per_pixel(positions: np.ndarray, camera: Camera, supersample: int = 1) -> float:
    """Mean number of splat centres per covered pixel of ``camera``'s image drawn ``supersample``
    times larger: centres in front of the near plane and inside the image, over the distinct pixels
    they land in (``positions`` (N, 3) in the camera's frame; 0 when none is in view)."""
    positions = np.asarray(positions, dtype=np.float32)
    step = max(1, -(-len(positions) // DENSITY_SAMPLE))
    inside, pixel, _, width = _pixels(positions[::step], camera, int(supersample))
    if len(pixel) == 0:
        return 0.0
    pixels = width * camera.height * int(supersample)
    covered = (np.count_nonzero(np.bincount(pixel, minlength=pixels)) if pixels <= 1 << 24
               else len(np.unique(pixel)))
    return float(len(pixel) * step) / float(covered)


def auto_lod_tolerance(supersample: int = 1) -> float:
    """The LOD tolerance (output pixels) ``lod_tolerance="auto"`` cuts a hierarchy at:
    :data:`AUTO_LOD_PX` pixels of the drawn grid (``supersample`` sub-pixels per pixel)."""
    return AUTO_LOD_PX / int(supersample)


def auto_merged(cloud: SplatCloud, camera: Camera, supersample: int = 1) -> SplatCloud:
    """What ``lod_tolerance="auto"`` draws of a point cloud: :func:`merge_in_pixels` where the view
    holds at least :data:`AUTO_MIN_DENSITY` points per covered pixel of the drawn grid
    (:func:`points_per_pixel`), else ``cloud`` itself. ``camera`` is in the cloud's local frame."""
    if points_per_pixel(cloud.positions, camera, supersample) < AUTO_MIN_DENSITY:
        return cloud
    return merge_in_pixels(cloud, camera, supersample)


#: Points of one bin farther apart along its ray than this many pixel footprints (at their
#: depth) are not merged: they belong to different surfaces (the front and back of a thin part).
MERGE_DEPTH_PX = 4.0
#: Side of the bins points are merged in, drawn pixels, and the factor on the merged splats' radius.
#: Chosen on the bunny sampled to 1M points (ewa, against the mesh, benchmarks/bench_lod_auto.py):
#: 1 px bins merge 13x at 256x256 but cost 0.7 dB (blur); half-pixel bins with radius 1.2 cost at
#: most 0.15 dB and leave no hole (radius 1.0 left some) where back faces were culled. Drawn two-sided
#: (back faces are not culled by default), 1.2 left cracks between merged front disks through which
#: the far side won the visibility pass (a sphere of 30,000 points at 48x48: 5 pixels, 35.6 dB against
#: every splat); 1.3 closes them (49.3 dB) for 1.3 dB less at 96x96 (52.6 against 53.9).
MERGE_BIN_PX = 0.5
MERGE_RADIUS_SCALE = 1.3


def merge_in_pixels(cloud: SplatCloud, camera: Camera, supersample: int = 1, bin_px: float = MERGE_BIN_PX,
                    radius_scale: float = MERGE_RADIUS_SCALE) -> SplatCloud:
    """The splats ``cloud`` draws for ``camera`` with the points that fall into one bin of
    ``bin_px`` drawn pixels (``supersample`` sub-pixels per output pixel) merged into one splat.

    The one-level, per-view counterpart of a hierarchy's cut (Pajarola 2003, sec. 3.4): no
    hierarchy is built (a few tenths of a second per million points instead of 1-2 s), so a single
    frame of a dense cloud is cheaper with it. Points of a bin are merged when they lie within
    :data:`MERGE_DEPTH_PX` pixel footprints of each other along the ray (log-spaced depth layers)
    and face the same side of the eye. A merged splat is round, at the members' mean position,
    with their mean colour and normalized mean normal; its radius is ``radius_scale`` times the
    root mean square of the members' distance to it and own radius (the second moment of their
    disks, as a node's covariance sums its points', Pajarola 2003, eq. 2-4); it takes the first
    member's attributes. Points alone in their bin, outside the image or behind the eye are kept
    as they are. Splats with clip lines or normal fields (sharp edges, Phong splats) are never
    merged. ``camera`` is in the cloud's local frame."""
    if cloud.clip_lines is not None or cloud.normal_field is not None or cloud.normals is None or cloud.u is None:
        return cloud
    scale = int(supersample) / bin_px
    inside, pixel, z, width = _pixels(cloud.positions, camera, scale)
    if len(inside) < 2:
        return cloud
    height, focal = int(round(camera.height * scale)), camera.focal_px * scale
    layer = np.floor(np.log(z.astype(np.float64)) / np.log1p(MERGE_DEPTH_PX / focal)).astype(np.int64)
    layer -= layer.min()
    layers = int(layer.max()) + 1
    if layers >= (1 << 62) // (2 * width * height):
        return cloud
    view = camera.view_matrix
    eye = np.linalg.solve(view[:3, :3], -view[:3, 3]).astype(np.float32)
    facing = np.einsum("nd,nd->n", cloud.normals[inside], eye - cloud.positions[inside]) >= 0
    key = (pixel * layers + layer) * 2 + facing
    by_key = np.argsort(key)
    order, sorted_key = inside[by_key], key[by_key]
    starts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    counts = np.diff(np.r_[starts, len(order)])
    groups = counts > 1
    if not groups.any():
        return cloud
    member = np.repeat(groups, counts)              # rows of `order` in a merged group
    rows = order[member]
    g_starts = np.r_[0, np.cumsum(counts[groups])[:-1]]
    g_counts = counts[groups].astype(np.float64)
    pos = cloud.positions[rows].astype(np.float64)
    center = np.add.reduceat(pos, g_starts) / g_counts[:, None]
    normal = np.add.reduceat(cloud.normals[rows].astype(np.float64), g_starts)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    first_normal = cloud.normals[rows[g_starts]].astype(np.float64)
    normal = np.where(length > 1e-6, normal / np.maximum(length, 1e-300), first_normal)
    u, v = cloud.u[rows], cloud.v[rows]
    own = np.maximum(np.einsum("nd,nd->n", u, u), np.einsum("nd,nd->n", v, v)).astype(np.float64)
    offset = pos - np.repeat(center, counts[groups], axis=0)
    spread = np.einsum("nd,nd->n", offset, offset)
    # root mean square of the members' offsets from the centre and of their own radii: the spread a
    # node's covariance sums from its points and their disks (Pajarola 2003, eq. 2-4)
    radius = np.sqrt(np.add.reduceat(spread + own, g_starts) / g_counts) * radius_scale
    t1, t2 = tangent_frame64(normal)
    merged = {"positions": center.astype(np.float32), "normals": normal.astype(np.float32),
              "u": (t1 * radius[:, None]).astype(np.float32), "v": (t2 * radius[:, None]).astype(np.float32)}
    if cloud.colors is not None:
        merged["colors"] = (np.add.reduceat(cloud.colors[rows].astype(np.float64), g_starts)
                            / g_counts[:, None]).astype(np.float32)
    kept = np.ones(len(cloud.positions), dtype=bool)
    kept[rows] = False
    single = cloud.subset(np.flatnonzero(kept))
    firsts = rows[g_starts]
    fields = {name: np.concatenate([getattr(single, name), merged[name]])
              for name in ("positions", "normals", "colors", "u", "v") if getattr(single, name) is not None}
    attributes = None if cloud.attributes is None else {
        name: np.concatenate([values[kept], values[firsts]]) for name, values in cloud.attributes.items()}
    return cloud.with_arrays(**fields, attributes=attributes)
