"""COPC (Cloud Optimized Point Cloud, COPC 1.0) writer: a LAZ 1.4 file whose points are stored as an
octree, one LAZ chunk per node, so viewers (Potree, QGIS, plas.io) and tools (PDAL, laspy's
``CopcReader``) read a region or a level of detail without decoding the whole file.

Layout of the file written by :func:`write_copc`:

- LAS 1.4 header (375 bytes), point data record format 7 (XYZ, RGB; the cloud has colours) or 6;
- VLRs: the COPC info VLR first (user ``copc``, record 1, 160 bytes: octree centre, half size, root
  spacing, offset and size of the root hierarchy page, GPS time range), the ``laszip encoded`` VLR
  (variable-size chunks), the extra bytes VLR;
- the points, LAZ compressed by lazrs (chunks in parallel), one variable-size chunk per octree node, then
  the chunk table;
- one EVLR (user ``copc``, record 1000): the hierarchy, one page of 32-byte entries (VoxelKey
  level, x, y, z as int32; chunk offset uint64; chunk bytes int32; point count int32).

The octree is a cube from half a quantization step below the points' lowest corner, whose node faces all
fall half a step between stored positions. Each point is stored exactly once, in one node: level by level
(Potree / Entwine style), a node holding more than ``leaf_points`` of the points not yet placed keeps
one point per cell of a ``grid`` x ``grid`` x ``grid`` grid over it (the one nearest the cell centre),
so a coarse level is a spatially even subsample; the rest go down to its children. The root spacing is
the node size over ``grid`` and halves per level.

Positions are stored as 32-bit integers with a decimal scale: the largest power of ten not above 1e-5
of the bounding-box diagonal (1 cm for a 1 km tile; each coordinate is within half that step of the
cloud's float64 world position ``origin + positions``, so the 3D error is at most 0.87e-5 of the
diagonal; ``scale`` sets another step). A step of 1e-4 of the diagonal would cost 4% fewer bytes but
move a render of the model read back from 75 dB to 46 dB PSNR against the original.

Colours are 16-bit (``round(c * 65535)``). The splats are LAS 1.4 extra bytes (float32,
:data:`SPLAT_DIMENSIONS`): unit normal ``nx ny nz`` and the two scaled tangent axes ``ux uy uz`` and
``vx vy vz`` (model units); :func:`surfsplat.io.las.read_las` reads them back as splats. The model's
up axis, where known, is a VLR (user ``surfsplat``, record 1, three float64; LAS readers otherwise
take LiDAR's +z). Attributes of the cloud that are LAS dimensions of the point format
(``intensity``, ``classification``, ``gps_time``, ...) fill them; other one-valued numeric attributes
become extra bytes of their dtype.
"""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError
from ..version import __version__
from .atomic import atomic_path, check_writable

#: The splat's extra bytes, float32 each: unit normal, then the scaled tangent axes u and v.
SPLAT_DIMENSIONS = ("nx", "ny", "nz", "ux", "uy", "uz", "vx", "vy", "vz")
#: Descriptions of :data:`SPLAT_DIMENSIONS` in the extra bytes VLR (at most 32 characters).
_DESCRIPTIONS = {"n": "splat unit normal {}", "u": "splat tangent axis u {} (units)",
                 "v": "splat tangent axis v {} (units)"}
#: (user, record) of the VLR holding the model's up axis (three float64), where the cloud has one.
UP_VLR = ("surfsplat", 1)
#: Cells per node side of the subsampling grid (Entwine and untwine use 128).
DEFAULT_GRID = 128
#: A node keeps all of its points not yet placed when they are at most this many.
DEFAULT_LEAF_POINTS = 20_000
#: Deepest level: the fine grid of a level (``2**level * grid`` cells a side) must fit 21 bits a
#: coordinate so that one cell id fits an int64.
_MAX_FINE_BITS = 20
#: Quantization step relative to the bounding-box diagonal (at most).
RELATIVE_STEP = 1e-5
#: Dimensions of point formats 6 and 7 that :func:`write_copc` writes itself (return numbers: 1 of 1 unless
#: the cloud's attributes give them).
_OWN = frozenset({"X", "Y", "Z", "red", "green", "blue"})
_EXTRA_DTYPES = (np.uint8, np.int8, np.uint16, np.int16, np.uint32, np.int32, np.uint64, np.int64,
                 np.float32, np.float64)


