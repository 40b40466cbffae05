"""E57 point clouds (ASTM E2807; read with pye57, optional: the ``e57`` extra).

Every scan of the file's ``data3D`` section is read and moved into the file's
coordinates by its pose (``p_file = R(q) p_scan + t``, the rigid-body transform
of the E57 standard, ``q`` a unit quaternion ``w x y z``); the scans are
concatenated in file order. Positions are Cartesian or, for scans that store
only spherical coordinates, converted (range r, azimuth a in the x-y plane from
+x toward +y, elevation e from that plane toward +z: ``x = r cos e cos a``,
``y = r cos e sin a``, ``z = r sin e``). Points whose ``cartesianInvalidState``
(or ``sphericalInvalidState``) is not 0 are dropped: their coordinates are
missing or carry a direction only.

Colors (``colorRed colorGreen colorBlue``) are scaled to [0, 1] by the scan's
``colorLimits`` (else by the prototype's integer bounds); points flagged
``isColorInvalid`` and points of scans without colors get the default 0.8 gray
when another scan has colors. ``intensity`` is kept as read (float32, the
file's units; NaN where ``isIntensityInvalid``) as the attribute ``intensity``,
and the index of each point's scan as the attribute ``scan`` (uint16), so
``--color-by intensity`` and ``--color-by scan`` work as for LAS attributes.

The fixed 48-byte file header is checked first (signature, page size, the
physical length against the file's size: a truncated file, the XML section
inside the file). The file is then decoded in a child process
(``sys.executable`` with pye57): libE57 is C++, and a corrupt file that made
it abort or crash would take down the child only; its error, crash or hang is
an :class:`~surfsplat.errors.InputError` naming the file.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from ..cloud import DEFAULT_ALBEDO, SplatCloud
from ..errors import InputError, file_reader
from ..orientation import Z_UP
from .atomic import memory_limit
from .child import decoded_in_child

#: The first bytes of every E57 file.
E57_SIGNATURE = b"ASTM-E57"
#: The standard's page size: 1020 bytes of data and a 4-byte CRC-32C checksum.
E57_PAGE_SIZE = 1024

#: The child process that decodes an E57 file: argv = [file, output .npz, memory limit in bytes]. For scan i
#: it writes ``i:<field>`` (float64 arrays of the fields in :data:`_FIELDS` present), ``i:pose`` (w x y z tx ty tz)
#: and ``i:color_limits`` (min and max of red, green, blue); errors go to stderr as one ``ERROR:`` line.
_E57_CHILD = r"""
import sys
import numpy as np
FIELDS = ("cartesianX", "cartesianY", "cartesianZ", "sphericalRange", "sphericalAzimuth", "sphericalElevation",
          "cartesianInvalidState", "sphericalInvalidState", "intensity", "isIntensityInvalid",
          "colorRed", "colorGreen", "colorBlue", "isColorInvalid")
COLORS = ("colorRed", "colorGreen", "colorBlue")


def number(node, *path, default=0.0):
    for name in path:
        if not node.isDefined(name):
            return default
        node = node[name]
    return float(node.value())


def main(path, out, limit):
    from pye57 import libe57
    imf = libe57.ImageFile(path, "r")
    root = imf.root()
    if not root.isDefined("data3D") or len(root["data3D"]) == 0:
        raise ValueError("the file holds no point cloud (its data3D section is empty)")
    data3d = root["data3D"]
    result = {"scans": np.array(len(data3d))}
    for i in range(len(data3d)):
        scan = data3d[i]
        if not scan.isDefined("points"):
            raise ValueError(f"scan {i} has no points")
        points = scan["points"]
        prototype = libe57.StructureNode(points.prototype())
        names = {prototype.get(k).elementName() for k in range(prototype.childCount())}
        fields = [name for name in FIELDS if name in names]
        n = points.childCount()
        if n * 8 * max(len(fields), 1) > limit:
            raise ValueError(f"scan {i} declares {n:,} points ({n * 8 * len(fields):,} bytes), more than the "
                             f"{limit:,} bytes of memory available")
        arrays = {name: np.zeros(n, np.float64) for name in fields}
        buffers = libe57.VectorSourceDestBuffer()
        for name in fields:
            buffers.append(libe57.SourceDestBuffer(imf, name, arrays[name], n, True, True))
        if n:
            reader = points.reader(buffers)
            got = reader.read()
            reader.close()
            if got != n:
                raise ValueError(f"scan {i}: only {got:,} of its {n:,} points could be read (truncated data)")
        result.update({f"{i}:{name}": value for name, value in arrays.items()})
        result[f"{i}:pose"] = np.array([number(scan, "pose", "rotation", "w", default=1.0)]
                                       + [number(scan, "pose", "rotation", c) for c in "xyz"]
                                       + [number(scan, "pose", "translation", c) for c in "xyz"])
        limits = []
        for name in COLORS:
            low, high = 0.0, 255.0
            if name in names:
                node = prototype[name]
                if isinstance(node, (libe57.IntegerNode, libe57.ScaledIntegerNode)):
                    low, high = float(node.minimum()), float(node.maximum())
            low = number(scan, "colorLimits", name + "Minimum", default=low)
            high = number(scan, "colorLimits", name + "Maximum", default=high)
            limits += [low, high]
        result[f"{i}:color_limits"] = np.array(limits)
    imf.close()
    np.savez(out, **result)


