"""Triangle meshes: the ground-truth surfaces that splats are sampled from.

A :class:`Mesh` is a plain indexed triangle list (float32 vertices, int64
faces) with optional per-vertex normals and colors. It is read from PLY files
with a ``face`` element (:mod:`surfsplat.io.ply`) or from OBJ files (trimesh,
here). :func:`area_weighted_normals` gives vertex normals to meshes that store
none.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ..errors import InputError


@dataclass
class Mesh:
    """An indexed triangle mesh.

    Attributes:
        vertices: (V, 3) float32, model space.
        faces: (F, 3) int64 vertex indices; counter-clockwise seen from the
            outside gives the outward normal (right-hand rule).
        vertex_normals: (V, 3) float32 unit normals, or None.
        vertex_colors: (V, 3) float32 linear RGB in [0, 1], or None.

    The constructor checks shapes and converts dtypes; :meth:`validated`
    checks the contents (faces present, finite vertices, indices in range).
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_normals: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None

    def __post_init__(self) -> None:
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

    def __repr__(self) -> str:
        extra = [name for name in ("vertex_normals", "vertex_colors") if getattr(self, name) is not None]
        return f"Mesh({len(self.vertices)} vertices, {len(self.faces)} faces" + \
            (f", with {', '.join(extra)})" if extra else ")")

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
        """Axis-aligned bounds ``(min, max)``, each (3,) float32, of the vertices
        used by faces (all vertices when there are no faces), model units."""
        used = self.vertices[np.unique(self.faces)] if len(self.faces) else self.vertices
        if len(used) == 0:
            raise InputError("mesh has no vertices")
        return used.min(axis=0), used.max(axis=0)

    # -- validation --------------------------------------------------------

    def validated(self, source: str = "mesh") -> "Mesh":
        """Return ``self`` after checking its contents, or raise InputError.

        Checked: at least one face, all vertices finite, every face index in
        ``[0, V)``. ``source`` names the file or array in messages.
        """
        n = len(self.vertices)
        if len(self.faces) == 0:
            raise InputError(f"{source}: mesh has no faces")
        finite = np.isfinite(self.vertices).all(axis=1)
        if not finite.all():
            raise InputError(f"{source}: {int((~finite).sum())} of {n} mesh vertices have "
                             f"non-finite coordinates (first at vertex {int(np.argmin(finite))})")
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
                         f"{int(bad.any(axis=1).sum())} faces have out-of-range indices")


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


def read_obj(path: Path) -> Mesh:
    """Read a Wavefront OBJ file as a :class:`Mesh` with trimesh (unvalidated).

    Polygons are triangulated by trimesh; several objects in one file are
    concatenated. Vertex normals are kept when the file has them (``vn`` lines),
    else ``vertex_normals`` is None. Per-vertex colors (``v x y z r g b``) are
    kept; texture-mapped colors are ignored. trimesh drops vertices that no
    face uses; an OBJ with vertices but no faces gives a Mesh with (0, 3)
    faces (a point cloud for ``load``, an error for ``load_mesh``). Any parse
    failure, and a file without vertices, raises InputError naming the file.
    """
    source = str(path)
    try:
        loaded = trimesh.load(source, file_type="obj", process=False)
        if isinstance(loaded, trimesh.Scene):
            parts = [g for g in loaded.dump() if isinstance(g, (trimesh.Trimesh, trimesh.PointCloud))]
            meshes = [g for g in parts if isinstance(g, trimesh.Trimesh)]
            if meshes:
                loaded = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
            elif parts:
                loaded = parts[0] if len(parts) == 1 else trimesh.PointCloud(
                    np.concatenate([p.vertices for p in parts]))
            else:
                loaded = trimesh.Trimesh()
        colors = normals = None
        if isinstance(loaded, trimesh.PointCloud):  # vertices only
            vertices = np.asarray(loaded.vertices, dtype=np.float64)
            faces = np.zeros((0, 3), dtype=np.int64)
            rgba = np.asarray(loaded.colors) if len(getattr(loaded, "colors", ())) else None
            if rgba is not None and rgba.shape[0] == len(vertices):
                colors = rgba[:, :3].astype(np.float64) / 255.0
        elif isinstance(loaded, trimesh.Trimesh):
            vertices = np.asarray(loaded.vertices, dtype=np.float64)
            faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
            # trimesh keeps normals read from the file in its cache; asking for
            # ``vertex_normals`` otherwise computes them (angle-weighted), so look first.
            cache = getattr(getattr(loaded, "_cache", None), "cache", {})
            normals = cache.get("vertex_normals") if hasattr(cache, "get") else None
            if normals is not None:
                normals = np.asarray(normals, dtype=np.float64)
                if normals.shape != vertices.shape:
                    normals = None
            visual = getattr(loaded, "visual", None)
            if getattr(visual, "kind", None) == "vertex":
                rgba = np.asarray(visual.vertex_colors)
                if rgba.shape[0] == len(vertices):
                    colors = rgba[:, :3].astype(np.float64) / 255.0
        else:
            raise InputError(f"{source}: OBJ file holds no triangle mesh ({type(loaded).__name__})")
    except InputError:
        raise
    except Exception as exc:  # trimesh raises many types (IndexError, ValueError, ...)
        raise InputError(f"{source}: cannot read OBJ file: {type(exc).__name__}: {exc}") from exc
    if len(vertices) == 0:
        raise InputError(f"{source}: OBJ file has no vertices")
    return Mesh(vertices, faces, normals, colors)


def _as_rows(value, dtype, name: str) -> np.ndarray:
    """``value`` as a C-contiguous (N, 3) array of ``dtype``, or InputError."""
    arr = np.ascontiguousarray(value, dtype=dtype)
    if arr.ndim != 2 or arr.shape[1] != 3:
        if arr.size == 0:
            return arr.reshape(0, 3)
        raise InputError(f"{name} must have shape (N, 3), got {arr.shape}")
    return arr
