"""View-dependent level-of-detail selection over a :class:`~surfsplat.hierarchy.model.Hierarchy`.

Pajarola, Sainz & Guidotti 2003, sec. 5.1, step 1: a top-down traversal
refines a node (visits its children) while its projected size exceeds the
screen tolerance ``lod_tolerance`` (the paper's tau, pixels); nodes outside the
view frustum or entirely back-facing are dropped with their subtrees (Guennebaud
& Paulin 2003, sec. 8: view-frustum culling and back-face culling with
visibility cones). The traversal runs level
by level, vectorized over all nodes of a level: no Python call per node.

Projected size (pixels) of a node, conservative: ``focal_px * 2 a / (|c - eye|
- R)`` with ``a`` the major semi-axis of the ellipse bounding its points
(``node_extent``, Pajarola 2003 fig. 6 a: the sampling scale the node stands
for; the splat drawn is the larger ellipse covering the points' disks, fig. 6 b),
``c`` its center and ``R`` its bounding-sphere radius; the distance is taken as at least ``near``,
and a node whose sphere reaches closer than ``near`` to the eye (or contains
it) is always refined, and so is a node over splats with clip lines (sharp
edges stay sharp). An unrefined node contributes its representative
splat; a refined leaf contributes its original points. At ``lod_tolerance`` 0
every node is refined: the selection is the original cloud, less culled leaves.

Point budget (Schuetz 2016, Potree, sec. 3.3: a priority queue over the octree by projected
size, the largest node refined first until the budget is spent): with ``point_budget`` N the
cut is the coarsest-first refinement of the tolerance cut that draws at most N splats. It is
computed without a queue: the traversal above yields every node the tolerance cut refines;
each gets the priority ``min`` of its projected size and its parent's (so a child never comes
before its parent) and a cost (splats it adds when refined: its visible children, or a leaf's
points, minus itself); sorted by priority, the longest prefix whose running total stays within
N is refined (ties: shallower first, then by node index). Larger budgets refine a longer prefix of
the same order: cuts are nested. :func:`refinements` and :func:`refined_cut` expose the priorities
and costs, for one budget over several hierarchies (the cells of a chunked model).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import InputError
from .model import Hierarchy, LodShading, Selection, check_lod_shading, ranges_to_indices

#: Candidates of a level are tested by gathering their rows when they are
#: fewer than this fraction of the level, else on the whole level with a mask.
SPARSE = 0.25

#: Relative slack on bounding spheres in the frustum test (float32 rounding).
CULL_SLACK = 1e-5


class _LodArrays:
    """Contiguous float32 columns of the node data the traversal reads (built once per hierarchy)."""

    def __init__(self, h: Hierarchy):
        pos, nrm = h.node_positions, h.node_normals
        self.cx, self.cy, self.cz = (np.ascontiguousarray(pos[:, k]) for k in range(3))
        self.nx, self.ny, self.nz = (np.ascontiguousarray(nrm[:, k]) for k in range(3))
        self.radius = h.node_radius.astype(np.float32)
        self.cull_radius = (h.node_radius * np.float32(1.0 + CULL_SLACK)).astype(np.float32)
        self.diameter = (2.0 * h.node_extent).astype(np.float32)
        cone = h.node_cone.astype(np.float64)
        self.sin_cone = np.sin(cone).astype(np.float32)
        self.cos_cone = np.cos(cone).astype(np.float32)
        self.leaf = h.node_child_count == 0
        self.sharp = sharp_nodes(h)
        off = h.level_offsets
        counts = h.node_child_count.astype(np.int64)
        self.child_count = counts
        level = np.repeat(np.arange(h.levels), h.level_sizes)
        self.child_first_local = h.node_child_start - off[np.minimum(level + 1, h.levels)]
        # local index (within its parent's level) of each node's parent, per level
        self.parent_local = [None] + [np.repeat(np.arange(off[L + 1] - off[L], dtype=np.int64),
                                                counts[off[L]:off[L + 1]]) for L in range(h.levels - 1)]
        # global index of each node's parent (-1 for the root), for the point budget
        self.parent = np.full(len(self.leaf), -1, dtype=np.int64)
        for L in range(1, h.levels):
            self.parent[off[L]:off[L + 1]] = off[L - 1] + self.parent_local[L]


def _lod_arrays(h: Hierarchy) -> _LodArrays:
    arrays = h._cache.get("lod")
    if arrays is None:
        arrays = h._cache["lod"] = _LodArrays(h)
    return arrays


@dataclass(frozen=True)
class _View:
    """Camera quantities for the tests, float32 where they meet node columns."""

    eye: np.ndarray
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray
    tan_h: float
    tan_v: float
    cos_h: float
    cos_v: float
    near: float
    far: float
    focal: float

    @classmethod
    def of(cls, camera: Camera, h: Hierarchy) -> "_View":
        if camera.near is None or camera.far is None:
            camera = camera.with_clip_from_bounds(*h.sphere_bounds())
        near, far = camera.near, camera.far
        assert near is not None and far is not None   # set from the bounds above
        m = camera.view_matrix
        tan_v = float(np.tan(np.radians(camera.fov) / 2.0))
        tan_h = tan_v * camera.width / camera.height
        return cls(eye=np.asarray(camera.eye, dtype=np.float64), right=m[0, :3], up=m[1, :3], forward=-m[2, :3],
                   tan_h=tan_h, tan_v=tan_v, cos_h=1.0 / np.sqrt(1.0 + tan_h * tan_h),
                   cos_v=1.0 / np.sqrt(1.0 + tan_v * tan_v), near=float(near), far=float(far),
                   focal=float(camera.focal_px))


def select(hierarchy: Hierarchy, camera: Camera, lod_tolerance: float, *, cull_frustum: bool = True,
           cull_backfaces: bool = False, lod_shading: LodShading = "fit",
           point_budget: int | None = None) -> Selection:
    """Select the splats to draw for a view: the LOD cut at screen tolerance ``lod_tolerance``, culled.

    Pajarola 2003, sec. 5.1 (top-down traversal with tolerance tau),
    Guennebaud 2003, sec. 8 (frustum and visibility-cone culling); see the
    module docstring for the projected-size test.

    Args:
        hierarchy: the hierarchy.
        camera: the view; where its near/far are None they are set from the
            hierarchy's bounding sphere (``Camera.with_clip_from_bounds``).
        lod_tolerance: the LOD screen tolerance (Pajarola's tau) >= 0, pixels:
            a node whose projected ellipse diameter is at most it is drawn as
            one splat. 0 selects all original points.
        cull_frustum: drop nodes whose bounding sphere lies entirely outside
            one of the six frustum planes.
        cull_backfaces: drop nodes whose normal cone faces away from the eye
            from every point of their bounding sphere (conservative
            cone-vs-sphere test). Off by default: two-sided rendering and open
            surfaces need back faces.
        lod_shading: normal field of the node splats in :meth:`Hierarchy.splats`:
            ``"fit"`` (least-squares linear field), ``"cone"`` (normal-cone
            spread, Pajarola 2003 fig. 14) or ``"flat"``.
        point_budget: at most this many splats (>= 1; None: no limit): the tolerance cut's
            refinements are made largest projected size first while the cut stays within the
            budget (Potree's priority; see the module docstring). The tolerance cut itself when
            it fits.

    Returns:
        A :class:`Selection`; ``hierarchy.splats(selection)`` gathers the SplatCloud.
    """
    if not isinstance(hierarchy, Hierarchy):
        raise InputError(f"select needs a Hierarchy, got {type(hierarchy).__name__}")
    if not isinstance(camera, Camera):
        raise InputError(f"select needs a Camera, got {type(camera).__name__}")
    if not (np.isfinite(float(lod_tolerance)) and float(lod_tolerance) >= 0):
        raise InputError(f"LOD tolerance must be a finite number of pixels >= 0, got {lod_tolerance!r}")
    lod_tolerance = float(lod_tolerance)
    if point_budget is not None:
        point_budget = check_point_budget(point_budget)
    check_lod_shading(lod_shading)
    lod = _lod_arrays(hierarchy)
    view = _View.of(camera, hierarchy)
    nodes, leaves, opened_all, counts = _traverse(hierarchy, lod, view, lod_tolerance, cull_frustum, cull_backfaces)
    if point_budget is not None:
        size = sum(len(x) for x in nodes) + int(sum(hierarchy.node_point_count[x].sum() for x in leaves))
        if size > point_budget:
            nodes, leaves = _budget_cut(hierarchy, lod, view, nodes, leaves, opened_all, point_budget)
    return _selection(hierarchy, nodes, leaves, lod_shading, lod_tolerance, counts)


def _selection(hierarchy: Hierarchy, nodes: list, leaves: list, lod_shading: LodShading, lod_tolerance: float,
               counts: tuple[int, int, int]) -> Selection:
    leaf_index = np.concatenate(leaves) if leaves else np.zeros(0, dtype=np.int64)
    return Selection(nodes=tuple(nodes), leaves=tuple(leaves),
                     point_start=hierarchy.node_point_start[leaf_index],
                     point_count=hierarchy.node_point_count[leaf_index],
                     lod_shading=lod_shading, lod_tolerance=lod_tolerance, visited=counts[0],
                     culled_frustum=counts[1], culled_backface=counts[2])


def _traverse(hierarchy: Hierarchy, lod: _LodArrays, view: _View, lod_tolerance: float, cull_frustum: bool,
              cull_backfaces: bool):
    """The tolerance cut, level by level: ``(nodes drawn, leaves refined, inner nodes refined,
    (visited, culled by the frustum, culled as back-facing))``, global indices per level."""
    off = hierarchy.level_offsets
    nodes, leaves, opened_all = [], [], []
    visited = culled_frustum = culled_backface = 0
    reach = None  # None: every node of the level; bool array: a mask over the level; int array: local indices
    frustum = cull_frustum  # False once every node left is entirely inside the frustum
    for level in range(hierarchy.levels):
        lo, hi = int(off[level]), int(off[level + 1])
        rows: np.ndarray | slice = (reach + lo if isinstance(reach, np.ndarray) and reach.dtype != bool
                                    else slice(lo, hi))
        out, inside, back, refine = _test(lod, rows, view, lod_tolerance, frustum, cull_backfaces)
        live = ~(out | back)
        if isinstance(reach, np.ndarray) and reach.dtype == bool:
            live &= reach
            visited += int(reach.sum())
            culled_frustum += int((out & reach).sum())
            culled_backface += int((back & ~out & reach).sum())
        else:
            visited += len(live)
            culled_frustum += int(out.sum())
            culled_backface += int((back & ~out).sum())
        if frustum and not (live & ~inside).any():
            frustum = False  # the subtrees of nodes entirely inside need no frustum test
        leaf = lod.leaf[rows]
        chosen = live & ~refine
        opened = live & refine
        points = opened & leaf
        opened &= ~leaf
        if isinstance(reach, np.ndarray) and reach.dtype != bool:
            local = reach
            nodes.append(lo + local[chosen])
            leaves.append(lo + local[points])
            go = local[opened]
        else:
            nodes.append(lo + np.flatnonzero(chosen))
            leaves.append(lo + np.flatnonzero(points))
            go = np.flatnonzero(opened)
        opened_all.append(lo + go)
        if level + 1 == hierarchy.levels or len(go) == 0:
            break
        counts = lod.child_count[lo + go]
        total = int(counts.sum())
        size = int(off[level + 2] - off[level + 1])
        if total == size:
            reach = None
        elif total >= SPARSE * size:
            full = np.zeros(hi - lo, dtype=bool)
            full[go] = True
            reach = full[lod.parent_local[level + 1]]
        else:
            reach = ranges_to_indices(lod.child_first_local[lo + go], counts)
    return nodes, leaves, opened_all, (visited, culled_frustum, culled_backface)


def check_point_budget(point_budget) -> int:
    """``point_budget`` as an int >= 1 (splats); InputError otherwise."""
    if isinstance(point_budget, bool) or not isinstance(point_budget, (int, np.integer)) or point_budget < 1:
        raise InputError(f"point budget must be an integer >= 1 (splats), got {point_budget!r}")
    return int(point_budget)


def projected_size(hierarchy: Hierarchy, camera: Camera, index: np.ndarray) -> np.ndarray:
    """(len(index),) float64 projected diameter (pixels) of nodes ``index``: ``focal * 2 a /
    (|c - eye| - R)``, inf where the bounding sphere reaches closer than ``near`` (module docstring)."""
    return _projected_size(_lod_arrays(hierarchy), _View.of(camera, hierarchy), np.asarray(index, dtype=np.int64))


def _projected_size(lod: _LodArrays, view: _View, index: np.ndarray) -> np.ndarray:
    d = np.sqrt((lod.cx[index] - view.eye[0]) ** 2 + (lod.cy[index] - view.eye[1]) ** 2
                + (lod.cz[index] - view.eye[2]) ** 2)
    gap = d - lod.radius[index]
    with np.errstate(divide="ignore"):
        size = view.focal * lod.diameter[index].astype(np.float64) / np.maximum(gap, view.near)
    size[gap < view.near] = np.inf
    return size


def _budget_cut(h: Hierarchy, lod: _LodArrays, view: _View, nodes: list, leaves: list, opened: list,
                budget: int) -> tuple[list, list]:
    """The tolerance cut (``nodes``, ``leaves``, refined inner nodes ``opened``, per level) cut back
    to at most ``budget`` splats, refining in Potree's priority order (module docstring)."""
    live, cand, priority, cost, depth = _candidates(h, lod, view, nodes, leaves, opened, np.inf)
    if len(live) == 0:
        return nodes, leaves
    order = np.lexsort((cand, depth, -priority))   # largest first, parents before children on ties
    total = 1 + np.cumsum(cost[order])
    over = np.flatnonzero(total > budget)
    keep = np.zeros(len(cand), dtype=bool)
    keep[order[:over[0] if len(over) else len(order)]] = True
    return _kept_cut(h, lod, live, cand[keep], len(nodes))


def _candidates(h: Hierarchy, lod: _LodArrays, view: _View, nodes: list, leaves: list, opened: list,
                root_priority: float):
    """The refinements of a tolerance cut: ``(live nodes (sorted), refined nodes, their priorities
    (pixels), costs (splats added), levels)``; the root's priority is at most ``root_priority``."""
    levels = len(nodes)
    live = np.sort(np.concatenate(nodes + leaves + opened)) if levels else np.zeros(0, dtype=np.int64)
    refined = [np.concatenate([opened[L], leaves[L]]) for L in range(levels)]
    live_children = np.bincount(lod.parent[live][lod.parent[live] >= 0], minlength=len(lod.leaf))
    priority = np.full(len(lod.leaf), np.inf)
    for L in range(levels):   # top-down: a node's priority is at most its parent's
        r = refined[L]
        p = _projected_size(lod, view, r)
        priority[r] = np.minimum(p, root_priority) if L == 0 else np.minimum(p, priority[lod.parent[r]])
    cand = np.concatenate(refined) if levels else np.zeros(0, dtype=np.int64)
    cost = np.where(lod.leaf[cand], h.node_point_count[cand], live_children[cand]) - 1
    depth = np.repeat(np.arange(levels), [len(r) for r in refined])
    return live, cand, priority[cand], cost, depth


def _kept_cut(h: Hierarchy, lod: _LodArrays, live: np.ndarray, kept: np.ndarray, levels: int) -> tuple[list, list]:
    """The cut refining the nodes ``kept`` (a set closed under parents) of a tolerance cut's ``live``
    nodes (sorted): its drawn nodes and refined leaves per level."""
    keep = np.zeros(len(lod.leaf), dtype=bool)
    keep[kept] = True
    parent = lod.parent[live]
    parent_kept = np.ones(len(live), dtype=bool)   # the root, and nodes whose parent is refined
    parent_kept[parent >= 0] = keep[parent[parent >= 0]]
    drawn = live[parent_kept & ~keep[live]]
    opened_leaves = live[keep[live] & lod.leaf[live]]   # a refined node's parent is refined (prefix)
    off = h.level_offsets[:levels + 1]
    return _by_level(drawn, off), _by_level(opened_leaves, off)


@dataclass(frozen=True, eq=False)
class Refinements:
    """The refinements a tolerance cut makes, in the point budget's terms (Schuetz 2016, Potree:
    largest projected node first), for a budget shared by several hierarchies (a chunked model's
    cells, :mod:`surfsplat.hierarchy.chunked.lazy`).

    Refining ``node[i]`` adds ``cost[i]`` splats (its visible children, or a leaf's points, less
    itself); ``priority[i]`` is its projected size (pixels) capped by its parent's, so a child never
    comes before its parent; ``depth[i]`` its level. Refining the nodes of any set closed under
    parents (e.g. all above a priority) gives a cut (:func:`refined_cut`); ``selection`` is the
    tolerance cut, every refinement made; ``live`` its nodes (drawn or refined, sorted) and
    ``levels`` the levels it reaches.
    """

    node: np.ndarray
    priority: np.ndarray
    cost: np.ndarray
    depth: np.ndarray
    selection: Selection
    live: np.ndarray
    levels: int


def refinements(hierarchy: Hierarchy, camera: Camera, lod_tolerance: float, *, cull_frustum: bool = True,
                cull_backfaces: bool = False, lod_shading: LodShading = "fit",
                root_priority: float = np.inf) -> Refinements:
    """The refinements of the tolerance cut :func:`select` makes (same arguments) with their
    priorities and costs (:class:`Refinements`); the root's priority is at most ``root_priority``
    (pixels: the priority of the node it hangs from in a larger tree)."""
    check_lod_shading(lod_shading)
    lod = _lod_arrays(hierarchy)
    view = _View.of(camera, hierarchy)
    nodes, leaves, opened, counts = _traverse(hierarchy, lod, view, float(lod_tolerance), cull_frustum,
                                              cull_backfaces)
    live, cand, priority, cost, depth = _candidates(hierarchy, lod, view, nodes, leaves, opened,
                                                    float(root_priority))
    selection = _selection(hierarchy, nodes, leaves, lod_shading, float(lod_tolerance), counts)
    return Refinements(cand, priority, cost, depth, selection, live, len(nodes))


def refined_cut(hierarchy: Hierarchy, refined: Refinements, keep: np.ndarray) -> Selection:
    """The cut that makes the refinements ``refined.node[keep]`` (``keep``: (K,) bool, closed under
    parents, e.g. a prefix of the priority order) and no other; the tolerance cut when all are kept."""
    keep = np.asarray(keep, dtype=bool)
    if keep.all():
        return refined.selection
    s = refined.selection
    nodes, leaves = _kept_cut(hierarchy, _lod_arrays(hierarchy), refined.live, refined.node[keep], refined.levels)
    return _selection(hierarchy, nodes, leaves, s.lod_shading, s.lod_tolerance,
                      (s.visited, s.culled_frustum, s.culled_backface))


def _by_level(index: np.ndarray, off: np.ndarray) -> list[np.ndarray]:
    """Sorted global node indices split into one array per level (``off``: level offsets)."""
    return [index[a:b] for a, b in zip(np.searchsorted(index, off[:-1]), np.searchsorted(index, off[1:]))]


def selection_flags(hierarchy: Hierarchy, selection: Selection, flags: np.ndarray) -> np.ndarray:
    """A per-point boolean ``flags`` ((P,) over ``hierarchy.points``) carried to the splats of
    ``selection`` (in ``hierarchy.splats`` order): a node splat is flagged when most of its points
    are (majority vote over its contiguous point range, by prefix sums), a point splat as it is."""
    flags = np.asarray(flags).astype(bool)
    if flags.shape != (len(hierarchy.points),):
        raise InputError(f"flags must have one entry per point ({len(hierarchy.points)}), got shape {flags.shape}")
    total = np.concatenate([[0], np.cumsum(flags, dtype=np.int64)])
    nodes = selection.node_indices()
    start, count = hierarchy.node_point_start[nodes], hierarchy.node_point_count[nodes]
    majority = 2 * (total[start + count] - total[start]) > count
    return np.concatenate([majority, flags[selection.point_indices()]])


def uniform_cut(hierarchy: Hierarchy, budget: int) -> np.ndarray:
    """The finest view-independent cut of at most ``budget`` nodes: every node of one level plus
    the leaves above it (int64 node indices).

    Like every cut it covers the surface (each point has exactly one ancestor in it, whose ellipse
    covers the point's disk). Its size grows with the level (a node is replaced by its children
    or stays as a leaf), so the deepest level that fits is found from the per-level counts; the
    root alone when even level 1 does not fit.
    """
    if int(budget) < 1:
        raise InputError(f"a cut needs a budget of at least 1 node, got {budget}")
    leaf, depth = hierarchy.is_leaf, hierarchy.node_depth
    leaves_above = np.concatenate([[0], np.cumsum(np.bincount(depth[leaf], minlength=hierarchy.levels))[:-1]])
    fits = np.flatnonzero(hierarchy.level_sizes + leaves_above <= int(budget))
    level = int(fits.max()) if len(fits) else 0
    sl = hierarchy.level(level)
    return np.concatenate([np.flatnonzero(leaf & (depth < level)), np.arange(sl.start, sl.stop)])


def sharp_nodes(h: Hierarchy) -> np.ndarray:
    """(M,) bool: the nodes over splats with clip lines, which a cut always refines: a representative
    splat has no clip lines and would blur the sharp edge they cut (Zwicker 2004, sec. 5)."""
    if h.points.clip_lines is None:
        return np.zeros(len(h), dtype=bool)
    clipped = np.any(h.points.clip_lines[:, :, :2] != 0.0, axis=(1, 2))
    total = np.concatenate([[0], np.cumsum(clipped)])
    return total[h.node_point_start + h.node_point_count] > total[h.node_point_start]


def _test(lod: _LodArrays, rows, view: _View, lod_tolerance: float, frustum: bool, cull_backfaces: bool):
    """Frustum, back-face and refinement tests of some nodes (``rows``: slice or global indices).

    Returns four bool arrays: outside the frustum, entirely inside it (None
    when ``frustum`` is False), back-facing, to refine.
    """
    e = view.eye.astype(np.float32)
    dx = lod.cx[rows] - e[0]
    dy = lod.cy[rows] - e[1]
    dz = lod.cz[rows] - e[2]
    radius = lod.radius[rows]
    with np.errstate(over="ignore"):   # float32: an eye ~1e19 away is at distance inf, farther than any reach
        d2 = dx * dx
        d2 += dy * dy
        d2 += dz * dz
    n = len(d2)
    if frustum:
        out, inside = _frustum(dx, dy, dz, lod.cull_radius[rows], view)
    else:
        out, inside = np.zeros(n, dtype=bool), None
    if cull_backfaces:
        back = _backfacing(dx, dy, dz, d2, radius, lod, rows)
    else:
        back = np.zeros(n, dtype=bool)
    # Pajarola 2003, sec. 5.1: refine while the projected size exceeds the tolerance l. The size
    # focal * 2a / max(|c - eye| - R, near) exceeds l iff |c - eye| < R + max(near, focal * 2a / l).
    if lod_tolerance > 0:
        with np.errstate(over="ignore"):   # a reach beyond float32 is inf: refine (any finite distance is nearer)
            reach = lod.diameter[rows] * np.float32(view.focal / lod_tolerance)
            np.maximum(reach, np.float32(view.near), out=reach)
            reach += radius
            reach *= reach
        refine = d2 < reach
    else:
        refine = np.ones(n, dtype=bool)
    refine |= lod.sharp[rows]
    return out, inside, back, refine


def _frustum(dx, dy, dz, radius, view: _View):
    """Bounding spheres (center offsets from the eye) entirely outside one of the six frustum
    planes, and entirely inside all of them."""
    f, r, u = (x.astype(np.float32) for x in (view.forward, view.right, view.up))
    depth = dx * f[0] + dy * f[1] + dz * f[2]
    near = depth - np.float32(view.near)  # signed distances inside the near and far planes
    far = np.float32(view.far) - depth
    out = near < -radius
    out |= far < -radius
    inside = near >= radius
    inside &= far >= radius
    for axis, tan, cos in ((r, view.tan_h, view.cos_h), (u, view.tan_v, view.cos_v)):
        x = np.abs(dx * axis[0] + dy * axis[1] + dz * axis[2])
        x -= np.float32(tan) * depth
        x *= np.float32(cos)  # signed distance outside the pair of side planes
        out |= x > radius
        inside &= x <= -radius
    return out, inside


def _backfacing(dx, dy, dz, d2, radius, lod: _LodArrays, rows) -> np.ndarray:
    """Cone-vs-sphere back-face test (normal cones, Shirman & Abi-Ezzi 1993; Guennebaud 2003 sec. 8).

    Every normal within theta of the axis n faces away from every point of
    the sphere seen from the eye iff the angle between n and the direction to
    the eye exceeds 90 deg + theta + phi, ``sin(phi) = R / |c - eye|``: that
    is ``n . (c - eye) / |c - eye| > sin(theta + phi)`` with
    ``theta + phi < 90 deg``. Multiplied by ``|c - eye|``, with
    ``w = sqrt(|c - eye|^2 - R^2)``: ``n . (c - eye) > sin(theta) w +
    cos(theta) R`` and ``cos(theta) w > sin(theta) R`` (false when the eye is
    inside the sphere, w = 0).
    """
    s_t, c_t = lod.sin_cone[rows], lod.cos_cone[rows]
    w = d2 - radius * radius
    np.maximum(w, np.float32(0.0), out=w)
    np.sqrt(w, out=w)
    ndot = dx * lod.nx[rows]
    ndot += dy * lod.ny[rows]
    ndot += dz * lod.nz[rows]
    bound = s_t * w
    bound += c_t * radius
    bound += np.float32(1e-6) * w
    back = ndot > bound
    back &= c_t * w > s_t * radius
    return back