try:
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]))
except BaseException as exc:
    lines = str(exc).strip().splitlines() or [type(exc).__name__]
    sys.stderr.write("ERROR: " + lines[0] + "\n")
    sys.exit(1)
"""


@file_reader
def check_e57_header(path: Path, source: str) -> None:
    """InputError naming ``source`` when the fixed E57 header cannot describe the file: shorter than
    48 bytes, no ``ASTM-E57`` signature, a page size other than 1024, a physical length other than the
    file's size (truncated or extended file), or an XML section outside the file."""
    size = os.stat(path).st_size
    with open(path, "rb") as stream:
        head = stream.read(48)
    if len(head) < 48 or head[:8] != E57_SIGNATURE:
        raise InputError(f"{source}: cannot read E57 file: not an E57 file (no ASTM-E57 header of 48 bytes)")
    major, _, length, xml_offset, xml_length, page = struct.unpack_from("<IIQQQQ", head, 8)
    if major != 1 or page != E57_PAGE_SIZE:
        raise InputError(f"{source}: cannot read E57 file: format version {major} with pages of {page} bytes "
                         f"(only version 1 with {E57_PAGE_SIZE}-byte pages exists)")
    if length != size:
        raise InputError(f"{source}: cannot read E57 file: the header declares {length:,} bytes but the file "
                         f"holds {size:,} (truncated or damaged file)")
    if xml_offset >= size or xml_length > size:
        raise InputError(f"{source}: cannot read E57 file: its XML section ({xml_length:,} bytes at byte "
                         f"{xml_offset:,}) lies outside the file ({size:,} bytes)")


@file_reader
def read_e57(path: Path) -> SplatCloud:
    """Read every scan of an ``.e57`` file as one (unvalidated) SplatCloud in the file's coordinates.

    Returns positions (N, 3) float32 (the file's units, metres by the standard), colors (N, 3) float32
    in [0, 1] when a scan has colors, and the attributes ``intensity`` (float32, as stored) when a scan
    has intensities and ``scan`` (uint16, the scan's index). See the module docstring for poses,
    spherical coordinates and invalid points.

    Raises:
        InputError naming the file: pye57 missing (the ``e57`` extra), a damaged header, a file libE57
        cannot decode (checksum, XML, truncated data; also a crash or hang of the decoder), a scan
        without coordinates, a pose that is no rotation, or more points than the memory available.
    """
    source = str(path)
    try:
        import pye57  # noqa: F401 (the child process needs it; checked here for a clear message)
    except ImportError as exc:
        raise InputError(f"{source}: reading E57 files needs pye57: `pip install pye57` (or "
                         "`pip install \".[e57]\"` in the surfsplat checkout)") from exc
    try:
        check_e57_header(Path(path), source)
    except OSError as exc:
        raise InputError(f"{source}: cannot read E57 file: {exc.strerror or exc}") from exc
    scans = _decode(Path(path), source)
    if not any(len(positions) for positions, *_ in scans):
        raise InputError(f"{source}: contains no valid points ({len(scans)} scans, every point empty or "
                         "flagged invalid)")
    positions = np.concatenate([s[0] for s in scans]).astype(np.float32)
    colors = None
    if any(s[1] is not None for s in scans):
        colors = np.concatenate([s[1] if s[1] is not None else np.full((len(s[0]), 3), DEFAULT_ALBEDO)
                                 for s in scans]).astype(np.float32)
    attributes = {"scan": np.concatenate([np.full(len(s[0]), i, np.uint16) for i, s in enumerate(scans)])}
    if any(s[2] is not None for s in scans):
        attributes["intensity"] = np.concatenate([s[2] if s[2] is not None else np.full(len(s[0]), np.nan)
                                                  for s in scans]).astype(np.float32)
    return SplatCloud(positions=positions, colors=colors, attributes=attributes, up=Z_UP)   # E57 scans are z-up


