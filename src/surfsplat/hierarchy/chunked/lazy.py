"""Opening a chunked hierarchy lazily and cutting it per view (:class:`ChunkedHierarchy`).

Opening reads the manifest, the coarse top hierarchy over the cells' roots (``top.npz``) and the
preview; nothing of the cells. Per view (:meth:`ChunkedHierarchy.view_splats`):

1. the top hierarchy is cut (:func:`surfsplat.hierarchy.lod.select`, Pajarola 2003 sec. 5.1):
   its coarse nodes are drawn as they are, culled ones dropped;
2. each cell root the cut reaches is tested with the same projected-size rule from the
   manifest (center, bounding-sphere radius, extent): a root small enough on screen is drawn
   as its one splat without reading the cell;
3. every other cell is loaded (its ``coarse.npz``, the first levels; ``nodes.npz``, all levels,
   only when the cut refines a coarse-level node that has children) and cut with the same
   tolerance, one cell at a time: its selected splats are copied into the view's output arrays
   (the splat files memory-mapped for that copy only, so only the pages of the points the cut
   selects are read, and let go after it) before the next cell is read.

A view thus holds its output (drawn splats x 68 bytes), the cells the LRU cache keeps and the one
cell being cut. The cache keeps at most ``cache_cells`` cells whose node arrays (and the LOD
traversal's columns) take at most ``cache_bytes`` (:data:`CACHE_BYTES`, or a quarter of the memory
available if less); cells are read without the nodes' covariances, which views never use.

With a point budget the cut is Potree's (Schuetz 2016, sec. 3.3): the refinements of the top
hierarchy and of every cell form one tree, refined largest projected size first, globally, until
the next one would exceed the budget (:func:`surfsplat.hierarchy.lod.refinements`). A cell's
refinements come after its root's (a child's priority is at most its parent's), so cells are
visited in the order of their roots' priorities, known from the manifest, and the visit stops at
the first cell whose root comes after the refinement the budget leaves out: the cells that are not
refined are never read. Positions are relative to :attr:`ChunkedHierarchy.origin` (float64);
cameras are given in that frame.
"""

from __future__ import annotations

import copy
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...camera import Camera
from ...cloud import SplatCloud
from ...colors import attribute_values, colorize, is_class_palette, resolve_colormap, robust_range
from ...errors import InputError
from ...io.atomic import memory_limit
from ...io.npz import read_npz
from ..lod import Refinements, check_point_budget, refined_cut, refinements, select
from ..model import Hierarchy, LodShading, Selection
from ..storage import load_hierarchy
from .layout import (chunked_up, CELLS, COARSE, NODE_FILES, NODES, POINT_FILES, PREVIEW, TOP, check_size, open_points,
                     read_manifest, read_nodes)

#: Cells kept loaded (node arrays in memory, splats memory-mapped).
CACHE_CELLS = 64
#: ... whose node arrays take at most this many bytes (a 64 M-point model's 81 cells hold about
#: 8 GB of them: a count alone let a view grow until the system killed it) ...
CACHE_BYTES = 512 * 2**20
#: ... and at most this share of the memory available when the model is opened.
CACHE_MEMORY_SHARE = 0.25

#: Node arrays a view needs (the covariances are for building only).
VIEW_NODE_FILES = tuple(name for name in NODE_FILES if name != "node_covariance")

#: Output columns of a view: name -> columns.
_COLUMNS = {"positions": 3, "normals": 3, "u": 3, "v": 3, "colors": 3, "normal_field": 2}


@dataclass(frozen=True)
class ChunkedSelection:
    """What a view of a chunked hierarchy drew: ``node_count`` (coarse splats: top nodes, cell roots
    and cell nodes), ``point_total`` (original splats), ``cells_loaded`` (cells cut for this view,
    read from disk or the cache), ``cells_root_only`` (cells drawn as their root splat, not read),
    ``lod_tolerance`` (pixels, the one asked for), ``cells_coarse`` (of the cells cut, those whose
    coarse-levels file sufficed), ``budget_priority`` (with a point budget that the tolerance cut
    exceeds: the priority, pixels, of the first refinement left out; every refinement made has at
    least it), ``cells_planned`` (cells read to find where the budget stops)."""

    node_count: int
    point_total: int
    cells_loaded: int
    cells_root_only: int
    lod_tolerance: float
    cells_coarse: int = 0
    budget_priority: float | None = None
    cells_planned: int = 0

    def __len__(self) -> int:
        """Splats drawn."""
        return self.node_count + self.point_total

    def summary(self) -> dict:
        """Counts for reports."""
        return {"splats": len(self), "nodes": self.node_count, "points": self.point_total,
                "lod_tolerance": self.lod_tolerance, "cells_loaded": self.cells_loaded,
                "cells_root_only": self.cells_root_only, "cells_coarse": self.cells_coarse,
                "budget_priority": self.budget_priority, "cells_planned": self.cells_planned}


