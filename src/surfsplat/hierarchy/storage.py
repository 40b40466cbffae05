"""One-file storage of a :class:`~surfsplat.hierarchy.model.Hierarchy`.

The file is an uncompressed NumPy ``.npz`` archive (a zip of ``.npy``
arrays, loaded without pickle) holding, besides the arrays of
:meth:`Hierarchy.arrays <surfsplat.hierarchy.model.Hierarchy.arrays>`:

- ``format``: the string ``"surfsplat-hierarchy"``,
- ``format_version``: int, :data:`FORMAT_VERSION` (files of a newer version are refused),
- ``leaf_capacity``, ``max_depth``: ints, the build parameters.

Arrays (M nodes, N points, L levels): ``order`` (N,) int64, ``level_offsets``
(L + 1,) int64, ``origin`` (3,) float64; node arrays ``node_positions``,
``node_normals``, ``node_u``, ``node_v`` (M, 3) float32, ``node_colors`` (M, 3)
float32 (optional), ``node_normal_field`` (M, 2) float32, ``node_radius``,
``node_cone``, ``node_extent`` (M,) float32, ``node_covariance`` (M, 10) float64,
``node_point_start``, ``node_point_count``, ``node_child_start``,
``node_child_count`` (M,) int64; point arrays (the reordered SplatCloud)
``point_positions``, ``point_normals``, ``point_u``, ``point_v`` (N, 3)
float32, optional ``point_colors`` (N, 3), ``point_normal_field`` (N, 2),
``point_clip_lines`` (N, 2, 3) float32; ``point_origin`` (3,) float64, the world position of
the points' zero (world coordinates are ``point_origin + point_positions``; files without it,
written before it existed, load with the origin at zero); ``point_up`` (3,) float64, optional: the
model's up axis (``SplatCloud.up``; absent where it is unknown and in older files).

Compact files (``save_hierarchy(..., compact=True)``, ``surfsplat build --compact``) have
``format_version`` :data:`COMPACT_VERSION` and store the splats of the nodes and of the points
quantized, 19 bytes a splat (:mod:`surfsplat.io.splat_codec`, the web viewer's format): for each prefix
``node_`` and ``point_``, instead of ``positions``, ``normals``, ``u``, ``v`` and ``colors``,
``q_position`` (K, 3) uint16, ``q_normal`` (K, 2) uint16, ``q_angle`` (K,) uint16, ``q_radii`` (K, 2)
uint16, optional ``q_color`` (K, 3) uint8, and the codes' ranges ``q_box`` (2, 3) float64 (the positions'
bounding box) and ``q_log_radius`` (2,) float64. ``node_covariance`` is left out (:func:`load_hierarchy`
sums it again over the decoded points, :func:`node_covariances`) and ``order``, ``node_point_start``,
``node_point_count``, ``node_child_start``, ``node_child_count`` are int32. Every other member is as in a
full file. :func:`load_hierarchy`
decodes them to the full arrays (float32): both layouts load the same way. The layout holds splats whose
normal is their plane's (``u`` and ``v`` at right angles to it): Phong splats, whose shading normal tilts
off the plane, are refused.

Per-point attributes (LAS dimensions, extra PLY properties, ``nonplanar``), optional: for each
attribute NAME, ``point_attribute:NAME`` (N,) in the points' order and ``node_attribute:NAME``
(M,), both of the attribute's numeric dtype (the node values: majority vote of integer columns,
mean of floating-point ones, see :class:`~surfsplat.hierarchy.model.Hierarchy`). Files written
before attributes were kept have none and load without them; older readers ignore them.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..cloud import SplatCloud, checked_up
from ..errors import InputError, error_context
from ..io.atomic import atomic_path, check_readable
from ..io import splat_codec
from ..io.npz import read_npz
from .model import FORMAT_VERSION, NODE_ATTRIBUTE, POINT_ATTRIBUTE, Hierarchy
from .nodes import COVARIANCE_ENTRIES

#: Value of the ``format`` member. The layout's version, :data:`FORMAT_VERSION`, is
#: defined with the arrays in :mod:`~surfsplat.hierarchy.model`.
FORMAT = "surfsplat-hierarchy"

#: ``format_version`` of compact files (quantized splats; full files keep :data:`FORMAT_VERSION`, so
#: readers of that version still read them).
COMPACT_VERSION = FORMAT_VERSION + 1
#: The splat arrays a compact file quantizes (for the nodes and the points), by their code streams.
QUANTIZED = ("positions", "normals", "u", "v", "colors")
#: Largest ``|n . axis| / |axis|`` of a splat the compact layout holds (a normal at right angles to u and v).
PLANAR_TOLERANCE = 1e-3
#: Index arrays a compact file stores as int32 (where the counts allow; int64 in memory).
NARROWED = ("order", "node_point_start", "node_point_count", "node_child_start", "node_child_count")
#: code stream -> (dtype, shape after the first axis, required)
_Q_SPEC: dict[str, tuple[Any, tuple[int, ...], bool]] = {
    "position": (np.uint16, (3,), True), "normal": (np.uint16, (2,), True), "angle": (np.uint16, (), True),
    "radii": (np.uint16, (2,), True), "color": (np.uint8, (3,), False)}

__all__ = ["COMPACT_VERSION", "FORMAT", "FORMAT_VERSION", "save_hierarchy", "load_hierarchy", "hierarchy_up"]

#: name -> (dtype, shape after the first axis, first axis: "nodes", "points", "levels+1" or a number, required)
_SPEC: dict[str, tuple[Any, tuple[int, ...], str | int, bool]] = {
    "order": (np.int64, (), "points", True),
    "level_offsets": (np.int64, (), "levels+1", True),
    "origin": (np.float64, (), 3, True),
    "node_positions": (np.float32, (3,), "nodes", True),
    "node_normals": (np.float32, (3,), "nodes", True),
    "node_colors": (np.float32, (3,), "nodes", False),
    "node_u": (np.float32, (3,), "nodes", True),
    "node_v": (np.float32, (3,), "nodes", True),
    "node_normal_field": (np.float32, (2,), "nodes", True),
    "node_radius": (np.float32, (), "nodes", True),
    "node_cone": (np.float32, (), "nodes", True),
    "node_extent": (np.float32, (), "nodes", True),
    "node_covariance": (np.float64, (10,), "nodes", False),   # absent from compact files (rebuilt on load)
    "node_point_start": (np.int64, (), "nodes", True),
    "node_point_count": (np.int64, (), "nodes", True),
    "node_child_start": (np.int64, (), "nodes", True),
    "node_child_count": (np.int64, (), "nodes", True),
    "point_positions": (np.float32, (3,), "points", True),
    "point_normals": (np.float32, (3,), "points", True),
    "point_colors": (np.float32, (3,), "points", False),
    "point_u": (np.float32, (3,), "points", True),
    "point_v": (np.float32, (3,), "points", True),
    "point_normal_field": (np.float32, (2,), "points", False),
    "point_clip_lines": (np.float32, (2, 3), "points", False),
    "point_origin": (np.float64, (), 3, False),   # world position of the points' zero; absent in older files
    "point_up": (np.float64, (), 3, False),   # the model's up axis; absent where unknown and in older files
}


def save_hierarchy(hierarchy: Hierarchy, path, *, overwrite: bool = True, compact: bool = False) -> Path:
    """Write a hierarchy to one uncompressed ``.npz`` file (see the module docstring) and return its Path.

    With ``compact``, the splats of the nodes and the points (positions, normals, axes, colours) are
    stored quantized, 19 bytes a splat instead of 60 (:data:`COMPACT_VERSION`); :func:`load_hierarchy`
    reads both layouts.

    The name is used as given (no extension is added; ``.npz`` is the
    convention). An existing file is replaced unless ``overwrite=False``.
    Every write goes to a temporary file beside ``path`` that replaces it on success
    (:func:`surfsplat.io.atomic.atomic_path`): a failed write (disk full, file size
    limit) leaves no partial file and an existing file as it was.

    Raises:
        InputError: the file exists (with ``overwrite=False``), is a directory,
            or cannot be written; ``compact`` with splats whose normal is not their plane's (Phong
            splats); the message names the file.
    """
    path = Path(path)
    if not isinstance(hierarchy, Hierarchy):
        raise InputError(f"{path}: save_hierarchy needs a Hierarchy, got {type(hierarchy).__name__}")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, not a file")
    members: dict[str, Any] = dict(hierarchy.arrays())
    members["format"] = np.array(FORMAT)
    members["format_version"] = np.array(FORMAT_VERSION, dtype=np.int64)
    members["leaf_capacity"] = np.array(hierarchy.leaf_capacity, dtype=np.int64)
    members["max_depth"] = np.array(hierarchy.max_depth, dtype=np.int64)
    members["point_origin"] = np.asarray(hierarchy.points.origin, dtype=np.float64)
    if hierarchy.points.up is not None:
        members["point_up"] = np.asarray(hierarchy.points.up, dtype=np.float64)
    if compact:
        members["format_version"] = np.array(COMPACT_VERSION, dtype=np.int64)
        for prefix in ("node_", "point_"):
            members.update(_quantized(members, prefix, path))
        del members["node_covariance"]   # rebuilt from the decoded points on load (Pajarola 2003, EQ 2, 4)
        if len(hierarchy.points) < 2**31:
            members.update({name: np.asarray(members[name]).astype(np.int32) for name in NARROWED})
    try:  # through a temporary file beside ``path``: a failed write leaves no partial file, an old one intact
        with atomic_path(path, overwrite=overwrite) as temp, open(temp, "wb") as handle:
            np.savez(handle, **members)
    except OSError as exc:
        raise InputError(f"{path}: cannot write: {exc.strerror or exc}") from None
    return path


def load_hierarchy(path) -> Hierarchy:
    """Read a hierarchy written by :func:`save_hierarchy`, validating it.

    Raises:
        InputError naming the file: missing, a directory, not an ``.npz``
            archive, corrupt (truncated, bad checksums), not a surfsplat
            hierarchy, a newer format version, missing or malformed arrays
            (dtypes, shapes, counts), non-finite values, or inconsistent
            structure (levels, child or point ranges out of bounds).
    """
    path = check_readable(path)  # a regular file: no FIFO, device or folder
    source = str(path)
    with error_context(file=path):
        # np.load guesses the format from the first bytes and reads anything else as a pickle, whose
        # error ("load it unsafely ...") misleads: a hierarchy is a zip (.npz) archive, check that first.
        if not zipfile.is_zipfile(path):
            raise InputError(f"{path}: not a surfsplat hierarchy file (not an .npz archive, or truncated)")
        # sizes checked before anything is inflated (a zip bomb, a header declaring a terabyte shape)
        return _from_members(read_npz(path, None, source), source)


def hierarchy_up(path) -> tuple[float, float, float] | None:
    """The up axis stored in a hierarchy file (its ``point_up`` member), or None where it has none or
    is not a readable ``.npz`` archive. Reads that member only (:func:`~surfsplat.io.npz.read_npz`)."""
    try:
        up = read_npz(path, ("point_up",)).get("point_up")
    except InputError:
        return None
    return checked_up(up) if up is not None and up.shape == (3,) and up.dtype.kind == "f" else None


def _quantized(members: dict[str, Any], prefix: str, path: Path) -> dict[str, np.ndarray]:
    """The code members of the splats ``prefix + QUANTIZED`` (popped from ``members``)."""
    arrays = {name: members.pop(prefix + name, None) for name in QUANTIZED}
    normals, u, v = (np.asarray(arrays[k], np.float64) for k in ("normals", "u", "v"))
    for axis in (u, v):
        length = np.linalg.norm(axis, axis=1)
        off = np.abs(np.einsum("ij,ij->i", normals, axis)) > PLANAR_TOLERANCE * np.maximum(length, 1e-30)
        if off.any():
            raise InputError(f"{path}: a compact hierarchy stores splats whose normal is their plane's; "
                             f"{int(off.sum()):,} {prefix[:-1]} splats have a shading normal off their plane "
                             f"(Phong splats): save it without compact", row=int(np.argmax(off)))
    colors = arrays["colors"]
    streams, header = splat_codec.encode(arrays["positions"], normals, np.zeros((len(u), 3)) if colors is None
                                         else colors, u, v)
    # the codes keep an axis up to its sign (an ellipse is symmetric): where the decoded u or v points the
    # other way, the splat's s or t runs the other way, so the normal field's alpha or beta (Botsch 2004,
    # eq. 2) and the clip lines' a or b change sign with it
    su, sv = splat_codec.axis_signs(streams, header, u, v)
    out: dict[str, np.ndarray] = {}
    if members.get(prefix + "normal_field") is not None:
        field = np.array(members[prefix + "normal_field"], dtype=np.float32)
        field *= np.stack([su, sv], axis=1).astype(np.float32)
        out[prefix + "normal_field"] = field
    if members.get(prefix + "clip_lines") is not None:
        lines = np.array(members[prefix + "clip_lines"], dtype=np.float32)
        lines[:, :, 0] *= su[:, None].astype(np.float32)
        lines[:, :, 1] *= sv[:, None].astype(np.float32)
        out[prefix + "clip_lines"] = lines
    out.update({f"{prefix}q_{name}": value for name, value in streams.items() if name != "color" or colors is not None})
    out[f"{prefix}q_box"] = np.array([header["lo"], header["hi"]], dtype=np.float64)
    out[f"{prefix}q_log_radius"] = np.array(header["log_radius"], dtype=np.float64)
    return out


def _dequantized(members: dict[str, np.ndarray], source: str) -> dict[str, np.ndarray]:
    """``members`` of a compact file with the splats of the nodes and points decoded (float32)."""
    out = dict(members)
    for prefix in ("node_", "point_"):
        streams: dict[str, np.ndarray] = {}
        rows = None
        for name, (dtype, tail, required) in _Q_SPEC.items():
            key = f"{prefix}q_{name}"
            if key not in members:
                if required:
                    raise InputError(f"{source}: compact hierarchy without array '{key}'", element=key)
                continue
            value = members[key]
            rows = len(value) if rows is None and value.ndim >= 1 else rows
            if value.dtype != dtype or value.shape != (rows,) + tail:
                raise InputError(f"{source}: array '{key}' has dtype {value.dtype} and shape {value.shape}, "
                                 f"expected {np.dtype(dtype)} {(rows,) + tail}", element=key)
            streams[name] = out.pop(key)
        ranges = {}
        for name, shape in (("box", (2, 3)), ("log_radius", (2,))):
            key = f"{prefix}q_{name}"
            span = out.pop(key) if key in out else None
            if span is None or span.shape != shape or span.dtype.kind != "f" or not np.isfinite(span).all():
                raise InputError(f"{source}: compact hierarchy with a missing or malformed '{key}'", element=key)
            ranges[name] = span
        decoded = splat_codec.decode({"color": np.zeros((rows or 0, 3), np.uint8), **streams},
                                     {"lo": ranges["box"][0], "hi": ranges["box"][1],
                                      "log_radius": tuple(ranges["log_radius"])})
        for name in ("positions", "normals", "u", "v") + (("colors",) if "color" in streams else ()):
            out[prefix + name] = decoded[name].astype(np.float32)
    for name in NARROWED:
        if name in out and out[name].dtype == np.int32:
            out[name] = out[name].astype(np.int64)
    return out


def node_covariances(positions: np.ndarray, origin: np.ndarray, point_start: np.ndarray, child_start: np.ndarray,
                     child_count: np.ndarray, level_offsets: np.ndarray) -> np.ndarray:
    """(M, 10) float64 packed ``M_bar`` of each node (Pajarola 2003, EQ 2: ``sum p' p'^T``, ``p' = (p - origin,
    1)``) over the reordered points ``positions`` (N, 3): leaves sum their point ranges (which tile the
    points), inner nodes their children's sums (EQ 4), level by level. What the build stores, for the
    points as loaded (a compact file's decoded ones)."""
    m = len(child_count)
    leaves = np.flatnonzero(child_count == 0)
    leaves = leaves[np.argsort(point_start[leaves], kind="stable")]
    h = np.concatenate([np.asarray(positions, np.float64) - np.asarray(origin, np.float64),
                        np.ones((len(positions), 1))], axis=1)
    sums = np.zeros((m, 10))
    for k, (i, j) in enumerate(COVARIANCE_ENTRIES):
        sums[leaves, k] = np.add.reduceat(h[:, i] * h[:, j], point_start[leaves])
    for level in range(len(level_offsets) - 3, -1, -1):
        lo, hi = level_offsets[level], level_offsets[level + 1]
        inner = lo + np.flatnonzero(child_count[lo:hi] > 0)
        if len(inner):
            below = sums[level_offsets[level + 1]:level_offsets[level + 2]]
            sums[inner] = np.add.reduceat(below, child_start[inner] - level_offsets[level + 1], axis=0)
    return sums


def _scalar(members: dict, name: str, source: str, kind) -> Any:
    if name not in members:
        raise InputError(f"{source}: not a surfsplat hierarchy file (no '{name}' entry)", element=name)
    value = members[name]
    if value.shape != () or not np.issubdtype(value.dtype, kind):
        raise InputError(f"{source}: malformed '{name}' entry", element=name)
    return value.item()


def _check_format(members: dict[str, np.ndarray], source: str) -> None:
    """The ``format`` and ``format_version`` entries name this layout and version."""
    if _scalar(members, "format", source, np.str_) != FORMAT:
        raise InputError(f"{source}: not a surfsplat hierarchy file (format {members['format'].item()!r})",
                         element="format")
    version = _scalar(members, "format_version", source, np.integer)
    if version not in (FORMAT_VERSION, COMPACT_VERSION):
        raise InputError(f"{source}: hierarchy format version {version} is not supported "
                         f"(this surfsplat reads versions {FORMAT_VERSION} and {COMPACT_VERSION}); rebuild it",
                         element="format_version")


def _from_members(members: dict[str, np.ndarray], source: str) -> Hierarchy:
    """Validate the archive members and build the Hierarchy."""
    _check_format(members, source)
    if members["format_version"].item() == COMPACT_VERSION:
        members = _dequantized(members, source)
    elif "node_covariance" not in members:
        raise InputError(f"{source}: missing array 'node_covariance'", element="node_covariance")
    leaf_capacity = _scalar(members, "leaf_capacity", source, np.integer)
    max_depth = _scalar(members, "max_depth", source, np.integer)
    sizes: dict[str, int | None] = {"nodes": None, "points": None, "levels+1": None}
    if "node_positions" in members and members["node_positions"].ndim >= 1:
        sizes["nodes"] = len(members["node_positions"])
    if "point_positions" in members and members["point_positions"].ndim >= 1:
        sizes["points"] = len(members["point_positions"])
    if "level_offsets" in members and members["level_offsets"].ndim >= 1:
        sizes["levels+1"] = len(members["level_offsets"])
    arrays: dict[str, Any] = {}
    for name, (dtype, tail, first, required) in _SPEC.items():
        if name not in members:
            if required:
                raise InputError(f"{source}: missing array '{name}'", element=name)
            arrays[name] = None
            continue
        value = members[name]
        want = (first if isinstance(first, int) else sizes[first],) + tail
        if value.dtype != dtype or value.shape != want:
            raise InputError(f"{source}: array '{name}' has dtype {value.dtype} and shape {value.shape}, "
                             f"expected {np.dtype(dtype)} {want}", element=name)
        if np.issubdtype(dtype, np.floating) and not np.isfinite(value).all():
            finite = np.isfinite(value.reshape(len(value), -1) if value.ndim else value.reshape(1, 1)).all(axis=1)
            raise InputError(f"{source}: array '{name}' has non-finite values", element=name,
                             row=int(np.argmin(finite)))
        arrays[name] = value
    _check_structure(arrays, source)
    if arrays["node_covariance"] is None:   # a compact file: the sums of its points as decoded
        arrays["node_covariance"] = node_covariances(arrays["point_positions"], arrays["origin"],
                                                     arrays["node_point_start"], arrays["node_child_start"],
                                                     arrays["node_child_count"], arrays["level_offsets"])
    point_attributes, node_attributes = _attributes(members, sizes, source)
    points = SplatCloud(**{name: arrays["point_" + name] for name in
                           ("positions", "normals", "colors", "u", "v", "normal_field", "clip_lines", "origin",
                            "up")},
                        attributes=point_attributes)
    return Hierarchy(points=points, order=arrays["order"], level_offsets=arrays["level_offsets"],
                     origin=arrays["origin"], leaf_capacity=int(leaf_capacity), max_depth=int(max_depth),
                     node_attributes=node_attributes,
                     **{name: arrays[name] for name in _SPEC if name.startswith("node_")})


def _attributes(members: dict, sizes: dict, source: str) -> tuple[dict | None, dict | None]:
    """The ``point_attribute:NAME`` and ``node_attribute:NAME`` members as two dicts (None when the
    file has none): the same names in both, numeric 1-D arrays of one dtype per name, a row per
    point and per node."""
    point = {k[len(POINT_ATTRIBUTE):]: v for k, v in members.items() if k.startswith(POINT_ATTRIBUTE)}
    node = {k[len(NODE_ATTRIBUTE):]: v for k, v in members.items() if k.startswith(NODE_ATTRIBUTE)}
    if set(point) != set(node):
        missing = sorted(set(point) ^ set(node))
        raise InputError(f"{source}: attribute(s) {', '.join(missing)} stored for the points or the nodes only",
                         element=POINT_ATTRIBUTE + missing[0])
    for name in point:
        for what, value, rows in (("point", point[name], sizes["points"]), ("node", node[name], sizes["nodes"])):
            if value.dtype.kind not in "uif" or value.shape != (rows,):
                raise InputError(f"{source}: array '{what}_attribute:{name}' has dtype {value.dtype} and shape "
                                 f"{value.shape}, expected a numeric ({rows},)", element=f"{what}_attribute:{name}")
        if point[name].dtype != node[name].dtype:
            raise InputError(f"{source}: attribute {name!r} has dtype {point[name].dtype} for the points "
                             f"but {node[name].dtype} for the nodes", element=POINT_ATTRIBUTE + name)
    return point or None, node or None


def _check_structure(a: dict[str, np.ndarray], source: str) -> None:
    """Levels, child ranges and point ranges consistent (vectorized)."""
    off = a["level_offsets"]
    m, n = len(a["node_positions"]), len(a["point_positions"])

    def fail(what: str):
        raise InputError(f"{source}: corrupt hierarchy: {what}")

    if n == 0 or m == 0:
        fail("no points or no nodes")
    if len(off) < 2 or off[0] != 0 or off[-1] != m or off[1] != 1 or np.any(np.diff(off) <= 0):
        fail("bad level offsets")
    start, count = a["node_point_start"], a["node_point_count"]
    if np.any(count < 1) or np.any(start < 0) or np.any(start + count > n) or count[0] != n:
        fail("node point ranges out of bounds")
    cstart, ccount = a["node_child_start"], a["node_child_count"]
    level = np.repeat(np.arange(len(off) - 1), np.diff(off))
    inner = ccount > 0
    nxt_lo = off[np.minimum(level + 1, len(off) - 1)]
    nxt_hi = off[np.minimum(level + 2, len(off) - 1)]
    if np.any(ccount < 0) or np.any(ccount > 8) or np.any(
            inner & ((cstart < nxt_lo) | (cstart + ccount > nxt_hi))):
        fail("child ranges out of bounds")
    if int(ccount.sum()) != m - 1:
        fail("child counts do not add up to the number of nodes")
    if int(count[~inner].sum()) != n:
        fail("leaves do not cover the points exactly once")
    order = a["order"]
    if np.any(order < 0) or np.any(order >= n) or np.any(np.bincount(order, minlength=n) != 1):
        fail("'order' is not a permutation of the points")
