"""The on-disk layout of a chunked hierarchy (``docs/chunked_format.md``): names, the manifest, cell files.

A chunked hierarchy is a directory::

    MODEL.ssh/
      manifest.json            format, float64 origin, bounds, cell grid, cell table (JSON)
      top.npz                  the coarse hierarchy over the cells' roots (surfsplat.hierarchy.storage)
      preview.npz              a uniform cut of every cell (framing, overviews)
      cells/<key>/coarse.npz   one cell's first levels (up to 4096 nodes), read first
      cells/<key>/nodes.npz    one cell's node arrays, all levels (read when a view goes deeper)
      cells/<key>/<name>.npy   one cell's splats, one plain .npy per array (memory-mapped)

Positions everywhere are float32 relative to the manifest's float64 ``origin``. Every reader
here raises :class:`~surfsplat.errors.InputError` naming the file and the problem.
"""

from __future__ import annotations

import json
import math
import threading
import zipfile
from pathlib import Path

import numpy as np

from ...cloud import checked_up
from ...errors import InputError
from ...io.npz import npz_names, read_npz

#: Serializes :func:`load_npy`: NumPy parses a ``.npy`` header with ``ast.literal_eval``, which CPython 3.11
#: (3.11.7 here) can break with "SystemError: AST constructor recursion depth mismatch" when two threads
#: parse at once, as a build's tasks do on threaded Dask workers.
_NPY_LOCK = threading.Lock()


def load_npy(path, mmap_mode=None) -> np.ndarray:
    """``np.load`` of one ``.npy`` file (no pickles), one thread at a time (:data:`_NPY_LOCK`)."""
    with _NPY_LOCK:
        return np.load(path, mmap_mode=mmap_mode, allow_pickle=False)

#: Value of the manifest's ``format``.
FORMAT = "surfsplat-chunked-hierarchy"
#: Version of this layout (2: point attributes per cell); directories of versions not in
#: :data:`READ_VERSIONS` are refused.
FORMAT_VERSION = 2
#: Versions read (version 1 directories have no attributes).
READ_VERSIONS = (1, 2)
MANIFEST = "manifest.json"
TOP = "top.npz"
PREVIEW = "preview.npz"
CELLS = "cells"
NODES = "nodes.npz"
COARSE = "coarse.npz"

#: Per-point arrays of a cell: name -> (dtype, columns or None for 1-D, required).
POINT_FILES = {
    "positions": (np.float32, 3, True),
    "normals": (np.float32, 3, True),
    "u": (np.float32, 3, True),
    "v": (np.float32, 3, True),
    "colors": (np.float32, 3, False),
    "ids": (np.int64, None, True),
}

#: Node arrays of a cell's ``nodes.npz``: name -> (dtype, columns or None, required).
NODE_FILES = {
    "node_positions": (np.float32, 3, True),
    "node_normals": (np.float32, 3, True),
    "node_colors": (np.float32, 3, False),
    "node_u": (np.float32, 3, True),
    "node_v": (np.float32, 3, True),
    "node_normal_field": (np.float32, 2, True),
    "node_radius": (np.float32, None, True),
    "node_cone": (np.float32, None, True),
    "node_extent": (np.float32, None, True),
    "node_covariance": (np.float64, 10, True),
    "node_point_start": (np.int64, None, True),
    "node_point_count": (np.int64, None, True),
    "node_child_start": (np.int64, None, True),
    "node_child_count": (np.int64, None, True),
}


def cell_key(ijk) -> str:
    """The directory name of the cell at grid index ``ijk``: ``c<i>_<j>_<k>``."""
    i, j, k = (int(x) for x in ijk)
    return f"c{i}_{j}_{k}"


def is_chunked_hierarchy(path) -> bool:
    """True for a directory holding a chunked hierarchy's ``manifest.json``."""
    return isinstance(path, (str, Path)) and (Path(path) / MANIFEST).is_file()


def chunked_up(directory) -> tuple[float, float, float] | None:
    """The up axis of the data a chunked hierarchy was built from (its manifest's ``up``: +z for
    LAS/LAZ input, a PLY's stored up), or None where the input did not say (``up`` null or absent;
    :func:`surfsplat.orientation.model_up` then guesses). InputError for a malformed ``up``."""
    up = read_manifest(directory).get("up")
    if up is None:
        return None
    try:
        return checked_up(up)
    except InputError:
        raise InputError(f"{Path(directory) / MANIFEST}: malformed 'up' {up!r} (expected 3 numbers)") from None


def write_manifest(directory: Path, manifest: dict) -> None:
    """Write ``manifest.json`` (through a temporary name, so a crash leaves no half manifest)."""
    temp = directory / (MANIFEST + ".tmp")
    temp.write_text(json.dumps(manifest, indent=1))
    temp.replace(directory / MANIFEST)