class ChunkedHierarchy:
    """A chunked hierarchy directory (``surfsplat build --chunked``), opened lazily.

    Attributes:
        path: the directory.
        manifest: the parsed ``manifest.json``.
        origin: (3,) float64: every position is relative to it (model units).
        top: the :class:`Hierarchy` over the cells' root splats (its points are the roots, in
            manifest order through ``top.order``).
        points: the preview splats (a uniform cut of every cell, about 200k splats; with
            :attr:`origin`), for framing.
        up: the data's up axis (+z for LAS/LAZ input).
        attributes: ``{name: dtype}`` of the point attributes the cells keep (LAS/LAZ dimensions
            such as ``classification``); views carry them (``SplatCloud.attributes``; node splats:
            the mean, or the majority for integer attributes).
        coloring: None, or the ``(by, colormap, value range, up)`` every view is coloured by
            (:meth:`colorized`).
        cache_cells: most cells kept loaded.
        cache_bytes: most bytes of node arrays kept loaded (the cell just read is kept whatever its size).
        peak_cells: most cells held at once (cached or being cut) since opening.
    """

    def __init__(self, path, cache_cells: int = CACHE_CELLS, cache_bytes: int | None = None):
        self.path = Path(path)
        self.manifest = read_manifest(self.path)
        self.origin = np.array(self.manifest["origin"], dtype=np.float64)
        self.up = chunked_up(self.path)   # None where the input did not say (guessed when shown)
        self.cells = self.manifest["cells"]
        try:
            self.attributes = {str(a["name"]): np.dtype(a["dtype"]) for a in self.manifest.get("attributes", [])}
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{self.path / 'manifest.json'}: malformed attribute table") from None
        self.coloring = None
        self.cache_cells = int(cache_cells)
        self.cache_bytes = int(min(CACHE_BYTES, CACHE_MEMORY_SHARE * memory_limit()) if cache_bytes is None
                               else cache_bytes)
        self._bytes: dict[int, int] = {}   # node-array bytes of each cached cell
        self._cache: OrderedDict[int, tuple[Hierarchy, bool]] = OrderedDict()   # (hierarchy, all levels)
        self._deeper: dict[int, np.ndarray | None] = {}
        self.loads = 0
        self.peak_cells = 0
        self.top = load_hierarchy(self.path / self.manifest.get("top", TOP))
        if len(self.top.points) != len(self.cells):
            raise InputError(f"{self.path / TOP}: holds {len(self.top.points)} cell roots, the manifest "
                             f"{len(self.cells)} cells")
        self.points = _read_preview(self.path / self.manifest.get("preview", PREVIEW), self.origin,
                                    list(self.attributes))
        self.points.up = self.up
        roots = self.cells
        self._root_center = np.array([c["root"]["position"] for c in roots], dtype=np.float64)
        self._root_radius = np.array([c["root"]["radius"] for c in roots], dtype=np.float64)
        self._root_extent = np.array([c["root"]["extent"] for c in roots], dtype=np.float64)

    def __repr__(self) -> str:
        return (f"ChunkedHierarchy({self.path}: {self.point_count:,} points in {len(self.cells):,} cells, "
                f"{len(self._cache)} loaded)")

    @property
    def point_count(self) -> int:
        """Splats stored in all cells."""
        return int(self.manifest["points"])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World bounds ``(min, max)`` of the splat centers (float64, model units)."""
        lo = np.min([c["bounds"][0] for c in self.cells], axis=0)
        hi = np.max([c["bounds"][1] for c in self.cells], axis=0)
        return lo + self.origin, hi + self.origin

    def sphere_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(min, max)`` of the top root's bounding sphere relative to :attr:`origin`: they
        enclose every splat disk."""
        return self.top.sphere_bounds()

    # -- cells -----------------------------------------------------------------

    def cell(self, index: int, full: bool = True) -> Hierarchy:
        """The hierarchy of cell ``index`` (manifest order), from the LRU cache or read from disk:
        node arrays loaded (without covariances: ``node_covariance`` is None), splat arrays
        memory-mapped. With ``full=False`` a cell that has a coarse-levels file may come with only
        its first levels, whose last level's nodes are then leaves (their points are their whole
        subtrees'); a view reads the rest when it refines one of them. InputError naming a missing
        or corrupt file."""
        index = int(index)
        cached = self._cache.get(index)
        if cached is not None and (cached[1] or not full):
            self._cache.move_to_end(index)
            return cached[0]
        entry = self.cells[index]
        folder = self.path / CELLS / entry["key"]
        files = entry["files"]
        coarse = not full and COARSE in files
        for name, size in files.items():
            check_size(folder / name, int(size))
        source = folder / (COARSE if coarse else NODES)
        if cached is not None:   # its coarse levels go before its whole node arrays are read
            self._evict(index)
        nodes = read_nodes(source, VIEW_NODE_FILES)
        points, ids, _ = self._points(index, attributes=False)
        n = int(entry["points"])
        off = nodes["level_offsets"]
        m = len(nodes["node_positions"])
        levels = int(entry.get("coarse_levels", entry["levels"])) if coarse else int(entry["levels"])
        if ((not coarse and m != int(entry["nodes"])) or len(off) != levels + 1
                or int(nodes["node_point_count"][0]) != n):
            raise InputError(f"{source}: corrupt chunk file: {m} nodes in {len(off) - 1} levels over "
                             f"{int(nodes['node_point_count'][0])} points, the manifest says {entry['nodes']} nodes "
                             f"in {entry['levels']} levels over {n} points")
        child_count = nodes["node_child_count"]
        deeper = None
        if coarse:  # the last level's nodes become leaves; `deeper` remembers which have children
            last = slice(int(off[-2]), int(off[-1]))
            deeper = np.zeros(m, dtype=bool)
            deeper[last] = child_count[last] > 0
            child_count = child_count.copy()
            child_count[last] = 0
        start, count, child = nodes["node_point_start"], nodes["node_point_count"], nodes["node_child_start"]
        if np.any(start < 0) or np.any(start + count > n) or np.any((child_count > 0) & (child + child_count > m)):
            raise InputError(f"{source}: corrupt chunk file: node ranges out of bounds")
        arrays = {name: nodes.get(name) for name in NODE_FILES}
        arrays["node_child_count"] = child_count
        values = {}
        for i, (name, dtype) in enumerate(self.attributes.items()):
            value = nodes.get(f"node_attribute_{i}")
            if value is None or value.dtype != dtype or value.shape != (m,):
                raise InputError(f"{source}: corrupt chunk file: 'node_attribute_{i}' ({name}) is missing or not "
                                 f"{dtype} ({m},)")
            values[name] = value
        h = Hierarchy(points=points, order=ids, level_offsets=off, origin=nodes["origin"],
                      leaf_capacity=int(nodes["leaf_capacity"]), max_depth=int(nodes["max_depth"]),
                      node_attributes=values or None, **arrays)
        self.loads += 1
        self._cache[index] = (h, not coarse)
        self._cache.move_to_end(index)
        self._deeper[index] = deeper
        self._bytes[index] = _held_bytes(h)
        self.peak_cells = max(self.peak_cells, len(self._cache))
        self._trim()
        return h

    def _points(self, index: int, attributes: bool = True) -> tuple[SplatCloud, np.ndarray, dict]:
        """Cell ``index``'s splats, input ids and (with ``attributes``) point attributes by name,
        memory-mapped read-only (checked)."""
        entry = self.cells[index]
        folder = self.path / CELLS / entry["key"]
        values = {}
        for i, (name, dtype) in enumerate(self.attributes.items() if attributes else ()):
            path = folder / f"attribute_{i}.npy"
            if path.name not in entry["files"]:
                raise InputError(f"{path}: missing chunk file of the chunked hierarchy (attribute {name})")
            values[name] = open_points(path, "ids", int(entry["points"]), dtype)
        arrays = {}
        for name, (_, _, required) in POINT_FILES.items():
            if f"{name}.npy" not in entry["files"]:
                if required:
                    raise InputError(f"{folder / (name + '.npy')}: missing chunk file of the chunked hierarchy")
                arrays[name] = None
                continue
            arrays[name] = open_points(folder / f"{name}.npy", name, int(entry["points"]))
        points = SplatCloud(positions=arrays["positions"], normals=arrays["normals"], colors=arrays["colors"],
                            u=arrays["u"], v=arrays["v"], origin=np.zeros(3))
        return points, arrays["ids"], values

    def _evict(self, index: int) -> None:
        self._cache.pop(index, None)
        self._deeper.pop(index, None)
        self._bytes.pop(index, None)

    def _trim(self) -> None:
        """Let go of the least recently used cells while the cache is over its bounds (never the
        most recent one: the cell being cut)."""
        while len(self._cache) > 1 and (len(self._cache) > self.cache_cells
                                        or sum(self._bytes.values()) > self.cache_bytes):
            self._evict(next(iter(self._cache)))

    def _refinements(self, index: int, local: Camera, tolerance: float, options: dict, root_priority: float,
                     keep) -> tuple[Hierarchy, Refinements, bool]:
        """A cell's refinements (:func:`surfsplat.hierarchy.lod.refinements`): on its coarse levels
        when they suffice (none of the refinements ``keep(refinements)`` selects opens a coarse leaf
        that has children), else on all its levels. Returns ``(hierarchy, refinements, coarse
        levels only)``."""
        h = self.cell(index, full=False)
        r = refinements(h, local, tolerance, root_priority=root_priority, **options)
        deeper = self._deeper.get(int(index))
        coarse = deeper is not None
        if coarse and deeper[r.node[keep(r)]].any():
            h = self.cell(index, full=True)
            r = refinements(h, local, tolerance, root_priority=root_priority, **options)
            coarse = False
        self._bytes[int(index)] = _held_bytes(h)   # with the LOD traversal's columns
        self._trim()
        return h, r, coarse

    def _select(self, index: int, local: Camera, tolerance: float, options: dict) -> tuple[Hierarchy, Selection, bool]:
        """A cell's tolerance cut (no budget): on its coarse levels when they suffice (no refined
        leaf there has children), else on all its levels. Returns ``(hierarchy, selection, coarse
        levels only)``."""
        h = self.cell(index, full=False)
        sel = select(h, local, tolerance, **options)
        deeper = self._deeper.get(int(index))
        coarse = deeper is not None
        if coarse and sel.leaves and deeper[np.concatenate(sel.leaves)].any():
            h = self.cell(index, full=True)
            sel = select(h, local, tolerance, **options)
            coarse = False
        self._bytes[int(index)] = _held_bytes(h)
        self._trim()
        return h, sel, coarse

    @property
    def cached(self) -> list[int]:
        """Indices of the cells loaded now, least recently used first."""
        return list(self._cache)

    @property
    def complete(self) -> list[int]:
        """Indices of the cached cells whose every level is loaded."""
        return [index for index, (_, full) in self._cache.items() if full]

    # -- views -----------------------------------------------------------------

    def colorized(self, by: str, colormap: str | None = None, value_range=None, *,
                  up=(0.0, 0.0, 1.0)) -> "ChunkedHierarchy":
        """The model (sharing its cells and cache) with every view and its preview coloured by the scalar ``by``
        (``elevation`` or one of :attr:`attributes`; arguments as :func:`surfsplat.colors.colorize`):
        node splats of a class palette (``asprs``, the default for ``classification``) get their
        majority class's colour; a continuous colormap spans ``value_range``, by default the
        2nd-98th percentiles of the attribute over the points (the manifest's ``range``, from a
        random sample at build time) or of the elevation over the preview, the same for every
        view. An unknown name is an InputError listing the attributes."""
        name, values = attribute_values(self.points, by, up)
        colormap = resolve_colormap(name, colormap)
        if value_range is None and not is_class_palette(name, colormap):
            ranges = {a["name"]: a.get("range") for a in self.manifest.get("attributes", [])}
            value_range = tuple(ranges[name]) if ranges.get(name) else robust_range(values)
        out = copy.copy(self)
        out.coloring = (name, colormap, value_range, tuple(up))
        out.points = colorize(self.points, name, colormap, value_range, up=up)   # the preview too
        return out

    def view_splats(self, camera: Camera, lod_tolerance: float, *, cull_backfaces: bool = False,
                    lod_shading: LodShading = "fit",
                    point_budget: int | None = None) -> tuple[SplatCloud, ChunkedSelection]:
        """The splats to draw for a view at screen tolerance ``lod_tolerance`` (pixels), reading only
        the cells the view needs, one at a time (see the module docstring); ``camera`` in world
        coordinates.

        With ``point_budget``, at most that many splats (or the top root alone, if even that is
        more): the tolerance cut's refinements over the top hierarchy and all cells are made
        largest projected size first while the cut stays within the budget (Potree's priority,
        Schuetz 2016; the order of :func:`surfsplat.hierarchy.lod.select`'s budget, ties to the
        shallower node). Larger budgets give nested cuts.

        Returns:
            ``(SplatCloud, ChunkedSelection)``; the splats carry :attr:`origin`.
        """
        local = camera.translated(-self.origin)
        if local.near is None or local.far is None:
            local = local.with_clip_from_bounds(*self.sphere_bounds())
        if point_budget is not None:
            point_budget = check_point_budget(point_budget)
        options = {"cull_backfaces": cull_backfaces, "lod_shading": lod_shading}
        plan = _Plan(self, local, float(lod_tolerance), options)
        if point_budget is not None:
            plan.fit(point_budget)
        cloud, selection = plan.gather()
        if self.coloring is not None:
            by, colormap, value_range, up = self.coloring
            cloud = colorize(cloud, by, colormap, value_range, up=up)
        return cloud, selection

    def _root_priority(self, cells: np.ndarray, camera: Camera) -> np.ndarray:
        """(len(cells),) float64 projected size (pixels) of the cells' roots, from the manifest:
        ``focal * 2 a / max(|c - eye| - R, near)``, inf where the sphere reaches closer than
        ``near`` (the priority of :mod:`surfsplat.hierarchy.lod`)."""
        gap = np.linalg.norm(self._root_center[cells] - np.asarray(camera.eye, dtype=np.float64), axis=1)
        gap -= self._root_radius[cells]
        with np.errstate(divide="ignore"):
            size = camera.focal_px * 2.0 * self._root_extent[cells] / np.maximum(gap, camera.near)
        size[gap < camera.near] = np.inf
        return size

    def _refine_roots(self, cells: np.ndarray, camera: Camera, lod_tolerance: float) -> np.ndarray:
        """(len(cells),) bool: the cell's root is refined by the rule of :mod:`surfsplat.hierarchy.lod`
        (Pajarola 2003 sec. 5.1): ``|c - eye| < R + max(near, focal * 2 a / tolerance)``, ``camera``
        in the local frame."""
        if lod_tolerance <= 0:
            return np.ones(len(cells), dtype=bool)
        d = np.linalg.norm(self._root_center[cells] - np.asarray(camera.eye, dtype=np.float64), axis=1)
        reach = np.maximum(camera.focal_px * 2.0 * self._root_extent[cells] / lod_tolerance, camera.near)
        return d < self._root_radius[cells] + reach


