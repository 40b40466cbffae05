"""Sequential point trees: a hierarchy laid out once as a list whose view-dependent cut is a
per-entry interval test (Dachsbacher, Vogelgsang & Stamminger 2003; Zwicker 2004, sec. 8 names it as
future work for surface splatting).

Every node of the :class:`~surfsplat.hierarchy.model.Hierarchy` and every original point is one
entry: the nodes' representative splats, then the points. The CPU cut (:mod:`~surfsplat.hierarchy.lod`,
Pajarola 2003, sec. 5.1) refines a node while its eye distance ``d`` is below its reach
``R + max(near, s D)``, ``s = focal_px / tolerance_px``, ``D`` the diameter of the ellipse bounding its
points and ``R`` its bounding-sphere radius; a node is drawn when it is not refined and its parent is.
Here each entry tests both halves with its *own* eye distance (the paper's sec. 3.2):

    r_min = R + max(near, s D)                       (the entry itself is not refined)
    r_max = R_p + |c - c_p| + max(near, s D_p)       (its parent is refined)

and is drawn iff ``r_min <= d < r_max``. The parent's reach is enlarged by the parent-child centre
distance: ``|d - d_p| <= |c - c_p|``, so whenever the parent is refined at its own distance the child
passes, and along every root-to-point path the first entry not refined is drawn: no holes (a few
entries near the boundary of their interval are drawn together with an ancestor, the overlap the
paper accepts). Original points have ``r_min = -inf`` (they are never refined), the root
``r_max = inf``, and nodes over clipped splats (always refined by :func:`~surfsplat.hierarchy.select`)
``r_min = inf``.

The four numbers per entry, ``(R, D, R_p + |c - c_p|, D_p)`` (:attr:`SequentialLayout.lod`), are all
that a frame needs besides ``s`` and ``near``: the GPU side (``render/sequential.py``) draws a prefix
of the entries sorted by ``D_p`` and the vertex shader runs the test (``glsl/splat_attributes.glsl``);
:func:`drawn_mask` is the same rule in NumPy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError
from .lod import _lod_arrays
from .model import Hierarchy, LodShading, Selection, check_lod_shading

#: Stands for an infinite reach in the float32 interval columns (finite, so that ``BIG + x`` and
#: ``-BIG + x`` stay ordered the same way in NumPy and GLSL without inf arithmetic).
BIG = np.float32(1e30)


@dataclass(frozen=True, eq=False)
class SequentialLayout:
    """A hierarchy as one list of entries with their LOD intervals (module docstring).

    Attributes:
        splats: the entries' splats: the node splats (``lod_shading`` normal fields) in node order,
            then the hierarchy's points in their order; the points' origin.
        lod: (E, 4) float32 ``(R, D, A, B)`` per entry, model units: the entry is drawn at eye
            distance ``d`` when ``R + max(near, s D) <= d < A + max(near, s B)``.
        node_count: the first ``node_count`` entries are nodes.
        lod_shading: the normal-field mode of the node splats.
    """

    splats: SplatCloud
    lod: np.ndarray
    node_count: int
    lod_shading: LodShading

    def __len__(self) -> int:
        """Number of entries (nodes + points)."""
        return len(self.lod)


def sequential_layout(hierarchy: Hierarchy, lod_shading: LodShading = "fit") -> SequentialLayout:
    """The sequential layout of ``hierarchy`` (cached on it per ``lod_shading`` while its points and node
    colours stay the same objects: ``set_colors`` replaces them): every node and point with its
    interval (module docstring). About the hierarchy's size in memory again."""
    if not isinstance(hierarchy, Hierarchy):
        raise InputError(f"a sequential layout needs a Hierarchy, got {type(hierarchy).__name__}")
    check_lod_shading(lod_shading)
    key = ("sequential", lod_shading)
    held = hierarchy._cache.get(key)
    if held is not None and held[0] is hierarchy.points and held[1] is hierarchy.node_colors:
        return held[2]
    h = hierarchy
    m, n = len(h), len(h.points)
    lod = _lod_arrays(h)
    leaves = np.flatnonzero(h.is_leaf)
    leaves = leaves[np.argsort(h.node_point_start[leaves], kind="stable")]
    covered = np.concatenate([[0], np.cumsum(h.node_point_count[leaves])])
    if covered[-1] != n or not np.array_equal(h.node_point_start[leaves], covered[:-1]):
        raise InputError(f"hierarchy with {n:,} points: its leaves' point ranges do not partition the points")
    # all nodes, then every point (the leaves' ranges in point order): Hierarchy.splats' gather
    everything = Selection(nodes=(np.arange(m, dtype=np.int64),), leaves=(leaves,),
                           point_start=h.node_point_start[leaves], point_count=h.node_point_count[leaves],
                           lod_shading=lod_shading, lod_tolerance=0.0, visited=m, culled_frustum=0,
                           culled_backface=0)
    splats = h.splats(everything)
    radius = h.node_radius.astype(np.float32)
    diameter = (2.0 * h.node_extent).astype(np.float32)
    parent = lod.parent
    centers = h.node_positions.astype(np.float64)
    owner = np.repeat(leaves, h.node_point_count[leaves])   # the leaf holding each point
    out = np.empty((m + n, 4), dtype=np.float32)
    # r_min: the entry's own refinement reach; inf for nodes always refined, -inf for points
    out[:m, 0] = np.where(lod.sharp, BIG, radius)
    out[:m, 1] = diameter
    out[m:, 0] = -BIG
    out[m:, 1] = 0.0
    # r_max: the parent's reach, enlarged by the parent-child centre distance (Dachsbacher 2003, sec. 3.2)
    has_parent = parent >= 0
    p = parent[has_parent]
    gap = np.linalg.norm(centers[has_parent] - centers[p], axis=1)
    out[:m, 2] = BIG
    out[:m, 3] = 0.0
    out[np.flatnonzero(has_parent), 2] = np.where(lod.sharp[p], BIG, radius[p] + gap).astype(np.float32)
    out[np.flatnonzero(has_parent), 3] = diameter[p]
    gap = np.linalg.norm(h.points.positions.astype(np.float64) - centers[owner], axis=1)
    out[m:, 2] = np.where(lod.sharp[owner], BIG, radius[owner] + gap).astype(np.float32)
    out[m:, 3] = diameter[owner]
    layout = SequentialLayout(splats=splats, lod=out, node_count=m, lod_shading=lod_shading)
    hierarchy._cache[key] = (hierarchy.points, hierarchy.node_colors, layout)
    return layout


def drawn_mask(lod: np.ndarray, distance: np.ndarray, scale: float, near: float) -> np.ndarray:
    """(E,) bool: the entries the interval rule draws at eye distances ``distance`` ((E,), model
    units), in float32 as the vertex shader evaluates it (``lod`` as :attr:`SequentialLayout.lod`)."""
    lod = np.asarray(lod, dtype=np.float32)
    d = np.asarray(distance, dtype=np.float32)
    s, near = np.float32(scale), np.float32(near)
    low = lod[:, 0] + np.maximum(near, s * lod[:, 1])
    high = lod[:, 2] + np.maximum(near, s * lod[:, 3])
    return (d >= low) & (d < high)
