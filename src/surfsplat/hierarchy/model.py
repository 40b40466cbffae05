"""The multiresolution hierarchy's data: :class:`Hierarchy` (a point-octree with a splat per
node) and :class:`Selection` (a cut through it), with the normal-field modes of node splats.

Pajarola, Sainz & Guidotti 2003, sections 3.2-3.4; storage as in Guennebaud &
Paulin 2003, section 8. Building is :mod:`~surfsplat.hierarchy.octree`,
view-dependent selection :mod:`~surfsplat.hierarchy.lod`, files
:mod:`~surfsplat.hierarchy.storage`; this module imports none of them.

Layout: node arrays are concatenated level by level (``level_offsets``);
children of a node are the range ``child_start .. child_start + child_count``
of the next level; a node's points are ``point_start .. point_start +
point_count`` of :attr:`Hierarchy.points`. A selection is therefore a list
of index ranges.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

from ..cloud import SplatCloud
from ..colors import attribute_values, class_colors, colorize, is_class_palette
from ..errors import InputError
from .nodes import is_majority_voted, range_sums

#: Default largest number of points in a leaf.
LEAF_CAPACITY = 8

#: Default depth limit: nodes at this depth are leaves whatever their size.
MAX_DEPTH = 48

#: Normal field of node splats (``lod_shading``): "fit" (least-squares linear field, Botsch
#: 2004), "cone" (normal-cone spread, Pajarola 2003 fig. 14) or "flat" (none).
LodShading = Literal["fit", "cone", "flat"]

#: The :data:`LodShading` modes (see :meth:`Hierarchy.node_normal_fields`).
SHADINGS: tuple[str, ...] = get_args(LodShading)

#: Largest normal-cone angle used for ``lod_shading="cone"`` (60 degrees).
CONE_SHADING_MAX_ANGLE = np.pi / 3

#: Version of the array layout (:meth:`Hierarchy.arrays`) and of the files holding it
#: (:mod:`~surfsplat.hierarchy.storage`).
FORMAT_VERSION = 2


@dataclass(frozen=True, eq=False)
class Selection:
    """The result of :func:`~surfsplat.hierarchy.lod.select`: index arrays into a hierarchy, no splat data.

    Attributes:
        nodes: per level, int64 global indices of the selected nodes (their
            representative splats are drawn).
        leaves: per level, int64 global indices of refined leaves (their
            original points are drawn).
        point_start, point_count: (K,) int64 ranges of the selected original
            points in ``hierarchy.points`` (one per refined leaf, in the order
            of ``leaves``).
        lod_shading: normal-field mode of the node splats (``"fit"``, ``"cone"``, ``"flat"``).
        lod_tolerance: the LOD screen tolerance (Pajarola's tau), pixels.
        visited: nodes tested.
        culled_frustum, culled_backface: nodes dropped (each with its subtree).
    """

    nodes: tuple
    leaves: tuple
    point_start: np.ndarray
    point_count: np.ndarray
    lod_shading: LodShading
    lod_tolerance: float
    visited: int
    culled_frustum: int
    culled_backface: int

    @property
    def node_count(self) -> int:
        """Number of selected representative (node) splats."""
        return int(sum(len(x) for x in self.nodes))

    @property
    def point_total(self) -> int:
        """Number of selected original points."""
        return int(self.point_count.sum())

    def __len__(self) -> int:
        """Number of splats the selection draws (nodes + points)."""
        return self.node_count + self.point_total

    @property
    def level_counts(self) -> list[int]:
        """Selected node splats per level."""
        return [len(x) for x in self.nodes]

    def node_indices(self) -> np.ndarray:
        """All selected node indices, level by level (int64)."""
        return np.concatenate(self.nodes) if self.nodes else np.zeros(0, dtype=np.int64)

    def point_indices(self) -> np.ndarray:
        """Indices of the selected original points in ``hierarchy.points`` (int64)."""
        return ranges_to_indices(self.point_start, self.point_count)

    def merged_point_ranges(self) -> tuple[np.ndarray, np.ndarray]:
        """The selected point ranges sorted and with adjacent ranges merged: ``(start, count)`` int64.

        Fewer, longer ranges, e.g. for drawing straight from a buffer holding
        ``hierarchy.points`` (Guennebaud 2003, sec. 8) instead of gathering.
        """
        if len(self.point_start) == 0:
            return self.point_start.copy(), self.point_count.copy()
        order = np.argsort(self.point_start, kind="stable")
        start, count = self.point_start[order], self.point_count[order]
        end = start + count
        new = np.concatenate([[True], start[1:] != end[:-1]])
        first = np.flatnonzero(new)
        last = np.concatenate([first[1:], [len(start)]]) - 1
        return start[first], end[last] - start[first]

    def summary(self) -> dict:
        """Counts for reports: splats, nodes, points, visited and culled nodes."""
        return {"splats": len(self), "nodes": self.node_count, "points": self.point_total,
                "lod_tolerance": self.lod_tolerance, "visited": self.visited,
                "culled_frustum": self.culled_frustum, "culled_backface": self.culled_backface}


@dataclass(eq=False)
class Hierarchy:
    """A point-octree over a splat cloud with a representative splat per node.

    Node arrays have one row per node, levels concatenated (level ``L`` is
    rows ``level_offsets[L]:level_offsets[L + 1]``; level 0 is the root).

    Attributes:
        points: the original splats, reordered so that every node's points
            are the contiguous range ``point_start .. + point_count``.
        order: (N,) int64 original index of each row of ``points``.
        level_offsets: (levels + 1,) int64 first node of each level.
        origin: (3,) float64 origin of the homogeneous covariances.
        node_positions: (M, 3) float32 average position (splat center, sphere center).
        node_normals: (M, 3) float32 unit average normal (normal-cone axis).
        node_colors: (M, 3) float32 average color, or None (cloud without colors).
        node_u, node_v: (M, 3) float32 scaled major / minor ellipse axes,
            model units: the ellipse covers every splat disk of the subtree
            projected into its plane (Pajarola 2003, sec. 3.4), hence its
            children's disks' union and all its points.
        node_extent: (M,) float32 major semi-axis (model units) of the
            ellipse of the same axes and aspect bounding only the subtree's
            points (fig. 6 a): the sampling scale the node stands for, which
            the LOD selection compares with ``lod_tolerance``.
        node_normal_field: (M, 2) float32 fitted ``(alpha, beta)``.
        node_radius: (M,) float32 radius of the bounding sphere (about
            ``node_positions``) of all splat disks of the subtree.
        node_cone: (M,) float32 normal-cone semi-angle, radians, about
            ``node_normals``; pi where the normals fit in no cone under 90 deg.
        node_covariance: (M, 10) float64 generic homogeneous covariance
            ``M_bar`` (Pajarola EQ 2) of the subtree's points relative to
            ``origin``, packed as :data:`~surfsplat.hierarchy.nodes.COVARIANCE_ENTRIES`.
        node_point_start, node_point_count: (M,) int64 the subtree's points.
        node_child_start: (M,) int64 global index of the first child.
        node_child_count: (M,) int64 number of children (0 for a leaf).
        leaf_capacity, max_depth: the build parameters.
        node_attributes: ``{name: (M,) array}``, each node's value of each of the points'
            attributes (``points.attributes``, in the points' order) over its subtree's points,
            or None: integer and boolean columns (classes, flags, counts) by majority vote (ties
            to the smallest value), floating-point columns as the mean of the finite values
            (:func:`~surfsplat.hierarchy.nodes.node_attribute_values`); dtypes kept.
    """

    points: SplatCloud
    order: np.ndarray
    level_offsets: np.ndarray
    origin: np.ndarray
    node_positions: np.ndarray
    node_normals: np.ndarray
    node_colors: np.ndarray | None
    node_u: np.ndarray
    node_v: np.ndarray
    node_normal_field: np.ndarray
    node_radius: np.ndarray
    node_cone: np.ndarray
    node_extent: np.ndarray
    node_covariance: np.ndarray
    node_point_start: np.ndarray
    node_point_count: np.ndarray
    node_child_start: np.ndarray
    node_child_count: np.ndarray
    leaf_capacity: int = LEAF_CAPACITY
    max_depth: int = MAX_DEPTH
    node_attributes: dict[str, np.ndarray] | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    # -- structure -----------------------------------------------------------

    def __len__(self) -> int:
        """Number of nodes (all levels)."""
        return len(self.node_positions)

    def __repr__(self) -> str:
        return (f"Hierarchy({len(self.points):,} points, {len(self):,} nodes, {self.levels} levels, "
                f"leaf capacity {self.leaf_capacity})")

    @property
    def levels(self) -> int:
        """Number of levels (root = level 0)."""
        return len(self.level_offsets) - 1

    @property
    def level_sizes(self) -> np.ndarray:
        """(levels,) int64 number of nodes per level."""
        return np.diff(self.level_offsets)

    def level(self, depth: int) -> slice:
        """The node rows of level ``depth`` as a slice."""
        return slice(int(self.level_offsets[depth]), int(self.level_offsets[depth + 1]))

    @property
    def is_leaf(self) -> np.ndarray:
        """(M,) bool: node has no children."""
        return self.node_child_count == 0

    @property
    def node_depth(self) -> np.ndarray:
        """(M,) int64 level of each node."""
        return np.repeat(np.arange(self.levels), self.level_sizes)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds ``(min, max)`` of the splat centers, model units (as ``SplatCloud.bounds``)."""
        if "bounds" not in self._cache:
            self._cache["bounds"] = self.points.bounds()
        return self._cache["bounds"]

    def sphere_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(min, max)`` of the root's bounding sphere: they enclose every splat disk."""
        c = self.node_positions[0].astype(np.float64)
        r = float(self.node_radius[0])
        return c - r, c + r

    # -- splats --------------------------------------------------------------

    def node_normal_fields(self, index, lod_shading: LodShading = "fit") -> np.ndarray:
        """(K, 2) float32 normal field ``(alpha, beta)`` of nodes for a LOD shading mode.

        ``"fit"``: the least-squares fit to the subtree's normals (Botsch
        2004, eq. 3-4); ``"cone"``: ``alpha = beta = tan(theta)`` with the
        normal-cone angle theta (capped at :data:`CONE_SHADING_MAX_ANGLE`),
        normals spread outward by the cone at the rim (Pajarola 2003, sec. 5.2,
        fig. 14); ``"flat"``: zeros.
        """
        check_lod_shading(lod_shading)
        index = np.asarray(index)
        if lod_shading == "fit":
            return np.take(self.node_normal_field, index, axis=0)
        if lod_shading == "cone":
            slope = np.tan(np.minimum(np.take(self.node_cone, index), CONE_SHADING_MAX_ANGLE)).astype(np.float32)
            return np.repeat(slope[:, None], 2, axis=1)
        return np.zeros((len(index), 2), dtype=np.float32)

    def node_splats(self, index=None, lod_shading: LodShading = "fit") -> SplatCloud:
        """The representative splats of nodes (all nodes when ``index`` is None) as a SplatCloud (with the
        points' origin)."""
        index = np.arange(len(self)) if index is None else np.asarray(index, dtype=np.int64)
        return self.points.with_arrays(   # node positions are relative to the points' origin
            positions=np.take(self.node_positions, index, axis=0),
            normals=np.take(self.node_normals, index, axis=0),
            colors=None if self.node_colors is None else np.take(self.node_colors, index, axis=0),
            u=np.take(self.node_u, index, axis=0),
            v=np.take(self.node_v, index, axis=0),
            normal_field=None if lod_shading == "flat" else self.node_normal_fields(index, lod_shading),
        )

    def splats(self, selection: Selection) -> SplatCloud:
        """Gather the splats of a selection: selected nodes' representative splats, then selected points
        (a SplatCloud with the points' origin).

        Normal fields follow ``selection.lod_shading`` for the nodes; selected
        original points keep their own normal field (zeros where the cloud
        has none). With ``lod_shading="flat"`` and a cloud without normal fields
        the result has none. Clip lines are kept for points (``(0, 0, 1)``
        for nodes) when the cloud has them. At ``lod_tolerance`` 0 the result holds
        exactly the original splats (less culled ones), in hierarchy order
        grouped by level.
        """
        nodes = selection.node_indices()
        pidx = selection.point_indices()
        m, k = len(nodes), len(pidx)
        pts = self.points

        def gather(node_array, point_array, width, dtype=np.float32):
            out = np.empty((m + k,) + width, dtype=dtype)
            np.take(node_array, nodes, axis=0, out=out[:m], mode="clip")
            np.take(point_array, pidx, axis=0, out=out[m:], mode="clip")
            return out

        positions = gather(self.node_positions, pts.positions, (3,))
        normals = gather(self.node_normals, pts.normals, (3,))
        u = gather(self.node_u, pts.u, (3,))
        v = gather(self.node_v, pts.v, (3,))
        colors = None
        if self.node_colors is not None and pts.colors is not None:
            colors = gather(self.node_colors, pts.colors, (3,))
        normal_field = None
        if selection.lod_shading != "flat" or pts.normal_field is not None:
            normal_field = np.zeros((m + k, 2), dtype=np.float32)
            if selection.lod_shading != "flat" and m:
                normal_field[:m] = self.node_normal_fields(nodes, selection.lod_shading)
            if pts.normal_field is not None and k:
                np.take(pts.normal_field, pidx, axis=0, out=normal_field[m:], mode="clip")
        clip_lines = None
        if pts.clip_lines is not None:
            clip_lines = np.empty((m + k, 2, 3), dtype=np.float32)
            clip_lines[:m] = np.array([[0.0, 0.0, 1.0]], dtype=np.float32)
            np.take(pts.clip_lines, pidx, axis=0, out=clip_lines[m:], mode="clip")
        return pts.with_arrays(positions=positions, normals=normals, colors=colors, u=u, v=v,
                               normal_field=normal_field, clip_lines=clip_lines)

    # -- colours -----------------------------------------------------------------

    def set_colors(self, colors: np.ndarray | None, node_colors: np.ndarray | None = None) -> None:
        """Give the hierarchy (in place) new point colours ((N,) rows in its point order, linear
        RGB in [0, 1], or None) and node colours: ``node_colors`` ((M, 3)) as given, or None for the
        mean of each node's point colours, as building averages them (Pajarola 2003, sec. 3.4)."""
        if colors is None:
            self.points = self.points.replace(colors=None)
            self.node_colors = None
            return
        colors = np.asarray(colors, dtype=np.float32)
        if node_colors is None:
            mean = range_sums(colors, self.node_point_start, self.node_point_count)
            mean /= np.maximum(self.node_point_count, 1)[:, None]
            node_colors = np.clip(mean, 0.0, 1.0)
        self.points = self.points.replace(colors=colors)
        self.node_colors = np.asarray(node_colors, dtype=np.float32)

    def colorized(self, by: str, colormap: str | None = None, value_range=None, *,
                  up=(0.0, 0.0, 1.0)) -> "Hierarchy":
        """A copy coloured by the scalar ``by`` (``elevation`` or one of ``points.attributes``;
        arguments as :func:`surfsplat.colors.colorize`, which colours the points).

        Node colours: with a class palette (``asprs``, the default for ``classification``) and
        a majority-voted (integer) attribute, the palette colour of the node's majority value,
        so coarse levels show crisp class colours; otherwise the mean of the node's point
        colours (a continuous colormap's blend). An unknown name is an InputError listing the
        hierarchy's attributes.
        """
        name, _ = attribute_values(self.points, by, up)
        points = colorize(self.points, by, colormap, value_range, up=up)
        nodes = (self.node_attributes or {}).get(name)
        node_colors = None
        if nodes is not None and is_majority_voted(nodes) and is_class_palette(name, colormap):
            node_colors = class_colors(nodes)
        out = dataclasses.replace(self, _cache=dict(self._cache))
        out.set_colors(points.colors, node_colors)
        return out

    # -- summaries -------------------------------------------------------------

    def describe(self) -> dict:
        """Summary for ``surfsplat info``: counts, levels, leaf sizes, bounds, memory.

        Keys: ``points``, ``nodes``, ``levels``, ``leaves``, ``nodes_per_level``
        (list), ``leaf_capacity``, ``max_depth``, ``max_leaf_points``,
        ``mean_leaf_points``, ``bounds`` (``[[min x, y, z], [max x, y, z]]``,
        splat centers), ``root_radius`` (model units), ``has_colors``,
        ``has_normal_field``, ``has_clip_lines`` (of the points), ``attributes``
        (``{name: dtype name}`` of the points' attributes), ``bytes`` (memory of all arrays),
        ``format_version``.
        """
        leaf = self.is_leaf
        lo, hi = self.bounds()
        leaf_points = self.node_point_count[leaf]
        return {
            "points": len(self.points),
            "nodes": len(self),
            "levels": self.levels,
            "leaves": int(leaf.sum()),
            "nodes_per_level": [int(x) for x in self.level_sizes],
            "leaf_capacity": int(self.leaf_capacity),
            "max_depth": int(self.max_depth),
            "max_leaf_points": int(leaf_points.max()),
            "mean_leaf_points": float(leaf_points.mean()),
            "bounds": [[float(x) for x in lo], [float(x) for x in hi]],
            "root_radius": float(self.node_radius[0]),
            "has_colors": self.points.colors is not None,
            "has_normal_field": self.points.normal_field is not None,
            "has_clip_lines": self.points.clip_lines is not None,
            "attributes": {name: str(values.dtype) for name, values in (self.points.attributes or {}).items()},
            "bytes": int(sum(a.nbytes for a in self.arrays().values())),
            "format_version": FORMAT_VERSION,
        }

    def arrays(self) -> dict[str, np.ndarray]:
        """Every stored array by name (the file's members, less the format fields); attributes as
        ``point_attribute:NAME`` and ``node_attribute:NAME``."""
        out = {"order": self.order, "level_offsets": self.level_offsets, "origin": self.origin}
        for name in NODE_ARRAYS:
            value = getattr(self, name)
            if value is not None:
                out[name] = value
        for name in POINT_ARRAYS:
            value = getattr(self.points, name)
            if value is not None:
                out["point_" + name] = value
        for name, value in (self.points.attributes or {}).items():
            out[POINT_ATTRIBUTE + name] = value
        for name, value in (self.node_attributes or {}).items():
            out[NODE_ATTRIBUTE + name] = value
        return out


#: Node arrays of :class:`Hierarchy` (node_colors may be None).
NODE_ARRAYS = ("node_positions", "node_normals", "node_colors", "node_u", "node_v", "node_normal_field",
               "node_radius", "node_cone", "node_extent", "node_covariance", "node_point_start", "node_point_count",
               "node_child_start", "node_child_count")

#: SplatCloud arrays of the points (all but positions may be None).
POINT_ARRAYS = ("positions", "normals", "colors", "u", "v", "normal_field", "clip_lines")

#: Name prefixes of the attribute arrays in :meth:`Hierarchy.arrays`.
POINT_ATTRIBUTE, NODE_ATTRIBUTE = "point_attribute:", "node_attribute:"


def check_lod_shading(lod_shading: str) -> None:
    """InputError unless ``lod_shading`` is one of :data:`SHADINGS`."""
    if lod_shading not in SHADINGS:
        raise InputError(f"lod_shading must be one of {', '.join(SHADINGS)}; got {lod_shading!r}")


def ranges_to_indices(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Concatenated index ranges ``[start_i, start_i + count_i)`` as one int64 array."""
    start = np.asarray(start, dtype=np.int64)
    count = np.asarray(count, dtype=np.int64)
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    first = np.cumsum(count) - count
    out = np.repeat(start - first, count)
    out += np.arange(total, dtype=np.int64)
    return out
