"""Building a chunked hierarchy from a point file of any size (``surfsplat build --chunked``).

The driver streams the file (:mod:`.stream`: bounds, voxel counts, the cell grid, points
bucketed into per-cell files), runs the per-cell work of :mod:`.cells` as Dask tasks (local
threads or processes, or a Dask cluster given its scheduler address), chooses each cell's
orientation sign so that adjacent cells agree, builds the coarse top hierarchy over the cells'
roots and writes the manifest (:mod:`.layout`). The build goes to a hidden folder beside
``OUTPUT`` that replaces it when complete (:func:`surfsplat.io.atomic.atomic_path`); an existing
folder that is not a chunked hierarchy is never replaced.

Memory: the driver holds one chunk of ``chunk_points`` points and a voxel histogram (at most
128**3 counters); each worker holds one cell (at most ``cell_points`` points plus its halo)
while it preprocesses and builds it.
"""

from __future__ import annotations

import importlib.util
import multiprocessing
import re
import shutil
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree

from ... import progress
from ...cloud import SplatCloud
from ...colors import robust_range
from ...errors import InputError
from ...geometry.robust import OUTLIER_ACTIONS
from ...io.atomic import atomic_path
from ..octree import build_hierarchy
from ..storage import save_hierarchy
from .cells import build_cell, orientation_votes, preprocess_cell
from .layout import FORMAT, FORMAT_VERSION, PREVIEW, TOP, cell_key, is_chunked_hierarchy, write_manifest
from .stream import PointStream, bucket, build_grid

#: Default most points of a cell (one task's memory: ~0.5 KB per point while preprocessing).
CELL_POINTS = 1_000_000
#: Default points read at a time from the input.
CHUNK_POINTS = 1_000_000
#: Splats of the preview (a uniform cut of every cell, for framing and overviews).
PREVIEW_SPLATS = 200_000
#: The local Dask schedulers ``scheduler`` may name; anything with ``://`` is a cluster address.
LOCAL_SCHEDULERS = ("threads", "processes", "synchronous")

_KEY = re.compile(r"^c(\d+)_(\d+)_(\d+)\.bin$")


@dataclass(frozen=True)
class BuildReport:
    """What :func:`build_chunked` did: ``points`` (splats written), ``input_points``, ``cells``,
    ``flipped`` (cells whose normals were turned to agree with their neighbours), ``nodes``,
    ``bytes`` (on disk), ``seconds`` per phase (``stream``, ``preprocess``, ``orient``, ``build``, ``total``)."""

    path: Path
    points: int
    input_points: int
    cells: int
    flipped: int
    nodes: int
    bytes: int
    seconds: dict


