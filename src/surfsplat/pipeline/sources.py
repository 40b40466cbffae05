"""From what a user hands over to a model: files, built-in scenes, objects; the data's up axis.

Loading reads and validates; raw points are preprocessed (normals, splat ellipses), a mesh is kept
as a mesh (its surface is sampled per view, :meth:`surfsplat.pipeline.models.MeshModel.sampled`).
"""

from __future__ import annotations

from pathlib import Path

from .. import progress
from ..cloud import SplatCloud
from ..colors import check_color_source
from ..errors import InputError
from ..geometry.preprocess import NONPLANAR, preprocess
from ..hierarchy import Hierarchy, load_hierarchy
from ..hierarchy.storage import hierarchy_up
from ..hierarchy.chunked import ChunkedHierarchy, chunked_up, is_chunked_hierarchy, open_chunked
from ..io import Mesh, load, load_input
from ..io.objects import from_object
from ..io.ply import ply_up
from ..orientation import DEMO_PREFIX, Z_UP_SUFFIXES, change_hint, model_up, stored_up, up_name
from ..scenes import SCENES, demo_scene
from .options import SourceOptions

#: Suffix of hierarchy files (``surfsplat build``).
HIERARCHY_SUFFIX = ".npz"
#: Suffixes of files whose z axis points up (LiDAR, E57 scans), drawn hybrid by default.
LIDAR_SUFFIXES = Z_UP_SUFFIXES


def is_hierarchy_file(source) -> bool:
    """True for a path naming a hierarchy file (``.npz``, written by ``surfsplat build``)."""
    return isinstance(source, (str, Path)) and Path(source).suffix.lower() == HIERARCHY_SUFFIX


def is_demo_source(source) -> bool:
    """True for ``"demo:NAME"``, a built-in procedural scene."""
    return isinstance(source, str) and source.startswith(DEMO_PREFIX)


def is_lidar(source) -> bool:
    """Whether ``source`` names a LAS/LAZ or E57 file (drawn hybrid by default)."""
    return isinstance(source, (str, Path)) and Path(source).suffix.lower() in LIDAR_SUFFIXES


def source_name(source) -> str:
    """A short name of ``source`` for messages and titles: a path's, a scene's, else the object's type."""
    if isinstance(source, (str, Path)):
        return str(source)
    return type(source).__name__


def check_source(source) -> None:
    """Cheap checks before any heavy work: a known demo scene, an existing file (InputError else)."""
    if is_demo_source(source):
        name = source[len(DEMO_PREFIX):]
        if name not in SCENES:
            raise InputError(f"unknown demo scene {name!r}; choose one of "
                             f"{', '.join(DEMO_PREFIX + n for n in sorted(SCENES))}")
    elif isinstance(source, (str, Path)) and not Path(source).is_file() and not is_chunked_hierarchy(source):
        raise InputError(f"{source}: no such file (or {DEMO_PREFIX}NAME for a built-in scene)")


def natural_up(source, model=None) -> tuple[float, float, float]:
    """The up axis to show a source with: :func:`up_of`'s, without the reason."""
    return up_of(source, model)[0]


def up_of(source, model=None) -> tuple[tuple[float, float, float], str]:
    """The up axis to show a source with, and one sentence saying why and how to change it
    (:func:`surfsplat.orientation.model_up`): the up stored in the file (a PLY's ``comment surfsplat
    up``, a hierarchy's ``point_up``, a chunked hierarchy's manifest) or with the model object, else
    its kind's (+z for LAS/LAZ/E57 files, +y for ``demo:`` scenes), else guessed from the shape of
    the loaded ``model`` where one is given (flat in z: +z), else +y."""
    if isinstance(source, (str, Path)) and not is_demo_source(source):
        path = Path(source)
        stored = (chunked_up(path) if is_chunked_hierarchy(path) else hierarchy_up(path) if is_hierarchy_file(path)
                  else ply_up(path) if path.suffix.lower() == ".ply" and path.is_file() else None)
        if stored is not None:
            return stored, f"up {up_name(stored)} (stored in {path.name}); {change_hint(stored)}"
    elif model is None:
        stored = stored_up(source)   # a model object's own up
        if stored is not None:
            return model_up(source)
    return model_up(model, source)


