"""The per-cell work of a chunked build, as plain functions of file paths (Dask tasks).

1. :func:`preprocess_cell`: a cell's points plus a halo of its neighbours' points within
   ``HALO_SPACINGS`` times its k-th-neighbour spacing (:func:`_margin`) are preprocessed together
   (:func:`surfsplat.geometry.preprocess.preprocess`: duplicates, outliers, normals, orientation,
   ellipses, size bounds); the cell keeps its own points' results. With the halo, every
   neighbourhood a border point's splat depends on (its k or 2k neighbours, their
   neighbours' sizes in the size bound) is the one an in-memory run sees. The normals the cell
   computed for its neighbours' points near the border are kept for step 2.
2. :func:`orientation_votes`: per pair of adjacent cells, the agreement of their normals on
   those shared points (sum of dot products): the MST orientation of each cell (Hoppe 1992)
   is consistent within the cell, and the sign of a whole cell is then chosen by the driver
   (:mod:`.build`) so that neighbours agree.
3. :func:`build_cell`: the cell's splats, flipped if the driver says so, into the point-octree
   (:func:`surfsplat.hierarchy.octree.build_hierarchy`, Pajarola 2003), written as the cell's
   files (:mod:`.layout`).

Every function reads and writes files under the build's work folder and returns small dicts,
so the tasks run on threads, processes or a Dask cluster sharing that folder.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ...cloud import SplatCloud
from ...errors import InputError
from ...geometry.preprocess import preprocess
from ..lod import uniform_cut
from ..model import Hierarchy
from ..octree import build_hierarchy
from .layout import CELLS, COARSE, NODE_FILES, NODES, load_npy

#: The halo reaches this many times the cell's 99th percentile k-th-neighbour distance.
HALO_SPACINGS = 4.0

#: A cell of fewer than this many times k points sizes its halo with its neighbours' points.
SMALL_CELL = 8

#: Points whose spacing is sampled to size the halo.
SPACING_SAMPLE = 20_000

#: A cell's coarse-levels file holds its first levels up to this many nodes.
COARSE_NODES = 4096

#: Bucket records read at a time when gathering a halo.
READ_BLOCK = 1 << 20


def _save(folder: Path, **arrays) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, value in arrays.items():
        if value is not None:
            np.save(folder / f"{name}.npy", np.ascontiguousarray(value))


def _halo(buckets: Path, neighbours: list, dtype: np.dtype, lo: np.ndarray, hi: np.ndarray):
    """Records of the neighbour cells inside the box ``[lo, hi]`` (relative coordinates), with the
    index of their cell (in ``neighbours``: (index, key) pairs) and their row in its bucket."""
    recs, cells, rows = [], [], []
    for index, key in neighbours:
        path = buckets / f"{key}.bin"
        if not path.is_file() or path.stat().st_size == 0:
            continue
        data = np.memmap(path, dtype=dtype, mode="r")
        for a in range(0, len(data), READ_BLOCK):
            block = np.asarray(data[a:a + READ_BLOCK])
            p = block["p"]
            inside = np.flatnonzero(np.all((p >= lo) & (p <= hi), axis=1))
            if len(inside):
                recs.append(block[inside])
                cells.append(np.full(len(inside), index, dtype=np.int64))
                rows.append(a + inside)
        del data
    if not recs:
        return np.zeros(0, dtype=dtype), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(recs), np.concatenate(cells), np.concatenate(rows)


def _spacing(positions: np.ndarray, among: np.ndarray, k: int) -> float:
    """The 99th percentile of the k-th-neighbour distance (among the points ``among``, which hold
    ``positions``) over a sample of ``positions`` (model units); inf when ``among`` has k points or fewer."""
    if len(among) <= k:
        return np.inf
    tree = cKDTree(among)
    n = len(positions)
    sample = positions[np.random.default_rng(0).choice(n, min(n, SPACING_SAMPLE), replace=False)]
    dist, _ = tree.query(sample, k=k + 1)
    return float(np.quantile(dist[:, k], 0.99))


def _margin(own: np.ndarray, k: int, cell_size: float, probe) -> float:
    """The halo's width: ``HALO_SPACINGS`` times the cell's spacing, at most a cell. A cell of a few
    points (the corner of a surface) cannot tell its spacing alone: it is taken among its points
    and its neighbours' within an eighth of a cell (``probe(width)`` returns those), so a dense
    neighbourhood gives a thin halo; only where even that finds too few points is it a whole cell
    (and then holds few points)."""
    if len(own) >= SMALL_CELL * k:
        spacing = _spacing(own, own, k)
    else:
        spacing = _spacing(own, np.concatenate([own, probe(cell_size / 8)]), k)
    return float(min(HALO_SPACINGS * spacing, cell_size))


def preprocess_cell(work: str, key: str, box: tuple, cell_size: float, neighbours: list, dtype: np.dtype,
                    options: dict) -> dict:
    """Step 1 for one cell (see the module docstring): preprocess its points with a halo.

    Args:
        work: the build's work folder (``buckets/`` holds the cells' records, results go to ``pre/<key>/``).
        key: the cell's key; ``box``: its bounds ``(lo, hi)`` relative to the origin (model units);
            ``cell_size``: its side, model units (the halo is at most that wide).
        neighbours: ``(index, key)`` of the adjacent cells (26-neighbourhood, existing or not).
        dtype: the bucket record dtype; ``options``: ``k``, ``outliers``, ``sharp_angle`` for preprocess.

    Returns:
        dict: ``points`` (kept), ``halo`` (halo points and margin, model units), ``top`` (highest z
        of the kept points), ``report`` counts (duplicates, outliers, capped).
    """
    work = Path(work)
    own = np.fromfile(work / "buckets" / f"{key}.bin", dtype=dtype)
    n = len(own)
    k = int(options["k"])
    lo, hi = np.asarray(box[0]), np.asarray(box[1])

    def probe(width):
        return _halo(work / "buckets", neighbours, dtype, lo - width, hi + width)[0]["p"]

    margin = _margin(own["p"], k, float(cell_size), probe)
    halo, halo_cell, halo_row = _halo(work / "buckets", neighbours, dtype, lo - margin, hi + margin)
    records = np.concatenate([own, halo])
    has_n, has_c = "n" in dtype.names, "c" in dtype.names
    cloud = SplatCloud(positions=records["p"], normals=records["n"] if has_n else None,
                       colors=records["c"] if has_c else None)
    pre = work / "pre" / key
    try:
        result, report = preprocess(cloud, k=k, outliers=options["outliers"], sharp_angle=options.get("sharp_angle"),
                                    source=f"cell {key}", return_report=True)
    except InputError:
        if len(records) > k + 1:
            raise
        # a point or a few alone in their cell and its halo: isolated, dropped as preprocessing drops floaters
        none, empty = np.zeros(0, dtype=np.int64), np.zeros((0, 3), dtype=np.float32)
        _save(pre, positions=empty, normals=empty, u=empty, v=empty, ids=none, rows=none, halo_cell=none,
              halo_row=none, halo_normals=empty)
        return {"key": key, "points": 0, "halo": int(len(halo)), "margin": margin, "top": -np.inf,
                "duplicates": 0, "outliers": n, "capped": 0}
    kept = report.kept
    mine = kept < n
    # normals of the neighbours' points near the border (half the halo: their neighbourhoods are whole)
    p = result.positions
    near = ~mine & (np.max(np.maximum(lo - p, p - hi), axis=1) <= 0.5 * margin)
    hrow = kept[near] - n
    _save(pre, positions=p[mine], normals=result.normals[mine], u=result.u[mine], v=result.v[mine],
          colors=None if result.colors is None else result.colors[mine], ids=own["id"][kept[mine]],
          rows=kept[mine], halo_cell=halo_cell[hrow], halo_row=halo_row[hrow], halo_normals=result.normals[near],
          **{f"attribute_{name[1:]}": own[name][kept[mine]] for name in dtype.names if name.startswith("a")})
    return {"key": key, "points": int(mine.sum()), "halo": int(len(halo)), "margin": margin,
            "top": float(p[mine, 2].max()) if mine.any() else -np.inf,
            "duplicates": int(report.duplicates), "outliers": int(report.outliers), "capped": int(report.capped)}


def orientation_votes(work: str, key: str, index: int, keys: list) -> list:
    """Step 2 for one cell: ``[(index, neighbour index, agreement, shared points)]``, the agreement
    being the sum over the shared points of the dot product of this cell's normal and the
    neighbour's own normal (> 0: same orientation)."""
    pre = Path(work) / "pre"
    cells = load_npy(pre / key / "halo_cell.npy")
    rows = load_npy(pre / key / "halo_row.npy")
    normals = load_npy(pre / key / "halo_normals.npy")
    votes = []
    for other in np.unique(cells):
        sel = cells == other
        their_rows = load_npy(pre / keys[other] / "rows.npy", mmap_mode="r")
        if len(their_rows) == 0:  # a cell whose points were all outliers
            continue
        their_normals = load_npy(pre / keys[other] / "normals.npy", mmap_mode="r")
        pos = np.searchsorted(their_rows, rows[sel])
        pos = np.minimum(pos, len(their_rows) - 1)
        found = np.asarray(their_rows[pos]) == rows[sel]
        if not found.any():
            continue
        dots = np.einsum("ij,ij->i", normals[sel][found], np.asarray(their_normals[pos[found]]))
        votes.append((int(index), int(other), float(dots.sum()), int(found.sum())))
    return votes


