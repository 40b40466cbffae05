"""PCD point clouds (the Point Cloud Library's format, version 0.7 and earlier headers).

A text header (``VERSION``, ``FIELDS``, ``SIZE``, ``TYPE``, ``COUNT``, ``WIDTH``, ``HEIGHT``,
``VIEWPOINT``, ``POINTS``, ``DATA``; ``#`` comments) followed by the points:

- ``DATA ascii``: one point per line, values separated by whitespace;
- ``DATA binary``: little-endian records, one per point, fields in header order;
- ``DATA binary_compressed`` (LZF, column-major): not supported; an InputError says so (convert
  with ``pcl_convert_pcd_ascii_binary <in> <out> 1``).

Fields read: ``x y z`` -> positions (required); ``normal_x normal_y normal_z`` (or ``nx ny
nz``) -> normals; ``rgb`` / ``rgba`` -> colors (the float32 or uint32 packs ``0x00RRGGBB`` /
``0xAARRGGBB``, as PCL writes them), or separate ``r g b`` / ``red green blue`` columns. Others
(``curvature``, ``intensity``, ``_`` padding, ...) are ignored. ``VIEWPOINT`` (the sensor pose)
is ignored, as PCL does when it draws the points. NaN points of organized clouds are dropped by
validation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError, file_reader

_TYPES = {("F", 4): "<f4", ("F", 8): "<f8", ("I", 1): "i1", ("I", 2): "<i2", ("I", 4): "<i4", ("I", 8): "<i8",
          ("U", 1): "u1", ("U", 2): "<u2", ("U", 4): "<u4", ("U", 8): "<u8"}
_KEYS = ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA")


@file_reader
def read_pcd(path: Path) -> SplatCloud:
    """Read a PCD file (see the module docstring) as an unvalidated SplatCloud.

    Raises InputError naming the file for a malformed or truncated header or body, unknown field
    types, ``binary_compressed`` data, or no ``x y z`` fields.
    """
    source = str(path)
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{source}: cannot read: {exc.strerror or exc}") from exc
    header, body_start = _header(raw, source)
    fields = header["FIELDS"]
    n_fields = len(fields)
    sizes = _ints(header.get("SIZE"), n_fields, "SIZE", source)
    counts = _ints(header.get("COUNT", ["1"] * n_fields), n_fields, "COUNT", source)
    types = header.get("TYPE")
    if types is None or len(types) != n_fields:
        raise InputError(f"{source}: PCD TYPE must name {n_fields} types, got {types}")
    dtype_fields = []
    for i, (name, size, kind, count) in enumerate(zip(fields, sizes, types, counts)):
        code = _TYPES.get((kind.upper(), size))
        if code is None:
            raise InputError(f"{source}: PCD field {name!r} has unknown TYPE {kind} SIZE {size}", element=name)
        unique = name if name != "_" else f"_pad{i}"
        dtype_fields.append((unique, code, (count,)) if count > 1 else (unique, code))
    dtype = np.dtype(dtype_fields)
    points = _ints(header.get("POINTS"), 1, "POINTS", source)[0] if "POINTS" in header else None
    if points is None:
        width = _ints(header.get("WIDTH"), 1, "WIDTH", source)[0]
        height = _ints(header.get("HEIGHT", ["1"]), 1, "HEIGHT", source)[0]
        points = width * height
    kind = header["DATA"][0].lower() if header.get("DATA") else ""
    if kind == "ascii":
        data = _ascii(raw[body_start:], dtype, points, source)
    elif kind == "binary":
        need = points * dtype.itemsize
        if len(raw) - body_start < need:
            raise InputError(f"{source}: PCD binary data truncated: {points} points need {need} bytes, "
                             f"{len(raw) - body_start} present")
        data = np.frombuffer(raw, dtype=dtype, count=points, offset=body_start)
    elif kind == "binary_compressed":
        raise InputError(f"{source}: PCD 'DATA binary_compressed' (LZF) is not supported; convert it to binary "
                         "or ascii first (e.g. pcl_convert_pcd_ascii_binary in.pcd out.pcd 1)")
    else:
        raise InputError(f"{source}: PCD DATA must be ascii, binary or binary_compressed, got {kind!r}")
    return _cloud(data, source)


def _header(raw: bytes, source: str) -> tuple[dict[str, list[str]], int]:
    header: dict[str, list[str]] = {}
    offset = 0
    while True:
        end = raw.find(b"\n", offset)
        if end < 0:
            raise InputError(f"{source}: not a PCD file: the header has no DATA line")
        try:
            line = raw[offset:end].decode("ascii").strip()
        except UnicodeDecodeError as exc:
            raise InputError(f"{source}: not a PCD file: the header is not text") from exc
        offset = end + 1
        if not line or line.startswith("#"):
            continue
        words = line.split()
        key = words[0].upper()
        if key not in _KEYS:
            raise InputError(f"{source}: not a PCD file: unexpected header line {line[:60]!r}")
        header[key] = words[1:]
        if key == "DATA":
            break
    if not header.get("FIELDS") or "x" not in header["FIELDS"]:
        raise InputError(f"{source}: PCD file has no x y z fields (FIELDS: {' '.join(header.get('FIELDS', []))})",
                         element="x")
    return header, offset


def _ints(words, n: int, key: str, source: str) -> list[int]:
    if words is None:
        raise InputError(f"{source}: PCD header has no {key} line", element=key)
    try:
        values = [int(w) for w in words]
    except ValueError as exc:
        raise InputError(f"{source}: PCD {key} must be integers, got {' '.join(words)}", element=key) from exc
    if len(values) != n or any(v < 0 for v in values):
        raise InputError(f"{source}: PCD {key} must be {n} non-negative integers, got {' '.join(words)}",
                         element=key)
    return values


def _ascii(body: bytes, dtype: np.dtype, points: int, source: str) -> np.ndarray:
    columns = sum(int(np.prod(dtype[name].shape)) or 1 for name in dtype.names or ())
    try:
        table = np.loadtxt(body.decode("ascii").splitlines(), dtype=np.float64, ndmin=2, comments="#")
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: malformed PCD ascii data: {exc}") from exc
    if table.size == 0:
        table = table.reshape(0, columns)
    if table.shape[1] != columns or len(table) < points:
        raise InputError(f"{source}: PCD ascii data has {len(table)} rows of {table.shape[1]} values; "
                         f"the header says {points} of {columns}")
    out = np.zeros(points, dtype=dtype)
    col = 0
    for name in dtype.names or ():
        width = int(np.prod(dtype[name].shape)) or 1
        values = table[:points, col:col + width]
        if name in ("rgb", "rgba") and dtype[name].kind == "f":
            # ascii PCD writes the packed colour as the float's value, or as the integer itself
            packed = values[:, 0]
            as_int = np.all((packed == np.round(packed)) & (packed >= 0)) and np.nanmax(packed, initial=0) > 1
            out[name] = (packed.astype(np.uint32).view(np.float32) if as_int else packed)
        else:
            out[name] = values.reshape(out[name].shape)
        col += width
    return out


def _cloud(data: np.ndarray, source: str) -> SplatCloud:
    names = set(data.dtype.names or ())

    def group(*names_):
        if not all(n in names for n in names_):
            if any(n in names for n in names_):
                raise InputError(f"{source}: PCD has {' '.join(n for n in names_ if n in names)} but not all of "
                                 f"{' '.join(names_)}", element=next(n for n in names_ if n not in names))
            return None
        return np.column_stack([np.asarray(data[n], dtype=np.float64).reshape(len(data), -1)[:, 0]
                                for n in names_])

    positions = group("x", "y", "z")
    normals = group("normal_x", "normal_y", "normal_z")
    if normals is None:
        normals = group("nx", "ny", "nz")
    colors = None
    packed_name = "rgb" if "rgb" in names else ("rgba" if "rgba" in names else None)
    if packed_name is not None:
        packed = np.ascontiguousarray(data[packed_name]).reshape(len(data), -1)[:, 0]
        bits = packed.view(np.uint32) if packed.dtype.itemsize == 4 else packed.astype(np.uint32)
        colors = np.column_stack([(bits >> 16) & 255, (bits >> 8) & 255, bits & 255]).astype(np.uint8)
    else:
        colors = group("r", "g", "b")
        if colors is None:
            colors = group("red", "green", "blue")
    return SplatCloud.from_arrays(positions, normals, colors)
