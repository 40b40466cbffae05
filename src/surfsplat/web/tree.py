"""Level of detail in the browser: a hierarchy's nodes and points exported together, the cut chosen by
the page per view (``viewer.js``, ``selectCut``).

The page gets every node's representative splat (Pajarola 2003, sec. 3.4: its ellipse covers the disks of
its subtree; flat shading) followed by every point of the hierarchy (with its clip lines and normal field),
all in the web format, and per node its children, its points, its bounding sphere and its extent. For a
view it runs the rule of :func:`surfsplat.hierarchy.lod.select` with a point budget: the tolerance cut
(a node is refined while its projected size ``f 2 a / (|c - eye| - R)`` exceeds the tolerance, or always
where it lies over splats with clip lines, nodes
outside the frustum dropped with their subtrees), and where that exceeds the budget the refinements in
Potree's order (Schuetz 2016, sec. 3.3: largest projected size first, a child never before its parent),
the longest prefix within the budget. The drawn entries are an index list; nothing is uploaded again.
"""

from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..hierarchy import Hierarchy
from ..hierarchy.lod import sharp_nodes
from ..pipeline import View
from .colors import cut_attributes
from .page import _b64, page_data

#: The page's first point budget (splats drawn) and LOD tolerance (pixels).
DEFAULT_WEB_BUDGET = 1_000_000
WEB_TOLERANCE = 1.0


def tree_entries(h: Hierarchy) -> SplatCloud:
    """Every node's splat (flat shading), then every point: the entries a browser LOD page draws from. The
    points keep their clip lines and normal fields where they have them, the nodes none (lines that keep
    the whole disk, a zero field), as :meth:`Hierarchy.splats <surfsplat.hierarchy.Hierarchy.splats>`
    gathers a flat-shaded cut for the desktop."""
    nodes, points = h.node_splats(lod_shading="flat"), h.points
    gray = np.full((1, 3), 0.8, np.float32)

    def colors(cloud: SplatCloud) -> np.ndarray:
        return cloud.colors if cloud.colors is not None else np.repeat(gray, len(cloud), axis=0)

    def rows(name: str) -> np.ndarray:
        return np.concatenate([getattr(nodes, name), getattr(points, name)])

    m = len(nodes)
    lines = None if points.clip_lines is None else np.concatenate(
        [np.broadcast_to(np.array([0.0, 0.0, 1.0], np.float32), (m, 2, 3)), points.clip_lines])
    field = None if points.normal_field is None else np.concatenate([np.zeros((m, 2), np.float32),
                                                                      points.normal_field])
    return points.with_arrays(positions=rows("positions"), normals=rows("normals"),
                              colors=np.concatenate([colors(nodes), colors(points)]), u=rows("u"), v=rows("v"),
                              normal_field=field, clip_lines=lines,
                              attributes=cut_attributes(h, np.arange(len(h)), np.arange(len(h.points))))


def tree_data(plan: View, camera: Camera, technique: str, background, name: str,
              budget: int | None = None, fine_positions: bool = False) -> tuple[dict, dict]:
    """The header and streams of a page that cuts the view plan's hierarchy itself (a cloud's built)."""
    model = plan.tree(camera)
    h = model.data
    if not isinstance(h, Hierarchy):
        raise InputError(f"{name}: no hierarchy to cut in the browser")
    header, streams = page_data(plan, camera, tree_entries(h), technique, background, name, ordered=False,
                                fine_positions=fine_positions)
    nodes = len(h)
    header["lod"] = {"nodes": nodes, "points": int(len(h.points)), "levels": int(h.levels),
                     "level_offsets": [int(x) for x in h.level_offsets], "budget": int(budget or DEFAULT_WEB_BUDGET),
                     "tolerance": WEB_TOLERANCE}
    streams.update(tree_streams(h))
    return header, streams


def tree_streams(h: Hierarchy) -> dict[str, str]:
    """The tree of ``h`` as the page cuts it (base64): per node its children, its points, its bounding
    sphere's centre and radius and its extent, and where the points have clip lines the ``sharp`` bit of
    the nodes over them (:func:`~surfsplat.hierarchy.lod.sharp_nodes`: refined whatever their size)."""
    streams = {
        "child_start": _b64(h.node_child_start.astype("<i4")), "child_count": _b64(h.node_child_count.astype("<i4")),
        "point_start": _b64(h.node_point_start.astype("<i4")), "point_count": _b64(h.node_point_count.astype("<i4")),
        "center": _b64(h.node_positions.astype("<f4")), "radius": _b64(h.node_radius.astype("<f4")),
        "extent": _b64(h.node_extent.astype("<f4")),
    }
    if h.points.clip_lines is not None:   # one bit a node (little bit order): always refined, as on the desktop
        streams["sharp"] = _b64(np.packbits(sharp_nodes(h), bitorder="little"))
    return streams
