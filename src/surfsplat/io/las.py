"""LAS / LAZ LiDAR point clouds (laspy and lazrs, optional: the ``las`` extra).

Positions are the scaled coordinates (``las.x``, ``las.y``, ``las.z``, i.e.
``X * scale + offset``) in the file's units, computed in float64 and kept as float32
relative to the cloud's float64 origin (``SplatCloud.origin``). Colors come from
the ``red green blue`` fields where the point format has them: the fields are
16-bit, but many files store 8-bit values; :func:`rgb_scale` decides which. LAS
has no normals, but the splat extra bytes of a file that :func:`surfsplat.io.copc.write_copc` wrote
(``nx ny nz``, ``ux uy uz``, ``vx vy vz``) are read back as the splats' normals and tangent axes, and
its up axis (a ``surfsplat`` VLR) as the model's up; other LAS files are z-up.
Every other dimension (``intensity``, ``classification``, ``return_number``, ``number_of_returns``,
``gps_time``, ``scan_angle`` / ``scan_angle_rank``, flags, ``point_source_id``, extra bytes, ...) becomes a
named attribute (``SplatCloud.attributes``) with its own dtype (flags as uint8;
extra-bytes arrays of several values per point are skipped).

Before anything is allocated, the header is checked against the file
(:func:`check_header`): the point count times the record length must fit in the
file (``.las``) and in the memory available, the VLR and EVLR counts in the bytes
that hold them; a FIFO or device is refused before opening (``surfsplat.io``).
``.laz`` files are decompressed in a child process (``sys.executable``, with
laspy and lazrs): a corrupt file that makes the decompressor abort or crash
takes down the child only and is an InputError naming the file.
"""

from __future__ import annotations

import os
import struct
import warnings
from pathlib import Path

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError, file_reader
from ..orientation import Z_UP
from .atomic import memory_limit
from .child import decoded_in_child
from .copc import SPLAT_DIMENSIONS, UP_VLR


class CoordinatePrecisionWarning(UserWarning):
    """The points spread so far about their origin that float32 cannot keep the file's resolution."""


#: The child process that decodes a LAZ file: argv = [file, output .npz]; the same arrays as :func:`_arrays`.
_LAZ_CHILD = """
import sys, numpy as np, laspy
SKIP = {"X", "Y", "Z", "x", "y", "z", "red", "green", "blue"}
las = laspy.read(sys.argv[1])
out = {"xyz": np.column_stack([np.asarray(las.x, dtype=np.float64), np.asarray(las.y, dtype=np.float64),
                               np.asarray(las.z, dtype=np.float64)]),
       "scales": np.asarray(las.header.scales, dtype=np.float64)}
if {"red", "green", "blue"} <= set(las.point_format.dimension_names):
    out["rgb"] = np.column_stack([np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)])
for name in las.point_format.dimension_names:
    if name not in SKIP:
        value = np.asarray(las[name])
        if value.ndim == 1 and value.dtype.kind in "uifb":
            out["attr:" + name] = value.astype(np.uint8) if value.dtype.kind == "b" else value
for vlr in las.header.vlrs:
    if vlr.user_id == "surfsplat" and vlr.record_id == 1 and len(vlr.record_data) == 24:
        out["up"] = np.frombuffer(vlr.record_data, "<f8")
np.savez(sys.argv[2], **out)
"""


def rgb_scale(rgb: np.ndarray) -> float:
    """The divisor of LAS colors: 65535 when more than 1% of the non-zero values exceed 255 (16-bit
    colors), else 255 (8-bit colors stored in the 16-bit fields; the rare values above 255 are then
    clipped to 1). A single out-of-range value thus cannot switch a whole 8-bit cloud to the 16-bit
    scale (and render it black)."""
    values = np.asarray(rgb).ravel()
    nonzero = int(np.count_nonzero(values))
    if nonzero == 0:
        return 255.0
    return 65535.0 if int(np.count_nonzero(values > 255)) > 0.01 * nonzero else 255.0