def build_cell(work: str, out: str, key: str, flip: bool, leaf_capacity: int, preview: int,
               attributes: tuple = ()) -> dict:
    """Step 3 for one cell: its splats (normals and ``v`` negated when ``flip``) into a point-octree,
    written to ``out/cells/<key>/`` (:mod:`.layout`), with the point attributes named
    ``attributes`` (in the order of the build's, file ``attribute_<i>.npy``; node values by mean or
    majority vote as the in-memory hierarchy's). Returns the cell's manifest entry (less ``ijk``)
    with its ``root`` splat, ``preview``: the splats of a uniform cut of at most ``preview``
    nodes (arrays, for the driver's preview file), and ``samples``: the attributes of ``preview``
    points drawn at random (for their value ranges over the whole cloud)."""
    pre = Path(work) / "pre" / key
    arrays = {name: load_npy(pre / f"{name}.npy") for name in ("positions", "normals", "u", "v", "ids")}
    colors = pre / "colors.npy"
    arrays["colors"] = load_npy(colors) if colors.is_file() else None
    if flip:
        arrays["normals"] *= -1.0
        arrays["v"] *= -1.0  # keep u x v along the normal
    values = {name: load_npy(pre / f"attribute_{i}.npy") for i, name in enumerate(attributes)}
    cloud = SplatCloud(positions=arrays["positions"], normals=arrays["normals"], colors=arrays["colors"],
                       u=arrays["u"], v=arrays["v"], attributes=values or None)
    h = build_hierarchy(cloud, leaf_capacity, source=f"cell {key}")
    folder = Path(out) / CELLS / key
    _save(folder, positions=h.points.positions, normals=h.points.normals, u=h.points.u, v=h.points.v,
          colors=h.points.colors, ids=arrays["ids"][h.order],
          **{f"attribute_{i}": h.points.attributes[name] for i, name in enumerate(attributes)})
    _save_nodes(folder / NODES, h, h.levels)
    # the first levels again, alone: a view that refines the cell no deeper reads only them
    coarse = int(np.searchsorted(h.level_offsets, COARSE_NODES, side="right")) - 1
    if 0 < coarse < h.levels:
        _save_nodes(folder / COARSE, h, coarse)
    files = {path.name: path.stat().st_size for path in sorted(folder.iterdir())}
    lo, hi = h.bounds()
    cut = uniform_cut(h, max(1, int(preview)))
    sample = np.random.default_rng(0).choice(len(h.points), min(len(h.points), max(1, int(preview))), replace=False)
    return {"key": key, "points": len(h.points), "nodes": len(h), "levels": h.levels, "flipped": bool(flip),
            "coarse_levels": coarse if 0 < coarse < h.levels else h.levels,
            "bounds": [[float(x) for x in lo], [float(x) for x in hi]], "files": files,
            "root": root_entry(h, attributes),
            "preview": splat_arrays(h.node_splats(cut)) | {f"attribute_{i}": h.node_attributes[name][cut]
                                                           for i, name in enumerate(attributes)},
            "samples": {name: values[name][sample] for name in attributes}}


