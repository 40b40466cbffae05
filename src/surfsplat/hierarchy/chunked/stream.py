"""Streaming a point file in chunks of a bounded number of points, and bucketing it into grid cells.

Readers (:class:`PointStream`): LAS/LAZ through laspy's chunk iterator, binary PLY memory-mapped
(the vertex element read ``chunk_points`` records at a time), anything else read whole by
:func:`surfsplat.io.load` (small inputs), and a folder of such tiles read one after the other.
Each chunk is a :class:`Chunk` of float64 positions
(the file's coordinates, so georeferenced LiDAR keeps its precision until the origin is
subtracted), optional normals and colors, and the point attributes (LAS/LAZ dimensions such as
``classification`` and ``intensity``, those of files read whole; a folder keeps those all its
tiles have with one dtype).

Passes over the file (:func:`build_grid`, :func:`bucket`): bounds (the LAS header or a scan),
counts on a fine voxel grid, then the cell grid (cubes of ``b**3`` voxels, ``b`` the largest with
no cell over ``cell_points`` points), then every chunk's points appended to their cell's
temporary file (float32 positions relative to the origin, normals, colors, attributes, the
point's row in the input as int64). Memory: one chunk plus the voxel histogram.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ... import progress
from ...errors import InputError
from ...io import load
from ...io.las import check_header, las_attributes, rgb_scale
from ...io.ply_layout import TYPE_SIZES, read_layout
from ...io.ply import ply_up
from ...orientation import Z_UP
from .layout import cell_key

#: Files of a folder of tiles that are read.
TILE_SUFFIXES = (".las", ".laz", ".ply")

#: Voxels along the longest axis of the bounds in the counting pass.
FINE = 128

#: PLY scalar type -> NumPy type code.
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


@dataclass
class Chunk:
    """Points of one chunk: ``positions`` (n, 3) float64 in the file's coordinates, ``normals`` and
    ``colors`` (n, 3) float32 or None, ``first``: the row of the first point in the input,
    ``attributes``: {name: (n,) array} (the stream's :attr:`PointStream.attributes`)."""

    positions: np.ndarray
    normals: np.ndarray | None
    colors: np.ndarray | None
    first: int
    attributes: dict | None = None


class PointStream:
    """A point file read in chunks of at most ``chunk_points`` points (see the module docstring).

    Attributes: ``path``, ``count`` (points), ``has_normals``, ``has_colors``, ``kind``
    ("las", "ply", "whole" or "tiles"), ``header_bounds`` (``(lo, hi)`` float64 from LAS headers,
    else None), ``up``: the input's up axis where its files say (LAS/LAZ: +z; a PLY written by
    surfsplat: its stored up; tiles: theirs when they all agree), else None; ``files``: ``(path, row
    of its first point)`` per file, ``attributes``: {name: dtype} of the point attributes every chunk carries.
    """

    def __init__(self, path, chunk_points: int):
        self.path = Path(path)
        self.chunk_points = int(chunk_points)
        self.header_bounds = None
        self._whole = None
        self._tiles = None
        self.attributes = {}
        suffix = self.path.suffix.lower()
        self.files = [(str(self.path), 0)]
        if self.path.is_dir():
            self._open_tiles()
            return
        if not self.path.is_file():
            raise InputError(f"{self.path}: no such file")
        self.up = Z_UP if suffix in (".las", ".laz") else ply_up(self.path) if suffix == ".ply" else None
        if suffix in (".las", ".laz"):
            self._open_las()
        elif suffix == ".ply" and self._open_ply():
            pass
        else:
            self.kind = "whole"
            cloud = load(self.path)
            self._whole = cloud
            self.up = cloud.up
            self.count = len(cloud)
            self.has_normals = cloud.normals is not None
            self.has_colors = cloud.colors is not None
            self.attributes = {name: values.dtype for name, values in (cloud.attributes or {}).items()}

    def _open_tiles(self) -> None:
        """A folder of tiles: its LAS, LAZ and PLY files in name order, read one after the other as
        one cloud (a point's row counts on from the previous files')."""
        names = sorted(p for p in self.path.iterdir() if p.is_file() and p.suffix.lower() in TILE_SUFFIXES)
        if not names:
            raise InputError(f"{self.path}: a folder with no {', '.join(TILE_SUFFIXES)} files")
        self._tiles = [PointStream(name, self.chunk_points) for name in names]
        firsts = np.concatenate([[0], np.cumsum([t.count for t in self._tiles])[:-1]])
        self.files = [(str(t.path), int(f)) for t, f in zip(self._tiles, firsts)]
        self.kind = "tiles"
        self.count = int(sum(t.count for t in self._tiles))
        self.has_normals = all(t.has_normals for t in self._tiles)
        self.has_colors = all(t.has_colors for t in self._tiles)
        ups = {t.up for t in self._tiles}
        self.up = ups.pop() if len(ups) == 1 else None
        self.attributes = {name: dtype for name, dtype in self._tiles[0].attributes.items()
                           if all(t.attributes.get(name) == dtype for t in self._tiles)}
        if all(t.header_bounds is not None for t in self._tiles):
            self.header_bounds = (np.min([t.header_bounds[0] for t in self._tiles], axis=0),
                                  np.max([t.header_bounds[1] for t in self._tiles], axis=0))

    def _open_las(self) -> None:
        try:
            import laspy
        except ImportError as exc:
            raise InputError(f"{self.path}: reading LAS/LAZ files needs laspy and lazrs "
                             "(pip install \"surfsplat[las]\")") from exc
        check_header(self.path, str(self.path))
        try:
            with laspy.open(self.path) as reader:
                header = reader.header
                self.count = int(header.point_count)
                self.header_bounds = (np.array(header.mins, dtype=np.float64), np.array(header.maxs, dtype=np.float64))
                names = set(header.point_format.dimension_names)
                if self.count:   # the attributes' dtypes, as the in-memory reader keeps them
                    self.attributes = {name: v.dtype for name, v in las_attributes(reader.read_points(1)).items()}
        except Exception as exc:  # laspy.LaspyException, OSError, ValueError
            raise InputError(f"{self.path}: cannot read LAS file: {type(exc).__name__}: {exc}") from exc
        self.kind = "las"
        self.has_normals = False
        self.has_colors = {"red", "green", "blue"} <= names
        self._rgb_scale = None

    def _open_ply(self) -> bool:
        """Memory-map a binary PLY's vertex element; False when the layout does not allow it."""
        layout = read_layout(self.path)
        if layout is None or not layout.format.startswith("binary"):
            return False
        offset = layout.body
        for name, count, props in layout.elements:
            if any(len(p) == 3 for p in props):
                return False  # lists in or before the vertices: their size is not known without parsing
            if name == "vertex":
                order = "<" if layout.format == "binary_little_endian" else ">"
                dtype = np.dtype([(p[0], order + _PLY_TYPES[p[1]]) for p in props])
                names = {p[0] for p in props}
                if not {"x", "y", "z"} <= names:
                    raise InputError(f"{self.path}: the PLY vertex element has no x, y, z properties")
                if offset + count * dtype.itemsize > layout.size:
                    raise InputError(f"{self.path}: malformed PLY file: the header declares {count:,} vertices "
                                     "but the file is shorter (truncated)")
                self._vertices = np.memmap(self.path, dtype=dtype, mode="r", offset=offset, shape=(count,))
                self.kind = "ply"
                self.count = count
                self.has_normals = {"nx", "ny", "nz"} <= names
                self.has_colors = {"red", "green", "blue"} <= names
                return True
            offset += count * sum(TYPE_SIZES[p[1]] for p in props)
        return False

    def chunks(self):
        """Yield the points as :class:`Chunk` s of at most ``chunk_points`` points, in file order."""
        if self.kind == "tiles":
            for tile, (_, first) in zip(self._tiles, self.files):
                for chunk in tile.chunks():  # normals and colors only where every tile has them
                    yield Chunk(chunk.positions, chunk.normals if self.has_normals else None,
                                chunk.colors if self.has_colors else None, first + chunk.first,
                                {name: chunk.attributes[name] for name in self.attributes})
        elif self.kind == "whole":
            cloud = self._whole
            for a in range(0, self.count, self.chunk_points):
                b = min(a + self.chunk_points, self.count)
                yield Chunk(cloud.positions[a:b].astype(np.float64) + cloud.origin,
                            None if cloud.normals is None else cloud.normals[a:b],
                            None if cloud.colors is None else cloud.colors[a:b], a,
                            {name: values[a:b] for name, values in (cloud.attributes or {}).items()})
        elif self.kind == "ply":
            v = self._vertices
            for a in range(0, self.count, self.chunk_points):
                rec = np.asarray(v[a:min(a + self.chunk_points, self.count)])
                pos = np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64)
                nrm = (np.column_stack([rec["nx"], rec["ny"], rec["nz"]]).astype(np.float32) if self.has_normals
                       else None)
                col = None
                if self.has_colors:
                    col = np.column_stack([rec["red"], rec["green"], rec["blue"]]).astype(np.float32)
                    if rec["red"].dtype.kind in "ui":
                        col /= np.float32(np.iinfo(rec["red"].dtype).max)
                yield Chunk(pos, nrm, col, a)
        else:
            yield from self._las_chunks()

    def _las_chunks(self):
        import laspy
        first = 0
        try:
            with laspy.open(self.path) as reader:
                for points in reader.chunk_iterator(self.chunk_points):
                    pos = np.column_stack([np.asarray(points.x, dtype=np.float64),
                                           np.asarray(points.y, dtype=np.float64),
                                           np.asarray(points.z, dtype=np.float64)])
                    col = None
                    if self.has_colors:
                        rgb = np.column_stack([np.asarray(points.red), np.asarray(points.green),
                                               np.asarray(points.blue)])
                        if self._rgb_scale is None:  # decided on the first chunk, kept for the file
                            self._rgb_scale = rgb_scale(rgb)
                        col = np.clip(rgb / self._rgb_scale, 0.0, 1.0).astype(np.float32)
                    attributes = las_attributes(points)
                    yield Chunk(pos, None, col, first, {name: attributes[name] for name in self.attributes})
                    first += len(pos)
        except InputError:
            raise
        except Exception as exc:  # laspy.LaspyException, lazrs errors, OSError
            raise InputError(f"{self.path}: cannot read LAS file at point {first:,}: "
                             f"{type(exc).__name__}: {exc}") from exc


