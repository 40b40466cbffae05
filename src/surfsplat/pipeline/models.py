"""The model kinds a view draws, behind one protocol (:class:`Model`).

A user hands over a SplatCloud, a Hierarchy, a chunked hierarchy or a Mesh (or a file or object
that reads as one); :func:`as_model` wraps it once, and from there every door asks the same
questions of any kind: its bounds and the points that frame it, the splats it has for a view
(a mesh sampled, a hierarchy cut), its hierarchy, its colours, its orientation. The type is
looked at in this module only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .. import progress
from ..camera import Camera
from ..cloud import SplatCloud
from ..colors import ELEVATION, ColorOptions, colorize
from ..errors import InputError
from ..geometry.closed import closed_orientation, flipped_normals, is_closed_surface, outward_splats
from ..geometry.sampling import samples_for_pixels, surface_splats
from ..hierarchy import Hierarchy, LodShading, Selection, build_hierarchy, select
from ..hierarchy.chunked import ChunkedHierarchy
from ..io import Mesh
from .options import SourceOptions


class Model(Protocol):
    """What every model kind answers (:class:`CloudModel`, :class:`HierarchyModel`,
    :class:`ChunkedModel`, :class:`MeshModel`)."""

    @property
    def data(self) -> Any:
        """The object wrapped (a SplatCloud, Hierarchy, ChunkedHierarchy or Mesh)."""

    @property
    def is_tree(self) -> bool:
        """Whether it is cut per view (a hierarchy, in memory or chunked)."""

    @property
    def in_memory(self) -> bool:
        """Whether its splats are all in memory (a chunked hierarchy reads cells per view)."""

    def points(self) -> SplatCloud:
        """The original points (positions, origin; splat axes where known), for framing and bounds."""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the points, model units (relative to the points' origin)."""

    def surface(self, camera: Camera | None, options: SourceOptions, image_size: int,
                facing: bool = False) -> "Model":
        """The model as splats (a mesh's surface sampled for ``camera``, others as they are; ``facing``:
        a closed mesh seen with back faces culled keeps only the samples facing ``camera``'s eye)."""

    def facing_only(self) -> bool:
        """Whether :meth:`surface` with ``facing`` keeps only the samples facing the eye (a closed mesh's)."""

    def tree(self) -> "Model":
        """The model as a hierarchy (a cloud's point-octree built; a hierarchy as it is)."""

    def cut(self, camera: Camera, tolerance: float, *, cull_backfaces: bool = False, shading: LodShading = "fit",
            point_budget: int | None = None) -> tuple[SplatCloud, Selection | None]:
        """The splats to draw for ``camera`` (world) and the LOD selection (None for a cloud)."""

    def colored(self, color: ColorOptions | None, up) -> "Model":
        """The model coloured by ``color`` along ``up`` (as it is without ``color``)."""

    def outward(self) -> tuple["Model", bool]:
        """``(model, outward)``: whether it samples closed surfaces with outward normals (a cloud with
        inward normals has them turned), so that from outside its bounds only front faces are seen."""


@dataclass(frozen=True)
class CloudModel:
    """A render-ready SplatCloud: drawn as it is."""

    data: SplatCloud
    closed: bool | None = None   # known closed and outward (a closed mesh's samples)
    is_tree = False
    in_memory = True

    def points(self) -> SplatCloud:
        return self.data

    def bounds(self):
        return self.data.bounds()

    def surface(self, camera, options, image_size, facing=False):
        return self

    def facing_only(self):
        return False

    def tree(self) -> "HierarchyModel":
        with progress.stage(f"building the point-octree of {len(self.data):,} splats"):
            return HierarchyModel(build_hierarchy(self.data), closed=self.closed, built_from=self.data)

    def cut(self, camera, tolerance, *, cull_backfaces=False, shading="fit", point_budget=None):
        return self.data, None

    def colored(self, color, up):
        return self if color is None else CloudModel(colorize(self.data, color.by, color.colormap,
                                                              _local_range(color, self.data, up), up=up), self.closed)

    def outward(self):
        if self.closed:
            return self, True
        orientation = closed_orientation(self.data)
        if orientation < 0:
            return CloudModel(flipped_normals(self.data), True), True
        return self, orientation != 0