def _save_nodes(path: Path, h: Hierarchy, levels: int) -> None:
    """The node arrays of the first ``levels`` levels of ``h`` as an uncompressed .npz (:mod:`.layout`)."""
    m = int(h.level_offsets[levels])
    members = {name: getattr(h, name)[:m] for name in NODE_FILES if getattr(h, name) is not None}
    for i, values in enumerate((h.node_attributes or {}).values()):
        members[f"node_attribute_{i}"] = values[:m]
    with open(path, "wb") as handle:
        np.savez(handle, level_offsets=h.level_offsets[:levels + 1], origin=h.origin,
                 leaf_capacity=np.int64(h.leaf_capacity), max_depth=np.int64(h.max_depth), **members)


def root_entry(h: Hierarchy, attributes: tuple = ()) -> dict:
    """The root node of a cell's hierarchy as JSON numbers: its splat (position, normal, u, v,
    color or None, normal field), bounding-sphere ``radius``, ``extent``, normal ``cone`` and
    its values of the ``attributes`` (a list in their order)."""
    def row(array):
        return None if array is None else [float(x) for x in array[0]]

    return {"position": row(h.node_positions), "normal": row(h.node_normals), "u": row(h.node_u), "v": row(h.node_v),
            "color": row(h.node_colors), "normal_field": row(h.node_normal_field), "radius": float(h.node_radius[0]),
            "extent": float(h.node_extent[0]), "cone": float(h.node_cone[0]),
            "attributes": [h.node_attributes[name][0].item() for name in attributes]}


def splat_arrays(cloud: SplatCloud) -> dict:
    """The splat arrays of a cloud by name (positions, normals, u, v, colors, normal_field; None where absent)."""
    return {name: getattr(cloud, name) for name in ("positions", "normals", "u", "v", "colors", "normal_field")}
