"""The one orchestrator: load -> (preprocess) -> LOD cut -> camera -> draw -> Frame.

Every way of turning a request into a picture goes through this module: the Python API
(:func:`render`), the command line (``surfsplat.cli`` parses flags into the typed options
below and calls these functions) and the viewer (``surfsplat.viewer`` uses the same loading,
framing and LOD selection per frame). Nothing below this module (io, geometry, hierarchy,
render) knows about the command line or the window; see ``docs/architecture.md``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path
from typing import Union

import numpy as np

from . import progress
from .camera import MIN_FOV, Camera, camera_flags, direction_vector, fit_points, rotate
from .camera_path import orbit_cameras  # noqa: F401 (part of the API: surfsplat.api.orbit_cameras)
from .cloud import SplatCloud
from .colors import ELEVATION, ColorOptions, colorize
from .errors import EmptyFrameWarning, InputError
from .geometry.closed import closed_orientation, eye_outside, flipped_normals, is_closed_surface, outward_splats
from .geometry.preprocess import NONPLANAR, preprocess
from .geometry.robust import OUTLIER_ACTIONS, OutlierAction
from .geometry.sampling import DEFAULT_SPACING_PX, samples_for_pixels, surface_splats
from .hierarchy import Hierarchy, LodShading, Selection, build_hierarchy, load_hierarchy, select
from .hierarchy.lod import check_point_budget, selection_flags
from .hierarchy.sequential import sequential_layout
from .hierarchy.chunked import ChunkedHierarchy, chunked_up, is_chunked_hierarchy, open_chunked
from .hierarchy.storage import hierarchy_up
from .io.ply import ply_up
from .orientation import model_up, stored_up
from .viewpoint import choose_direction
from .io import Mesh, load, load_input, load_mesh
from .io.image_maps import normals_from_depth
from .io.objects import from_object
from .io.surface import AUTO
from .lighting import Lights
from .rendering.frame import Frame
from .rendering.hybrid import facing_points
from .rendering.lod_auto import AUTO, auto_lod_tolerance, auto_merged
from .rendering.mesh import render_mesh as rasterize_mesh
from .rendering.options import RenderOptions, TechniqueName
from .rendering.renderer import default_renderer
from .rendering.sequential import LOD_MODES, LodMode, render_sequential
from .scenes import SCENES, demo_scene

#: What can be rendered: splats as they are, a point-octree cut per view, or a surface (a mesh,
#: sampled into splats for the view).
Model = Union[SplatCloud, Hierarchy, ChunkedHierarchy, Mesh]

#: Image size (pixels) of :func:`render` when no camera is given.
DEFAULT_WIDTH = DEFAULT_HEIGHT = 512
#: Background color (RGB in [0, 1]).
DEFAULT_BACKGROUND = (1.0, 1.0, 1.0)
#: Neighbours used to preprocess raw points.
DEFAULT_K = 8
#: LOD screen tolerance (pixels) used when a hierarchy is rendered without one.
DEFAULT_LOD_TOLERANCE = 1.0
#: Normal field of coarse LOD splats (see :func:`surfsplat.hierarchy.select`).
DEFAULT_LOD_SHADING: LodShading = "fit"
#: Default viewing direction (toward the eye) for a y-up world: front, a little right and above.
DEFAULT_DIRECTION = (0.4, 0.35, 1.0)
#: Suffix of hierarchy files (``surfsplat build``).
HIERARCHY_SUFFIX = ".npz"
#: A frame covering less than this fraction of the pixels the model's bounds project to warns.
MIN_COVERAGE = 0.01
#: Prefix naming a built-in scene as a source: ``"demo:torus"``.
DEMO_PREFIX = "demo:"


# -- loading -------------------------------------------------------------------

def is_hierarchy_file(source) -> bool:
    """True for a path naming a hierarchy file (``.npz``, written by ``surfsplat build``)."""
    return isinstance(source, (str, Path)) and Path(source).suffix.lower() == HIERARCHY_SUFFIX


def is_demo_source(source) -> bool:
    """True for ``"demo:NAME"``, a built-in procedural scene."""
    return isinstance(source, str) and source.startswith(DEMO_PREFIX)


def check_source(source) -> None:
    """Cheap checks before any heavy work: a known demo scene, an existing file (InputError else)."""
    if is_demo_source(source):
        name = source[len(DEMO_PREFIX):]
        if name not in SCENES:
            raise InputError(f"unknown demo scene {name!r}; choose one of "
                             f"{', '.join(DEMO_PREFIX + n for n in sorted(SCENES))}")
    elif isinstance(source, (str, Path)) and not Path(source).is_file() and not is_chunked_hierarchy(source):
        raise InputError(f"{source}: no such file (or {DEMO_PREFIX}NAME for a built-in scene)")


def load_cloud(path: str | Path, noun: str = "points") -> SplatCloud:
    """:func:`surfsplat.io.load` with progress: the stage, then the count of ``noun``."""
    with progress.stage(f"loading {path}"):
        cloud = load(path)
    progress.message(f"{len(cloud):,} {noun}")
    return cloud


@dataclass(frozen=True)
class SourceOptions:
    """How a source becomes splats: raw points (preprocessed) and meshes (sampled).

    Attributes:
        k: neighbours for preprocessing raw points (>= 3).
        outliers: raw points with no surface neighbourhood of their own (stray points,
            isolated clusters): "drop" (default: the best picture), "cap" their splats, or
            "keep" (:func:`surfsplat.geometry.preprocess.preprocess`).
        vertices: draw a mesh's vertices as points (preprocessed like a scan) instead of
            sampling its surface (the default).
        samples: number of surface samples of a mesh; None: from the view, ``spacing_px``
            apart on screen (:func:`surfsplat.geometry.sampling.samples_for_pixels`, capped at 2M).
        spacing_px: mean on-screen sample spacing, pixels, when ``samples`` is None.
        sharp_angle: dihedral angle (degrees) above which edges are sharp (crease normals, clip
            lines); "auto": 30 for meshes with creases (CAD), none for smooth scans and raw
            points (:func:`surfsplat.io.surface.auto_sharp_angle`); None: no sharp edges. A
            number also detects sharp features in raw points.
        seed: random seed of the samples.
        color: colour the splats by elevation or a per-point attribute
            (:class:`~surfsplat.colors.ColorOptions`, :func:`colored`); None: their own colours.
    """

    k: int = DEFAULT_K
    outliers: OutlierAction = "drop"
    vertices: bool = False
    samples: int | None = None
    spacing_px: float = DEFAULT_SPACING_PX
    sharp_angle: float | str | None = AUTO
    seed: int = 0
    color: ColorOptions | None = None

    def __post_init__(self) -> None:
        if self.color is not None and not isinstance(self.color, ColorOptions):
            raise InputError(f"color must be a ColorOptions, got {type(self.color).__name__}")
        if not (isinstance(self.k, (int, np.integer)) and self.k >= 3):
            raise InputError(f"k must be an integer >= 3 (neighbours), got {self.k!r}")
        if self.outliers not in OUTLIER_ACTIONS:
            raise InputError(f"outliers must be one of {', '.join(OUTLIER_ACTIONS)}, got {self.outliers!r}")
        if self.samples is not None and not (isinstance(self.samples, (int, np.integer)) and self.samples >= 2):
            raise InputError(f"samples must be an integer >= 2, got {self.samples!r}")
        if not (np.isfinite(self.spacing_px) and self.spacing_px > 0):
            raise InputError(f"sample spacing must be a positive number of pixels, got {self.spacing_px!r}")

    @property
    def raw_sharp_angle(self) -> float | None:
        """The sharp-feature angle for raw points: a number given, else none ("auto" decides for meshes)."""
        angle = self.sharp_angle
        return float(angle) if isinstance(angle, (int, float)) and not isinstance(angle, bool) else None


def as_splats(source: SplatCloud | str | Path, options: SourceOptions | None = None) -> SplatCloud:
    """A render-ready SplatCloud from a cloud or a point file, preprocessed if needed (``options``:
    k neighbours, outliers, sharp features)."""
    options = options or SourceOptions()
    if isinstance(source, (str, Path)):
        source = load_cloud(source)
    if not isinstance(source, SplatCloud):
        raise InputError(f"expected a SplatCloud or a file path, got {type(source).__name__}")
    if not source.has_splats:
        source = preprocess(source, k=options.k, sharp_angle=options.raw_sharp_angle, outliers=options.outliers,
                            mark_nonplanar=True)
    return source


def surface_model(model: Model, camera: Camera | None = None, source_options: SourceOptions | None = None, *,
                  image_size: int = DEFAULT_WIDTH, closed: bool | None = None) -> SplatCloud | Hierarchy:
    """A mesh's surface as splats (others as they are): sampled for ``camera`` (the spacing on
    screen), or with the model's diagonal spanning ``image_size`` pixels when no view is known.
    The splats of a closed mesh (``closed``; None: :func:`is_closed_surface` decides) get outward
    normals (:func:`outward_splats`), so that back-face culling keeps the visible side."""
    if not isinstance(model, Mesh):
        return model
    surface = source_options or SourceOptions()
    n = surface.samples
    if n is None:
        n = samples_for_pixels(model, surface.spacing_px, camera=camera, image_size=image_size)
    where = (f"{surface.spacing_px:g} px apart at {camera.width}x{camera.height}" if camera is not None and
             surface.samples is None else "as asked" if surface.samples is not None else
             f"{surface.spacing_px:g} px apart with the model {image_size} px wide")
    progress.message(f"{n:,} samples on the surface ({where})")
    cloud = colored(surface_splats(model, n, sharp_angle=surface.sharp_angle, seed=surface.seed), surface)
    if closed if closed is not None else is_closed_surface(model):
        cloud = outward_splats(cloud)
    lines = cloud.clip_lines is not None
    progress.message(f"{len(cloud):,} surface splats" + (", clipped at sharp and open edges" if lines else ""))
    return cloud


def load_model(source, source_options: SourceOptions | None = None) -> Model:
    """The model a source names, ready to draw (:func:`_load_model`), coloured as
    ``source_options.color`` says (:func:`colored`)."""
    model = _load_model(source, source_options)
    return colored(model, source_options, natural_up(source))


def colored(model: Model, source_options: SourceOptions | None, up=(0.0, 1.0, 0.0)) -> Model:
    """A SplatCloud coloured by ``source_options.color`` along ``up``
    (:func:`surfsplat.colors.colorize`; a hierarchy built from it averages those colours per
    node); a Hierarchy (object or ``.npz``) coloured the same from its points' attributes, its
    nodes by their majority class or mean colour (:meth:`Hierarchy.colorized`); a mesh is
    coloured when its surface is sampled; without ``color`` the model as it is. A chunked
    hierarchy colours each view's splats from the attributes its cells keep
    (:meth:`ChunkedHierarchy.colorized`)."""
    color = source_options.color if source_options is not None else None
    if color is None or isinstance(model, Mesh):
        return model
    value_range = color.value_range
    origin = model_points(model).origin
    if value_range is not None and color.by.lower() == ELEVATION and origin.any():
        # colorize reads the local positions: a range in world elevations moves by the origin's
        shift = float(origin @ np.asarray(up, dtype=np.float64)) / float(np.linalg.norm(up))
        value_range = (value_range[0] - shift, value_range[1] - shift)
    if isinstance(model, (Hierarchy, ChunkedHierarchy)):
        return model.colorized(color.by, color.colormap, value_range, up=up)
    return colorize(model, color.by, color.colormap, value_range, up=up)


def _load_model(source, source_options: SourceOptions | None = None) -> Model:
    """The model a source names, ready to draw.

    A :class:`~surfsplat.hierarchy.Hierarchy` for a hierarchy (object or ``.npz`` file from
    ``surfsplat build``); for ``"demo:NAME"`` the built-in scene; a :class:`~surfsplat.io.Mesh`
    for a mesh (a file with faces: PLY, OBJ, STL, OFF, GLB/glTF; welded; its surface is sampled
    for the view by :func:`render_model`), or its vertices as points with
    ``source_options.vertices``; else a render-ready SplatCloud from a SplatCloud or a point
    file (see :func:`as_splats`). Other objects go through :func:`surfsplat.io.objects.from_object`:
    an (N, 3) array, a dict/record array/DataFrame of named columns, trimesh and Open3D point
    clouds and meshes.
    """
    surface = source_options or SourceOptions()
    if isinstance(source, (Hierarchy, ChunkedHierarchy)):
        return source
    if not isinstance(source, (str, Path, SplatCloud, Mesh)):
        source = from_object(source)   # arrays, tables, trimesh and Open3D objects
    if isinstance(source, Mesh):
        return as_splats(SplatCloud(source.vertices, source.vertex_normals, source.vertex_colors, origin=source.origin),
                         surface) if surface.vertices else source
    if is_demo_source(source):
        check_source(source)
        with progress.stage(f"building scene {source[len(DEMO_PREFIX):]}"):
            return demo_scene(source[len(DEMO_PREFIX):])
    if is_hierarchy_file(source):
        with progress.stage(f"loading the hierarchy {source}"):
            hierarchy = load_hierarchy(source)
        progress.message(f"{len(hierarchy.points):,} points, {len(hierarchy):,} nodes in {hierarchy.levels} levels")
        return hierarchy
    if is_chunked_hierarchy(source):  # a directory from `surfsplat build --chunked`: cells are read per view
        chunked = open_chunked(source)
        progress.message(f"{chunked.point_count:,} points in {len(chunked.cells):,} cells (read as views need them)")
        return chunked
    if isinstance(source, (str, Path)) and not surface.vertices:
        with progress.stage(f"loading {source}"):
            data = load_input(source)
        if isinstance(data, Mesh):
            merged = f"; welded {data.merged_vertices:,} coincident vertices" if data.merged_vertices else ""
            progress.message(f"a mesh: {len(data.faces):,} faces, {len(data.vertices):,} vertices{merged} "
                             f"(its surface is sampled; --vertices draws the vertices instead)")
            return data
        progress.message(f"{len(data):,} points")
        return as_splats(data, surface)
    return as_splats(source, surface)


def as_hierarchy(model: Model, source_options: SourceOptions | None = None, *, image_size: int = DEFAULT_WIDTH) -> Hierarchy:
    """A Hierarchy as it is, or the point-octree built over a render-ready SplatCloud (a mesh's
    surface is sampled first, see :func:`surface_model`)."""
    if isinstance(model, (Hierarchy, ChunkedHierarchy)):
        return model
    model = surface_model(model, None, source_options, image_size=image_size)
    with progress.stage(f"building the point-octree of {len(model):,} splats"):
        return build_hierarchy(model)


def model_points(model: Model) -> SplatCloud:
    """The original splats of a model (for framing): a SplatCloud itself, a Hierarchy's points, a
    mesh's vertices."""
    if isinstance(model, Mesh):
        return SplatCloud(model.vertices, origin=model.origin)
    return model.points if isinstance(model, (Hierarchy, ChunkedHierarchy)) else model


