"""PLY point clouds, surfel models and triangle meshes (read and write, with plyfile).

Reading accepts ascii, binary_little_endian and binary_big_endian files. The
``vertex`` element's properties map to :class:`~surfsplat.cloud.SplatCloud`
arrays as follows (every group but ``x y z`` is optional, and a group must be
complete):

- ``x y z`` -> ``positions`` (required)
- ``nx ny nz`` -> ``normals``
- ``red green blue`` (``alpha`` ignored; or ``diffuse_red diffuse_green
  diffuse_blue``) -> ``colors``, scaled to [0, 1] as :func:`color_scale` says
- ``ux uy uz vx vy vz`` -> ``u``, ``v`` (elliptical splat axes)
- ``radius`` -> ``u``, ``v`` of a circular splat of that radius (Pointshop3D /
  MeshLab convention; needs normals, ignored with a warning without them;
  ``ux ...`` take precedence)
- ``alpha beta`` -> ``normal_field``
- ``clip0_a clip0_b clip0_c`` and optionally ``clip1_a clip1_b clip1_c`` ->
  ``clip_lines`` (a missing line is ``(0, 0, 1)``, keep everything)

``alpha`` alone is a color's opacity and is ignored; ``alpha`` together with
``beta`` is the linear normal field. Other numeric scalar properties
(``confidence``, ``intensity``, ...) become named attributes
(``SplatCloud.attributes``, dtype kept); writing stores them back.

A ``face`` element (list property ``vertex_indices`` or ``vertex_index``,
polygons triangulated as fans) makes the file a mesh; its vertices become the
splat centers. When a mesh stores no normals, each vertex gets the
area-weighted normal of its faces; vertices used by no face then have no
normal and are dropped by validation (the warning counts them as points with
zero-length normals).

The model's up axis (``SplatCloud.up``) is stored as a header comment ``comment surfsplat up X Y Z``
(:data:`UP_COMMENT`), written when the cloud has one and read back by every reader of the file.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement, PlyElementParseError, PlyParseError

from ..cloud import NO_CLIP, SplatCloud, checked_up
from ..errors import InputError, file_reader
from ..frames import tangent_frame
from .gaussians import cloud_from_gaussians, is_gaussian_ply
from .mesh import Mesh, area_weighted_normals, check_face_indices
from .atomic import atomic_path
from .ply_layout import check_body, check_consumed

#: Names of the face element's list property, in order of preference.
FACE_LIST_NAMES = ("vertex_indices", "vertex_index")

#: The header comment storing the model's up axis: ``comment surfsplat up 0 0 1``.
UP_COMMENT = "surfsplat up"

_CLIP_NAMES = tuple(f"clip{k}_{c}" for k in (0, 1) for c in "abc")


# -- reading ---------------------------------------------------------------


@file_reader
def read_elements(path: Path) -> dict[str, np.ndarray]:
    """Parse a PLY file into ``{element name: structured array}``, in file order.

    Every parse failure becomes an InputError naming the file and the problem.
    Scalar properties are fields of their type; a list property is an object
    field of arrays, or an (M, k) subarray field when all its lists have length
    k (binary triangle meshes are memory-mapped this way, and ascii files are
    read by NumPy's C parser when their rows are regular). Anything the fast
    readers do not accept is read by plyfile, which gives the error messages.
    """
    source = str(path)
    try:
        layout = check_body(path, source)  # the header's counts against the body's size
    except OSError as exc:
        raise InputError(f"{source}: cannot read PLY file: {exc.strerror or exc}") from exc
    try:
        fast = _read_ascii_fast(path)
    except MemoryError:
        raise
    except Exception:  # the fast reader only ever declines; plyfile decides
        fast = None
    if fast is not None:
        return fast
    try:
        known = {"face": {name: 3 for name in FACE_LIST_NAMES}}
        try:
            ply = PlyData.read(source, known_list_len=known)
        except PlyElementParseError as exc:
            if exc.message != "unexpected list length":
                raise
            ply = PlyData.read(source)  # polygons: variable-length lists
    except PlyParseError as exc:
        raise InputError(f"{source}: malformed PLY file: {exc}", **_parse_context(exc)) from exc
    except MemoryError:
        raise
    except OSError as exc:
        raise InputError(f"{source}: cannot read PLY file: {exc.strerror or exc}") from exc
    except Exception as exc:  # ValueError, EOFError, UnicodeDecodeError, struct errors, ...
        raise InputError(f"{source}: malformed PLY file: {type(exc).__name__}: {exc}") from exc
    elements = {element.name: element.data for element in ply.elements}
    check_consumed(layout, elements, source)
    return elements


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_LIST_LENGTH_SUFFIX = "\nlen"


def _read_ascii_fast(path: Path) -> dict[str, np.ndarray] | None:
    """Read a regular ascii PLY with ``numpy.loadtxt`` (C speed), or None to decline.

    Declines (returns None) for binary files, any header it does not fully
    understand, elements with more than one list property or lists of varying
    length, and any row that does not parse exactly (plyfile then reads the
    file and reports the problem).
    """
    with open(path, "rb") as stream:
        head = b""
        while b"end_header" not in head:
            block = stream.read(1 << 16)
            if not block or len(head) > (1 << 22):
                return None
            head += block
        end = head.index(b"end_header")
        eol = head.find(b"\n", end)
        if eol < 0 or head[end:eol].strip() != b"end_header":
            return None
        lines = [line.strip() for line in head[:end].decode("ascii").splitlines()]
        if len(lines) < 2 or lines[0] != "ply" or lines[1].split() != ["format", "ascii", "1.0"]:
            return None
        elements: list[tuple[str, int, list[tuple]]] = []
        for line in lines[2:]:
            words = line.split()
            if not words or words[0] in ("comment", "obj_info"):
                continue
            if words[0] == "element" and len(words) == 3 and words[2].isdigit():
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property" and elements and len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
            elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
                  and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES):
                elements[-1][2].append((words[4], _PLY_TYPES[words[2]], _PLY_TYPES[words[3]]))
            else:
                return None
        stream.seek(0)
        raw = stream.read()
    body = eol + 1
    newlines = _newline_offsets(raw, body)
    line_end = np.concatenate([newlines, [len(raw)]]) if not raw.endswith(b"\n") else newlines
    line_start = np.concatenate([[body], line_end[:-1] + 1])
    out: dict[str, np.ndarray] = {}
    first = 0  # first line of the current element
    for name, count, props in elements:
        if name in out or len({p[0] for p in props}) != len(props):
            return None
        lists = [p for p in props if len(p) == 3]
        if count == 0:
            out[name] = np.empty(0, dtype=[(p[0], p[1] if len(p) == 2 else object) for p in props])
            continue
        if first + count > len(line_start) or len(lists) > 1:
            return None
        chunk = raw[int(line_start[first]):int(line_end[first + count - 1])]
        dtype = []
        if lists:
            tokens = len(raw[int(line_start[first]):int(line_end[first])].split())
            k = tokens - len(props)  # list length: its count token is one of len(props)
            if k < 1:
                return None
            for prop in props:
                if len(prop) == 3:
                    dtype += [(prop[0] + _LIST_LENGTH_SUFFIX, prop[1]), (prop[0], prop[2], (k,))]
                else:
                    dtype.append(prop)
        else:
            dtype = list(props)
        try:
            data = np.loadtxt(io.BytesIO(chunk), dtype=np.dtype(dtype), comments=None,
                              ndmin=1, encoding="ascii")
        except ValueError:
            return None
        if len(data) != count:  # blank lines are skipped by loadtxt, not by PLY
            return None
        if lists:
            length = lists[0][0] + _LIST_LENGTH_SUFFIX
            if not np.all(data[length] == k):
                return None
            data = data[[p[0] for p in props]]
        out[name] = data
        first += count
    return out


def _newline_offsets(raw: bytes, start: int) -> np.ndarray:
    """(L,) int64 offsets of the b"\\n" bytes of ``raw`` from ``start`` on (chunked)."""
    step = 1 << 26
    parts = [np.zeros(0, dtype=np.int64)]
    for offset in range(start, len(raw), step):
        block = np.frombuffer(raw, dtype=np.uint8, count=min(step, len(raw) - offset), offset=offset)
        parts.append(np.flatnonzero(block == 10).astype(np.int64) + offset)
    return np.concatenate(parts)


@file_reader
def read_ply(path: Path) -> SplatCloud:
    """Read a PLY point cloud, surfel model or mesh as an (unvalidated) SplatCloud.

    See the module docstring for the property names. Returns positions
    (N, 3) float32 model space, and where the file has them normals (N, 3),
    colors (N, 3) in [0, 1], u, v (N, 3) model units, normal_field (N, 2),
    clip_lines (N, 2, 3). The caller runs ``validated``.
    """
    return with_stored_up(cloud_from_elements(read_elements(path), str(path)), path)


def ply_up(path) -> tuple[float, float, float] | None:
    """The up axis stored in a PLY header (``comment surfsplat up X Y Z``, see :data:`UP_COMMENT`), or
    None when the header has none (or ``path`` is no readable PLY header). Reads the header only.
    InputError for a malformed up comment."""
    try:
        with open(path, "rb") as stream:
            head = stream.read(1 << 16)
    except OSError:
        return None
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return None
    for line in head[:end].decode("ascii", "replace").splitlines():
        words = line.split()
        if words[:1] == ["comment"] and " ".join(words[1:3]) == UP_COMMENT:
            try:
                return checked_up([float(x) for x in words[3:]])
            except (ValueError, InputError):
                raise InputError(f"{path}: malformed up comment {line.strip()!r} (expected "
                                 f"'comment {UP_COMMENT} X Y Z')") from None
    return None


def with_stored_up(data, path):
    """``data`` (a SplatCloud or a Mesh read from ``path``) with the up axis stored in its header
    (:func:`ply_up`); a Mesh is returned as it is (meshes carry no up)."""
    if isinstance(data, SplatCloud):
        up = ply_up(path)
        if up is not None:
            data.up = up
    return data


@file_reader
def read_ply_input(path: Path) -> Mesh | SplatCloud:
    """Read a PLY file, parsed once, as a :class:`Mesh` when it has a non-empty ``face``
    element, else as a SplatCloud (:func:`read_ply`); both unvalidated."""
    source = str(path)
    elements = read_elements(path)
    if "face" in elements and len(elements["face"]):
        return mesh_from_elements(elements, source)
    return with_stored_up(cloud_from_elements(elements, source), path)


def cloud_from_elements(elements: dict[str, np.ndarray], source: str) -> SplatCloud:
    """The SplatCloud of parsed PLY elements (:func:`read_elements`); see :func:`read_ply`."""
    data = _vertex_element(elements, source)
    names = set(data.dtype.names or ())
    if is_gaussian_ply(names):  # a trained 3DGS / 2DGS model: see surfsplat.io.gaussians
        return cloud_from_gaussians(data, source)

    # float64 world coordinates: the SplatCloud keeps them relative to an origin where they sit far out
    positions = _positions(data, names, source)
    normals = _group(data, names, ("nx", "ny", "nz"), source)
    colors = read_colors(data, names, source)

    faces = read_faces(elements, len(data), source)
    if normals is None and faces is not None and len(faces):
        normals = area_weighted_normals(positions, faces)

    u = _group(data, names, ("ux", "uy", "uz"), source)
    v = _group(data, names, ("vx", "vy", "vz"), source)
    if (u is None) != (v is None):
        missing = "vx vy vz" if v is None else "ux uy uz"
        raise InputError(f"{source}: vertex has {'ux uy uz' if v is None else 'vx vy vz'} "
                         f"but not {missing}; splat axes need both", element="vertex." + missing.split()[0])
    if u is None and "radius" in names:
        if normals is None:
            warnings.warn(f"{source}: 'radius' ignored because the points have no normals "
                          "(a circular splat needs a normal to orient it)", UserWarning, stacklevel=4)
        else:
            u, v = circular_axes(normals, _column(data, "radius"))

    normal_field = None
    if "beta" in names:
        normal_field = _group(data, names, ("alpha", "beta"), source)

    clip_lines = None
    if names & set(_CLIP_NAMES):
        lines = []
        for k in (0, 1):
            line = _group(data, names, tuple(f"clip{k}_{c}" for c in "abc"), source)
            lines.append(np.broadcast_to(NO_CLIP, (len(data), 3)) if line is None else line)
        clip_lines = np.stack(lines, axis=1)

    return SplatCloud(positions=positions, normals=normals, colors=colors, u=u, v=v,
                      normal_field=normal_field, clip_lines=clip_lines,
                      attributes=_extra_properties(data) or None)


#: Vertex properties that are arrays of the SplatCloud, not attributes.
_KNOWN_PROPERTIES = frozenset(("x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "alpha",
                               "diffuse_red", "diffuse_green", "diffuse_blue", "ux", "uy", "uz",
                               "vx", "vy", "vz", "radius", "beta") + _CLIP_NAMES)


def _extra_properties(data: np.ndarray) -> dict[str, np.ndarray]:
    """The vertex element's other numeric scalar properties, by name (list properties skipped)."""
    return {name: np.ascontiguousarray(data[name]) for name in data.dtype.names or ()
            if name.lower() not in _KNOWN_PROPERTIES and data.dtype[name].kind in "uif"
            and data.dtype[name].shape == ()}


@file_reader
def read_ply_mesh(path: Path) -> Mesh:
    """Read a PLY file with a ``face`` element as an (unvalidated) :class:`Mesh`.

    Vertices from ``x y z``, normals from ``nx ny nz`` (None if absent), colors
    from ``red green blue`` (None if absent), faces fan-triangulated. Raises
    InputError naming the file when it has no faces.
    """
    return mesh_from_elements(read_elements(path), str(path))


def mesh_from_elements(elements: dict[str, np.ndarray], source: str) -> Mesh:
    """The Mesh of parsed PLY elements (:func:`read_elements`); see :func:`read_ply_mesh`."""
    data = _vertex_element(elements, source)
    names = set(data.dtype.names or ())
    vertices = _positions(data, names, source)
    faces = read_faces(elements, len(data), source)
    if faces is None or len(faces) == 0:
        raise InputError(f"{source}: PLY file has no faces; it is a point cloud, not a mesh", element="face")
    return Mesh(vertices=vertices, faces=faces,
                vertex_normals=_group(data, names, ("nx", "ny", "nz"), source),
                vertex_colors=read_colors(data, names, source))


def read_faces(elements: dict[str, np.ndarray], n_vertices: int, source: str) -> np.ndarray | None:
    """(F, 3) int64 triangles from the ``face`` element, or None without one.

    Polygons with k > 3 corners become k - 2 triangles ``(p0, p_i, p_i+1)``.
    Raises InputError for faces with fewer than 3 corners or out-of-range
    indices.
    """
    if "face" not in elements:
        return None
    face = elements["face"]
    names = face.dtype.names or ()
    prop = next((name for name in FACE_LIST_NAMES if name in names), None)
    if prop is None:
        raise InputError(f"{source}: face element has no 'vertex_indices' (or 'vertex_index') "
                         f"list property (it has: {', '.join(names) or 'none'})", element="face")
    column = face[prop]
    if len(column) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if column.dtype != object:  # fixed-length lists: (F, k)
        fixed = np.asarray(column, dtype=np.int64).reshape(len(column), -1)
        lengths = np.full(len(fixed), fixed.shape[1], dtype=np.int64)
        flat = fixed.ravel()
    else:  # plyfile's object array of per-face arrays
        lengths = np.fromiter(map(len, column), dtype=np.int64, count=len(column))
        flat = None
    short = lengths < 3
    if short.any():
        row = int(np.argmax(short))
        raise InputError(f"{source}: face {row} has {lengths[row]} vertices; faces need at least 3 "
                         f"({int(short.sum())} such faces)", element="face." + prop, row=row)
    if flat is None:
        flat = np.concatenate(list(column)).astype(np.int64)
    triangles = fan_triangulate(flat, lengths)
    check_face_indices(triangles, n_vertices, source)
    return triangles


def fan_triangulate(flat: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Triangulate polygons as fans, vectorized.

    Args:
        flat: (sum(lengths),) int64 concatenated polygon corner indices.
        lengths: (P,) int64 corner counts, each >= 3.

    Returns:
        (sum(lengths - 2), 3) int64 triangles ``(p0, p_i, p_i+1)``, i = 1..k-2,
        polygon by polygon.
    """
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    per = lengths - 2
    if np.all(per == 1):
        return flat.reshape(-1, 3)
    owner_start = np.repeat(starts, per)
    tri_first = np.concatenate([[0], np.cumsum(per)[:-1]])
    i = np.arange(int(per.sum())) - np.repeat(tri_first, per) + 1  # 1 .. k-2 within each polygon
    return np.column_stack([flat[owner_start], flat[owner_start + i], flat[owner_start + i + 1]])


def color_scale(values: np.ndarray) -> float:
    """The divisor that maps a PLY color column to [0, 1].

    - uchar (uint8): 255; ushort (uint16): 65535.
    - other integer types: 255 if the largest value is <= 255, 65535 if it is
      <= 65535, else the type's maximum.
    - float: 1 (colors already in [0, 1]), except that a largest finite value
      above 1 means the file stores 0..255 floats, so 255.
    """
    dtype = values.dtype
    if dtype.kind in "ui":
        if dtype.itemsize == 1 and dtype.kind == "u":
            return 255.0
        if dtype.itemsize == 2 and dtype.kind == "u":
            return 65535.0
        top = int(values.max()) if len(values) else 0
        if top <= 255:
            return 255.0
        if top <= 65535:
            return 65535.0
        return float(np.iinfo(dtype).max)
    finite = values[np.isfinite(values)]
    return 255.0 if finite.size and float(finite.max()) > 1.0 else 1.0


def read_colors(data: np.ndarray, names: set[str], source: str) -> np.ndarray | None:
    """(N, 3) float32 colors from ``red green blue`` (or ``diffuse_red ...``), or None.

    One divisor for the three channels, chosen by :func:`color_scale` from
    their type and their largest value (mixed types are decided as floats).
    """
    for group in (("red", "green", "blue"), ("diffuse_red", "diffuse_green", "diffuse_blue")):
        if any(name in names for name in group):
            break
    else:
        return None
    _require(names, group, source)
    stacked = np.column_stack([np.asarray(data[name]) for name in group])
    kinds = {np.asarray(data[name]).dtype for name in group}
    if len(kinds) == 1:
        scale = color_scale(stacked.ravel())
    else:  # mixed types: decide on the common float values
        scale = color_scale(stacked.astype(np.float64).ravel())
    return (stacked.astype(np.float64) / scale).astype(np.float32)


def circular_axes(normals: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent axes u, v of circular splats: (N, 3) float32 each, |u| = |v| = radius.

    ``u``, ``v`` and the unit normal form a right-handed orthogonal frame
    (``u x v`` along ``n``; :func:`surfsplat.frames.tangent_frame`).
    Zero-length or non-finite normals give NaN axes and non-positive or
    non-finite radii give zero axes; validation drops both.
    """
    n = np.asarray(normals, dtype=np.float64)
    r = np.asarray(radius, dtype=np.float64)
    length = np.linalg.norm(n, axis=1)
    ok = np.isfinite(length) & (length > 0)
    t1 = np.full(n.shape, np.nan)
    t2 = np.full(n.shape, np.nan)
    if ok.any():
        t1[ok], t2[ok] = tangent_frame(n[ok])
    r = np.where(np.isfinite(r) & (r > 0), r, 0.0)[:, None]
    return (t1 * r).astype(np.float32), (t2 * r).astype(np.float32)


def _parse_context(exc: PlyParseError) -> dict:
    """``element`` ("vertex" or "vertex.x": element and property) and ``row`` of a plyfile parse error."""
    element, prop = getattr(exc, "element", None), getattr(exc, "prop", None)
    name = None if element is None else element.name + ("" if prop is None else "." + prop.name)
    return {"element": name, "row": getattr(exc, "row", None)}


def _vertex_element(elements: dict[str, np.ndarray], source: str) -> np.ndarray:
    if "vertex" not in elements:
        present = ", ".join(elements) or "none"
        raise InputError(f"{source}: PLY file has no 'vertex' element (elements: {present})", element="vertex")
    return elements["vertex"]


def _column(data: np.ndarray, name: str) -> np.ndarray:
    return np.asarray(data[name], dtype=np.float64)


def _require(names: set[str], group: tuple[str, ...], source: str) -> None:
    missing = [name for name in group if name not in names]
    if missing:
        have = [name for name in group if name in names]
        raise InputError(f"{source}: vertex has {' '.join(have) or 'none of ' + ' '.join(group)} but is "
                         f"missing {' '.join(missing)}", element="vertex." + missing[0])


def _group(data: np.ndarray, names: set[str], group: tuple[str, ...], source: str,
           required: bool = False, dtype=np.float32) -> np.ndarray | None:
    """(N, len(group)) ``dtype`` from scalar vertex properties, or None if absent."""
    if not required and not any(name in names for name in group):
        return None
    _require(names, group, source)
    for name in group:
        if data.dtype[name].kind not in "uif":
            raise InputError(f"{source}: vertex property {name!r} must be a number, not a list",
                             element="vertex." + name)
    return np.column_stack([_column(data, name) for name in group]).astype(dtype, copy=False)


def _positions(data: np.ndarray, names: set[str], source: str) -> np.ndarray:
    """(N, 3) float64 x, y, z of the vertex element (InputError naming the missing ones)."""
    positions = _group(data, names, ("x", "y", "z"), source, required=True, dtype=np.float64)
    assert positions is not None   # required
    return positions


# -- writing ---------------------------------------------------------------


def write_ply(cloud: SplatCloud, path: Path, *, binary: bool = True, overwrite: bool = True) -> Path:
    """Write ``cloud`` as a PLY ``vertex`` element; see ``surfsplat.io.save_ply``."""
    path = Path(path)
    columns = ply_columns(cloud)
    dtype = [(name, values.dtype.str.lstrip("<>=|")) for name, values in columns]
    records = np.empty(len(cloud), dtype=dtype)
    for name, values in columns:
        records[name] = values
    element = PlyElement.describe(records, "vertex")
    comments = ["written by surfsplat"]
    if cloud.up is not None:
        comments.append(f"{UP_COMMENT} " + " ".join(repr(float(x)) for x in cloud.up))
    ply = PlyData([element], text=not binary, byte_order="<", comments=comments)
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a file")
    try:  # through a temporary file beside ``path``: a failed write leaves no partial file, an old one intact
        with atomic_path(path, overwrite=overwrite) as temp, open(temp, "wb") as stream:
            if binary:
                ply.write(stream)
            else:  # plyfile writes ascii row by row with one savetxt call each: slow
                stream.write(ply.header.encode("ascii") + b"\n")
                fmt = ["%d" if values.dtype.kind in "ui" else "%.9g" for _, values in columns]
                np.savetxt(stream, np.column_stack([values.astype(np.float64) for _, values in columns]),
                           fmt=fmt, delimiter=" ", newline="\n")
    except OSError as exc:
        raise InputError(f"{path}: cannot write PLY file: {exc.strerror or exc}") from exc
    return path


def ply_columns(cloud: SplatCloud) -> list[tuple[str, np.ndarray]]:
    """The (name, (N,) array) columns :func:`write_ply` writes, in file order.

    Colors are clipped to [0, 1] and written as uchar when every value is
    exactly ``k / 255`` as float32 (so reading divides back to the same
    float32), else as float32. Positions of a cloud with a non-zero origin are written as double
    world coordinates (``origin + positions``); everything else is float32.
    """
    f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    if cloud.origin.any():
        world = cloud.world_positions()
        columns = [(name, np.ascontiguousarray(world[:, k])) for k, name in enumerate("xyz")]
    else:
        columns = [(name, f32(cloud.positions[:, k])) for k, name in enumerate("xyz")]
    if cloud.normals is not None:
        columns += [(name, f32(cloud.normals[:, k])) for k, name in enumerate(("nx", "ny", "nz"))]
    if cloud.colors is not None:
        colors = np.clip(cloud.colors, 0.0, 1.0)
        with np.errstate(invalid="ignore"):
            k255 = np.rint(np.nan_to_num(colors) * 255.0)
        exact = np.array_equal((k255.astype(np.float64) / 255.0).astype(np.float32), colors)
        if exact:
            columns += [(name, k255[:, k].astype(np.uint8)) for k, name in enumerate(("red", "green", "blue"))]
        else:
            columns += [(name, f32(colors[:, k])) for k, name in enumerate(("red", "green", "blue"))]
    if cloud.u is not None and cloud.v is not None:
        columns += [(name, f32(cloud.u[:, k])) for k, name in enumerate(("ux", "uy", "uz"))]
        columns += [(name, f32(cloud.v[:, k])) for k, name in enumerate(("vx", "vy", "vz"))]
    if cloud.normal_field is not None:
        columns += [("alpha", f32(cloud.normal_field[:, 0])), ("beta", f32(cloud.normal_field[:, 1]))]
    if cloud.clip_lines is not None:
        columns += [(f"clip{k}_{c}", f32(cloud.clip_lines[:, k, j])) for k in (0, 1) for j, c in enumerate("abc")]
    taken = {name for name, _ in columns}
    for name, values in (cloud.attributes or {}).items():  # PLY has no 64-bit integers: float64
        if name not in taken and name.isidentifier():
            wide = values.dtype.kind in "ui" and values.dtype.itemsize == 8
            columns.append((name, values.astype(np.float64) if wide else np.ascontiguousarray(values)))
    return columns


__all__ = ["read_ply", "read_ply_mesh", "ply_up", "UP_COMMENT", "read_elements", "read_faces", "write_ply",
           "fan_triangulate", "color_scale", "read_colors", "circular_axes", "ply_columns"]
