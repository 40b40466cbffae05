"""Multiresolution point hierarchy: point-octree LOD with conservative splats, culling and selection.

Pajarola, Sainz & Guidotti 2003 (sec. 3.2-3.4, 5.1-5.2) and Guennebaud &
Paulin 2003 (sec. 8). Typical use::

    from surfsplat.hierarchy import build_hierarchy, load_hierarchy, select

    h = build_hierarchy(surfsplat.preprocess(cloud))
    h.save("model.npz")
    h = load_hierarchy("model.npz")
    cut = select(h, camera, tolerance_px=1.0)
    splats = h.splats(cut)          # a SplatCloud to render
"""

from .lod import Selection, select, uniform_cut
from .octree import (CONE_SHADING_MAX_ANGLE, LEAF_CAPACITY, MAX_DEPTH, SHADINGS, Hierarchy, build_hierarchy,
                     octree_topology, ranges_to_indices)
from .storage import FORMAT, FORMAT_VERSION, load_hierarchy, save_hierarchy

__all__ = [
    "Hierarchy",
    "Selection",
    "build_hierarchy",
    "select",
    "uniform_cut",
    "load_hierarchy",
    "save_hierarchy",
    "octree_topology",
    "ranges_to_indices",
    "FORMAT",
    "FORMAT_VERSION",
    "LEAF_CAPACITY",
    "MAX_DEPTH",
    "SHADINGS",
    "CONE_SHADING_MAX_ANGLE",
]