# -- the camera ------------------------------------------------------------------

#: Points used to fit the automatic view (a regular subsample of larger clouds).
FIT_SAMPLE = 200_000
#: Suffixes of files whose z axis points up (LiDAR, E57 scans).
Z_UP_SUFFIXES = (".las", ".laz", ".e57")
#: A model whose extent along up is below this fraction of its horizontal extent (terrain, an
#: aerial survey) is looked at from about 45 degrees above instead of from the front.
FLAT_MODEL_RATIO = 0.2


def natural_up(source, model=None) -> tuple[float, float, float]:
    """The up axis to show a source with (:func:`surfsplat.orientation.model_up`): the up stored with
    the model or in the file (a PLY's ``comment surfsplat up``, a hierarchy's ``point_up``, a chunked
    hierarchy's manifest), else its kind's (+z for LAS/LAZ/E57 files, +y for ``demo:`` scenes), else
    guessed from the shape of ``model`` where one is given, else +y. (No guess without ``model``: a
    guessed up must not tilt a camera the caller placed along it.)"""
    if isinstance(source, (str, Path)) and not is_demo_source(source):
        path = Path(source)
        stored = (chunked_up(path) if is_chunked_hierarchy(path) else hierarchy_up(path) if is_hierarchy_file(path)
                  else ply_up(path) if path.suffix.lower() == ".ply" and path.is_file() else None)
        if stored is not None:
            return stored
    elif model is None:
        stored = stored_up(source)   # a model object's own up
        if stored is not None:
            return stored
    return model_up(model, source)[0]