@dataclass(frozen=True)
class CopcResult:
    """What :func:`write_copc` wrote.

    Attributes:
        path: the file.
        points: points written.
        nodes: octree nodes (LAZ chunks).
        levels: octree levels (the root is level 0).
        bytes: size of the file.
        scale: the quantization step of the positions (model units, all three axes).
    """

    path: Path
    points: int
    nodes: int
    levels: int
    bytes: int
    scale: float


def is_surfsplat_copc(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a LAS file whose generating software is surfsplat (one :func:`write_copc` wrote)."""
    try:
        with open(path, "rb") as stream:
            head = stream.read(90)
    except OSError:
        return False
    return head[:4] == b"LASF" and head[58:90].startswith(b"surfsplat")


def quantization_step(diagonal: float) -> float:
    """The largest power of ten not above ``RELATIVE_STEP * diagonal`` (model units; 1e-3 for a point)."""
    if not diagonal > 0:
        return 1e-3
    return 10.0 ** math.floor(math.log10(RELATIVE_STEP * diagonal))


def max_depth(grid: int) -> int:
    """The deepest octree level for a subsampling grid of ``grid`` cells a side (its cell ids fit an int64)."""
    return max(_MAX_FINE_BITS - int(math.ceil(math.log2(grid))), 0)


def octree_nodes(t: np.ndarray, grid: int = DEFAULT_GRID, leaf_points: int = DEFAULT_LEAF_POINTS,
                 depth_limit: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(level (N,) int32, key (N, 3) int64)``: the octree node of each point, given its position
    ``t`` (N, 3) in the unit cube ``[0, 1]``. Level by level, a node with more than ``leaf_points``
    unplaced points keeps one per cell of a ``grid``-cubed grid (the nearest the cell centre); a node
    with fewer, or at the deepest level (``depth_limit``, at most :func:`max_depth`), keeps them all.
    Every point lands in exactly one node, and a node holding points has a parent holding points."""
    n = len(t)
    level = np.full(n, -1, np.int32)
    key = np.zeros((n, 3), np.int64)
    remaining = np.arange(n)
    max_level = max_depth(grid) if depth_limit is None else min(depth_limit, max_depth(grid))
    depth = 0
    while len(remaining):
        cells = 1 << depth
        tr = t[remaining]
        node = np.minimum((tr * cells).astype(np.int64), cells - 1)
        node_id = (node[:, 0] * cells + node[:, 1]) * cells + node[:, 2]
        _, inverse, counts = np.unique(node_id, return_inverse=True, return_counts=True)
        keep = counts[inverse.ravel()] <= leaf_points
        if depth >= max_level:
            keep[:] = True
        elif not keep.all():
            big = np.flatnonzero(~keep)
            keep[big[_nearest_per_cell(tr[big] * (cells * grid), cells * grid)]] = True
        placed = remaining[keep]
        level[placed] = depth
        key[placed] = node[keep]
        remaining = remaining[~keep]
        depth += 1
    return level, key


def _nearest_per_cell(scaled: np.ndarray, cells: int) -> np.ndarray:
    """Indices of the points of ``scaled`` (N, 3), in grid units of a ``cells``-cubed grid, nearest the
    centre of their cell: one per occupied cell."""
    fine = np.minimum(scaled.astype(np.int64), cells - 1)
    fine_id = (fine[:, 0] * cells + fine[:, 1]) * cells + fine[:, 2]
    distance = ((scaled - fine - 0.5) ** 2).sum(axis=1)
    order = np.argsort(fine_id)
    sorted_id, sorted_distance = fine_id[order], distance[order]
    new_cell = np.r_[True, sorted_id[1:] != sorted_id[:-1]]
    group = np.cumsum(new_cell) - 1
    nearest = np.flatnonzero(sorted_distance == np.minimum.reduceat(sorted_distance, np.flatnonzero(new_cell))[group])
    first = np.r_[True, group[nearest[1:]] != group[nearest[:-1]]]   # of equally near points, one
    return order[nearest[first]]


def _attribute_dimensions(cloud: SplatCloud, names: set[str]) -> tuple[dict, dict]:
    """``(standard, extra)``: the cloud's attributes that fill dimensions of the point format, and the
    other one-valued numeric ones (written as extra bytes of their dtype)."""
    standard, extra = {}, {}
    for name, value in (cloud.attributes or {}).items():
        array = np.asarray(value)
        if name in _OWN or name in SPLAT_DIMENSIONS or array.ndim != 1 or array.dtype.kind not in "uifb":
            continue
        if name in names:
            standard[name] = array
        elif array.dtype.type in _EXTRA_DTYPES or array.dtype.kind == "b":
            extra[name] = array.astype(np.uint8) if array.dtype.kind == "b" else array
    return standard, extra


def _evlr(user: str, record: int, description: str, data: bytes) -> bytes:
    """A LAS 1.4 extended VLR: the 60-byte header then ``data``."""
    return struct.pack("<H16sHQ32s", 0, user.encode(), record, len(data), description.encode()) + data


def _info(center, halfsize: float, spacing: float, root_offset: int, root_size: int, gps: tuple) -> bytes:
    """The 160 bytes of the COPC info VLR."""
    data = struct.pack("<3dddQQdd", *center, halfsize, spacing, root_offset, root_size, *gps) + bytes(88)
    assert len(data) == 160
    return data


def write_copc(cloud: SplatCloud, path: str | os.PathLike, *, overwrite: bool = True, scale: float | None = None,
               grid: int = DEFAULT_GRID, leaf_points: int = DEFAULT_LEAF_POINTS) -> CopcResult:
    """Write ``cloud`` as a COPC 1.0 file (``.copc.laz``; the layout is in the module docstring).

    Args:
        cloud: the splats (positions needed; colours, normals, tangent axes and attributes stored
            where present). World positions are ``cloud.origin + cloud.positions`` (model units).
        path: the output file.
        overwrite: replace an existing file (False: InputError).
        scale: the quantization step of the positions, model units (None: the largest power of ten
            not above 1e-5 of the bounding-box diagonal).
        grid: cells per node side of the subsampling grid (the root spacing is the cube's side over it).
        leaf_points: a node keeps all of its unplaced points when they are at most this many.

    Returns:
        :class:`CopcResult`.
    """
    try:
        import laspy
        import lazrs
    except ImportError as exc:
        raise InputError(f"{path}: writing COPC needs laspy and lazrs: `pip install laspy lazrs` "
                         "(or `pip install \".[las]\"` in the surfsplat checkout)") from exc
    check_writable(path, overwrite=overwrite)
    n = len(cloud)
    if n == 0:
        raise InputError(f"{path}: no points to write")
    if n >= 2**31:
        raise InputError(f"{path}: {n:,} points: a COPC node count is an int32; write fewer points")
    if grid < 1 or leaf_points < 1:
        raise InputError(f"{path}: grid ({grid}) and leaf_points ({leaf_points}) must be >= 1")
    world = np.asarray(cloud.origin, np.float64) + cloud.positions.astype(np.float64)
    if not np.isfinite(world).all():
        raise InputError(f"{path}: {int((~np.isfinite(world).all(axis=1)).sum()):,} points have NaN or "
                         "infinite coordinates; validate the cloud first")
    low, high = world.min(axis=0), world.max(axis=0)
    step = float(scale) if scale is not None else quantization_step(float(np.linalg.norm(high - low)))
    if not step > 0:
        raise InputError(f"{path}: the position scale must be > 0, got {scale!r}")
    offset = np.round((low + high) / 2 / step) * step
    integers = np.round((world - offset) / step)
    if np.abs(integers).max() >= 2**31 - 1:
        raise InputError(f"{path}: the points span more than 2**31 steps of {step:g}; pass a larger scale")
    xyz = integers.astype(np.int32)
    stored = xyz * step + offset                      # what a reader gets back
    low, high = stored.min(axis=0), stored.max(axis=0)
    # The cube, in steps: from half a step below the lowest point, a side of S steps, S a multiple of 2**depth
    # (the deepest level): every node boundary then lies half a step between stored positions, so no point
    # sits on one, whatever rounding a reader's bounds arithmetic does.
    first = xyz.min(axis=0).astype(np.int64)
    extent = int((xyz.max(axis=0).astype(np.int64) - first).max()) + 1
    depth = min(max_depth(grid), max(int(math.ceil(math.log2(extent))), 0))
    side = -(-extent // 2**depth) * 2**depth
    halfsize = side * step / 2
    center = (first - 0.5) * step + offset + halfsize
    t = (xyz - first + 0.5) / side                    # in (0, 1): exact node cells for levels <= depth
    level, key = octree_nodes(t, grid, leaf_points, depth)

    point_format = 7 if cloud.colors is not None else 6
    header = laspy.LasHeader(version="1.4", point_format=point_format)
    standard, extra = _attribute_dimensions(cloud, set(header.point_format.dimension_names))
    splats = cloud.has_splats
    params = []
    if splats:
        params += [laspy.ExtraBytesParams(name=name, type=np.float32,
                                          description=_DESCRIPTIONS[name[0]].format(name[1]))
                   for name in SPLAT_DIMENSIONS]
    params += [laspy.ExtraBytesParams(name=name, type=array.dtype) for name, array in extra.items()]
    if params:
        header.add_extra_dims(params)
    record = laspy.PackedPointRecord.zeros(n, header.point_format)
    for axis, name in enumerate("XYZ"):
        record[name] = xyz[:, axis]
    record["return_number"] = np.ones(n, np.uint8)
    record["number_of_returns"] = np.ones(n, np.uint8)
    if cloud.colors is not None:
        rgb = np.round(np.clip(cloud.colors, 0.0, 1.0) * 65535.0).astype(np.uint16)
        for axis, name in enumerate(("red", "green", "blue")):
            record[name] = rgb[:, axis]
    if splats:
        for prefix, values in (("n", cloud.normals), ("u", cloud.u), ("v", cloud.v)):
            for axis, coordinate in enumerate("xyz"):
                record[prefix + coordinate] = values[:, axis]   # type: ignore[index]
    for name, array in {**standard, **extra}.items():
        record[name] = array
    gps = (0.0, 0.0)
    if "gps_time" in standard and n:
        gps = (float(np.min(standard["gps_time"])), float(np.max(standard["gps_time"])))

    # nodes in order of level then key; points of a node contiguous (one LAZ chunk each)
    order = np.lexsort((key[:, 2], key[:, 1], key[:, 0], level))
    node_rows = np.column_stack([level[order], key[order]])
    starts = np.flatnonzero(np.r_[True, (node_rows[1:] != node_rows[:-1]).any(axis=1)])
    ends = np.r_[starts[1:], n]
    points = record.array[order]

    vlr = lazrs.LazVlr.new_for_compression(point_format, header.point_format.num_extra_bytes, True)
    header.global_encoding.wkt = True   # LAS 1.4: required for point formats 6-10
    header.generating_software = f"surfsplat {__version__}"
    header.scales = np.full(3, step)
    header.offsets = offset
    header.mins, header.maxs = low, high
    header.point_count = n
    returns = np.bincount(np.clip(np.asarray(record["return_number"]), 1, 15) - 1, minlength=15)
    header.number_of_points_by_return = returns
    others = [v for v in header.vlrs]
    info_vlr = laspy.VLR("copc", 1, "COPC info VLR", _info(center, halfsize, 2 * halfsize / grid, 0, 0, gps))
    header.vlrs.clear()
    if cloud.up is not None:
        others.append(laspy.VLR(UP_VLR[0], UP_VLR[1], "model up axis", struct.pack("<3d", *cloud.up)))
    header.vlrs.extend([info_vlr, laspy.vlrs.known.LasZipVlr(vlr.record_data()), *others])
    header.are_points_compressed = True

    with atomic_path(path, overwrite=overwrite) as temp, open(temp, "w+b") as stream:
        header.write_to(stream)
        compressor = lazrs.ParLasZipCompressor(stream, vlr)   # the chunks compressed in parallel
        compressor.compress_chunks([points[start:end].view(np.uint8) for start, end in zip(starts, ends)])
        compressor.done()
        stream.seek(header.offset_to_point_data)
        table = np.array(lazrs.read_chunk_table(stream, vlr), np.int64).reshape(-1, 2)
        counts, sizes = table[:, 0], table[:, 1]
        if len(table) != len(starts) or not np.array_equal(counts, ends - starts):
            raise RuntimeError("the LAZ chunk table does not match the octree nodes")
        # chunks follow the 8-byte offset to the chunk table, in order
        offsets = header.offset_to_point_data + 8 + np.r_[0, np.cumsum(sizes)[:-1]]
        entries = np.zeros(len(starts), np.dtype([("key", "<i4", 4), ("offset", "<u8"), ("bytes", "<i4"),
                                                   ("count", "<i4")]))
        entries["key"] = node_rows[starts]
        entries["offset"], entries["bytes"], entries["count"] = offsets, sizes, ends - starts
        page = entries.tobytes()
        evlr_start = stream.seek(0, os.SEEK_END)
        stream.write(_evlr("copc", 1000, "EPT hierarchy", page))
        header.start_of_first_evlr = evlr_start
        header.number_of_evlrs = 1
        header.vlrs[0] = laspy.VLR("copc", 1, "COPC info VLR",
                                   _info(center, halfsize, 2 * halfsize / grid, evlr_start + 60, len(page), gps))
        stream.seek(0)
        header.write_to(stream, ensure_same_size=True)
        size = stream.seek(0, os.SEEK_END)
    return CopcResult(Path(path), n, len(starts), int(level.max()) + 1, size, step)