@file_reader
def check_header(path: Path, source: str) -> None:
    """InputError naming ``source`` when the LAS header cannot describe the file: too short, no
    ``LASF`` signature, header or point offsets outside the file, more VLRs or EVLRs than the bytes
    reserved for them can hold, or more points (count times record length) than the file (``.las``)
    or the available memory can hold."""
    size = os.stat(path).st_size
    with open(path, "rb") as stream:
        head = stream.read(375)
    if len(head) < 227 or head[:4] != b"LASF":
        raise InputError(f"{source}: cannot read LAS file: not a LAS file (no LASF header of 227 bytes)")
    minor = head[25]
    header_size, offset, n_vlr = struct.unpack_from("<HII", head, 94)
    record = struct.unpack_from("<H", head, 105)[0]
    count = struct.unpack_from("<I", head, 107)[0]
    if header_size < 227 or header_size > size or offset < header_size or offset > size:
        raise InputError(f"{source}: cannot read LAS file: header size {header_size} or point data offset "
                         f"{offset} outside the file ({size:,} bytes)")
    if n_vlr * 54 > offset - header_size:
        raise InputError(f"{source}: cannot read LAS file: the header declares {n_vlr:,} VLRs (at least "
                         f"{54 * n_vlr:,} bytes) but only {offset - header_size:,} bytes precede the points")
    if minor >= 4 and len(head) >= 255 and header_size >= 255:
        start_evlr, n_evlr, count64 = struct.unpack_from("<QIQ", head, 235)
        count = count64 or count
        if n_evlr and (start_evlr < offset or n_evlr * 60 > size - min(start_evlr, size)):
            raise InputError(f"{source}: cannot read LAS file: the header declares {n_evlr:,} EVLRs at "
                             f"byte {start_evlr:,}, which the file ({size:,} bytes) cannot hold")
    need = count * record
    if path.suffix.lower() != ".laz" and need > size - offset:
        raise InputError(f"{source}: cannot read LAS file: the header declares {count:,} points of {record} "
                         f"bytes ({need:,} bytes) but the file holds {size - offset:,} bytes of points "
                         "(truncated file, or a wrong point count)")
    limit = memory_limit()
    if need > limit:
        raise InputError(f"{source}: cannot read LAS file: the header declares {count:,} points "
                         f"({need:,} bytes), more than the {limit:,} bytes of memory available")


@file_reader
def read_las(path: Path) -> SplatCloud:
    """Read a .las or .laz file as an (unvalidated) SplatCloud.

    Returns positions (N, 3) float32 in the file's units relative to the cloud's float64
    ``origin`` (the points' centre when they sit far from zero, as georeferenced data do:
    world coordinates are ``origin + positions``), and colors (N, 3) float32 in [0, 1] when
    the point format has RGB (scale: :func:`rgb_scale`). Warns
    (:class:`CoordinatePrecisionWarning`) when the points spread so far about that origin that
    float32 rounds them more coarsely than the file's scale.
    ``.laz`` is decoded in a child process (see the module docstring).
    """
    source = str(path)
    try:
        import laspy
    except ImportError as exc:
        raise InputError(f"{source}: reading LAS/LAZ files needs laspy and, for LAZ, lazrs: "
                         "`pip install laspy lazrs` (or `pip install \".[las]\"` in the surfsplat checkout)") from exc
    try:
        check_header(Path(path), source)
    except OSError as exc:
        raise InputError(f"{source}: cannot read LAS file: {exc.strerror or exc}") from exc
    if Path(path).suffix.lower() == ".laz":
        xyz, rgb, scales, attributes, up = _decode_laz(Path(path), source)
    else:
        try:
            las = laspy.read(source)
            xyz = np.column_stack([np.asarray(las.x, dtype=np.float64),
                                   np.asarray(las.y, dtype=np.float64),
                                   np.asarray(las.z, dtype=np.float64)])
            rgb = None
            if {"red", "green", "blue"} <= set(las.point_format.dimension_names):
                rgb = np.column_stack([np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)])
            scales = np.asarray(las.header.scales, dtype=np.float64)
            attributes = las_attributes(las)
            up = stored_up(las.header.vlrs)
        except MemoryError:
            raise
        except Exception as exc:  # laspy.LaspyException (bad header), OSError, ValueError, ...
            raise InputError(f"{source}: cannot read LAS file: {type(exc).__name__}: {exc}") from exc
    colors = None
    if rgb is not None and not rgb.any():   # point formats 2, 3, 5, 7, 8 always carry RGB; all zero: none given
        rgb = None
    if rgb is not None:
        colors = np.clip(rgb.astype(np.float64) / rgb_scale(rgb), 0.0, 1.0).astype(np.float32)

    splats = splat_axes(attributes)
    # float64 world coordinates: kept as float32 positions relative to an origin near the points
    cloud = SplatCloud(positions=xyz, colors=colors, attributes=attributes or None,
                       up=Z_UP if up is None else up, **splats)   # LiDAR is z-up unless surfsplat said otherwise
    finite = cloud.positions[np.isfinite(cloud.positions).all(axis=1)]
    if len(finite):
        extent = np.abs(finite).max(axis=0)
        spacing = np.spacing(extent).astype(np.float64)
        if np.any(spacing > scales):
            warnings.warn(
                f"{source}: coordinates up to {extent.max():,.0f} from their centre are rounded to steps of "
                f"{spacing.max():g} in float32 positions (the file's resolution is {scales.min():g})",
                CoordinatePrecisionWarning, stacklevel=3)
    return cloud