def read_manifest(directory) -> dict:
    """The checked manifest of a chunked hierarchy directory.

    Raises:
        InputError naming the file: no directory or manifest, not JSON, another format or
            version, missing or malformed entries (origin, grid, cell table).
    """
    directory = Path(directory)
    path = directory / MANIFEST
    if not directory.is_dir():
        raise InputError(f"{directory}: no such directory (a chunked hierarchy is a directory)")
    if not path.is_file():
        raise InputError(f"{path}: missing: {directory} is not a chunked hierarchy (surfsplat build --chunked)")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not a readable manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise InputError(f"{path}: not a surfsplat chunked hierarchy manifest")
    if manifest.get("format_version") not in READ_VERSIONS:
        raise InputError(f"{path}: chunked format version {manifest.get('format_version')!r} is not supported "
                         f"(this surfsplat reads versions {', '.join(map(str, READ_VERSIONS))}); rebuild it")
    try:
        origin = np.array(manifest["origin"], dtype=np.float64)
        grid = manifest["grid"]
        corner = np.array(grid["corner"], dtype=np.float64)
        size = float(grid["cell_size"])
        dims = [int(x) for x in grid["dims"]]
        cells = manifest["cells"]
        ok = (origin.shape == (3,) and corner.shape == (3,) and np.isfinite(origin).all() and math.isfinite(size)
              and size > 0 and len(dims) == 3 and isinstance(cells, list) and len(cells) > 0)
        for cell in cells:
            ok = ok and int(cell["points"]) > 0 and int(cell["nodes"]) > 0 and isinstance(cell["files"], dict)
            ok = ok and len(cell["root"]["position"]) == 3 and len(cell["ijk"]) == 3
    except (KeyError, TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"{path}: malformed manifest (origin, grid or cell table)")
    return manifest


def check_size(path: Path, expected: int) -> None:
    """InputError naming ``path`` when it is missing or its size is not the ``expected`` bytes."""
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise InputError(f"{path}: missing chunk file of the chunked hierarchy") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if size != expected:
        raise InputError(f"{path}: corrupt chunk file: {size:,} bytes, the manifest says {expected:,} "
                         "(truncated or overwritten)")


def open_points(path: Path, name: str, count: int, dtype=None) -> np.ndarray:
    """A cell's per-point array ``name`` memory-mapped read-only, checked against :data:`POINT_FILES`
    (or, given ``dtype``, a 1-D array of that dtype: a point attribute)."""
    if dtype is None:
        dtype, columns, _ = POINT_FILES[name]
    else:
        columns = None
    try:
        array = load_npy(path, mmap_mode="r")
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"{path}: corrupt chunk file ({exc})") from None
    want = (count,) if columns is None else (count, columns)
    if array.dtype != dtype or array.shape != want:
        raise InputError(f"{path}: corrupt chunk file: {array.dtype} {array.shape}, expected {np.dtype(dtype)} {want}")
    return array


def read_nodes(path: Path, names=tuple(NODE_FILES)) -> dict[str, np.ndarray]:
    """A cell's ``nodes.npz`` members, checked (no pickles, dtypes, matching node counts, finite
    floats); of the node arrays only ``names`` are read (the others are neither read nor returned)."""
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: corrupt chunk file (not an .npz archive, or truncated)")
    wanted = set(names) | {"level_offsets", "origin", "leaf_capacity", "max_depth"}
    # sizes checked before anything is inflated (read_npz): no zip bomb
    source = f"{path}: corrupt chunk file"
    members = read_npz(path, [name for name in npz_names(path, source) if name in wanted or name not in NODE_FILES],
                       source)
    for name in ("level_offsets", "origin", "leaf_capacity", "max_depth"):
        if name not in members:
            raise InputError(f"{path}: corrupt chunk file (no '{name}')")
    m = len(members.get("node_positions", ()))
    for name, (dtype, columns, required) in NODE_FILES.items():
        if name not in members:
            if required and name in wanted:
                raise InputError(f"{path}: corrupt chunk file (no '{name}')")
            continue
        value = members[name]
        want = (m,) if columns is None else (m, columns)
        if value.dtype != dtype or value.shape != want:
            raise InputError(f"{path}: corrupt chunk file: '{name}' is {value.dtype} {value.shape}, "
                             f"expected {np.dtype(dtype)} {want}")
        if value.dtype.kind == "f" and not np.isfinite(value).all():
            raise InputError(f"{path}: corrupt chunk file: '{name}' has non-finite values")
    off = members["level_offsets"]
    if off.ndim != 1 or len(off) < 2 or off[0] != 0 or off[-1] != m or np.any(np.diff(off) <= 0):
        raise InputError(f"{path}: corrupt chunk file: bad level offsets")
    return members
