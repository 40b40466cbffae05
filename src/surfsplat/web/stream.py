"""Streaming a chunked hierarchy (``surfsplat build --chunked``) to the browser: a page that loads the
cells a view needs from a static server, or from ``file://``.

The exported folder holds the page (``data.js``: the top hierarchy over the cells' roots, in the format of
:mod:`surfsplat.web.tree`, and per cell its root's bounding sphere and extent, its file and its size) and
one file per cell, ``cells/<key>.js``: the cell's hierarchy (every node's splat, then every point, with
its children, points, spheres and extents), which calls ``surfsplatCell(index, data)`` when loaded. The
page adds a ``<script>`` element per cell it wants: scripts load from a web server and from ``file://``
alike, where ``fetch`` may not.

Per view the page cuts the forest as :meth:`surfsplat.hierarchy.chunked.ChunkedHierarchy.view_splats` does
(the top hierarchy, then each loaded cell below its root; Potree's priority within the point budget,
Schuetz 2016 sec. 3.3), draws the root splat of a cell it has not loaded, and when the camera stops
requests the cells whose roots the cut would refine, largest projected size first, a few at a time.
Loaded cells are kept within a memory budget (bytes of their GPU arrays): before a request, the least
recently drawn cells the current cut does not use are let go, then those it uses of a lower priority than
the cell requested; where that cannot make room, nothing more is requested.
"""

from __future__ import annotations

import json

import numpy as np

from .. import progress
from ..camera import Camera
from ..colors import ASPRS
from ..errors import InputError
from ..hierarchy.chunked import ChunkedHierarchy
from ..pipeline import View
from . import format as web_format
from .colors import encode_attribute
from .page import _b64, page_data
from .tree import DEFAULT_WEB_BUDGET, WEB_TOLERANCE, tree_entries, tree_streams

#: Bytes a loaded splat takes on the page's GPU: position, normal, u, v (float32 x 3 each), colour (3 bytes).
GPU_BYTES_PER_SPLAT = 4 * 3 * 4 + 3
#: The page's first memory budget for loaded cells (bytes).
DEFAULT_MEMORY_BUDGET = 512 * 2**20
#: Cells requested at once.
CONCURRENT_REQUESTS = 4
#: The folder of the cell files in an exported folder.
CELLS_FOLDER = "cells"


def cell_payload(h, point_attributes: dict | None = None, names=()) -> dict:
    """The header and streams (base64) of one cell's hierarchy ``h``: its entries (nodes, then points)
    in the web format, its tree (:func:`surfsplat.web.tree.tree_streams`) and the attributes ``names`` of
    its entries (``point_attributes``: the points' values; nodes: ``h.node_attributes``), each encoded
    by :func:`~surfsplat.web.colors.encode_attribute`."""
    entries = tree_entries(h)
    assert entries.normals is not None and entries.colors is not None and entries.u is not None \
        and entries.v is not None   # tree_entries gives every one
    streams, header = web_format.encode(entries.positions, entries.normals, entries.colors, entries.u, entries.v)
    header["lod"] = {"nodes": len(h), "points": int(len(h.points)), "level_offsets": [int(x) for x in h.level_offsets]}
    out = {key: _b64(value) for key, value in streams.items()}
    out.update(tree_streams(h))
    header["attributes"] = {}
    nodes, points = h.node_attributes or {}, point_attributes or {}
    for name in names:
        codes, info = encode_attribute(np.concatenate([np.asarray(nodes[name]), np.asarray(points[name])]))
        header["attributes"][name] = info
        out[f"attr_{name}"] = _b64(codes)
    return {"header": header, "streams": out}


def stream_data(plan: View, camera: Camera, technique: str, background, name: str, budget: int | None,
                memory_budget: int | None) -> tuple[dict, dict, dict[str, str]]:
    """The header, streams and cell files (path in the folder -> text) of a page streaming the view plan's
    chunked hierarchy."""
    model = plan.tree(camera)
    ch = model.data
    if not isinstance(ch, ChunkedHierarchy):
        raise InputError(f"{name}: not a chunked hierarchy")
    if memory_budget is not None and not (isinstance(memory_budget, (int, np.integer)) and memory_budget >= 1):
        raise InputError(f"memory budget must be a whole number of bytes >= 1, got {memory_budget!r}")
    top = ch.top
    header, streams = page_data(plan, camera, tree_entries(top), technique, background, name, ordered=False)
    # the colourings of ChunkedHierarchy.colorized: ranges from the manifest (a sample of every point) where
    # it has them, else from the preview
    ranges = {a["name"]: a.get("range") for a in ch.manifest.get("attributes", [])}
    for mode in header["color"]["modes"]:
        if mode.get("attribute") in ranges and ranges[mode["attribute"]] and mode["colormap"] != ASPRS:
            mode["range"] = [float(x) for x in ranges[mode["attribute"]]]
    names = list(header["color"]["attributes"])
    files: dict[str, str] = {}
    cells, radius = [], 0.0
    with progress.stage("encoding the cells for the web", len(ch.cells), "cells") as bar:
        for index, entry in enumerate(ch.cells):
            h = ch.cell(index, full=True)
            values = ch._points(index)[2] if names else None   # the cell's point attributes, memory-mapped
            payload = cell_payload(h, values, names)
            radius = max(radius, float(np.exp2(payload["header"]["log_radius"][1])))
            key = str(entry["key"])
            files[f"{CELLS_FOLDER}/{key}.js"] = (f"surfsplatCell({index}, "
                                                 f"{json.dumps(payload, separators=(',', ':'))});\n")
            entries = len(h) + len(h.points)
            cells.append({"key": key, "entries": entries, "bytes": entries * GPU_BYTES_PER_SPLAT})
            bar.update(1)
    roots = ch.cells
    lo, hi = ch.bounds()
    header["bounds"] = [lo.tolist(), hi.tolist()]   # world, as SplatCloud.bounds
    header["origin"] = ch.origin.tolist()
    header["max_radius"] = radius
    header["lod"] = {"nodes": len(top), "points": int(len(top.points)), "levels": int(top.levels),
                     "level_offsets": [int(x) for x in top.level_offsets], "budget": int(budget or DEFAULT_WEB_BUDGET),
                     "tolerance": WEB_TOLERANCE,
                     "streamed": {"cells": cells, "folder": CELLS_FOLDER, "concurrent": CONCURRENT_REQUESTS,
                                  "memory_budget": int(memory_budget or DEFAULT_MEMORY_BUDGET),
                                  "points": ch.point_count}}
    streams.update(tree_streams(top))
    streams["cell_of_point"] = _b64(np.asarray(top.order, "<i4"))
    streams["root_center"] = _b64(np.array([c["root"]["position"] for c in roots], "<f4"))
    streams["root_radius"] = _b64(np.array([c["root"]["radius"] for c in roots], "<f4"))
    streams["root_extent"] = _b64(np.array([c["root"]["extent"] for c in roots], "<f4"))
    return header, streams, files
