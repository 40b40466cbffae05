"""Chunked hierarchies: clouds larger than memory, built in cells on Dask and opened lazily.

``build`` streams a point file into grid cells and builds, per cell, preprocessing with a halo
and a point-octree (Pajarola 2003), as Dask tasks; ``lazy`` opens the result and reads only the
cells a view needs. The on-disk layout is ``layout`` (spec: ``docs/chunked_format.md``)::

    from surfsplat.hierarchy.chunked import build_chunked, open_chunked

    build_chunked("city.laz", "city.ssh", cell_points=1_000_000, scheduler="tcp://head:8786")
    model = open_chunked("city.ssh")
    splats, selection = model.view_splats(camera, lod_tolerance=1.0)
"""

from .build import CELL_POINTS, CHUNK_POINTS, LOCAL_SCHEDULERS, BuildReport, build_chunked, cell_flips
from .layout import FORMAT, FORMAT_VERSION, chunked_up, is_chunked_hierarchy, read_manifest
from .lazy import CACHE_CELLS, ChunkedHierarchy, ChunkedSelection, concatenate, open_chunked

__all__ = [
    "build_chunked",
    "open_chunked",
    "is_chunked_hierarchy",
    "chunked_up",
    "read_manifest",
    "cell_flips",
    "concatenate",
    "BuildReport",
    "ChunkedHierarchy",
    "ChunkedSelection",
    "CELL_POINTS",
    "CHUNK_POINTS",
    "CACHE_CELLS",
    "LOCAL_SCHEDULERS",
    "FORMAT",
    "FORMAT_VERSION",
]