def load_cloud(path: str | Path, noun: str = "points") -> SplatCloud:
    """:func:`surfsplat.io.load` with progress: the stage, then the count of ``noun``."""
    with progress.stage(f"loading {path}"):
        cloud = load(path)
    progress.message(f"{len(cloud):,} {noun}")
    return cloud


def as_splats(source: SplatCloud | str | Path, options: SourceOptions | None = None) -> SplatCloud:
    """A render-ready SplatCloud from a cloud or a point file, preprocessed if needed (``options``:
    k neighbours, outliers, sharp features)."""
    options = options or SourceOptions()
    cloud = load_cloud(source) if isinstance(source, (str, Path)) else source
    if not isinstance(cloud, SplatCloud):
        raise InputError(f"expected a SplatCloud or a file path, got {type(source).__name__}")
    if not cloud.has_splats:
        check_color_source(cloud, options, added=(NONPLANAR,))   # a misspelt attribute fails before the work
        cloud = preprocess(cloud, k=options.k, sharp_angle=options.raw_sharp_angle, outliers=options.outliers,
                           mark_nonplanar=True)
    return cloud


def read_source(source, options: SourceOptions | None = None):
    """What a source names, read: a :class:`~surfsplat.hierarchy.Hierarchy` (object or ``.npz`` from
    ``surfsplat build``), a :class:`~surfsplat.hierarchy.chunked.ChunkedHierarchy` (a directory from
    ``surfsplat build --chunked``: cells are read per view), the built-in scene of ``"demo:NAME"``, a
    :class:`~surfsplat.io.Mesh` (a file with faces: PLY, OBJ, STL, OFF, GLB/glTF; welded), or a
    render-ready SplatCloud (raw points preprocessed, :func:`as_splats`); with ``options.vertices`` a
    mesh's vertices as points. Other objects go through :func:`surfsplat.io.objects.from_object`: an
    (N, 3) array, a dict/record array/DataFrame of named columns, trimesh and Open3D objects."""
    options = options or SourceOptions()
    if isinstance(source, (Hierarchy, ChunkedHierarchy)):
        return source
    if not isinstance(source, (str, Path, SplatCloud, Mesh)):
        source = from_object(source)   # arrays, tables, trimesh and Open3D objects
    if isinstance(source, Mesh):
        return as_splats(SplatCloud(source.vertices, source.vertex_normals, source.vertex_colors, origin=source.origin),
                         options) if options.vertices else source
    if is_demo_source(source):
        check_source(source)
        with progress.stage(f"building scene {source[len(DEMO_PREFIX):]}"):
            return demo_scene(source[len(DEMO_PREFIX):])
    if is_hierarchy_file(source):
        with progress.stage(f"loading the hierarchy {source}"):
            hierarchy = load_hierarchy(source)
        progress.message(f"{len(hierarchy.points):,} points, {len(hierarchy):,} nodes in {hierarchy.levels} levels")
        return hierarchy
    if is_chunked_hierarchy(source):
        chunked = open_chunked(source)
        progress.message(f"{chunked.point_count:,} points in {len(chunked.cells):,} cells (read as views need them)")
        return chunked
    if isinstance(source, (str, Path)) and not options.vertices:
        with progress.stage(f"loading {source}"):
            data = load_input(source)
        if isinstance(data, Mesh):
            check_color_source(data, options)
            merged = f"; welded {data.merged_vertices:,} coincident vertices" if data.merged_vertices else ""
            progress.message(f"a mesh: {len(data.faces):,} faces, {len(data.vertices):,} vertices{merged} "
                             f"(its surface is sampled; --vertices draws the vertices instead)")
            return data
        progress.message(f"{len(data):,} points")
        return as_splats(data, options)
    return as_splats(source, options)
