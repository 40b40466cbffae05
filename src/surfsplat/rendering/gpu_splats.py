"""A SplatCloud's copy on the GPU: float32 attribute buffers ordered by radius class (renderer.py draws them).

The splats are uploaded ordered by radius class, largest first (:func:`radius_classes`), each class in
Morton order, so that a frame draws the large ones as quads and the small ones as GL_POINTS (or
computes their visibility) from contiguous ranges; positions relative to the cloud's float64 origin,
lengths scaled by a power of two (:func:`gpu_scale`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..geometry.neighbors import spatial_order


#: Radius classes per octave: the splats are uploaded ordered by class, largest first, so the quads
#: and the points of a frame are two contiguous ranges.
CLASSES_PER_OCTAVE = 4
#: Classes kept apart (32 octaves below the largest radius); smaller splats share the last one.
MAX_CLASSES = 128
#: Splats checked and converted per step of :meth:`Renderer.upload` (bounds its temporary memory).
UPLOAD_CHUNK = 1 << 20
#: Consecutive splats per block of :attr:`GpuSplats.blocks`: per frame, the blocks whose splats are all
#: small in the view go through the compute passes (:meth:`GpuSplats.small_blocks`).
BLOCK = 4096


@dataclass
class GpuSplats:
    """A SplatCloud uploaded to the GPU: one buffer per attribute, float32.

    The splats are stored ordered by radius class, largest first: ``class_radius[i]`` is the
    largest radius (GPU units) of the splats from ``class_start[i]`` on.

    The buffers hold the cloud's positions relative to its float64 ``origin``, times ``scale`` (a
    power of two, :func:`gpu_scale`: GPU units); ``bounds`` and ``max_radius`` are in world units.
    Cameras given to the renderer are world cameras; :meth:`gpu_camera` is the one the GPU draws with.
    """

    buffers: dict[str, moderngl.Buffer]
    count: int
    bounds: tuple[np.ndarray, np.ndarray]
    max_radius: float
    _vaos: dict = field(default_factory=dict)
    class_start: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    class_radius: np.ndarray = field(default_factory=lambda: np.full(1, np.inf))
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float = 1.0
    #: Attribute buffers read beyond the technique's (``in_<name>``; a sequential layout's ``lod``).
    extra_attributes: tuple[str, ...] = ()
    #: Shader defines of every program drawing these splats (a sequential layout's ``SEQUENTIAL_LOD``).
    defines: dict = field(default_factory=dict)
    #: Per block of :data:`BLOCK` consecutive splats (:func:`block_bounds`, GPU units): lower and upper
    #: corner of the centers, largest radius; None: no block is split off.
    blocks: np.ndarray | None = None
    #: Per block of :attr:`blocks`: the cone of its splats' normals (:func:`block_cones`); None: no
    #: block is culled as back-facing (:meth:`facing_blocks`).
    cones: np.ndarray | None = None

    def draw_ranges(self, camera: Camera, point_radius: float) -> tuple[list, list]:
        """``(quads, points)``: the ``(first, count)`` ranges of splats a frame draws as instanced quads
        and as GL_POINTS points (``camera``: the GPU frame's): all splats, the quads first
        (:meth:`quad_count`). A sequential layout draws a prefix of each radius class
        (``render/sequential.py``)."""
        quads = self.quad_count(point_radius)
        return ([(0, quads)] if quads else []), ([(quads, self.count - quads)] if quads < self.count else [])

    def extra_uniforms(self, camera: Camera) -> dict:
        """Uniforms these splats add to a frame's (``camera``: the GPU frame's): none here; a
        sequential layout's LOD scale."""
        return {}

    def gpu_camera(self, camera: Camera) -> Camera:
        """The world ``camera`` in the buffers' frame: eye and target moved by ``-origin`` in float64,
        then scaled by ``scale`` (exact: a power of two), so that the GPU composes its float32
        transform from numbers of the size of the model wherever it sits."""
        return camera.translated(-self.origin).scaled(self.scale)

    @property
    def gpu_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The bounds in GPU units (relative to ``origin``, times ``scale``)."""
        return tuple((np.asarray(b, dtype=np.float64) - self.origin) * self.scale for b in self.bounds)

    def quad_count(self, point_radius: float) -> int:
        """Number of leading splats drawn as quads when splats of radius <= ``point_radius`` (model
        units) may be points: those of every class whose largest radius exceeds it."""
        if not point_radius > 0:   # no points (0: none allowed; degenerate radii draw as quads too)
            return self.count
        big = int(np.count_nonzero(self.class_radius > point_radius))   # a prefix: radii descend
        return self.count if big == len(self.class_radius) else int(self.class_start[big])

    def block_depths(self, camera: Camera) -> np.ndarray | None:
        """(B,) the nearest depth (GPU units, at least the near plane's) any splat of each block of
        :attr:`blocks` can reach in this view (``camera``: the GPU frame's): that of its centers'
        bounding box less its largest radius; None without blocks."""
        if self.blocks is None:
            return None
        depth = -_block_corners(self.blocks[:, :3], self.blocks[:, 3:6], camera.view_matrix)[..., 2].max(axis=1)
        return np.maximum(depth - self.blocks[:, 6], float(camera.near))

    def small_blocks(self, camera: Camera, box_px: float) -> np.ndarray | None:
        """(B,) bool per block of :attr:`blocks`: every splat of it has a window box at most ``box_px``
        pixels wide in this view (``camera``: the GPU frame's); None without blocks.

        A splat of radius r whose center is at depth z covers a box at most ``2 sqrt(2) r f / (z cos
        phi)`` wide (its parallelogram's corners; phi the largest angle off the axis in the image), plus
        a pixel of rounding; a block's nearest depth is :meth:`block_depths`. Splats in the buffers'
        order (radius classes, each in Morton order) make compact blocks: the estimate is a close
        bound, per block, not per model.
        """
        if self.blocks is None:
            return None
        f = float(camera.focal_px)
        stretch = float(np.hypot(1.0, np.hypot(camera.width, camera.height) / (2.0 * f)))   # 1 / cos(phi)
        return 2.0 * np.sqrt(2.0) * self.blocks[:, 6] * f * stretch / self.block_depths(camera) + 1.0 <= box_px

    def visible_blocks(self, camera: Camera, margin_px: float,
                       tile: tuple[float, float, float, float] | None = None) -> np.ndarray | None:
        """(B,) bool per block of :attr:`blocks`: some splat of it may reach the view (``camera``: the
        GPU frame's; ``tile`` ``(x0, y0, w, h)``: the part of its image drawn, window pixels, y up;
        None: all of it) grown by ``margin_px`` pixels on each side (a filter's footprint beyond the disk);
        None without blocks. Conservative: a block is dropped only when its centers' box grown by its
        largest radius lies wholly before the near plane or beyond the far one (where the vertex
        shaders cull each of its splats), or beyond a side of the grown frustum while its splats are
        small for their depth: EWA draws a splat's footprint through the affine approximation at its
        center (Guennebaud 2003, eq. 8), which can reach pixels its disk does not, by about
        ``f (r / z)^2`` pixels; a block is tested against the sides only where that stays within
        the margin."""
        if not margin_px > 0:
            raise InputError(f"the view's margin must be a positive number of pixels, got {margin_px!r}")
        if self.blocks is None:
            return None
        radius = self.blocks[:, 6:7]
        corners = _block_corners(self.blocks[:, :3] - radius, self.blocks[:, 3:6] + radius, camera.view_matrix)
        x, y, depth = corners[..., 0], corners[..., 1], -corners[..., 2]
        f = float(camera.focal_px)
        x0, y0, w, h = tile if tile is not None else (0.0, 0.0, camera.width, camera.height)
        # the sides through the eye: window pixel px = c + f x / depth (c the image's center)
        cx, cy = 0.5 * camera.width, 0.5 * camera.height
        left, right = x0 - margin_px - cx, x0 + w + margin_px - cx
        bottom, top = y0 - margin_px - cy, y0 + h + margin_px - cy
        beyond_side = ((f * x > right * depth).all(axis=1) | (f * x < left * depth).all(axis=1)
                       | (f * y > top * depth).all(axis=1) | (f * y < bottom * depth).all(axis=1))
        affine = radius[:, 0] * np.sqrt(f / margin_px) <= self.block_depths(camera)
        outside = ((depth < float(camera.near)).all(axis=1) | (depth > float(camera.far)).all(axis=1)
                   | (beyond_side & affine))
        return ~outside

    def split_blocks(self, ranges: list, flagged: np.ndarray | None) -> tuple[list, list]:
        """``(others, flagged)``: the ``(first, count)`` ranges cut into the parts in blocks of
        :attr:`blocks` not flagged and those in flagged ones (``flagged``: (B,) bool, e.g.
        :meth:`small_blocks` or :meth:`visible_blocks`; None: nothing is flagged)."""
        if flagged is None or not ranges:
            return ranges, []
        others, picked = [], []
        for first, count in ranges:
            blocks = np.arange(first // BLOCK, (first + count - 1) // BLOCK + 1)
            flags = flagged[blocks]
            cuts = np.flatnonzero(np.diff(flags)) + 1   # runs of blocks of one kind
            bounds = np.concatenate([[first], blocks[cuts] * BLOCK, [first + count]])
            kinds = np.concatenate([flags[:1], flags[cuts]])
            for start, end, kind in zip(bounds[:-1].tolist(), bounds[1:].tolist(), kinds.tolist()):
                (picked if kind else others).append((start, end - start))
        return others, picked

    def facing_blocks(self, camera: Camera) -> np.ndarray | None:
        """(B,) bool per block of :attr:`blocks`: some splat of it may face the eye (``camera``: the
        GPU frame's); None without :attr:`cones`. Where back faces are culled, the shaders drop a
        splat whose plane and shading normal both face away from the eye (``splat_vertex.glsl``); a
        block is dropped here only when that holds for every splat: for centers in its box (center
        ``c``, half-diagonal ``R``) and normals in its cone (axis ``a``, half-angle ``alpha``),
        ``n . (e - p) <= |d| cos(max(theta - alpha, 0)) + R`` with ``d = e - c`` and ``theta`` the
        angle between ``a`` and ``d`` (the back-face test of a normal cone, Pajarola et al. 2003,
        sec. 5.1). Blocks in Morton order are compact: the CAD part featuretype.ply sampled
        for 1024 x 1024 (2 M splats) drops 56 of its 489 blocks, a fifth of its back-facing splats."""
        if self.blocks is None or self.cones is None:
            return None
        lo, hi = self.blocks[:, :3], self.blocks[:, 3:6]
        d = np.asarray(camera.eye, dtype=np.float64) - 0.5 * (lo + hi)
        length = np.linalg.norm(d, axis=1)
        half = 0.5 * np.linalg.norm(hi - lo, axis=1)
        axis, cos_a, sin_a = self.cones[:, :3], self.cones[:, 3], self.cones[:, 4]
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_t = np.clip(np.einsum("ij,ij->i", axis, d) / length, -1.0, 1.0)
        sin_t = np.sqrt(1.0 - cos_t * cos_t)
        reach = np.where(cos_t < cos_a, length * (cos_t * cos_a + sin_t * sin_a), length) + half + self.cones[:, 5]
        return ~(reach < -1e-4 * length)   # NaN (the eye at a block's center): kept

    def release(self) -> None:
        """Free the GPU buffers."""
        for vao in self._vaos.values():
            vao.release()
        for buffer in self.buffers.values():
            buffer.release()
        self._vaos.clear()
        self.buffers.clear()


#: Largest magnitude of a splat's coordinates and axes: their squares stay finite in float32.
MAX_COORDINATE = 1e18

#: Local extents (model units) the renderer draws as they are; a model outside this range is drawn
#: scaled by a power of two to about unit size (:func:`gpu_scale`): the shaders' products of axes
#: (a splat's normal is ``u x v``, its squared length a 4th power) leave float32's range for
#: splat radii below ~1e-9 or above ~1e9; within 1e-6..1e6 the picture is drawn bit for bit as given.
GPU_EXTENT_RANGE = (2.0 ** -20, 2.0 ** 20)


def gpu_scale(cloud: SplatCloud, radii: np.ndarray | None = None) -> float:
    """The power of two the renderer scales a cloud's local coordinates (and the camera) by: 1 when
    their extent (and largest splat radius) is within :data:`GPU_EXTENT_RANGE`, else the one
    bringing it to about 1 (exact in float32)."""
    if len(cloud) == 0:
        return 1.0
    lo, hi = cloud.positions.min(axis=0), cloud.positions.max(axis=0)
    extent = float(np.max(hi.astype(np.float64) - lo))
    if cloud.u is not None:
        extent = max(extent, float((cloud.radii if radii is None else radii).max()))
    if not np.isfinite(extent) or extent <= 0 or GPU_EXTENT_RANGE[0] <= extent <= GPU_EXTENT_RANGE[1]:
        return 1.0
    return float(2.0 ** -np.round(np.log2(extent)))


def _check_gpu_values(arrays: dict[str, np.ndarray]) -> None:
    """InputError for splats the GPU cannot draw: non-finite values, zero normals, coordinates or axes
    beyond :data:`MAX_COORDINATE` (``SplatCloud.validated`` drops the first two kinds)."""
    for name, values in arrays.items():
        values = np.asarray(values)
        bad = 0
        for start in range(0, len(values), UPLOAD_CHUNK):   # temporaries of one chunk at a time
            chunk = values[start:start + UPLOAD_CHUNK]
            with np.errstate(invalid="ignore", over="ignore"):
                finite = np.isfinite(chunk)
                # the usual case first, in whole-array reductions (rows of 3 reduce ~10x slower)
                if finite.all() and (name not in ("position", "u", "v") or not np.abs(chunk).max() > MAX_COORDINATE) \
                        and (name != "normal" or (np.einsum("ij,ij->i", chunk, chunk) > 0).all()):
                    continue
                wrong = ~finite.all(axis=-1)
                if name in ("position", "u", "v"):
                    wrong |= (np.abs(chunk) > MAX_COORDINATE).any(axis=-1)
                if name == "normal":
                    wrong |= ~(np.einsum("ij,ij->i", chunk, chunk) > 0)
            bad += int(np.count_nonzero(wrong))
        if bad:
            limit = f" or beyond +-{MAX_COORDINATE:g}" if name in ("position", "u", "v") else ""
            raise InputError(f"{bad:,} splats have non-finite{limit} {name} values"
                             f"{' (or zero normals)' if name == 'normal' else ''}; SplatCloud.validated() drops "
                             f"invalid splats")


def splat_arrays(cloud: SplatCloud, radii: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], float]:
    """The per-splat vertex attributes of a preprocessed cloud as the GPU gets them (float32, lengths
    multiplied by the power-of-two :func:`gpu_scale`, checked by :func:`_check_gpu_values`), and that
    scale (``radii``: ``cloud.radii`` where computed already)."""
    arrays = {"position": cloud.positions, "normal": cloud.normals, "color": cloud.albedo,
              "u": cloud.u, "v": cloud.v}
    if cloud.clip_lines is not None:
        arrays["clip0"], arrays["clip1"] = cloud.clip_lines[:, 0], cloud.clip_lines[:, 1]
    if cloud.normal_field is not None:
        arrays["normal_field"] = cloud.normal_field
    _check_gpu_values(arrays)
    scale = gpu_scale(cloud, radii)
    if scale != 1.0:   # a power of two: exact
        for name in ("position", "u", "v"):
            arrays[name] = arrays[name] * np.float32(scale)
    return arrays, scale


def radius_classes(radii: np.ndarray, positions: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Splats ordered by radius class, largest first: (order, first index of each non-empty class,
    the largest radius a splat of that class may have). Class ``c`` holds the radii in
    ``(top 2^-(c+1)/k, top 2^-c/k]`` (k = :data:`CLASSES_PER_OCTAVE`); a stable counting sort.

    With ``positions`` ((N, 3)), each class in Morton order (:func:`~surfsplat.geometry.neighbors.spatial_order`),
    else in the given order. Neighbouring splats then run together: llvmpipe shades a point's pixels
    in 4x4 blocks and bins the primitives per tile, the compute visibility pass runs 8 splats per SIMD
    loop, and neighbours share a facing (culled together) and a size. Measured on the peers' bunny
    (1M splats sampled in random order, 1024x1024, ewa): 20-25% less CPU time per frame."""
    if positions is not None:
        spatial = spatial_order(positions)
        order, starts, radius = radius_classes(np.asarray(radii)[spatial])
        return spatial[order], starts, radius
    radii = np.asarray(radii, dtype=np.float32)
    top = float(radii.max())
    with np.errstate(divide="ignore", invalid="ignore"):
        octaves = np.log2(np.float32(top) / radii) if top > 0 else np.zeros_like(radii)
    key = np.nan_to_num(np.floor(octaves * CLASSES_PER_OCTAVE), nan=0.0, posinf=MAX_CLASSES - 1)
    key = np.clip(key, 0, MAX_CLASSES - 1).astype(np.uint8)
    del octaves
    order = np.argsort(key, kind="stable")
    counts = np.bincount(key, minlength=MAX_CLASSES)
    present = np.flatnonzero(counts)
    starts = (np.cumsum(counts) - counts)[present]
    return order, starts, top * 2.0 ** (-present / CLASSES_PER_OCTAVE)


def merge_ranges(ranges: list) -> list:
    """The ``(first, count)`` ranges sorted, those that touch joined into one."""
    merged: list = []
    for first, count in sorted(ranges):
        if merged and merged[-1][0] + merged[-1][1] == first:
            merged[-1] = (merged[-1][0], merged[-1][1] + count)
        else:
            merged.append((first, count))
    return merged


def _block_corners(lo: np.ndarray, hi: np.ndarray, view: np.ndarray) -> np.ndarray:
    """(B, 8, 3) the 8 corners of each box ``[lo, hi]`` ((B, 3) each) in camera space (``view``: the
    4x4 world-to-camera matrix)."""
    corners = np.stack([np.where(np.array(c, bool), hi, lo) for c in np.ndindex(2, 2, 2)], axis=1)
    return corners @ view[:3, :3].T + view[:3, 3]


def ordered_buffers(ctx: moderngl.Context, arrays: dict[str, np.ndarray], order: np.ndarray,
                    radii: np.ndarray) -> tuple[dict[str, moderngl.Buffer], np.ndarray, np.ndarray | None]:
    """The attribute ``arrays`` (:func:`splat_arrays`, GPU units) copied to float32 buffers in ``order``,
    one attribute's copy at a time, colours clipped to [0, 1]; the :func:`block_bounds` of the splats
    in that order (``radii``: GPU units, in the arrays' order), and their :func:`block_cones` (None for
    splats with a linear normal field, which the back-face test of the shaders keeps by more than
    their normals)."""
    blocks = None
    buffers = {}
    kept = {}
    for name, values in arrays.items():
        # np.take of whole rows: ~2.5x faster than fancy indexing of (N, 3) arrays
        values = np.take(np.asarray(values, dtype="f4"), order, axis=0)
        if name == "color":
            np.clip(values, 0.0, 1.0, out=values)
        if name == "position":
            blocks = block_bounds(values, np.take(np.asarray(radii), order))
        buffers[name] = ctx.buffer(values)
        if name in ("normal", "u", "v") and "normal_field" not in arrays:
            kept[name] = values
        del values
    assert blocks is not None   # every cloud has positions
    cones = block_cones(kept["normal"], kept["u"], kept["v"]) if len(kept) == 3 else None
    return buffers, blocks, cones


#: Slack (radians) added to the half-angle of each block's normal cone (:func:`block_cones`): float32
#: rounding of the normals the shaders recompute.
CONE_SLACK = 1e-3


def block_cones(normals: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(B, 6) float64 per block of :data:`BLOCK` consecutive splats: a cone bounding both the shading
    normals and the oriented plane normals ``u x v`` of its splats (the two the shaders' back-face
    test reads, ``splat_vertex.glsl``): unit axis, cosine and sine of the half-angle (with
    :data:`CONE_SLACK`), and the largest ``|(n . u, n . v)|`` (GPU units: how far a shading normal
    leans out of its splat's plane, times the axes). A block whose normals sum to about zero gets the
    whole sphere (cosine -1). The normal cones of Pajarola et al. 2003 (sec. 3.3), per block of the
    GPU's order."""
    n = len(normals)
    starts = np.arange(0, n, BLOCK)
    counts = np.diff(np.append(starts, n))
    # per component, on contiguous columns (rows of 3 reduce ~10x slower)
    nx, ny, nz = np.ascontiguousarray(np.asarray(normals, dtype=np.float32).T)
    ux, uy, uz = np.ascontiguousarray(np.asarray(u, dtype=np.float32).T)
    vx, vy, vz = np.ascontiguousarray(np.asarray(v, dtype=np.float32).T)
    tiny = np.float32(1e-30)
    inv = 1.0 / np.maximum(np.sqrt(nx * nx + ny * ny + nz * nz), tiny)
    sx, sy, sz = nx * inv, ny * inv, nz * inv
    px, py, pz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    inv = 1.0 / np.maximum(np.sqrt(px * px + py * py + pz * pz), tiny)
    inv[px * sx + py * sy + pz * sz < 0] *= -1.0   # oriented as the shaders orient it
    px, py, pz = px * inv, py * inv, pz * inv
    total = np.stack([np.add.reduceat(s_ + p_, starts, dtype=np.float64) for s_, p_ in ((sx, px), (sy, py), (sz, pz))],
                     axis=1)
    length = np.linalg.norm(total, axis=1)
    axis = total / np.maximum(length, 1e-300)[:, None]
    ax, ay, az = (np.repeat(axis[:, c].astype(np.float32), counts) for c in range(3))
    cos = np.minimum(np.minimum.reduceat(sx * ax + sy * ay + sz * az, starts),
                     np.minimum.reduceat(px * ax + py * ay + pz * az, starts)).astype(np.float64)
    angle = np.arccos(np.clip(cos, -1.0, 1.0)) + CONE_SLACK
    # a degenerate block (normals cancelling, or zero axes) bounds nothing: the whole sphere
    angle[~(length > 1e-6 * counts)] = np.pi
    angle = np.minimum(angle, np.pi)
    # the shaders keep a splat also where its shading normal leans out of its plane by |(n . u, n . v)|
    # (field_faces_eye without a normal field): the block's largest such lean widens its test
    lean = np.maximum.reduceat(np.hypot(sx * ux + sy * uy + sz * uz, sx * vx + sy * vy + sz * vz),
                               starts).astype(np.float64)
    return np.column_stack([axis, np.cos(angle), np.sin(angle), lean])


def block_bounds(positions: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(B, 7) float64 per block of :data:`BLOCK` consecutive splats (the last one shorter): the lower
    and upper corner of their centers' bounding box and their largest radius (the units given)."""
    p, r = np.asarray(positions), np.asarray(radii)
    starts = np.arange(0, len(p), BLOCK)
    # extremes in the given precision, then widened: the same numbers, without a float64 copy of all
    bounds = [np.minimum.reduceat(p, starts, axis=0), np.maximum.reduceat(p, starts, axis=0),
              np.maximum.reduceat(r, starts)]
    return np.column_stack([b.astype(np.float64) for b in bounds])
