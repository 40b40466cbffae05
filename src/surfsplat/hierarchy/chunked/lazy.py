"""Opening a chunked hierarchy lazily and cutting it per view (:class:`ChunkedHierarchy`).

Opening reads the manifest, the coarse top hierarchy over the cells' roots (``top.npz``) and the
preview; nothing of the cells. Per view (:meth:`ChunkedHierarchy.view_splats`):

1. the top hierarchy is cut (:func:`surfsplat.hierarchy.lod.select`, Pajarola 2003 sec. 5.1):
   its coarse nodes are drawn as they are, culled ones dropped;
2. each cell root the cut reaches is tested with the same projected-size rule from the
   manifest (center, bounding-sphere radius, extent): a root small enough on screen is drawn
   as its one splat without reading the cell;
3. every other cell is loaded (its ``coarse.npz``, the first levels; ``nodes.npz``, all levels,
   only when the cut refines a coarse-level node that has children; its splat arrays
   memory-mapped, so only the pages of the points the cut selects are read) and cut with the
   same tolerance.

Loaded cells stay in an LRU cache of ``cache_cells`` cells whose node arrays take at most
:data:`CACHE_MEMORY_SHARE` of the memory available when the model is opened. Positions are relative to
:attr:`ChunkedHierarchy.origin` (float64); cameras are given in that frame.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...camera import Camera
from ...cloud import SplatCloud
from ...errors import InputError
from ...io.atomic import memory_limit
from ..lod import select
from ..model import Hierarchy, LodShading
from ..storage import load_hierarchy
from .layout import (CELLS, COARSE, NODE_FILES, NODES, POINT_FILES, PREVIEW, TOP, check_size, open_points,
                     read_manifest, read_nodes)

#: Cells kept loaded (node arrays in memory, splats memory-mapped).
CACHE_CELLS = 64
#: ... and at most this share of the memory available when the model is opened, in node arrays (a
#: 64 M-point model's 81 cells hold about 8 GB of them: a count alone let a viewer or a series of
#: renders grow until the system killed it).
CACHE_MEMORY_SHARE = 0.25

#: Ratio between the tolerances bracketing the budget's when the search stops.
BUDGET_STEP = 1.03


@dataclass(frozen=True)
class ChunkedSelection:
    """What a view of a chunked hierarchy drew: ``node_count`` (coarse splats: top nodes, cell roots
    and cell nodes), ``point_total`` (original splats), ``cells_loaded`` (cells cut for this view,
    read from disk or the cache), ``cells_root_only`` (cells drawn as their root splat, not read),
    ``lod_tolerance`` (pixels: the one asked for, or the larger one a point budget needed),
    ``cells_coarse`` (of the cells cut, those whose coarse-levels file sufficed)."""

    node_count: int
    point_total: int
    cells_loaded: int
    cells_root_only: int
    lod_tolerance: float
    cells_coarse: int = 0

    def __len__(self) -> int:
        """Splats drawn."""
        return self.node_count + self.point_total

    def summary(self) -> dict:
        """Counts for reports."""
        return {"splats": len(self), "nodes": self.node_count, "points": self.point_total,
                "lod_tolerance": self.lod_tolerance, "cells_loaded": self.cells_loaded,
                "cells_root_only": self.cells_root_only, "cells_coarse": self.cells_coarse}


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
        cache_cells: most cells kept loaded.
    """

    def __init__(self, path, cache_cells: int = CACHE_CELLS):
        self.path = Path(path)
        self.manifest = read_manifest(self.path)
        self.origin = np.array(self.manifest["origin"], dtype=np.float64)
        self.up = tuple(float(x) for x in self.manifest.get("up", (0.0, 1.0, 0.0)))
        self.cells = self.manifest["cells"]
        self.cache_cells = int(cache_cells)
        self.cache_bytes = int(CACHE_MEMORY_SHARE * memory_limit())
        self._bytes: dict[int, int] = {}   # node-array bytes of each cached cell
        self._cache: OrderedDict[int, tuple[Hierarchy, bool]] = OrderedDict()   # (hierarchy, all levels)
        self._deeper: dict[int, np.ndarray | None] = {}
        self.loads = 0
        self.top = load_hierarchy(self.path / self.manifest.get("top", TOP))
        if len(self.top.points) != len(self.cells):
            raise InputError(f"{self.path / TOP}: holds {len(self.top.points)} cell roots, the manifest "
                             f"{len(self.cells)} cells")
        self.points = _read_preview(self.path / self.manifest.get("preview", PREVIEW), self.origin)
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
        node arrays loaded, splat arrays memory-mapped. With ``full=False`` a cell that has a
        coarse-levels file may come with only its first levels, whose last level's nodes are then
        leaves (their points are their whole subtrees'); :meth:`_select` reads the rest when a view
        refines one of them. InputError naming a missing or corrupt file."""
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
        nodes = read_nodes(source)
        n = int(entry["points"])
        if cached is not None:
            points, ids = cached[0].points, cached[0].order
        else:
            arrays = {}
            for name, (_, _, required) in POINT_FILES.items():
                if f"{name}.npy" not in files:
                    if required:
                        raise InputError(f"{folder / (name + '.npy')}: missing chunk file of the chunked hierarchy")
                    arrays[name] = None
                    continue
                arrays[name] = open_points(folder / f"{name}.npy", name, n)
            points = SplatCloud(positions=arrays["positions"], normals=arrays["normals"], colors=arrays["colors"],
                                u=arrays["u"], v=arrays["v"])
            ids = arrays["ids"]
        off = nodes["level_offsets"]
        m = len(nodes["node_positions"])
        levels = int(entry.get("coarse_levels", entry["levels"])) if coarse else int(entry["levels"])
        if (not coarse and m != int(entry["nodes"])) or len(off) != levels + 1 or int(nodes["node_point_count"][0]) != n:
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
        h = Hierarchy(points=points, order=ids, level_offsets=off, origin=nodes["origin"],
                      leaf_capacity=int(nodes["leaf_capacity"]), max_depth=int(nodes["max_depth"]), **arrays)
        self.loads += 1
        self._cache[index] = (h, not coarse)
        self._cache.move_to_end(index)
        self._deeper[index] = deeper
        self._bytes[index] = sum(a.nbytes for a in arrays.values() if isinstance(a, np.ndarray)
                                 and not isinstance(a, np.memmap))
        # least recently used first, never the cell just read
        while len(self._cache) > 1 and (len(self._cache) > self.cache_cells
                                        or sum(self._bytes.values()) > self.cache_bytes):
            evicted, _ = self._cache.popitem(last=False)
            self._deeper.pop(evicted, None)
            self._bytes.pop(evicted, None)
        return h

    def _select(self, index: int, local: Camera, tolerance: float, options: dict) -> tuple[Hierarchy, object, bool]:
        """A cell's cut: on its coarse levels when they suffice (no refined leaf there has
        children), else on all its levels. Returns ``(hierarchy, selection, coarse levels only)``."""
        h = self.cell(index, full=False)
        sel = select(h, local, tolerance, **options)
        deeper = self._deeper.get(int(index))
        if deeper is None:
            return h, sel, False
        leaves = np.concatenate(sel.leaves) if sel.leaves else np.zeros(0, dtype=np.int64)
        if not deeper[leaves].any():
            return h, sel, True
        h = self.cell(index, full=True)
        return h, select(h, local, tolerance, **options), False

    @property
    def cached(self) -> list[int]:
        """Indices of the cells loaded now, least recently used first."""
        return list(self._cache)

    @property
    def complete(self) -> list[int]:
        """Indices of the cached cells whose every level is loaded."""
        return [index for index, (_, full) in self._cache.items() if full]

    # -- views -----------------------------------------------------------------

    def view_splats(self, camera: Camera, lod_tolerance: float, *, cull_backfaces: bool = False,
                    lod_shading: LodShading = "fit",
                    point_budget: int | None = None) -> tuple[SplatCloud, ChunkedSelection]:
        """The splats to draw for a view at screen tolerance ``lod_tolerance`` (pixels), reading only
        the cells the view needs (see the module docstring); ``camera`` in world coordinates.

        With ``point_budget``, at most that many splats (or the coarsest cut, the top root alone,
        if even that is more): when the cut at ``lod_tolerance`` is larger, the tolerance is raised
        to the smallest (within 3 %) whose cut fits. One tolerance over all cells refines every node
        larger on screen than it, wherever it lies: the cut a priority queue by projected size
        (Potree's, Schuetz 2016) reaches when it stops at the budget, up to the tolerance steps.

        Returns:
            ``(SplatCloud, ChunkedSelection)``; the splats carry :attr:`origin`.
        """
        local = camera.translated(-self.origin)
        if local.near is None or local.far is None:
            local = local.with_clip_from_bounds(*self.sphere_bounds())
        options = {"cull_backfaces": cull_backfaces, "lod_shading": lod_shading}
        tolerance = float(lod_tolerance)
        if point_budget is not None and self._cut_size(local, tolerance, options) > point_budget:
            # only sizes while searching: a cut holds the node arrays of every cell it reads
            low, high = tolerance, max(tolerance, 0.25)
            size = point_budget + 1
            while size > point_budget and high < 1e6:  # double until the cut fits
                low, high = high, 2.0 * high
                size = self._cut_size(local, high, options)
            low = max(low, 1e-3)
            while high / low > BUDGET_STEP:  # then bisect (geometrically) to the finest that fits
                mid = float(np.sqrt(low * high))
                if self._cut_size(local, mid, options) <= point_budget:
                    high = mid
                else:
                    low = mid
            tolerance = high
        cut = self._cut(local, tolerance, options)
        top_sel, rows, refine, loaded, cuts, _, coarse = cut
        parts = [self.top.node_splats(top_sel.node_indices(), lod_shading)]
        if (~refine).any():
            parts.append(self.top.points.subset(rows[~refine]))
        nodes, points = top_sel.node_count + int((~refine).sum()), 0
        for h, sel in zip(loaded, cuts):
            if len(sel):
                parts.append(h.splats(sel))
            nodes += sel.node_count
            points += sel.point_total
        summary = ChunkedSelection(nodes, points, len(loaded), int((~refine).sum()), tolerance, int(coarse))
        return concatenate(parts).replace(origin=self.origin), summary

    def _cut(self, local: Camera, tolerance: float, options: dict):
        """The selections of a view at one tolerance (``local``: the camera in the local frame):
        ``(top selection, top point rows reached, their cells refined (bool), loaded cell
        hierarchies, their selections, total splats, cells cut on their coarse levels)``."""
        top_sel = select(self.top, local, tolerance, **options)
        rows = top_sel.point_indices()
        refine = self._refine_roots(self.top.order[rows], local, tolerance)
        picked = [self._select(index, local, tolerance, options) for index in self.top.order[rows][refine]]
        loaded, cuts = [h for h, _, _ in picked], [c for _, c, _ in picked]
        total = top_sel.node_count + int((~refine).sum()) + sum(len(c) for c in cuts)
        return top_sel, rows, refine, loaded, cuts, total, sum(coarse for _, _, coarse in picked)

    def _cut_size(self, local: Camera, tolerance: float, options: dict) -> int:
        """The number of splats of :meth:`_cut`, the cells cut one at a time and let go (the cache
        keeps what its bounds allow)."""
        top_sel = select(self.top, local, tolerance, **options)
        rows = top_sel.point_indices()
        refine = self._refine_roots(self.top.order[rows], local, tolerance)
        total = top_sel.node_count + int((~refine).sum())
        for index in self.top.order[rows][refine]:
            total += len(self._select(index, local, tolerance, options)[1])
        return total

    def _refine_roots(self, cells: np.ndarray, camera: Camera, lod_tolerance: float) -> np.ndarray:
        """(len(cells),) bool: the cell's root is refined by the rule of :mod:`surfsplat.hierarchy.lod`
        (Pajarola 2003 sec. 5.1): ``|c - eye| < R + max(near, focal * 2 a / tolerance)``, ``camera``
        in the local frame."""
        if lod_tolerance <= 0:
            return np.ones(len(cells), dtype=bool)
        d = np.linalg.norm(self._root_center[cells] - np.asarray(camera.eye, dtype=np.float64), axis=1)
        reach = np.maximum(camera.focal_px * 2.0 * self._root_extent[cells] / lod_tolerance, camera.near)
        return d < self._root_radius[cells] + reach


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


def _read_preview(path: Path, origin: np.ndarray) -> SplatCloud:
    if not path.is_file():
        raise InputError(f"{path}: missing preview file of the chunked hierarchy")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
        return SplatCloud(**arrays, origin=origin)
    except (OSError, ValueError, EOFError, TypeError) as exc:
        raise InputError(f"{path}: corrupt preview file ({exc})") from None


def open_chunked(path, cache_cells: int = CACHE_CELLS) -> ChunkedHierarchy:
    """Open a chunked hierarchy directory lazily (:class:`ChunkedHierarchy`)."""
    return ChunkedHierarchy(path, cache_cells)
