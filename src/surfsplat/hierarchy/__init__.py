"""Multiresolution point hierarchy: point-octree LOD with conservative splats, culling and selection.

Pajarola, Sainz & Guidotti 2003 (sec. 3.2-3.4, 5.1-5.2) and Guennebaud &
Paulin 2003 (sec. 8). Modules, none importing a later one: ``model`` (the
:class:`Hierarchy` and :class:`Selection` data), ``nodes`` (per-node
formulas), ``octree`` (building), ``lod`` (view-dependent selection),
``storage`` (files), ``sequential`` (the layout whose cut the GPU selects, Dachsbacher 2003).
Typical use::

    from surfsplat.hierarchy import build_hierarchy, load_hierarchy, save_hierarchy, select

    h = build_hierarchy(surfsplat.preprocess(cloud))
    save_hierarchy(h, "model.npz")
    h = load_hierarchy("model.npz")
    cut = select(h, camera, lod_tolerance=1.0)
    splats = h.splats(cut)          # a SplatCloud to render
"""

from .lod import select, uniform_cut
from .model import (CONE_SHADING_MAX_ANGLE, FORMAT_VERSION, LEAF_CAPACITY, MAX_DEPTH, SHADINGS, Hierarchy,
                    LodShading, Selection, check_lod_shading, ranges_to_indices)
from .octree import build_hierarchy, octree_topology
from .sequential import SequentialLayout, sequential_layout
from .storage import FORMAT, load_hierarchy, save_hierarchy

__all__ = [
    "Hierarchy",
    "Selection",
    "LodShading",
    "build_hierarchy",
    "select",
    "sequential_layout",
    "SequentialLayout",
    "uniform_cut",
    "load_hierarchy",
    "save_hierarchy",
    "check_lod_shading",
    "octree_topology",
    "ranges_to_indices",
    "FORMAT",
    "FORMAT_VERSION",
    "LEAF_CAPACITY",
    "MAX_DEPTH",
    "SHADINGS",
    "CONE_SHADING_MAX_ANGLE",
]