def _finite(chunk: Chunk) -> np.ndarray:
    return np.isfinite(chunk.positions).all(axis=1)


@dataclass(frozen=True)
class Grid:
    """The cell grid: cubes of side ``cell_size`` from ``corner`` (float64, file coordinates),
    ``dims`` cells per axis; ``origin`` (float64): the center of the bounds, which positions are
    stored relative to; ``counts``: {(i, j, k): points} of the non-empty cells."""

    corner: np.ndarray
    cell_size: float
    dims: tuple[int, int, int]
    origin: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    counts: dict

    def cell_of(self, positions: np.ndarray) -> np.ndarray:
        """(n, 3) int64 cell indices of positions (file coordinates), clamped into the grid."""
        ijk = np.floor((positions - self.corner) / self.cell_size).astype(np.int64)
        return np.clip(ijk, 0, np.array(self.dims) - 1)

    def cell_box(self, ijk) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(lo, hi)`` of a cell relative to ``origin`` (float64)."""
        lo = self.corner + np.asarray(ijk, dtype=np.float64) * self.cell_size - self.origin
        return lo, lo + self.cell_size


def build_grid(stream: PointStream, cell_points: int) -> Grid:
    """Passes 1 and 2 over the stream: bounds, counts on a fine voxel grid, and the cell grid whose
    cells hold at most ``cell_points`` points (cubes of ``b**3`` voxels, ``b`` as large as that
    allows; a single voxel over the limit stays one cell, with a progress message)."""
    if stream.header_bounds is not None:
        lo, hi = stream.header_bounds
    else:
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        with progress.stage("pass 1: bounds", stream.count, total=stream.count) as stage:
            for chunk in stream.chunks():
                p = chunk.positions[_finite(chunk)]
                if len(p):
                    lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
                stage.update(len(chunk.positions))
    if not np.all(np.isfinite(lo)):
        raise InputError(f"{stream.path}: no finite point")
    extent = float(np.max(hi - lo))
    voxel = max(extent, 1e-9) / FINE * (1 + 1e-9)
    fine_dims = np.maximum(np.ceil((hi - lo) / voxel).astype(np.int64), 1)
    histogram = np.zeros(int(np.prod(fine_dims)), dtype=np.int64)
    with progress.stage("pass 2: counts per voxel", stream.count, total=stream.count) as stage:
        for chunk in stream.chunks():
            p = chunk.positions[_finite(chunk)]
            v = np.clip(np.floor((p - lo) / voxel).astype(np.int64), 0, fine_dims - 1)
            histogram += np.bincount(np.ravel_multi_index(v.T, fine_dims), minlength=len(histogram))
            stage.update(len(chunk.positions))
    histogram = histogram.reshape(fine_dims)
    # a large cube of block**3 voxels with no cell over the limit (block = the longest side: one cell),
    # by bisection: only blocks that fit are kept, so the limit holds even where the maximum is not monotone
    block, top = 1, int(fine_dims.max())
    while block < top:
        mid = (block + top + 1) // 2
        if _block_max(histogram, mid) <= cell_points:
            block = mid
        else:
            top = mid - 1
    if block == 1 and int(histogram.max()) > cell_points:
        progress.message(f"  a {voxel:.3g}-wide voxel holds {int(histogram.max()):,} points, more than "
                         f"--cell-points {cell_points:,}: its cell is larger")
    counts = _block_counts(histogram, block)
    nz = np.argwhere(counts > 0)
    return Grid(corner=lo.copy(), cell_size=voxel * block, dims=tuple(int(x) for x in counts.shape),
                origin=0.5 * (lo + hi), lo=lo, hi=hi,
                counts={tuple(int(x) for x in ijk): int(counts[tuple(ijk)]) for ijk in nz})


def _block_counts(histogram: np.ndarray, block: int) -> np.ndarray:
    dims = np.array(histogram.shape)
    padded = -(-dims // block) * block
    h = np.zeros(padded, dtype=np.int64)
    h[:dims[0], :dims[1], :dims[2]] = histogram
    a, b, c = padded // block
    return h.reshape(a, block, b, block, c, block).sum(axis=(1, 3, 5))


def _block_max(histogram: np.ndarray, block: int) -> int:
    return int(_block_counts(histogram, block).max())


def record_dtype(has_normals: bool, has_colors: bool, attributes: dict | None = None) -> np.dtype:
    """The record of the bucket files: position relative to the origin (float32), optional normal
    and color (float32), the point's row in the input (int64), then the attributes (``{name:
    dtype}``) as fields ``a0``, ``a1``, ... in that order."""
    fields = [("p", "<f4", (3,))]
    if has_normals:
        fields.append(("n", "<f4", (3,)))
    if has_colors:
        fields.append(("c", "<f4", (3,)))
    fields.append(("id", "<i8"))
    fields += [(f"a{i}", np.dtype(dtype).newbyteorder("<")) for i, dtype in enumerate((attributes or {}).values())]
    return np.dtype(fields)


def bucket(stream: PointStream, grid: Grid, folder: Path) -> np.dtype:
    """Pass 3: append every chunk's points to ``folder/<cell key>.bin`` (records of
    :func:`record_dtype`); returns the record dtype. Non-finite points are skipped."""
    dtype = record_dtype(stream.has_normals, stream.has_colors, stream.attributes)
    folder.mkdir(parents=True, exist_ok=True)
    with progress.stage("pass 3: points into cell files", stream.count, total=stream.count) as stage:
        for chunk in stream.chunks():
            keep = _finite(chunk)
            rows = np.flatnonzero(keep)
            rec = np.empty(len(rows), dtype=dtype)
            rec["p"] = chunk.positions[rows] - grid.origin
            if stream.has_normals:
                rec["n"] = chunk.normals[rows]
            if stream.has_colors:
                rec["c"] = chunk.colors[rows]
            rec["id"] = chunk.first + rows
            for i, name in enumerate(stream.attributes):
                rec[f"a{i}"] = chunk.attributes[name][rows]
            ijk = grid.cell_of(chunk.positions[rows])
            flat = np.ravel_multi_index(ijk.T, grid.dims)
            order = np.argsort(flat, kind="stable")
            flat, rec = flat[order], rec[order]
            cuts = np.flatnonzero(np.diff(flat)) + 1
            for part, first in zip(np.split(rec, cuts), np.concatenate([[0], cuts]).astype(np.int64)):
                if len(part):  # one write per cell present in the chunk
                    key = cell_key(np.unravel_index(int(flat[first]), grid.dims))
                    with open(folder / f"{key}.bin", "ab") as handle:
                        part.tofile(handle)
            stage.update(len(chunk.positions))
    return dtype