def default_direction(cloud: SplatCloud, up) -> np.ndarray:
    """The automatic viewing direction (toward the eye): front, a little right and above relative to
    ``up``, unless that view looks at one face of the model head-on and another shows clearly more
    (:func:`surfsplat.viewpoint.choose_direction`: viewpoint entropy); flat models
    (:data:`FLAT_MODEL_RATIO`: terrain, whose ground is one face by nature) from about 45 degrees above."""
    up = direction_vector(up, "up")
    up = up / np.linalg.norm(up)
    lo, hi = cloud.bounds()
    extent = np.asarray(hi, dtype=np.float64) - lo
    along = abs(float(extent @ up))
    across = float(np.linalg.norm(extent - (extent @ up) * up))
    x, y, z = DEFAULT_DIRECTION
    flat = along < FLAT_MODEL_RATIO * across
    if flat:
        y = 1.2   # about 45 degrees above the horizon
    # the y-up direction turned so +y goes to up: about y x up, or half a turn about x for -y
    direction = np.array([x, y, z])
    axis = np.cross([0.0, 1.0, 0.0], up)
    if np.linalg.norm(axis) < 1e-12:
        direction = direction if up[1] > 0 else rotate(direction, np.array([1.0, 0.0, 0.0]), 180.0)
    else:
        angle = np.degrees(np.arctan2(np.linalg.norm(axis), up[1]))
        direction = rotate(direction, axis / np.linalg.norm(axis), angle)
    return direction if flat else choose_direction(cloud, up, direction).direction