def _held_bytes(h: Hierarchy) -> int:
    """Bytes of a cell's node arrays in memory and of the LOD traversal's columns computed from them
    (memory-mapped splat arrays are not counted: their pages are the system's)."""
    arrays = [getattr(h, name) for name in NODE_FILES] + [h.level_offsets] + list((h.node_attributes or {}).values())
    for value in h._cache.values():
        for item in vars(value).values() if hasattr(value, "__dict__") else ():
            arrays.extend(item if isinstance(item, list) else [item])
    return int(sum(a.nbytes for a in arrays if isinstance(a, np.ndarray) and not isinstance(a, np.memmap)))


def _before(priority, depth, rank, node, key) -> np.ndarray:
    """Whether refinements come before ``key`` = (priority, depth, rank, node) in the budget's
    order: larger priority first, then shallower, then by cell rank and node index."""
    p, d, r, n = key
    same_depth = (rank < r) | ((rank == r) & (node < n))
    return (priority > p) | ((priority == p) & ((depth < d) | ((depth == d) & same_depth)))


class _Plan:
    """One view of a chunked hierarchy: the top hierarchy's refinements, the cells their refined
    leaves reach in the budget's order, where a point budget stops (:meth:`fit`), and the splats
    gathered cell by cell (:meth:`gather`)."""

    def __init__(self, model: ChunkedHierarchy, local: Camera, tolerance: float, options: dict):
        self.model, self.local, self.tolerance, self.options = model, local, tolerance, options
        top = model.top
        self.top = refinements(top, local, tolerance, **options)
        sel = self.top.selection
        rows = sel.point_indices()   # the cell roots the tolerance cut reaches (top points)
        cells = top.order[rows]
        leaf_of_row = np.repeat(np.concatenate(sel.leaves) if sel.leaves else np.zeros(0, dtype=np.int64),
                                sel.point_count)
        leaf_priority = np.full(len(top), np.inf)
        leaf_priority[self.top.node] = self.top.priority
        refine = model._refine_roots(cells, local, tolerance)
        priority = np.minimum(model._root_priority(cells, local), leaf_priority[leaf_of_row])
        # the refined cells in the order of their roots' keys: (priority desc, depth, rank, node 0)
        order = np.flatnonzero(refine)[np.argsort(-priority[refine], kind="stable")]
        self.cell_rows, self.cell_priority = rows[order], priority[order]
        self.rank_of_row = np.full(len(top.points), -1, dtype=np.int64)
        self.rank_of_row[self.cell_rows] = np.arange(len(order))
        self.depth = top.levels   # cell nodes' depth below the top's (ties: parents first)
        self.key = None            # the first refinement the budget leaves out (None: all are made)
        self.expected = None       # splats of the budget's cut
        self.planned = 0

    def _cell_keys(self, r: Refinements, rank: int) -> tuple:
        return r.priority, self.depth + r.depth, np.full(len(r.node), rank, dtype=np.int64), r.node

    def _kept(self, r: Refinements, rank: int) -> np.ndarray:
        if self.key is None:
            return np.ones(len(r.node), dtype=bool)
        return _before(*self._cell_keys(r, rank), self.key)

    def _root_kept(self, rank: int) -> bool:
        return self.key is None or bool(_before(self.cell_priority[rank], self.depth, rank, 0, self.key))

    def fit(self, budget: int) -> None:
        """Find the first refinement the budget leaves out (:attr:`key`), reading cells in the order
        of their roots' priorities until the next root comes after it."""
        base = 1 if len(self.top.live) else 0
        pool = {"priority": self.top.priority, "depth": self.top.depth,
                "rank": np.full(len(self.top.node), -1, dtype=np.int64), "node": self.top.node,
                "cost": self.top.cost}
        pool = self._settle(pool, base, budget)
        model = self.model
        for rank, row in enumerate(self.cell_rows):
            if not self._root_kept(rank):
                break   # every later cell's refinements come after the one left out
            index = int(model.top.order[row])
            _, r, _ = model._refinements(index, self.local, self.tolerance, self.options,
                                         float(self.cell_priority[rank]), lambda r: self._kept(r, rank))
            self.planned += 1
            priority, depth, ranks, node = self._cell_keys(r, rank)
            cost = r.cost
            if len(r.selection) == 0 and len(r.node) == 0:   # culled whole: refining its root drops it
                priority, depth = np.array([self.cell_priority[rank]]), np.array([self.depth])
                ranks, node, cost = np.array([rank]), np.zeros(1, dtype=np.int64), np.array([-1])
            keep = self._kept_items(priority, depth, ranks, node)
            items = {"priority": priority[keep], "depth": depth[keep], "rank": ranks[keep], "node": node[keep],
                     "cost": cost[keep]}
            pool = self._settle({k: np.concatenate([pool[k], items[k]]) for k in pool}, base, budget)
        self.expected = int(base + pool["cost"].sum())

    def _kept_items(self, priority, depth, rank, node) -> np.ndarray:
        if self.key is None:
            return np.ones(len(priority), dtype=bool)
        return _before(priority, depth, rank, node, self.key)

    def _settle(self, pool: dict, base: int, budget: int) -> dict:
        """The longest prefix of ``pool``'s refinements in the budget's order that fits; the first
        one after it becomes :attr:`key`."""
        order = np.lexsort((pool["node"], pool["rank"], pool["depth"], -pool["priority"]))
        total = base + np.cumsum(pool["cost"][order])
        over = np.flatnonzero(total > budget)
        if len(over) == 0:
            return pool
        first = order[over[0]]
        self.key = (float(pool["priority"][first]), int(pool["depth"][first]), int(pool["rank"][first]),
                    int(pool["node"][first]))
        return {k: v[order[:over[0]]] for k, v in pool.items()}

    def gather(self) -> tuple[SplatCloud, ChunkedSelection]:
        """The view's splats, gathered cell by cell into arrays allocated once (with a budget: its
        exact size) or grown geometrically."""
        model, top = self.model, self.model.top
        top_keep = self._kept_items(self.top.priority, self.top.depth, np.full(len(self.top.node), -1), self.top.node)
        top_sel = refined_cut(top, self.top, top_keep)
        rows = top_sel.point_indices()
        ranks = self.rank_of_row[rows]
        refined = ranks >= 0
        if self.key is not None:
            refined[refined] = _before(self.cell_priority[ranks[refined]], self.depth, ranks[refined], 0, self.key)
        colors = top.node_colors is not None and top.points.colors is not None
        shading = self.options["lod_shading"]
        normal_field = shading != "flat" or top.points.normal_field is not None
        top_nodes = top_sel.node_indices()
        capacity = self.expected if self.expected is not None else len(top_nodes) + len(rows) + len(model.points)
        out = _Output(capacity, colors, normal_field, model.attributes)
        out.add(top.node_splats(top_nodes, shading), {name: top.node_attributes[name][top_nodes]
                                                      for name in model.attributes})
        out.add(top.points.subset(rows[~refined]), {name: top.points.attributes[name][rows[~refined]]
                                                    for name in model.attributes})
        nodes, points, coarse_cells = len(top_nodes) + int((~refined).sum()), 0, 0
        cell_ranks = np.sort(ranks[refined])
        for rank in cell_ranks:
            index = int(top.order[self.cell_rows[rank]])
            if self.key is None:   # no budget: the tolerance cut of each cell
                h, sel, coarse = model._select(index, self.local, self.tolerance, self.options)
            else:
                h, r, coarse = model._refinements(index, self.local, self.tolerance, self.options,
                                                  float(self.cell_priority[rank]), lambda r: self._kept(r, int(rank)))
                sel = refined_cut(h, r, self._kept(r, int(rank)))
            out.add_cell(model, index, h, sel, shading)
            nodes += sel.node_count
            points += sel.point_total
            coarse_cells += int(coarse)
        summary = ChunkedSelection(nodes, points, len(cell_ranks), int((~refined).sum()), self.tolerance, coarse_cells,
                                   None if self.key is None else self.key[0], self.planned)
        return out.cloud(model.origin), summary


