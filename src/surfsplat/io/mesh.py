"""Triangle meshes: the ground-truth surfaces that splats are sampled from.

A :class:`Mesh` is a plain indexed triangle list (float32 vertices, int64
faces) with optional per-vertex normals and colors (and per-corner normals,
which welding produces from stored normals that differ at a crease). It is read
from PLY files with a ``face`` element (:mod:`surfsplat.io.ply`) or from OBJ,
STL, OFF, GLB and glTF files (trimesh, here: :func:`read_trimesh`).
:func:`area_weighted_normals` gives vertex normals to meshes that store none;
:mod:`surfsplat.io.surface` welds meshes and gives them crease-aware normals.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..cloud import MAX_COORDINATE, split_origin
from ..errors import InputError, file_reader


@dataclass
class Mesh:
    """An indexed triangle mesh.

    Attributes:
        vertices: (V, 3) float32 relative to ``origin``, model units.
        faces: (F, 3) int64 vertex indices; counter-clockwise seen from the
            outside gives the outward normal (right-hand rule).
        vertex_normals: (V, 3) float32 unit normals, or None.
        vertex_colors: (V, 3) float32 linear RGB in [0, 1], or None.
        corner_normals: (F, 3, 3) float32 unit normals of each face's three
            corners (in the order of ``faces``), or None. They take precedence
            over ``vertex_normals``: :func:`surfsplat.io.surface.weld` keeps a
            file's stored normals this way where it merges vertices whose
            normals differ (a crease that the file split).
        merged_vertices: how many vertices welding removed (0 for a mesh as
            read; see :func:`surfsplat.io.surface.weld`).
        collapsed_faces: how many faces welding removed because two of their
            corners became one vertex.
        origin: (3,) float64 world position of the vertices' zero (world = ``origin +
            vertices``); None: chosen as for :class:`~surfsplat.cloud.SplatCloud` (zeros, or the
            centre of float64 vertices lying far from zero, :func:`~surfsplat.cloud.split_origin`).

    The constructor checks shapes and converts dtypes; :meth:`validated`
    checks the contents (faces present, finite vertices, indices in range).
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_normals: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None
    corner_normals: np.ndarray | None = None
    merged_vertices: int = field(default=0, compare=False)
    collapsed_faces: int = field(default=0, compare=False)
    origin: np.ndarray = field(default=None, compare=False)  # type: ignore[arg-type]  # None given: zeros

    def __post_init__(self) -> None:
        if self.origin is None:
            self.origin, self.vertices = split_origin(self.vertices)
        else:
            origin = np.array(self.origin, dtype=np.float64).reshape(-1)
            if origin.shape != (3,) or not np.isfinite(origin).all():
                raise InputError(f"origin must be 3 finite numbers, got {self.origin!r}")
            self.origin = origin
        self.vertices = _as_rows(self.vertices, np.float32, "vertices")
        self.faces = _as_rows(self.faces, np.int64, "faces")
        n = len(self.vertices)
        for name in ("vertex_normals", "vertex_colors"):
            value = getattr(self, name)
            if value is None:
                continue
            value = _as_rows(value, np.float32, name)
            if len(value) != n:
                raise InputError(f"{name} has {len(value)} rows but vertices has {n}")
            setattr(self, name, value)
        if self.corner_normals is not None:
            corners = np.ascontiguousarray(self.corner_normals, dtype=np.float32)
            if corners.shape != (len(self.faces), 3, 3):
                raise InputError(f"corner_normals must have shape (F, 3, 3) = {(len(self.faces), 3, 3)}, "
                                 f"got {corners.shape}")
            self.corner_normals = corners

    def __repr__(self) -> str:
        extra = [name for name in ("vertex_normals", "vertex_colors", "corner_normals")
                 if getattr(self, name) is not None]
        text = f"Mesh({len(self.vertices)} vertices, {len(self.faces)} faces"
        if extra:
            text += f", with {', '.join(extra)}"
        if self.merged_vertices or self.collapsed_faces:
            text += f"; welded: {self.merged_vertices} vertices merged, {self.collapsed_faces} faces collapsed"
        return text + ")"

    @property
    def has_normals(self) -> bool:
        """True when the mesh stores normals (per vertex or per corner)."""
        return self.vertex_normals is not None or self.corner_normals is not None

    # -- derived quantities -------------------------------------------------

    def _corners(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The three corners of every face, each (F, 3) float64."""
        v = self.vertices.astype(np.float64)
        return v[self.faces[:, 0]], v[self.faces[:, 1]], v[self.faces[:, 2]]

    def face_normals(self) -> np.ndarray:
        """(F, 3) float32 unit geometric normals, right-hand rule on the face's
        vertex order; zero vectors for degenerate (zero-area) faces."""
        a, b, c = self._corners()
        cross = np.cross(b - a, c - a)
        length = np.linalg.norm(cross, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = np.where(length > 0, cross / length, 0.0)
        return unit.astype(np.float32)

    def face_areas(self) -> np.ndarray:
        """(F,) float64 face areas, squared model units."""
        a, b, c = self._corners()
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned world bounds ``(min, max)``, each (3,) float64, of the vertices
        used by faces (all vertices when there are no faces), model units."""
        used = self.vertices[np.unique(self.faces)] if len(self.faces) else self.vertices
        if len(used) == 0:
            raise InputError("mesh has no vertices")
        return used.min(axis=0) + self.origin, used.max(axis=0) + self.origin

    # -- validation --------------------------------------------------------

    def validated(self, source: str = "mesh") -> "Mesh":
        """Return ``self`` after checking its contents, or raise InputError.

        Checked: at least one face, all vertices finite and within
        :data:`~surfsplat.cloud.MAX_COORDINATE` (1e18) of the origin (the float32 renderer's
        limit: beyond it its squares overflow and the picture comes out blank), every face index
        in ``[0, V)``. ``source`` names the file or array in messages.

        Raises:
            InputError with ``element`` ("vertex" or "face") and ``row`` (the first bad one).
        """
        n = len(self.vertices)
        if len(self.faces) == 0:
            raise InputError(f"{source}: mesh has no faces", element="face")
        finite = np.isfinite(self.vertices).all(axis=1)
        if not finite.all():
            raise InputError(f"{source}: {int((~finite).sum())} of {n} mesh vertices have "
                             f"non-finite coordinates (first at vertex {int(np.argmin(finite))})",
                             element="vertex", row=int(np.argmin(finite)))
        near = (np.abs(self.vertices) <= MAX_COORDINATE).all(axis=1)
        if not near.all():
            first = int(np.argmin(near))
            world = self.vertices[first].astype(np.float64) + self.origin
            raise InputError(f"{source}: {int((~near).sum())} of {n} mesh vertices lie farther than "
                             f"{MAX_COORDINATE:.0e} from the model's origin (first: vertex {first} at "
                             f"{np.array2string(world, precision=4)}); the float32 renderer cannot draw "
                             "them (remove them, or rescale the model)", element="vertex", row=first)
        check_face_indices(self.faces, n, source)
        return self


def check_face_indices(faces: np.ndarray, n_vertices: int, source: str) -> None:
    """Raise InputError naming ``source`` if a face index is outside ``[0, n_vertices)``.

    ``faces``: (F, k) integer vertex indices.
    """
    if faces.size == 0:
        return
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= n_vertices:
        bad = (faces < 0) | (faces >= n_vertices)
        row = int(np.argmax(bad.any(axis=1)))
        value = int(faces[row][bad[row]][0])
        raise InputError(f"{source}: face {row} refers to vertex {value}, but there are only "
                         f"{n_vertices} vertices (valid indices 0..{n_vertices - 1}); "
                         f"{int(bad.any(axis=1).sum())} faces have out-of-range indices", element="face", row=row)


def area_weighted_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Vertex normals as the area-weighted mean of the adjacent faces' normals.

    Args:
        vertices: (V, 3) float, model space.
        faces: (F, 3) int vertex indices in ``[0, V)``.

    Returns:
        (V, 3) float32 unit normals. The unnormalized face cross products
        (twice the area times the unit normal) are summed onto each face's three
        vertices and the sums normalized. Vertices used by no face, or whose
        faces cancel or are all degenerate, get a zero vector (no normal).
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    n = len(v)
    if len(f) == 0:
        return np.zeros((n, 3), dtype=np.float32)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cross = np.cross(b - a, c - a)  # (F, 3), length = 2 * area
    index = f.ravel()  # corner k of face i at 3 i + k
    summed = np.empty((n, 3), dtype=np.float64)
    for axis in range(3):  # three bincounts, vectorized over all corners
        summed[:, axis] = np.bincount(index, weights=np.repeat(cross[:, axis], 3), minlength=n)
    length = np.linalg.norm(summed, axis=1, keepdims=True)
    scale = np.max(length) if n else 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(length > 1e-12 * scale, summed / length, 0.0)
    return unit.astype(np.float32)


#: File types read with trimesh, by lower-case extension: trimesh's ``file_type`` names.
TRIMESH_TYPES = {".obj": "obj", ".stl": "stl", ".off": "off", ".glb": "glb", ".gltf": "gltf"}


@file_reader
def read_obj(path: Path) -> Mesh:
    """Read a Wavefront OBJ file as a :class:`Mesh` (unvalidated); see :func:`read_trimesh`."""
    return read_trimesh(path, "obj")


@file_reader
def read_trimesh(path: Path, file_type: str | None = None) -> Mesh:
    """Read an OBJ, STL, OFF, GLB or glTF file as a :class:`Mesh` with trimesh (unvalidated).

    ``file_type`` is trimesh's name for the format (default: from the
    extension, :data:`TRIMESH_TYPES`). The mesh is taken as the file stores it
    (trimesh's ``process=False``: no merging or reordering): an STL file is a
    triangle soup, three vertices per face, which :func:`surfsplat.io.surface.weld`
    connects. Polygons are triangulated by trimesh. Scenes (glTF, GLB, OBJ
    with several objects) are flattened: every mesh instance is placed by its
    node's transform (normals by its inverse transpose) and the instances are
    concatenated. Vertex normals are kept when the file has them (OBJ ``vn``,
    glTF ``NORMAL``) in every part, else ``vertex_normals`` is None (STL and
    OFF store none; STL's facet normals are not used, the faces' winding
    gives them). Per-vertex colors are kept when every part has them
    (texture-mapped colors are not read). An OBJ with vertices but no faces
    gives a Mesh with (0, 3) faces (a point cloud for ``load``, an error for
    ``load_mesh``). Any parse failure, and a file without vertices, raises
    InputError naming the file.
    """
    source = str(path)
    file_type = file_type or TRIMESH_TYPES.get(Path(path).suffix.lower(), Path(path).suffix.lower().lstrip("."))
    name = file_type.upper()
    if file_type == "obj":
        check_obj_indices(Path(path), source)
    import trimesh   # deferred: 0.7 s to import, needed by these formats only (see _trimesh)

    try:
        loaded = trimesh.load(source, file_type=file_type, process=False)
        parts = _trimesh_parts(loaded)
        meshes = [p for p in parts if isinstance(p[0], trimesh.Trimesh)]
        if meshes:
            vertices, faces, normals, colors = _concatenate([_trimesh_arrays(g, m) for g, m in meshes])
        elif parts:  # vertices only (an OBJ point cloud)
            clouds = [_trimesh_arrays(g, m) for g, m in parts]
            vertices = np.concatenate([c[0] for c in clouds])
            faces = np.zeros((0, 3), dtype=np.int64)
            normals = None
            colors = np.concatenate([c[3] for c in clouds]) if all(c[3] is not None for c in clouds) else None
        elif isinstance(loaded, (trimesh.Trimesh, trimesh.Scene, trimesh.PointCloud)):
            vertices = np.zeros((0, 3))
            faces, normals, colors = np.zeros((0, 3), dtype=np.int64), None, None
        else:
            raise InputError(f"{source}: {name} file holds no triangle mesh ({type(loaded).__name__})")
    except InputError:
        raise
    except Exception as exc:  # trimesh raises many types (IndexError, ValueError, KeyError, ...)
        raise InputError(f"{source}: cannot read {name} file: {type(exc).__name__}: {exc}") from exc
    if len(vertices) == 0:
        raise InputError(f"{source}: {name} file has no vertices")
    return Mesh(vertices, faces, normals, colors)


@file_reader
def check_obj_indices(path: Path, source: str) -> None:
    """InputError naming ``source`` when a face of an OBJ file refers to a vertex that does not exist:
    index 0 (OBJ indices are 1-based; trimesh would wrap it to the last vertex), an index above the
    number of ``v`` lines, or a negative (relative) index reaching before the first vertex. Checks the
    vertex index of each face corner (``f v``, ``f v/t``, ``f v/t/n``, ``f v//n``) against all the
    file's vertices."""
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{source}: cannot read OBJ file: {exc.strerror or exc}") from exc
    n_vertices = len(re.findall(rb"(?m)^[ \t]*v[ \t]", text))
    faces = re.findall(rb"(?m)^[ \t]*f[ \t]+([^\r\n#]*)", text)
    if not faces:
        return
    tokens = re.findall(rb"(?:^|(?<=\s))([+-]?\d+)", b"\n".join(faces))
    if not tokens:
        return
    if max(map(len, tokens)) > 18:
        raise InputError(f"{source}: cannot read OBJ file: a face index with more than 17 digits; "
                         "no file has that many vertices")
    indices = np.array(tokens).astype(np.int64)
    zero = indices == 0
    if zero.any():
        raise InputError(f"{source}: cannot read OBJ file: a face refers to vertex 0, "
                         "but OBJ vertex indices start at 1 "
                         f"({int(zero.sum())} such corners)")
    too_big = (indices > n_vertices) | (indices < -n_vertices)
    if too_big.any():
        value = indices[np.argmax(too_big)]
        raise InputError(f"{source}: cannot read OBJ file: a face refers to vertex {value}, "
                         f"but the file has {n_vertices} vertices "
                         f"(valid indices 1..{n_vertices} or -1..-{n_vertices}); "
                         f"{int(too_big.sum())} corners out of range")


def _trimesh():
    """The trimesh module where it is loaded already (a trimesh object was handed over or read), else
    None: no object can then be a trimesh geometry. ``import surfsplat`` does not import trimesh (0.7 s
    of every command's start); the functions that make trimesh objects import it."""
    return sys.modules.get("trimesh")


def _trimesh_parts(loaded) -> list[tuple[Any, np.ndarray]]:
    """``[(Trimesh or PointCloud, 4x4 transform)]``: a single geometry with the identity, or
    every geometry instance of a Scene with its node's world transform."""
    trimesh = _trimesh()
    if trimesh is None:
        return []
    if isinstance(loaded, (trimesh.Trimesh, trimesh.PointCloud)):
        return [(loaded, np.eye(4))]
    if not isinstance(loaded, trimesh.Scene):
        return []
    parts = []
    for node in loaded.graph.nodes_geometry:
        transform, geometry_name = loaded.graph[node]
        geometry = loaded.geometry.get(geometry_name)
        if isinstance(geometry, (trimesh.Trimesh, trimesh.PointCloud)) and len(geometry.vertices):
            parts.append((geometry, np.asarray(transform, dtype=np.float64)))
    return parts


def _trimesh_arrays(geometry, transform: np.ndarray):
    """``(vertices, faces, normals or None, colors or None)`` of one trimesh geometry placed by
    ``transform`` (float64; normals by the inverse transpose, renormalized; colors in [0, 1])."""
    vertices = np.asarray(geometry.vertices, dtype=np.float64)
    vertices = vertices @ transform[:3, :3].T + transform[:3, 3]
    faces = np.asarray(getattr(geometry, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    normals = colors = None
    trimesh = _trimesh()
    if trimesh is not None and isinstance(geometry, trimesh.Trimesh):
        # trimesh keeps normals read from the file in its cache; asking for
        # ``vertex_normals`` otherwise computes them (angle-weighted), so look first.
        cache = getattr(getattr(geometry, "_cache", None), "cache", {})
        normals = cache.get("vertex_normals") if hasattr(cache, "get") else None
        if normals is not None:
            normals = np.asarray(normals, dtype=np.float64)
            if normals.shape != vertices.shape:
                normals = None
            else:
                normals = normals @ np.linalg.inv(transform[:3, :3])  # rows times the inverse transpose
                length = np.linalg.norm(normals, axis=1, keepdims=True)
                normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), 0.0)
        visual = getattr(geometry, "visual", None)
        if visual is not None and getattr(visual, "kind", None) == "vertex":
            rgba = np.asarray(visual.vertex_colors)
            if rgba.shape[0] == len(vertices):
                colors = rgba[:, :3].astype(np.float64) / 255.0
    else:
        rgba = np.asarray(getattr(geometry, "colors", ()))
        if rgba.ndim == 2 and rgba.shape[0] == len(vertices):
            colors = rgba[:, :3].astype(np.float64) / 255.0
    return vertices, faces, normals, colors


def _concatenate(parts):
    """One ``(vertices, faces, normals, colors)`` from several: faces re-indexed; normals and colors
    only when every part has them."""
    if len(parts) == 1:
        return parts[0]
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    vertices = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + o for p, o in zip(parts, offsets)])
    normals = np.concatenate([p[2] for p in parts]) if all(p[2] is not None for p in parts) else None
    colors = np.concatenate([p[3] for p in parts]) if all(p[3] is not None for p in parts) else None
    return vertices, faces, normals, colors


def _as_rows(value, dtype, name: str) -> np.ndarray:
    """``value`` as a C-contiguous (N, 3) array of ``dtype``, or InputError."""
    arr = np.ascontiguousarray(value, dtype=dtype)
    if arr.ndim != 2 or arr.shape[1] != 3:
        if arr.size == 0:
            return arr.reshape(0, 3)
        raise InputError(f"{name} must have shape (N, 3), got {arr.shape}")
    return arr