class _TreeModel:
    """What the two hierarchy kinds share: their points (a chunked hierarchy's: the preview splats made
    by the build) frame the view; they are drawn as they are, already a tree."""

    data: Hierarchy | ChunkedHierarchy

    def points(self) -> SplatCloud:
        return self.data.points

    def bounds(self):
        return self.data.points.bounds()

    def surface(self, camera, options, image_size, facing=False):
        return self

    def facing_only(self):
        return False

    def tree(self):
        return self


@dataclass(frozen=True)
class HierarchyModel(_TreeModel):
    """A point-octree in memory (Pajarola 2003), cut per view on the CPU or the GPU."""

    data: Hierarchy
    closed: bool | None = None
    #: The cloud it was built from (its rows are the hierarchy's points reordered by ``data.order``).
    built_from: SplatCloud | None = None
    is_tree = True
    in_memory = True

    def cut(self, camera, tolerance, *, cull_backfaces=False, shading="fit", point_budget=None):
        return lod_splats(self.data, camera, tolerance, cull_backfaces=cull_backfaces, lod_shading=shading,
                          point_budget=point_budget)

    def colored(self, color, up):
        if color is None:
            return self
        return HierarchyModel(self.data.colorized(color.by, color.colormap, _local_range(color, self.data.points, up),
                                                  up=up), self.closed, self.built_from)

    def outward(self):
        return self, bool(self.closed) or closed_orientation(self.data.points) > 0


@dataclass(frozen=True)
class ChunkedModel(_TreeModel):
    """A chunked hierarchy on disk (``surfsplat build --chunked``): only the cells a view needs are read."""

    data: ChunkedHierarchy
    is_tree = True
    in_memory = False

    def cut(self, camera, tolerance, *, cull_backfaces=False, shading="fit", point_budget=None):
        return self.data.view_splats(camera, tolerance, cull_backfaces=cull_backfaces, lod_shading=shading,
                                     point_budget=point_budget)

    def colored(self, color, up):
        if color is None:
            return self
        return ChunkedModel(self.data.colorized(color.by, color.colormap, _local_range(color, self.data.points, up),
                                                up=up))

    def outward(self):
        return self, closed_orientation(self.data.points) > 0


