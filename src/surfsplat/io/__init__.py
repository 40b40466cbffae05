"""Reading point clouds and meshes, writing PLY.

- :func:`load_input`: the one entry point that tells a mesh from a point
  cloud: a file with faces (PLY with a non-empty ``face`` element, OBJ with
  faces, STL, OFF, GLB, glTF) -> welded :class:`Mesh` (its surface is what
  should be drawn, see ``surfsplat.geometry.sampling.surface_splats``); any
  other file -> validated :class:`~surfsplat.cloud.SplatCloud`.
- :func:`load`: ``.ply`` (point cloud, surfel model or triangle mesh), ``.obj``,
  ``.stl``, ``.off``, ``.glb``, ``.gltf`` (triangle meshes: their vertices),
  ``.las`` / ``.laz`` (LiDAR, needs laspy and lazrs: the ``las`` extra), ``.pcd`` (PCL,
  :mod:`.pcd`), ``.xyz`` / ``.pts`` / ``.csv`` / ``.txt`` (point text,
  :mod:`.text`), trained Gaussian-splat ``.ply`` (:mod:`.gaussians`) -> validated
  :class:`~surfsplat.cloud.SplatCloud`.
- :func:`save_ply`: a SplatCloud -> PLY with every array it holds; ``load``
  reads it back identically.
- :func:`load_mesh`: ``.ply`` with faces, ``.obj``, ``.stl``, ``.off``,
  ``.glb``, ``.gltf`` -> :class:`Mesh` (the ground truth that splats are
  sampled from).
- :mod:`.surface`: welding (:func:`weld`), edge adjacency, dihedral angles and
  crease-aware normals of meshes.

Every failure raises :class:`~surfsplat.errors.InputError` naming the file.
These functions print no progress themselves (callers such as the CLI wrap
them in ``surfsplat.progress.stage``).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..cloud import SplatCloud
from ..errors import InputError, file_reader
from .atomic import check_readable
from .mesh import TRIMESH_TYPES, Mesh, area_weighted_normals, check_face_indices, read_trimesh
from .e57 import read_e57
from .las import read_las
from .pcd import read_pcd
from .text import TEXT_EXTENSIONS, read_text
from .ply import read_ply, read_ply_input, read_ply_mesh, write_ply
from .surface import (AUTO, DEFAULT_SHARP_ANGLE, WELD_TOLERANCE, auto_sharp_angle, crease_normals, dihedral_angles,
                      shading_normals, weld)

#: File extensions :func:`load_mesh` understands (lower case).
MESH_EXTENSIONS = (".ply", ".obj", ".stl", ".off", ".glb", ".gltf")
#: File extensions :func:`load` and :func:`load_input` understand (lower case).
CLOUD_EXTENSIONS = MESH_EXTENSIONS + (".las", ".laz", ".pcd", ".e57") + TEXT_EXTENSIONS


@file_reader
def load(path: str | os.PathLike) -> SplatCloud:
    """Read a point cloud or mesh file as a validated SplatCloud.

    Dispatches on the extension:

    - ``.ply``: see :mod:`surfsplat.io.ply` for the vertex properties read
      (positions, normals, colors, splat axes or radius, normal field, clip
      lines). With a ``face`` element the vertices become the points; stored
      normals are kept, else vertices get area-weighted face normals and
      vertices used by no face are dropped (counted in the warning).
    - ``.obj``, ``.stl``, ``.off``, ``.glb``, ``.gltf``: triangle mesh read
      with trimesh: vertices become points with the file's normals (or
      area-weighted ones) and vertex colors if any; an OBJ with vertices and
      no faces is read as a point cloud (no normals). (:func:`load_input`
      gives the mesh itself, whose surface is what should be drawn.)
    - ``.las`` / ``.laz``: positions and RGB (optional dependency laspy).
    - ``.pcd``: PCL point clouds, ascii or binary (:mod:`surfsplat.io.pcd`).
    - ``.e57``: every scan with its pose applied, colors, ``intensity`` and
      ``scan`` attributes (optional dependency pye57, :mod:`surfsplat.io.e57`).
    - ``.xyz``, ``.pts``, ``.csv``, ``.txt``: point text, with a header row of
      names or columns ``x y z [nx ny nz] [r g b]`` (:mod:`surfsplat.io.text`).
    - a ``.ply`` of trained Gaussians (3DGS / 2DGS): splat ellipses
      (:mod:`surfsplat.io.gaussians`).

    Returns a SplatCloud: positions (N, 3) float32 model space (the file's
    units); normals (N, 3) unit, colors (N, 3) in [0, 1], u, v (N, 3) model
    units, normal_field (N, 2), clip_lines (N, 2, 3) where present. The cloud
    went through ``SplatCloud.validated``: invalid rows (non-finite values,
    zero normals, degenerate axes) are dropped with an
    :class:`~surfsplat.cloud.InvalidPointsWarning` giving counts.

    Raises:
        InputError: missing file, unknown extension, malformed file, or no
            valid point; the message names the file.
    """
    path = _existing(path, CLOUD_EXTENSIONS)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        cloud = read_ply(path)
    elif suffix in TRIMESH_TYPES:
        cloud = _mesh_to_cloud(read_trimesh(path, TRIMESH_TYPES[suffix]), str(path))
    else:
        cloud = _read_points(path)
    return cloud.validated(source=str(path), file=path)


@file_reader
def load_mesh(path: str | os.PathLike, *, welded: bool = False) -> Mesh:
    """Read a triangle mesh: ``.ply`` with a face element, ``.obj``, ``.stl``, ``.off``, ``.glb``, ``.gltf``.

    Args:
        path: the file. OBJ, STL, OFF, GLB and glTF are read with trimesh as
            stored (no merging): an STL file is a triangle soup (see
            :func:`surfsplat.io.mesh.read_trimesh`).
        welded: merge coincident vertices (:func:`weld`, tolerance
            :data:`WELD_TOLERANCE` (1e-6) times the bounding-box diagonal;
            ``merged_vertices`` and ``collapsed_faces`` count the changes).

    Returns a validated :class:`Mesh`: vertices (V, 3) float32 model space,
    faces (F, 3) int64 (polygons fan-triangulated), vertex_normals (V, 3)
    float32 or None (None when the file stores none), vertex_colors (V, 3)
    float32 in [0, 1] or None; after welding, possibly corner_normals.

    Raises:
        InputError naming the file: missing file, unknown extension, malformed
        file, no faces, non-finite vertices, face indices out of range.
    """
    path = _existing(path, MESH_EXTENSIONS)
    suffix = path.suffix.lower()
    mesh = read_ply_mesh(path) if suffix == ".ply" else read_trimesh(path, TRIMESH_TYPES[suffix])
    mesh = mesh.validated(str(path))
    return weld(mesh, source=str(path)) if welded else mesh


@file_reader
def load_input(path: str | os.PathLike) -> Mesh | SplatCloud:
    """Read any supported file as what it is: a surface (:class:`Mesh`) or points (SplatCloud).

    A file with faces is a mesh: PLY with a non-empty ``face`` element, OBJ
    with faces, and STL, OFF, GLB, glTF. It is returned validated and welded
    (:func:`weld`: coincident vertices within :data:`WELD_TOLERANCE` (1e-6)
    of the bounding-box diagonal merged, so triangle soups and crease-split
    CAD meshes are connected surfaces; the count is ``Mesh.merged_vertices``,
    faces that collapsed ``Mesh.collapsed_faces``). Stored normals survive
    welding (per corner where merged vertices disagree). Every other file (PLY
    without faces, OBJ without faces, LAS/LAZ) is read as by :func:`load`: a
    validated SplatCloud.

    Raises:
        InputError naming the file: missing file, unknown extension, malformed
        file, a mesh with non-finite vertices or bad face indices, no valid point.
    """
    path = _existing(path, CLOUD_EXTENSIONS)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        data = read_ply_input(path)
    elif suffix in TRIMESH_TYPES:
        data = read_trimesh(path, TRIMESH_TYPES[suffix])
        if len(data.faces) == 0:  # an OBJ with vertices only
            data = _mesh_to_cloud(data, str(path))
    else:
        data = _read_points(path)
    if isinstance(data, Mesh):
        return weld(data.validated(str(path)), source=str(path))
    return data.validated(source=str(path), file=path)


def save_ply(cloud: SplatCloud, path: str | os.PathLike, *, binary: bool = True,
             overwrite: bool = True) -> Path:
    """Write every array of ``cloud`` to a PLY file and return the Path written.

    One ``vertex`` element with the properties, in this order, of the arrays
    present: ``x y z``, ``nx ny nz``, ``red green blue``, ``ux uy uz vx vy vz``
    (u and v both present), ``alpha beta`` (normal field), ``clip0_a clip0_b
    clip0_c clip1_a clip1_b clip1_c`` (clip lines), then each of ``cloud.attributes``
    in its own dtype (64-bit integers as double). All float32, except colors:
    uchar when every color is exactly a float32 ``k / 255`` (as read from 8-bit
    files), else float32 in [0, 1]. Colors are clipped to [0, 1] first; for any
    other cloud ``load(save_ply(cloud, p))`` returns equal arrays.

    Args:
        cloud: the splats to write.
        path: destination file (conventionally ``.ply``).
        binary: binary_little_endian (default) or ascii.
        overwrite: replace an existing file (default; atomically, see
            :func:`surfsplat.io.atomic.atomic_path`); False: an existing file
            raises InputError.
    """
    path = Path(path)
    if not isinstance(cloud, SplatCloud):
        raise InputError(f"{path}: save_ply needs a SplatCloud, got {type(cloud).__name__}")
    return write_ply(cloud, path, binary=binary, overwrite=overwrite)


def _existing(path: str | os.PathLike, extensions: tuple[str, ...]) -> Path:
    """``path`` as a Path after checking that it is a file with a known extension."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in extensions:
        raise InputError(f"{path}: unknown file type {suffix or '(no extension)'!r}; "
                         f"expected one of {', '.join(extensions)}")
    return check_readable(path)  # a regular file: no FIFO, device or folder