def quaternion_matrix(q) -> np.ndarray:
    """The (3, 3) rotation matrix of the quaternion ``q = (w, x, y, z)`` after normalizing it.

    Raises InputError when ``q`` is not finite or has (nearly) zero length."""
    q = np.asarray(q, dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if not np.isfinite(norm) or norm < 1e-9:
        raise InputError(f"rotation quaternion {q.tolist()} is not a rotation (zero or non-finite)")
    w, x, y, z = q / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def spherical_to_cartesian(rae: np.ndarray) -> np.ndarray:
    """(N, 3) float64 Cartesian points of (N, 3) ``(range, azimuth, elevation)`` (radians), as the E57
    standard defines them (see the module docstring)."""
    r, azimuth, elevation = np.asarray(rae, dtype=np.float64).T
    flat = r * np.cos(elevation)
    return np.column_stack([flat * np.cos(azimuth), flat * np.sin(azimuth), r * np.sin(elevation)])


def _scan(data, i: int, source: str) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """``(positions (M, 3) float64 in file coordinates, colors (M, 3) or None, intensity (M,) or None)``
    of scan ``i`` of the child's output, its invalid points dropped."""
    fields = {key.split(":", 1)[1]: data[key] for key in data.files if key.startswith(f"{i}:")}
    if all(f"cartesian{c}" in fields for c in "XYZ"):
        local = np.column_stack([fields[f"cartesian{c}"] for c in "XYZ"])
        state = fields.get("cartesianInvalidState")
    elif all(f"spherical{c}" in fields for c in ("Range", "Azimuth", "Elevation")):
        local = spherical_to_cartesian(np.column_stack([fields[f"spherical{c}"]
                                                        for c in ("Range", "Azimuth", "Elevation")]))
        state = fields.get("sphericalInvalidState")
    else:
        raise InputError(f"{source}: cannot read E57 file: scan {i} has neither cartesianX/Y/Z nor "
                         "sphericalRange/Azimuth/Elevation coordinates", element="scan", row=i)
    keep = np.ones(len(local), bool) if state is None else state == 0
    pose = fields["pose"]
    try:
        rotation = quaternion_matrix(pose[:4])
    except InputError as exc:
        raise InputError(f"{source}: cannot read E57 file: scan {i}'s pose: {exc}",
                         **{**exc.context(), "element": "pose", "row": i}) from None
    if not np.isfinite(pose[4:]).all():
        raise InputError(f"{source}: cannot read E57 file: scan {i}'s pose translation {pose[4:].tolist()} is "
                         "not finite", element="pose", row=i)
    positions = local[keep] @ rotation.T + pose[4:]
    colors = None
    if all(name in fields for name in ("colorRed", "colorGreen", "colorBlue")):
        limits = fields["color_limits"].reshape(3, 2)
        span = limits[:, 1] - limits[:, 0]
        span = np.where(np.isfinite(span) & (span > 0), span, 255.0)
        low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], 0.0)
        rgb = np.column_stack([fields[name] for name in ("colorRed", "colorGreen", "colorBlue")])
        colors = np.clip((rgb - low) / span, 0.0, 1.0)
        if "isColorInvalid" in fields:
            colors[fields["isColorInvalid"] != 0] = DEFAULT_ALBEDO
        colors = colors[keep]
    intensity = None
    if "intensity" in fields:
        intensity = fields["intensity"].copy()
        if "isIntensityInvalid" in fields:
            intensity[fields["isIntensityInvalid"] != 0] = np.nan
        intensity = intensity[keep]
    return positions, colors, intensity


def _decode(path: Path, source: str) -> list[tuple[np.ndarray, np.ndarray | None, np.ndarray | None]]:
    """Every scan of the file (see :func:`_scan`), decoded by :data:`_E57_CHILD` in a child process
    (:func:`surfsplat.io.child.decoded_in_child`); its crash, abort, failure or hang is an InputError."""
    with decoded_in_child(_E57_CHILD, Path(path), source, "E57 file", args=(memory_limit(),)) as data:
        return [_scan(data, i, source) for i in range(int(data["scans"]))]