class _Output:
    """The output arrays of a view, filled part by part (allocated once when the size is known,
    else grown by half as needed, one array at a time)."""

    def __init__(self, capacity: int, colors: bool, normal_field: bool, attributes: dict):
        names = [name for name in _COLUMNS if (name != "colors" or colors) and (name != "normal_field" or normal_field)]
        capacity = max(int(capacity), 1)
        self.arrays = {name: np.empty((capacity, _COLUMNS[name]), dtype=np.float32) for name in names}
        self.values = {name: np.empty(capacity, dtype=dtype) for name, dtype in attributes.items()}
        self.n = 0

    def _reserve(self, count: int) -> slice:
        need = self.n + count
        for table in (self.arrays, self.values):
            for name, array in table.items():
                if need > len(array):
                    grown = np.empty((max(need, len(array) + len(array) // 2),) + array.shape[1:], dtype=array.dtype)
                    grown[:self.n] = array[:self.n]
                    table[name] = grown
        part = slice(self.n, need)
        self.n = need
        return part

    def add(self, cloud: SplatCloud, values: dict) -> None:
        """Append a SplatCloud's splats (normal fields zero where it has none) and their attribute ``values``."""
        part = self._reserve(len(cloud))
        for name, array in self.arrays.items():
            value = getattr(cloud, name)
            if value is None:
                array[part] = 0.0
            else:
                array[part] = value
        for name, array in self.values.items():
            array[part] = values[name]

    def add_cell(self, model: ChunkedHierarchy, index: int, h: Hierarchy, sel: Selection,
                 shading: LodShading) -> None:
        """Append the splats of cell ``index``'s cut ``sel``: its node splats, then its points read
        through memory maps opened for this copy only."""
        nodes = sel.node_indices()
        part = self._reserve(len(nodes))
        sources = {"positions": h.node_positions, "normals": h.node_normals, "u": h.node_u, "v": h.node_v,
                   "colors": h.node_colors}
        for name, array in self.arrays.items():
            if name == "normal_field":
                array[part] = h.node_normal_fields(nodes, shading) if shading != "flat" else 0.0
            elif sources[name] is None:
                raise InputError(f"{model.path / CELLS / model.cells[index]['key']}: the cell has no colours, "
                                 "the manifest says the model has (corrupt chunked hierarchy)")
            else:
                np.take(sources[name], nodes, axis=0, out=array[part], mode="clip")
        for name, array in self.values.items():
            np.take(h.node_attributes[name], nodes, out=array[part], mode="clip")
        rows = sel.point_indices()
        if len(rows) == 0:
            return
        points, _, values = model._points(index, attributes=bool(self.values))
        part = self._reserve(len(rows))
        for name, array in self.values.items():
            np.take(values[name], rows, out=array[part], mode="clip")
        for name, array in self.arrays.items():
            value = getattr(points, name, None)
            if name == "normal_field":
                array[part] = 0.0
            elif value is None:
                raise InputError(f"{model.path / CELLS / model.cells[index]['key'] / 'colors.npy'}: missing chunk "
                                 "file of the chunked hierarchy (the manifest says the model has colours)")
            else:
                np.take(value, rows, axis=0, out=array[part], mode="clip")
        del points, values   # the memory maps go with them: their pages stop counting for this process

    def cloud(self, origin: np.ndarray) -> SplatCloud:
        """The splats gathered (views of the arrays), with ``origin`` and their attributes."""
        return SplatCloud(**{name: array[:self.n] for name, array in self.arrays.items()}, origin=origin,
                          attributes={name: array[:self.n] for name, array in self.values.items()} or None)


def concatenate(parts: list[SplatCloud]) -> SplatCloud:
    """One SplatCloud of several (colors and normal fields kept when every part has them, normal
    fields zero-filled where a part has none)."""
    parts = [p for p in parts if len(p)]
    if not parts:
        return SplatCloud(positions=np.zeros((0, 3), dtype=np.float32), normals=np.zeros((0, 3), dtype=np.float32),
                          u=np.zeros((0, 3), dtype=np.float32), v=np.zeros((0, 3), dtype=np.float32))
    fields = {name: np.concatenate([getattr(p, name) for p in parts]) for name in ("positions", "normals", "u", "v")}
    if all(p.colors is not None for p in parts):
        fields["colors"] = np.concatenate([p.colors for p in parts])
    if any(p.normal_field is not None for p in parts):
        fields["normal_field"] = np.concatenate([p.normal_field if p.normal_field is not None
                                                 else np.zeros((len(p), 2), dtype=np.float32) for p in parts])
    return SplatCloud(**fields)


def _read_preview(path: Path, origin: np.ndarray, attributes: list) -> SplatCloud:
    if not path.is_file():
        raise InputError(f"{path}: missing preview file of the chunked hierarchy", file=path)
    # sizes checked before anything is inflated (no zip bomb); its errors name the file and member
    arrays = read_npz(path, source=f"{path}: corrupt preview file")
    try:
        values = {name: arrays.pop(f"attribute_{i}") for i, name in enumerate(attributes)}
        arrays = {name: value for name, value in arrays.items() if not name.startswith("attribute_")}
        return SplatCloud(**arrays, origin=origin, attributes=values or None)
    except (OSError, ValueError, EOFError, TypeError, KeyError) as exc:   # InputError is a ValueError
        raise InputError(f"{path}: corrupt preview file ({exc})", file=path,
                         element=getattr(exc, "element", None) or getattr(exc, "argument", None)) from None


def open_chunked(path, cache_cells: int = CACHE_CELLS, cache_bytes: int | None = None) -> ChunkedHierarchy:
    """Open a chunked hierarchy directory lazily (:class:`ChunkedHierarchy`; ``cache_bytes``: most
    bytes of cell node arrays kept loaded, None for :data:`CACHE_BYTES` or a quarter of the memory
    available if less)."""
    return ChunkedHierarchy(path, cache_cells, cache_bytes)