def auto_camera(cloud: SplatCloud, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT, fov: float = 40.0,
                direction=None, up=(0.0, 1.0, 0.0)) -> Camera:
    """A camera framing the whole cloud from ``direction`` (world, toward the eye).

    The splat centers' projections (grown by the 99th percentile splat radius) fill 90% of the
    image's limiting side, centered (:func:`surfsplat.camera.fit_points`); near/far enclose the
    splats. Without a direction: :func:`default_direction` (so ``up=(0, 0, 1)`` suits z-up
    data such as LiDAR).
    """
    up = direction_vector(up, "up")
    if not np.abs(up).max() > 0:
        raise InputError(f"up must be a finite non-zero vector, got {tuple(up)!r}")
    if direction is None:
        direction = default_direction(cloud, up)
    step = max(1, len(cloud) // FIT_SAMPLE)
    margin = float(np.percentile(cloud.radii, 99)) if cloud.u is not None else 0.0
    lo, hi = cloud.bounds()
    # world positions in float64: the camera is composed where the data sit, whatever their offset
    camera = fit_points(cloud.positions[::step].astype(np.float64) + cloud.origin, direction=direction, up=up,
                        fov=fov, width=width, height=height, margin=margin)
    # near/far from every splat, not only the subsample
    return replace(camera, near=None, far=None).with_clip_from_bounds(
        lo, hi, float(cloud.radii.max()) if cloud.u is not None else 0.0)


@dataclass(frozen=True)
class CameraSpec:
    """A camera described before the model is known; :meth:`camera_for` resolves it.

    Attributes:
        eye: camera position (world units), or None to frame the model automatically
            (:func:`auto_camera`).
        target: point looked at (world units); None: the model's bounding-box center.
            Needs ``eye``.
        up: world up vector (also the axis the viewer orbits about); None: the data's own
            (:func:`natural_up` of the source: +z for LAS/LAZ, else +y).
        fov: vertical field of view, degrees, in (0, 180).
    """

    eye: tuple[float, float, float] | None = None
    target: tuple[float, float, float] | None = None
    up: tuple[float, float, float] | None = None
    fov: float = 40.0

    def __post_init__(self) -> None:
        if self.target is not None and self.eye is None:
            raise InputError("--target needs --eye (without camera flags the model is framed automatically)")
        if not (MIN_FOV <= float(self.fov) < 180.0):
            raise InputError(f"--fov must be in [{MIN_FOV:g}, 180) degrees, got {self.fov:g}")

    def camera_for(self, cloud: SplatCloud, width: int, height: int, default_up=(0.0, 1.0, 0.0)) -> Camera:
        """The camera for a model whose splats (or points) are ``cloud``, at ``width`` x ``height`` pixels;
        near/far enclose the model. ``default_up`` stands in for ``up`` None."""
        up = tuple(self.up) if self.up is not None else tuple(default_up)
        if self.eye is None:
            return auto_camera(cloud, width, height, self.fov, up=up)
        lo, hi = cloud.bounds()
        target = self.target if self.target is not None else 0.5 * (lo + hi)
        camera = Camera(eye=tuple(self.eye), target=tuple(target), up=up, fov=self.fov, width=width, height=height)
        return camera.with_clip_from_bounds(lo, hi, margin=float(cloud.radii.max()) if cloud.u is not None else 0.0)


def resolve_camera(model: Model, camera: Camera | CameraSpec | None, width: int, height: int, *,
                   default_up=(0.0, 1.0, 0.0)) -> Camera:
    """A Camera as it is; a CameraSpec (None: automatic framing) resolved against the model at
    ``width`` x ``height`` pixels, with ``default_up`` (see :func:`natural_up`) where it has no up."""
    if isinstance(camera, Camera):
        return camera
    return (camera or CameraSpec()).camera_for(model_points(model), width, height, default_up)


# -- level of detail -------------------------------------------------------------

def lod_splats(hierarchy: Hierarchy, camera: Camera, lod_tolerance: float = DEFAULT_LOD_TOLERANCE, *,
               cull_backfaces: bool = False, lod_shading: LodShading = DEFAULT_LOD_SHADING,
               point_budget: int | None = None):
    """The splats of a hierarchy to draw for a view (``camera`` in world coordinates), and the
    selection (Pajarola 2003, sec. 5.1). The splats keep the points' origin: draw them with
    :func:`local_camera`.

    Nodes whose projected ellipse is at most ``lod_tolerance`` pixels wide are
    drawn as one splat, others are refined; nodes outside the view frustum (and
    with ``cull_backfaces`` those whose normal cone faces away) are dropped with
    their subtrees. ``lod_shading`` is the normal field of node splats: "fit"
    (least-squares linear field), "cone" (Pajarola 2003, fig. 14) or "flat". With ``point_budget``
    at most that many splats: the largest nodes on screen are refined first (Potree's priority).

    Returns:
        (SplatCloud, :class:`~surfsplat.hierarchy.Selection`).
    """
    origin = hierarchy.points.origin
    selection = select(hierarchy, camera.translated(-origin), lod_tolerance, cull_backfaces=cull_backfaces,
                       lod_shading=lod_shading, point_budget=point_budget)
    return hierarchy.splats(selection), selection   # relative to the points' origin, which it carries


def local_camera(splats: SplatCloud, camera: Camera) -> Camera:
    """The world ``camera`` in the local frame of ``splats`` (what the renderer draws them with):
    near/far set from their world bounds where None (grown by the largest splat radius), then eye
    and target moved by ``-splats.origin`` in float64. The GPU then only sees coordinates of the
    size of the model, wherever it sits (positions relative to a float64 origin, see
    :class:`~surfsplat.cloud.SplatCloud`)."""
    if camera.near is None or camera.far is None:
        margin = float(splats.radii.max()) if splats.u is not None and len(splats) else 0.0
        camera = camera.with_clip_from_bounds(*splats.bounds(), margin=margin)
    return camera.translated(-splats.origin)


def view_splats(model: Model, camera: Camera, lod_tolerance: float | None = None, *, cull_backfaces: bool = False,
                lod_shading: LodShading = DEFAULT_LOD_SHADING,
                point_budget: int | None = None) -> tuple[SplatCloud, Selection | None]:
    """The splats to draw for a view: a SplatCloud as it is, or a Hierarchy's LOD cut (:func:`lod_splats`,
    tolerance :data:`DEFAULT_LOD_TOLERANCE` when None, at most ``point_budget`` splats when given).
    Returns (SplatCloud, Selection or None)."""
    tolerance = DEFAULT_LOD_TOLERANCE if lod_tolerance is None else lod_tolerance
    if isinstance(model, ChunkedHierarchy):
        return model.view_splats(camera, tolerance, cull_backfaces=cull_backfaces, lod_shading=lod_shading,
                                 point_budget=point_budget)
    if not isinstance(model, Hierarchy):
        return model, None
    return lod_splats(model, camera, tolerance, cull_backfaces=cull_backfaces, lod_shading=lod_shading,
                      point_budget=point_budget)


def is_lidar(source) -> bool:
    """Whether ``source`` names a LAS/LAZ file (drawn hybrid by default, :func:`hybrid_splats`)."""
    return isinstance(source, (str, Path)) and Path(source).suffix.lower() in Z_UP_SUFFIXES


def hybrid_splats(model: Model, drawn: Model, cloud: SplatCloud, selection: Selection | None,
                  camera: Camera) -> SplatCloud:
    """The splats ``cloud`` drawn for ``model`` with the non-planar ones (the ``nonplanar``
    attribute of preprocessing) made round points facing the eye of ``camera`` (in the splats'
    frame) and the planar ones left surface splats (:func:`surfsplat.rendering.hybrid.facing_points`).
    ``drawn`` is what was cut: ``model`` itself, or the Hierarchy built over it, whose
    ``selection`` gives a node splat the majority flag of its points. Unchanged when the points
    carry no such attribute (splat files, given normals, hierarchy files)."""
    flags = (model_points(model).attributes or {}).get(NONPLANAR)
    if flags is None or len(cloud) == 0:
        return cloud
    if selection is not None:
        if isinstance(drawn, Hierarchy) and drawn is not model:
            flags = flags[drawn.order]   # the hierarchy's points are the model's, reordered
        flags = selection_flags(drawn, selection, flags)
    return facing_points(cloud, np.asarray(flags, dtype=bool), camera)


# -- drawing -----------------------------------------------------------------------

def check_background(background) -> tuple[float, float, float]:
    """``background`` as 3 floats in [0, 1] (InputError else)."""
    values = tuple(float(x) for x in np.asarray(background, dtype=float).reshape(-1))
    if len(values) != 3 or not all(0.0 <= x <= 1.0 for x in values):
        raise InputError(f"background must be 3 numbers in [0, 1], got {values}")
    return values


@dataclass(frozen=True)
class RenderResult:
    """A rendered view and what was drawn.

    Attributes:
        frame: the image, depth and weight.
        splats: number of splats drawn.
        selection: the LOD selection (a hierarchy's cut), or None for a plain cloud.
        seconds: wall-clock time of merging or selection, upload, drawing and read-back.
        merged_from: the cloud's splats when ``lod_tolerance="auto"`` merged them per half pixel
            (:func:`~surfsplat.rendering.lod_auto.merge_in_pixels`), else None.
        gpu_lod_tolerance: the tolerance (pixels) of a cut made on the GPU (``lod_mode="gpu"``;
            ``splats``: the entries handed to it, each kept or dropped by its vertex shader), else None.
    """

    frame: Frame
    splats: int
    selection: Selection | None = None
    seconds: float = 0.0
    merged_from: int | None = None
    gpu_lod_tolerance: float | None = None

    def describe(self) -> str:
        """One line: what was drawn ('1,234 splats' or the LOD cut's counts)."""
        s = self.selection
        if self.gpu_lod_tolerance is not None:
            return f"the GPU LOD cut (tolerance {self.gpu_lod_tolerance:g} px) of {self.splats:,} entries"
        if s is None and self.merged_from is not None:
            return f"{self.splats:,} splats (merged per half pixel from {self.merged_from:,})"
        if s is None:
            return f"{self.splats:,} splats"
        budget = getattr(s, "budget_priority", None)   # a chunked model's budget: where its priority order stopped
        return (f"{self.splats:,} LOD splats (tolerance {s.lod_tolerance:g} px, {s.node_count:,} nodes, "
                f"{s.point_total:,} points{'' if budget is None else f'; budget reached {budget:.3g} px'})")

    def normals(self, space: str = "camera") -> np.ndarray:
        """(H, W, 3) float32 unit normals of the visible surface, computed from the depth map (NaN where
        empty; :func:`surfsplat.io.image_maps.normals_from_depth`), in "camera" or "world" space."""
        return normals_from_depth(self.frame.depth, self.frame.camera, space=space)

    @property
    def coverage(self) -> np.ndarray:
        """(H, W) float32 antialiased coverage in [0, 1]: the fraction of each pixel the surface covers."""
        return self.frame.alpha


def bounds_pixels(camera: Camera, lo, hi) -> float:
    """Pixels of the image the box [lo, hi] (model units) projects to: the area of its projected
    corners' bounding rectangle clipped to the image; the whole image when the eye is inside or
    beside the box (a corner at or behind the eye); 0 when the box lies behind the eye."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                       dtype=np.float64)
    view = camera.view_matrix
    p = corners @ view[:3, :3].T + view[:3, 3]
    depth = -p[:, 2]
    if (depth <= 0).all():
        return 0.0
    if (depth <= 0).any():
        return float(camera.width * camera.height)
    xy = p[:, :2] / depth[:, None] * camera.focal_px
    x0, y0 = np.clip(xy.min(axis=0) + (camera.width / 2, camera.height / 2), 0, (camera.width, camera.height))
    x1, y1 = np.clip(xy.max(axis=0) + (camera.width / 2, camera.height / 2), 0, (camera.width, camera.height))
    return float((x1 - x0) * (y1 - y0))


def check_coverage(frame: Frame, model: Model, what: str = "the model") -> None:
    """Warn (:class:`~surfsplat.errors.EmptyFrameWarning`) when ``frame`` shows nothing, or less
    than :data:`MIN_COVERAGE` of the pixels the model's bounds project to; the message names the
    bounds and the camera (as flags)."""
    lo, hi = model_points(model).bounds()
    expected = bounds_pixels(frame.camera, lo, hi)
    drawn = int(frame.mask.sum())
    if drawn > 0 and drawn >= MIN_COVERAGE * expected:
        return
    where = (f"{what}'s bounds are min {np.array2string(np.asarray(lo), precision=4)} max "
             f"{np.array2string(np.asarray(hi), precision=4)}; the camera is {camera_flags(frame.camera)}")
    if drawn == 0:
        warnings.warn(f"nothing was drawn: {where}", EmptyFrameWarning, stacklevel=3)
    else:
        warnings.warn(f"only {drawn:,} pixels were drawn, {100 * drawn / expected:.2g}% of the {expected:,.0f} "
                      f"its bounds cover in the image: {where}", EmptyFrameWarning, stacklevel=3)


def oriented_outward(drawn, closed: bool):
    """``(drawn, outward)``: whether the splats ``drawn`` of a model sample closed surfaces with
    outward normals, so that from outside their bounds only front faces are seen: a closed mesh
    (``closed``), or a cloud or hierarchy (a chunked one by its preview splats) that
    :func:`~surfsplat.geometry.closed.closed_orientation` finds closed. A cloud with inward normals has
    them turned (the splats returned); a hierarchy's are kept, so only an outward one counts."""
    if isinstance(drawn, (Hierarchy, ChunkedHierarchy)):
        return drawn, closed or closed_orientation(drawn.points) > 0
    if closed:
        return drawn, True
    orientation = closed_orientation(drawn)
    return (flipped_normals(drawn) if orientation < 0 else drawn), orientation != 0


def cull_automatically(drawn, camera: Camera, closed: bool):
    """``(drawn, cull)``: whether back-face culling is safe for the splats ``drawn`` of a model seen
    by ``camera`` (``VisibilityOptions.cull_backfaces=None``), with the splats to draw: where they are
    :func:`oriented_outward` and the eye is outside their bounds. There the back side's splats, never
    visible, are not drawn: a frame is faster and silhouettes lose the dark rim of mirrored back splats."""
    drawn, outward = oriented_outward(drawn, closed)
    cull = outward and eye_outside(drawn.bounds(), camera.eye)
    if cull and not closed:
        _tell_once("a closed surface seen from outside: back faces culled (--no-cull-backfaces draws them)")
    return drawn, cull


@cache
def _tell_once(text: str) -> None:
    """A progress message printed once per process (not for every frame of a turntable)."""
    progress.message(text)


def render_model(model: Model, camera: Camera, *, technique: TechniqueName = "ewa", lights: Lights | None = None,
                 background=DEFAULT_BACKGROUND, options: RenderOptions | None = None,
                 lod_tolerance: float | str | None = None, lod_shading: LodShading = DEFAULT_LOD_SHADING,
                 supersample: int = 1, source_options: SourceOptions | None = None,
                 point_budget: int | None = None, hybrid: bool = False, lod_mode: LodMode = "cpu") -> RenderResult:
    """Draw a loaded model (:func:`load_model`) with a resolved camera.

    A mesh's surface is sampled for this camera (:func:`surface_model`); a SplatCloud given
    ``lod_tolerance`` or ``point_budget`` gets its hierarchy built first; a Hierarchy is cut per
    view (:func:`view_splats`); with ``hybrid`` the non-planar splats are drawn as round points
    (:func:`hybrid_splats`). See :func:`render` for the arguments.
    """
    options = options or RenderOptions()
    background = check_background(background)
    if lod_mode not in LOD_MODES:
        raise InputError(f"lod_mode must be one of {', '.join(LOD_MODES)}, got {lod_mode!r}")
    if point_budget is not None:
        point_budget = check_point_budget(point_budget)
    closed = isinstance(model, Mesh) and is_closed_surface(model)
    drawn = surface_model(model, camera, source_options, closed=closed)
    if options.visibility.cull_backfaces is None:   # automatic: the back of a closed surface is never seen
        drawn, cull = cull_automatically(drawn, camera, closed)
        options = replace(options, visibility=replace(options.visibility, cull_backfaces=cull))
    merged_from, merge_s = None, 0.0
    tree = isinstance(drawn, (Hierarchy, ChunkedHierarchy))
    if lod_tolerance == AUTO:   # from the output resolution (render/lod_auto.py)
        if tree or point_budget is not None or lod_mode == "gpu":
            lod_tolerance = auto_lod_tolerance(supersample)   # cut a hierarchy at one drawn pixel
        else:   # a cloud: its points merged per half pixel where the view is dense, no hierarchy built
            lod_tolerance = None
            if not hybrid:   # hybrid points are picked from the cloud's own rows
                merge_s = time.perf_counter()
                merged = auto_merged(drawn, local_camera(drawn, camera), supersample)
                merged_from, drawn = (len(drawn) if merged is not drawn else None), merged
                merge_s = time.perf_counter() - merge_s
    elif lod_tolerance == 0 and not tree and point_budget is None and lod_mode == "cpu":
        lod_tolerance = None   # every splat of a cloud: no hierarchy to build for a cut at 0
    if lod_tolerance is not None or point_budget is not None:
        drawn = as_hierarchy(drawn)
    if lod_mode == "gpu" and isinstance(drawn, (Hierarchy, ChunkedHierarchy)):
        return _render_gpu_lod(model, drawn, camera, technique, lights, background, options, lod_tolerance,
                               lod_shading, supersample, point_budget, hybrid)
    start = time.perf_counter() - merge_s
    cloud, selection = view_splats(drawn, camera, lod_tolerance, cull_backfaces=options.visibility.cull_backfaces,
                                   lod_shading=lod_shading, point_budget=point_budget)
    if len(cloud) == 0:
        frame = Frame.empty(camera, background)
    else:
        if hybrid:
            cloud = hybrid_splats(model, drawn, cloud, selection, local_camera(cloud, camera))
        frame = default_renderer().render(cloud, camera, technique, lights or Lights(), options, background,
                                          supersample=supersample)   # world camera: the renderer handles the origin
    result = RenderResult(frame, len(cloud), selection, time.perf_counter() - start, merged_from)
    check_coverage(frame, model)
    return result


def _render_gpu_lod(model: Model, hierarchy, camera: Camera, technique, lights, background, options: RenderOptions,
                    lod_tolerance, lod_shading: LodShading, supersample: int, point_budget, hybrid) -> RenderResult:
    """:func:`render_model` with ``lod_mode="gpu"``: the hierarchy's sequential layout (uploaded once per
    hierarchy, :mod:`surfsplat.rendering.sequential`), the cut chosen per entry by the vertex shader."""
    if isinstance(hierarchy, ChunkedHierarchy) or point_budget is not None or hybrid:
        raise InputError("lod_mode 'gpu' draws the tolerance cut of a hierarchy in memory; a point budget, hybrid "
                         "points and chunked hierarchies need lod_mode 'cpu'")
    start = time.perf_counter()
    layout = sequential_layout(hierarchy, lod_shading)
    tolerance = DEFAULT_LOD_TOLERANCE if lod_tolerance is None else lod_tolerance
    frame, given = render_sequential(default_renderer(), layout.splats, layout.lod, camera, technique,
                                     lights or Lights(), options, background, tolerance, supersample)
    result = RenderResult(frame, given, None, time.perf_counter() - start, gpu_lod_tolerance=float(tolerance))
    check_coverage(frame, model)
    return result


def render(source, camera: Camera | CameraSpec | None = None, *, technique: TechniqueName = "ewa",
           width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT, lights: Lights | None = None,
           background=DEFAULT_BACKGROUND, options: RenderOptions | None = None,
           lod_tolerance: float | str | None = None,
           lod_shading: LodShading = DEFAULT_LOD_SHADING, supersample: int = 1,
           source_options: SourceOptions | None = None, point_budget: int | None = None,
           hybrid: bool | None = None, lod_mode: LodMode = "cpu") -> Frame:
    """Render a SplatCloud, a hierarchy, a file or a built-in scene to a :class:`Frame`.

    Args:
        source: a SplatCloud (preprocessed if it lacks normals or splat axes), a
            :class:`~surfsplat.hierarchy.Hierarchy`, a :class:`~surfsplat.io.Mesh`,
            ``"demo:NAME"``, or a path: a point/splat file, a mesh file (its surface is
            sampled for the view, see ``source_options``), a hierarchy file (``.npz`` from
            ``surfsplat build``) or a chunked hierarchy directory (``surfsplat build --chunked``:
            only the cells a view needs are read).
        camera: a :class:`Camera`; or a :class:`CameraSpec` (eye, target, up, fov) or None
            (automatic framing), resolved at ``width`` x ``height`` pixels.
        technique: "ewa" (Guennebaud 2003), "perspective" (Zwicker 2004), "phong"
            (Botsch 2004), "blend" (Pajarola 2003), all three passes, or "flat"
            (opaque disks, one pass).
        lights: lighting and material; None is a headlight with the default material.
        background: RGB in [0, 1].
        options: :class:`~surfsplat.rendering.options.RenderOptions`: EWA filter, visibility,
            blend kernel, deferred shading (None: the defaults).
        lod_tolerance: LOD screen tolerance in pixels (see :func:`lod_splats`); a cloud
            given a tolerance > 0 is turned into a hierarchy first (``surfsplat build`` saves one).
            None (default): every splat of a cloud, a hierarchy cut at :data:`DEFAULT_LOD_TOLERANCE`.
            ``"auto"``: a hierarchy cut at one pixel of the drawn grid; a cloud's points merged per
            half pixel for the view where it holds at least 8 points per pixel, without a hierarchy
            (:mod:`surfsplat.rendering.lod_auto`; else every splat).
        lod_shading: normal field of coarse LOD splats: "fit", "cone" or "flat".
        supersample: K in 1..8: draw K x K sub-pixels per pixel and average them (antialiased
            edges and an antialiased ``Frame.alpha``; any size is drawn in tiles). The LOD cut
            is chosen for the output pixel, the EWA prefilter acts on the sub-pixels.
        source_options: how the source becomes splats (:class:`SourceOptions`): raw points
            preprocessed (k neighbours, outliers dropped); a mesh's surface sampled 0.75 px
            apart for the view, with crease-aware normals and clip lines at sharp and open
            edges (or its vertices).
        point_budget: at most this many splats (>= 1): the LOD cut refined largest node on
            screen first until the budget is spent (Potree's priority; a cloud gets its
            hierarchy built first). None: the whole tolerance cut.
        hybrid: draw non-planar neighbourhoods (vegetation, wires) as round points facing the
            eye and planar ones as surface splats, in one frame (:func:`hybrid_splats`); None:
            on for LAS/LAZ files (:func:`is_lidar`), off otherwise.
        lod_mode: where a hierarchy's LOD cut is chosen: "cpu" (:func:`lod_splats`: the cut is
            gathered and uploaded per view) or "gpu" (sequential point trees, Dachsbacher 2003: every
            node and point uploaded once per hierarchy, each kept or dropped by the vertex shader;
            :mod:`surfsplat.rendering.sequential`). "gpu" draws the tolerance cut of an in-memory
            hierarchy only: no point budget, no hybrid points, no chunked hierarchy.
    """
    background = check_background(background)
    model = load_model(source, source_options)
    camera = resolve_camera(model, camera, width, height, default_up=natural_up(source))
    hybrid = is_lidar(source) if hybrid is None else bool(hybrid)
    return render_model(model, camera, technique=technique, lights=lights, background=background, options=options,
                        lod_tolerance=lod_tolerance, lod_shading=lod_shading, supersample=supersample,
                        source_options=source_options, point_budget=point_budget, hybrid=hybrid,
                        lod_mode=lod_mode).frame


def render_mesh(source, camera: Camera | CameraSpec | None = None, *, width: int = DEFAULT_WIDTH,
                height: int = DEFAULT_HEIGHT, lights: Lights | None = None, background=DEFAULT_BACKGROUND,
                supersample: int = 4, smooth: bool = True) -> Frame:
    """Render a triangle mesh (a :class:`~surfsplat.io.Mesh` or a PLY/OBJ path): the ground truth.

    Same camera conventions, lighting and linear depth as :func:`render`, per-pixel
    shading of the interpolated vertex normals (``smooth``) or the face normals,
    antialiased by ``supersample`` x ``supersample`` samples per pixel. A CameraSpec or
    None is resolved against the mesh's vertices as :func:`render` resolves it against splats.
    """
    if isinstance(source, Mesh):
        mesh = source
    else:
        with progress.stage(f"loading {source}"):
            mesh = load_mesh(source)
    camera = resolve_camera(SplatCloud(mesh.vertices, origin=mesh.origin), camera, width, height,
                            default_up=natural_up(source))
    return rasterize_mesh(mesh, camera, lights or Lights(), background=background, supersample=supersample,
                          smooth=smooth, renderer=default_renderer())


# -- animations ------------------------------------------------------------------------------

def turntable_frames(model: Model, cameras: list[Camera], *, technique: TechniqueName = "ewa",
                     lights: Lights | None = None, background=DEFAULT_BACKGROUND,
                     options: RenderOptions | None = None, lod_tolerance: float | None = None,
                     lod_shading: LodShading = DEFAULT_LOD_SHADING, supersample: int = 1,
                     source_options: SourceOptions | None = None, point_budget: int | None = None,
                     hybrid: bool = False, lod_mode: LodMode = "cpu"):
    """Yield the (H, W, 3) uint8 image of each camera (a mesh is sampled once, for the first camera;
    a hierarchy is cut per frame, within ``point_budget`` splats if given, on the CPU or the GPU
    (``lod_mode``); ``hybrid`` as in :func:`render_model`). Progress per frame (:func:`surfsplat.progress.stage`)."""
    if not cameras:
        return
    model = surface_model(model, cameras[0], source_options)
    if (lod_tolerance is not None and lod_tolerance != AUTO) or point_budget is not None:
        model = as_hierarchy(model)   # built once; "auto" merges a cloud's points per frame instead
    with progress.stage(f"rendering {len(cameras)} frames", unit="frames", total=len(cameras)) as frames:
        for camera in cameras:
            result = render_model(model, camera, technique=technique, lights=lights, background=background,
                                  options=options, lod_tolerance=lod_tolerance, lod_shading=lod_shading,
                                  supersample=supersample, point_budget=point_budget, hybrid=hybrid,
                                  lod_mode=lod_mode)
            frames.update()
            yield result.frame.image()