def stored_up(vlrs) -> tuple[float, float, float] | None:
    """The model's up axis that :func:`surfsplat.io.copc.write_copc` stores (VLR user ``surfsplat``, record
    1: three float64), or None."""
    for vlr in vlrs:
        if vlr.user_id == UP_VLR[0] and vlr.record_id == UP_VLR[1] and len(vlr.record_data) == 24:
            x, y, z = struct.unpack("<3d", vlr.record_data)
            return (x, y, z)
    return None


def splat_axes(attributes: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``{"normals", "u", "v"}`` as (N, 3) float32 arrays, taken out of ``attributes``, where the file has
    all the splat extra bytes that :func:`surfsplat.io.copc.write_copc` writes (``nx ny nz ux uy uz vx vy
    vz``); else nothing (and ``attributes`` unchanged)."""
    if not all(name in attributes for name in SPLAT_DIMENSIONS):
        return {}
    columns = [np.asarray(attributes.pop(name), dtype=np.float32) for name in SPLAT_DIMENSIONS]
    return {"normals": np.column_stack(columns[0:3]), "u": np.column_stack(columns[3:6]),
            "v": np.column_stack(columns[6:9])}


#: LAS dimensions that are positions or colors, not attributes.
_NOT_ATTRIBUTES = frozenset({"X", "Y", "Z", "x", "y", "z", "red", "green", "blue"})


def las_attributes(las) -> dict[str, np.ndarray]:
    """Every per-point dimension of a laspy ``LasData`` but positions and colors, by name, as
    (N,) arrays of the file's dtype (flags as uint8; multi-valued extra bytes skipped)."""
    out = {}
    for name in las.point_format.dimension_names:
        if name in _NOT_ATTRIBUTES:
            continue
        value = np.asarray(las[name])
        if value.ndim == 1 and value.dtype.kind in "uifb":
            out[name] = value.astype(np.uint8) if value.dtype.kind == "b" else value
    return out


def _decode_laz(path: Path, source: str) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, dict,
                                                 tuple[float, float, float] | None]:
    """``(xyz (N, 3) float64, rgb (N, 3) uint16 or None, scales (3,), attributes, up or None)`` of a LAZ file,
    decoded by
    :data:`_LAZ_CHILD` in a child process (:func:`surfsplat.io.child.decoded_in_child`); its crash,
    abort, failure or hang is an InputError."""
    hint = lambda problem: " (LAZ needs a backend: `pip install lazrs`)" if "backend" in problem.lower() else ""  # noqa: E731
    with decoded_in_child(_LAZ_CHILD, Path(path), source, "LAZ file", hint=hint) as data:
        attributes = {key[5:]: data[key] for key in data.files if key.startswith("attr:")}
        up = tuple(float(c) for c in data["up"]) if "up" in data.files else None
        return (data["xyz"], (data["rgb"] if "rgb" in data.files else None), data["scales"], attributes,
                up)  # type: ignore[return-value]
