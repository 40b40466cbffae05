"""Python objects in and out: NumPy arrays, dicts, DataFrames, trimesh and Open3D geometry.

:func:`from_object` turns what the 3D Python ecosystem holds in memory into what
the renderer draws:

- a :class:`~surfsplat.cloud.SplatCloud` or :class:`~surfsplat.io.mesh.Mesh`: as it is
  (validated; a Mesh welded as :func:`surfsplat.io.load_input` welds files);
- an (N, 3) float array: positions;
- a mapping of named columns (``dict``), a NumPy structured or record array, or a pandas
  ``DataFrame`` (duck-typed: ``.columns`` and ``.to_numpy``): columns named as
  :meth:`SplatCloud.from_dict <surfsplat.cloud.SplatCloud.from_dict>` reads them
  (``positions`` or ``x y z``, ``nx ny nz``, ``red green blue`` or ``r g b`` (uint8 or
  float), ``radius``, ``ux .. vz``); other columns are kept aside (``extras``);
- ``trimesh.Trimesh`` -> Mesh (vertex normals only when the object stores them; vertex colors);
  ``trimesh.PointCloud`` -> SplatCloud (colors); ``trimesh.Scene`` -> its geometry placed by
  the scene graph, a Mesh when it has faces;
- an Open3D ``PointCloud`` (``points``, ``normals``, ``colors``) or ``TriangleMesh``
  (``vertices``, ``triangles``, ``vertex_normals``, ``vertex_colors``), duck-typed (Open3D
  itself is not imported). Open3D colors are floats in [0, 1].

:func:`to_trimesh` and :func:`to_open3d` go the other way (Open3D only when installed).
Every failure is an :class:`~surfsplat.errors.InputError` naming the object's type.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError
from .mesh import Mesh, _trimesh, _trimesh_arrays, _trimesh_parts
from .surface import weld

if TYPE_CHECKING:
    import trimesh

#: What :func:`from_object` accepts, for messages.
ACCEPTED = ("a SplatCloud, a Mesh, an (N, 3) array of positions, a dict / structured array / "
            "pandas DataFrame of named columns (x y z or positions, nx ny nz, red green blue, radius, ...), "
            "a trimesh Trimesh, PointCloud or Scene, or an Open3D PointCloud or TriangleMesh")


def from_object(obj, *, extras: dict | None = None) -> SplatCloud | Mesh:
    """A validated SplatCloud or Mesh from an in-memory object (see the module docstring).

    Args:
        obj: the object.
        extras: when given, columns of a table that name no SplatCloud array (``intensity``,
            ``classification``, ...) are stored here by their original names.

    Returns a SplatCloud (validated: invalid rows dropped with a warning) or a Mesh (validated,
    then welded like a mesh file).

    Raises:
        InputError naming the type and what is accepted.
    """
    what = type(obj).__name__
    if isinstance(obj, Mesh):
        return weld(obj.validated(what))
    if isinstance(obj, SplatCloud):
        return obj.validated(source=what)
    data = _convert(obj, what, extras)
    if isinstance(data, Mesh):
        return weld(data.validated(what))
    return data.validated(source=what)


def _convert(obj, what: str, extras: dict | None) -> SplatCloud | Mesh:
    trimesh = _trimesh()   # an object of trimesh's has it loaded
    if trimesh is not None and isinstance(obj, (trimesh.Trimesh, trimesh.PointCloud, trimesh.Scene)):
        return _from_trimesh(obj, what)
    if isinstance(obj, np.ndarray):
        if obj.dtype.names:
            return _table(obj, what, extras)
        arr = obj
        if arr.ndim != 2 or arr.shape[1] != 3 or arr.dtype.kind not in "uif":
            raise InputError(f"{what}: an array of positions must have shape (N, 3) and a numeric dtype, "
                             f"got shape {arr.shape} dtype {arr.dtype}; a table needs named columns "
                             f"(a structured array or a dict). Accepted: {ACCEPTED}")
        return SplatCloud(positions=arr)
    if hasattr(obj, "columns") and hasattr(obj, "to_numpy"):  # a pandas DataFrame
        columns = {name: obj[name].to_numpy() for name in obj.columns}
        return _table(columns, what, extras)
    if isinstance(obj, dict) or (hasattr(obj, "keys") and hasattr(obj, "items") and hasattr(obj, "__getitem__")):
        return _table(obj, what, extras)
    if hasattr(obj, "vertices") and hasattr(obj, "triangles"):  # Open3D TriangleMesh
        return _open3d_mesh(obj, what)
    if hasattr(obj, "points") and not isinstance(obj, (str, bytes)):  # Open3D PointCloud
        return _open3d_cloud(obj, what)
    raise InputError(f"cannot render a {what}; accepted: {ACCEPTED}")


def _table(columns, what: str, extras: dict | None) -> SplatCloud:
    try:
        return SplatCloud.from_dict(columns, extras=extras)
    except InputError as exc:   # attributes kept
        raise InputError(f"{what}: {exc}", **exc.context()) from exc
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what}: columns are not numeric arrays of one length: {exc}") from exc


def _from_trimesh(obj, what: str) -> SplatCloud | Mesh:
    parts = [_trimesh_arrays(geometry, transform) for geometry, transform in _trimesh_parts(obj)]
    if not parts:
        raise InputError(f"{what}: has no geometry")
    faces_in = [p for p in parts if len(p[1])]
    if faces_in:  # a scene with meshes and point clouds: the meshes
        parts = faces_in
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    vertices = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + o for p, o in zip(parts, offsets)])
    normals = np.concatenate([p[2] for p in parts]) if all(p[2] is not None for p in parts) else None
    colors = np.concatenate([p[3] for p in parts]) if all(p[3] is not None for p in parts) else None
    if len(faces):
        return Mesh(vertices, faces, normals, colors)
    return SplatCloud(positions=vertices, normals=normals, colors=colors)


def _rows(obj, name: str, what: str, n: int | None = None) -> np.ndarray | None:
    """``np.asarray(obj.name)`` as (M, 3), or None when absent or empty (Open3D's way to say none)."""
    value = getattr(obj, name, None)
    if value is None:
        return None
    arr = np.asarray(value)
    if arr.size == 0:
        return None
    if arr.ndim != 2 or arr.shape[1] != 3 or (n is not None and len(arr) != n):
        expected = "(N, 3)" if n is None else f"({n}, 3)"
        raise InputError(f"{what}: {name} must have shape {expected}, got {arr.shape}")
    return arr


def _open3d_cloud(obj, what: str) -> SplatCloud:
    points = _rows(obj, "points", what)
    if points is None:
        raise InputError(f"{what}: has no points")
    n = len(points)
    return SplatCloud.from_arrays(points, _rows(obj, "normals", what, n), _rows(obj, "colors", what, n))


def _open3d_mesh(obj, what: str) -> Mesh | SplatCloud:
    vertices = _rows(obj, "vertices", what)
    if vertices is None:
        raise InputError(f"{what}: has no vertices")
    n = len(vertices)
    triangles = np.asarray(obj.triangles)
    normals = _rows(obj, "vertex_normals", what, n)
    colors = _rows(obj, "vertex_colors", what, n)
    if triangles.size == 0:
        return SplatCloud.from_arrays(vertices, normals, colors)
    if triangles.ndim != 2 or triangles.shape[1] != 3:
        raise InputError(f"{what}: triangles must have shape (F, 3), got {triangles.shape}")
    return Mesh(vertices, triangles, normals, None if colors is None else colors.astype(np.float32))


# -- out ---------------------------------------------------------------------


def to_trimesh(cloud: SplatCloud) -> trimesh.PointCloud:
    """The splat centers (world coordinates, float64) as a ``trimesh.PointCloud`` with 8-bit RGBA
    colors (when the cloud has colors). Normals and splat axes have no place in a trimesh
    PointCloud: normals are kept in ``metadata["normals"]``."""
    if not isinstance(cloud, SplatCloud):
        raise InputError(f"to_trimesh needs a SplatCloud, got {type(cloud).__name__}")
    colors = None
    if cloud.colors is not None:
        rgb = np.round(np.clip(cloud.colors, 0.0, 1.0) * 255.0).astype(np.uint8)
        colors = np.column_stack([rgb, np.full(len(cloud), 255, np.uint8)])
    import trimesh   # deferred: 0.7 s to import (see surfsplat.io.mesh._trimesh)

    out = trimesh.PointCloud(cloud.world_positions(), colors=colors)
    if cloud.normals is not None:
        out.metadata["normals"] = cloud.normals.copy()
    return out


def to_open3d(cloud: SplatCloud):
    """The cloud as an ``open3d.geometry.PointCloud`` (world points, normals, colors in [0, 1]).

    Raises InputError when Open3D is not installed (``pip install open3d``)."""
    if not isinstance(cloud, SplatCloud):
        raise InputError(f"to_open3d needs a SplatCloud, got {type(cloud).__name__}")
    try:
        import open3d
    except ImportError as exc:
        raise InputError("to_open3d needs Open3D, which is not installed (pip install open3d)") from exc
    out = open3d.geometry.PointCloud()
    out.points = open3d.utility.Vector3dVector(cloud.world_positions())
    if cloud.normals is not None:
        out.normals = open3d.utility.Vector3dVector(cloud.normals.astype(np.float64))
    if cloud.colors is not None:
        out.colors = open3d.utility.Vector3dVector(np.clip(cloud.colors, 0, 1).astype(np.float64))
    return out


__all__ = ["from_object", "to_trimesh", "to_open3d", "ACCEPTED"]