def build_chunked(source, output, *, k: int = 8, outliers: str = "drop", sharp_angle: float | None = None,
                  leaf_capacity: int = 8, cell_points: int = CELL_POINTS, chunk_points: int = CHUNK_POINTS,
                  scheduler=None, workers: int | None = None, overwrite: bool = True) -> BuildReport:
    """Build a chunked hierarchy (a directory, ``docs/chunked_format.md``) from a point file.

    Args:
        source: a LAS/LAZ or binary PLY file (streamed), any other point file (read whole), or a
            folder of LAS/LAZ/PLY tiles (read in name order as one cloud; ``ids`` count on across them).
        output: the directory to write; an existing chunked hierarchy is replaced (unless
            ``overwrite=False``), anything else there is refused.
        k, outliers, sharp_angle: preprocessing (:func:`surfsplat.geometry.preprocess.preprocess`).
        leaf_capacity: points per leaf of each cell's octree.
        cell_points: most points of a cell (the grid is refined until no cell holds more, down to
            1/128 of the bounds).
        chunk_points: points read from the input at a time.
        scheduler: None or "threads" (default), "processes", "synchronous", a Dask scheduler
            address (``tcp://host:8786``: the workers must see ``output``'s folder), or a
            ``distributed.Client``.
        workers: local threads or processes (None: Dask's default, the CPU count).
        overwrite: replace an existing chunked hierarchy (default).

    Returns:
        A :class:`BuildReport`.

    Raises:
        InputError: bad arguments, an unreadable input, or an output that exists and is not a chunked
            hierarchy (or any existing output with ``overwrite=False``).
    """
    start = time.perf_counter()
    source, output = Path(source), Path(output)
    for name, value, low in (("k", k, 3), ("leaf_capacity", leaf_capacity, 1), ("cell_points", cell_points, 100),
                             ("chunk_points", chunk_points, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise InputError(f"{name} must be an integer >= {low}, got {value!r}")
    if outliers not in OUTLIER_ACTIONS:
        raise InputError(f"outliers must be one of {', '.join(OUTLIER_ACTIONS)}, got {outliers!r}")
    _check_output(output, overwrite)
    runner = _Runner(scheduler, workers)
    seconds = {}
    try:  # into a hidden folder beside ``output`` that replaces it when complete
        with atomic_path(output, overwrite=overwrite, directory=True) as partial:
            work = partial / "work"
            stream = PointStream(source, chunk_points)
            progress.message(f"{stream.count:,} points in {source} (read {stream.kind}: "
                             f"{'whole' if stream.kind == 'whole' else f'{chunk_points:,} at a time'})")
            grid = build_grid(stream, cell_points)
            dtype = bucket(stream, grid, work / "buckets")
            ijks = sorted(tuple(int(g) for g in _KEY.match(p.name).groups()) for p in (work / "buckets").iterdir()
                          if _KEY.match(p.name))
            keys = [cell_key(ijk) for ijk in ijks]
            index = {ijk: i for i, ijk in enumerate(ijks)}
            progress.message(f"  {len(keys):,} cells of side {grid.cell_size:.4g} "
                             f"(at most {cell_points:,} points each)")
            seconds["stream"] = time.perf_counter() - start

            t = time.perf_counter()
            options = {"k": int(k), "outliers": outliers, "sharp_angle": sharp_angle}
            calls = [(str(work), key, grid.cell_box(ijk), grid.cell_size, _neighbours(ijk, index, keys), dtype, options)
                     for key, ijk in zip(keys, ijks)]
            pre = runner.run(preprocess_cell, calls, "preprocessing cells (with halos)")
            seconds["preprocess"] = time.perf_counter() - t

            t = time.perf_counter()
            votes = runner.run(orientation_votes, [(str(work), key, i, keys) for i, key in enumerate(keys)],
                               "orientation across cells")
            flips = cell_flips(len(keys), [v for cell in votes for v in cell], [p["top"] for p in pre])
            seconds["orient"] = time.perf_counter() - t

            t = time.perf_counter()
            total = sum(p["points"] for p in pre)
            if total == 0:
                raise InputError(f"{source}: no point was kept by preprocessing")
            keep = [i for i, p in enumerate(pre) if p["points"] > 0]
            names = tuple(stream.attributes)
            calls = [(str(work), str(partial), keys[i], bool(flips[i]), int(leaf_capacity),
                      max(1, PREVIEW_SPLATS * pre[i]["points"] // total), names) for i in keep]
            cells = runner.run(build_cell, calls, "cell hierarchies")
            for i, cell in zip(keep, cells):
                cell["ijk"] = list(ijks[i])
                cell["halo"] = {"margin": pre[i]["margin"], "points": pre[i]["halo"]}
            previews = [cell.pop("preview") for cell in cells]
            samples = [cell.pop("samples") for cell in cells]
            with progress.stage(f"top hierarchy over {len(cells):,} cell roots"), progress.enabled(False):
                top = _top_hierarchy(cells, leaf_capacity, stream.attributes)
                save_hierarchy(top, partial / TOP)
                _save_preview(partial / PREVIEW, previews)
            seconds["build"] = time.perf_counter() - t
            shutil.rmtree(work)
            seconds["total"] = time.perf_counter() - start
            manifest = {
                "format": FORMAT, "format_version": FORMAT_VERSION,
                "origin": [float(x) for x in grid.origin],
                "bounds": {"min": [float(x) for x in grid.lo], "max": [float(x) for x in grid.hi]},
                "grid": {"corner": [float(x) for x in grid.corner], "cell_size": float(grid.cell_size),
                         "dims": list(grid.dims)},
                "up": None if stream.up is None else [float(x) for x in stream.up],   # None: unknown (guessed)
                "points": int(sum(c["points"] for c in cells)), "nodes": int(sum(c["nodes"] for c in cells)),
                "has_colors": bool(stream.has_colors),
                # colormaps span the points' 2nd-98th percentiles
                "attributes": [{"name": name, "dtype": np.dtype(dtype).str,
                                "range": list(robust_range(np.concatenate([s[name] for s in samples])))}
                               for name, dtype in stream.attributes.items()],
                "build": {"input": str(source), "input_points": int(stream.count),
                          "files": [{"path": path, "first_id": first} for path, first in stream.files],
                          "k": int(k), "outliers": outliers,
                          "sharp_angle": sharp_angle, "leaf_capacity": int(leaf_capacity),
                          "cell_points": int(cell_points), "chunk_points": int(chunk_points),
                          "scheduler": runner.name, "seconds": {name: round(s, 3) for name, s in seconds.items()}},
                "top": TOP, "preview": PREVIEW, "cells": cells,
            }
            write_manifest(partial, manifest)
    finally:
        runner.close()
    size = sum(p.stat().st_size for p in output.rglob("*") if p.is_file())
    return BuildReport(output, manifest["points"], int(stream.count), len(cells), int(sum(flips[i] for i in keep)),
                       manifest["nodes"], size, seconds)


def _check_output(output: Path, overwrite: bool) -> None:
    if output.suffix.lower() == ".npz":
        raise InputError(f"{output}: a chunked hierarchy is a directory; name it MODEL.ssh (not .npz)")
    if output.exists():
        if not is_chunked_hierarchy(output):
            raise InputError(f"{output}: exists and is not a chunked hierarchy; refusing to replace it")
        if not overwrite:
            raise InputError(f"{output}: exists (not replaced: overwrite=False)")


def _neighbours(ijk, index: dict, keys: list) -> list:
    """``(index, key)`` of the existing cells of the 26-neighbourhood of ``ijk``."""
    out = []
    for d in np.ndindex(3, 3, 3):
        other = tuple(int(a) + int(b) - 1 for a, b in zip(ijk, d))
        if other != tuple(ijk) and other in index:
            out.append((index[other], keys[index[other]]))
    return out


def cell_flips(cells: int, votes: list, tops) -> np.ndarray:
    """(cells,) bool: which cells to flip so that adjacent cells' normals agree.

    ``votes``: ``(a, b, agreement, shared)`` from :func:`~.cells.orientation_votes`. The pair
    agreements (both directions summed) weight a cell graph; over its maximum spanning tree
    (the most shared evidence first) every cell takes its parent's sign times the sign of their
    agreement, starting in each connected component from the cell with the highest point
    (``tops``), which keeps its own orientation: the in-memory rule (the highest point's normal
    up, :func:`surfsplat.geometry.normals.orientation_signs`) decides the component's sign.
    """
    flips = np.zeros(cells, dtype=bool)
    if cells < 2 or not votes:
        return flips
    v = np.array([(a, b, w) for a, b, w, _ in votes], dtype=np.float64)
    a, b = v[:, 0].astype(np.int64), v[:, 1].astype(np.int64)
    w = coo_matrix((v[:, 2], (a, b)), shape=(cells, cells)).tocsr()
    w = (w + w.T).tocoo()
    strong = np.abs(w.data)
    keep = strong > 0
    cost = coo_matrix((strong.max() + 1.0 - strong[keep], (w.row[keep], w.col[keep])), shape=(cells, cells))
    tree = minimum_spanning_tree(cost.tocsr())
    tree = tree + tree.T
    sign_of = dict(zip(zip(w.row.tolist(), w.col.tolist()), np.sign(w.data).tolist()))
    count, label = connected_components(tree, directed=False)
    tops = np.asarray(tops, dtype=np.float64)
    sign = np.ones(cells)
    for component in range(count):  # one traversal per group of connected cells
        members = np.flatnonzero(label == component)
        root = int(members[np.argmax(tops[members])])
        order, parent = breadth_first_order(tree, root, directed=False)
        for node in order[1:]:
            sign[node] = sign[parent[node]] * (sign_of.get((int(parent[node]), int(node)), 1.0) or 1.0)
    flips[:] = sign < 0
    return flips


def _top_hierarchy(cells: list, leaf_capacity: int, attributes: dict | None = None):
    """The point-octree over the cells' root splats (with the roots' values of the ``attributes``,
    ``{name: dtype}``). A top node's extent (the sampling scale the LOD test compares) is its
    covering ellipse's major semi-axis: its "points" are whole cells, whose spread its centers
    alone would understate."""
    def rows(name):
        return np.array([c["root"][name] for c in cells], dtype=np.float32)

    colors = rows("color") if all(c["root"]["color"] is not None for c in cells) else None
    values = {name: np.array([c["root"]["attributes"][i] for c in cells], dtype=dtype)
              for i, (name, dtype) in enumerate((attributes or {}).items())}
    roots = SplatCloud(positions=rows("position"), normals=rows("normal"), u=rows("u"), v=rows("v"), colors=colors,
                       normal_field=rows("normal_field"), attributes=values or None)
    top = build_hierarchy(roots, leaf_capacity, source="cell roots")
    top.node_extent = np.maximum(top.node_extent, np.linalg.norm(top.node_u, axis=1)).astype(np.float32)
    return top


def _save_preview(path: Path, previews: list) -> None:
    arrays = {}
    names = ["positions", "normals", "u", "v", "colors", "normal_field"] + [
        name for name in previews[0] if name.startswith("attribute_")]
    for name in names:
        if all(p[name] is not None for p in previews):
            arrays[name] = np.concatenate([p[name] for p in previews])
    np.savez(path, **arrays)


class _Runner:
    """Runs one function over many argument tuples as Dask tasks (local schedulers, a cluster's client)."""

    def __init__(self, scheduler, workers):
        if importlib.util.find_spec("dask") is None:
            raise InputError("the chunked build runs on Dask: pip install \"surfsplat[dask]\"")
        self.client = None
        self.workers = workers
        if scheduler is None:
            scheduler = "threads"
        self.pool = None
        if isinstance(scheduler, str) and scheduler in LOCAL_SCHEDULERS:
            self.name = scheduler
            self.scheduler = scheduler
            if scheduler == "processes":  # one pool for all phases: each new process imports surfsplat
                self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
        elif isinstance(scheduler, str) and "://" in scheduler:
            try:
                import distributed
            except ImportError as exc:
                raise InputError("a Dask cluster needs the dask extra: pip install \"surfsplat[dask]\"") from exc
            try:
                self.client = distributed.Client(scheduler, timeout=30, set_as_default=False)
            except OSError as exc:
                raise InputError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
            self.own_client = True
            self.name = scheduler
        elif type(scheduler).__name__ == "Client":
            self.client, self.own_client, self.name = scheduler, False, "distributed"
        else:
            raise InputError(f"scheduler must be one of {', '.join(LOCAL_SCHEDULERS)}, a Dask scheduler address "
                             f"(tcp://host:port) or a distributed.Client; got {scheduler!r}")

    def run(self, fn, calls: list, label: str) -> list:
        """``[fn(*args) for args in calls]`` as Dask tasks, in order; progress (rate, time left) per
        finished task. The tasks' own stages are silenced: they would interleave."""
        import dask
        tasks = [dask.delayed(fn, pure=False)(*args) for args in calls]
        with progress.stage(label, len(tasks), unit="cells", total=len(tasks)) as stage, progress.enabled(False):
            if self.client is not None:
                import distributed
                futures = self.client.compute(tasks)
                for _ in distributed.as_completed(futures):
                    stage.update(1)
                return self.client.gather(futures)
            from dask.callbacks import Callback

            class Ticks(Callback):
                def _posttask(self, key, result, dsk, state, worker_id):
                    if isinstance(key, str) and key.startswith(fn.__name__):
                        stage.update(1)

            with Ticks():
                extra = {"pool": self.pool} if self.pool is not None else {"num_workers": self.workers}
                return list(dask.compute(*tasks, scheduler=self.scheduler, **extra))

    def close(self) -> None:
        if self.client is not None and getattr(self, "own_client", False):
            self.client.close()
        if self.pool is not None:
            self.pool.shutdown()