def _read_points(path: Path) -> SplatCloud:
    """A point-only file (LAS/LAZ, PCD, point text) by its extension, unvalidated."""
    suffix = path.suffix.lower()
    if suffix == ".pcd":
        return read_pcd(path)
    if suffix == ".e57":
        return read_e57(path)
    if suffix in TEXT_EXTENSIONS:
        return read_text(path)
    return read_las(path)


def _mesh_to_cloud(mesh: Mesh, source: str) -> SplatCloud:
    """The mesh's vertices as points, with its normals or area-weighted ones
    (no normals when the mesh has no faces: a point cloud)."""
    if len(mesh.faces) == 0:
        return SplatCloud(positions=mesh.vertices, normals=mesh.vertex_normals, colors=mesh.vertex_colors,
                          origin=mesh.origin)
    check_face_indices(mesh.faces, len(mesh.vertices), source)
    normals = mesh.vertex_normals
    if normals is None:
        normals = area_weighted_normals(mesh.vertices, mesh.faces)
    return SplatCloud(positions=mesh.vertices, normals=normals, colors=mesh.vertex_colors, origin=mesh.origin)


__all__ = ["load", "load_input", "load_mesh", "save_ply", "Mesh", "CLOUD_EXTENSIONS", "MESH_EXTENSIONS",
           "weld", "crease_normals", "shading_normals", "dihedral_angles", "auto_sharp_angle", "AUTO",
           "DEFAULT_SHARP_ANGLE", "WELD_TOLERANCE"]