@dataclass(frozen=True)
class MeshModel:
    """A triangle mesh: its surface is sampled into splats for a view (coloured as it is sampled)."""

    data: Mesh
    color: ColorOptions | None = None
    up: tuple = (0.0, 1.0, 0.0)
    _closed: list = field(default_factory=list, compare=False, repr=False)   # cache of is_closed_surface
    is_tree = False
    in_memory = True

    @property
    def closed(self) -> bool:
        """Whether the mesh is a closed surface (:func:`~surfsplat.geometry.closed.is_closed_surface`)."""
        if not self._closed:
            self._closed.append(bool(is_closed_surface(self.data)))
        return self._closed[0]

    def points(self) -> SplatCloud:
        return SplatCloud(self.data.vertices, origin=self.data.origin)

    def bounds(self):
        return self.points().bounds()

    def facing_only(self):
        return self.closed and self.color is None   # a colouring's range is the whole sampling's

    def surface(self, camera, options, image_size, facing=False):
        """The surface sampled for ``camera`` (``options.spacing_px`` apart on screen) or, without a
        camera, with the model's diagonal spanning ``image_size`` pixels; ``options.samples`` if given.
        A closed mesh's splats get outward normals so that back-face culling keeps the visible side;
        with ``facing`` (a closed mesh, :meth:`facing_only`, and a camera) only the samples facing its
        eye are kept (``surface_splats(facing_eye=...)``: the others are culled in the view; about
        half of them from outside)."""
        n = options.samples
        if n is None:
            n = samples_for_pixels(self.data, options.spacing_px, camera=camera, image_size=image_size)
        where = ("as asked" if options.samples is not None else
                 f"{options.spacing_px:g} px apart at {camera.width}x{camera.height}" if camera is not None else
                 f"{options.spacing_px:g} px apart with the model {image_size} px wide")
        progress.message(f"{n:,} samples on the surface ({where})")
        eye = None
        if facing and camera is not None and self.facing_only():
            eye = np.asarray(camera.eye, dtype=np.float64) - np.asarray(self.data.origin, dtype=np.float64)
        cloud = surface_splats(self.data, n, sharp_angle=options.sharp_angle, seed=options.seed, facing_eye=eye)
        if self.color is not None:
            cloud = CloudModel(cloud).colored(self.color, self.up).data
        if self.closed and eye is None:   # facing_eye turned them outward already
            cloud = outward_splats(cloud)
        lines = cloud.clip_lines is not None
        progress.message(f"{len(cloud):,} surface splats" + (", clipped at sharp and open edges" if lines else ""))
        return CloudModel(cloud, closed=self.closed or None)

    def tree(self):
        raise InputError("a mesh is sampled for a view before its hierarchy is built")

    def cut(self, camera, tolerance, *, cull_backfaces=False, shading="fit", point_budget=None):
        raise InputError("a mesh is sampled for a view before it is drawn")

    def colored(self, color, up):
        return self if color is None else MeshModel(self.data, color, tuple(up))

    def outward(self):
        return self, self.closed


def as_model(data) -> Model:
    """The :class:`Model` of a SplatCloud, Hierarchy, ChunkedHierarchy or Mesh (a Model as it is)."""
    if isinstance(data, (CloudModel, HierarchyModel, ChunkedModel, MeshModel)):
        return data
    if isinstance(data, SplatCloud):
        return CloudModel(data)
    if isinstance(data, Hierarchy):
        return HierarchyModel(data)
    if isinstance(data, ChunkedHierarchy):
        return ChunkedModel(data)
    if isinstance(data, Mesh):
        return MeshModel(data)
    raise InputError(f"expected a SplatCloud, Hierarchy, chunked hierarchy or Mesh, got {type(data).__name__}")


def _local_range(color: ColorOptions, points: SplatCloud, up):
    """``color.value_range`` in the points' local frame: a range in world elevations moves by the
    origin's elevation (:func:`surfsplat.colors.colorize` reads the local positions)."""
    value_range = color.value_range
    origin = points.origin
    if value_range is not None and color.by.lower() == ELEVATION and np.any(origin):
        shift = float(origin @ np.asarray(up, dtype=np.float64)) / float(np.linalg.norm(up))
        value_range = (value_range[0] - shift, value_range[1] - shift)
    return value_range


def lod_splats(hierarchy: Hierarchy, camera: Camera, lod_tolerance: float, *, cull_backfaces: bool = False,
               lod_shading: LodShading = "fit", point_budget: int | None = None) -> tuple[SplatCloud, Selection]:
    """The splats of a hierarchy to draw for a view (``camera`` in world coordinates), and the
    selection (Pajarola 2003, sec. 5.1): nodes whose projected ellipse is at most ``lod_tolerance``
    pixels wide are drawn as one splat, others refined; nodes outside the view frustum (and with
    ``cull_backfaces`` those whose normal cone faces away) are dropped with their subtrees.
    ``lod_shading``: the normal field of node splats ("fit", "cone" or "flat"). With ``point_budget``
    at most that many splats: the largest nodes on screen are refined first (Potree's priority).
    The splats keep the points' origin."""
    origin = hierarchy.points.origin
    selection = select(hierarchy, camera.translated(-origin), lod_tolerance, cull_backfaces=cull_backfaces,
                       lod_shading=lod_shading, point_budget=point_budget)
    return hierarchy.splats(selection), selection
