"""What the viewer draws: the view-dependent LOD cut of its full-quality frames and the motion preview."""

from __future__ import annotations

import time

import numpy as np

from ..api import DEFAULT_LOD_SHADING, hybrid_splats, local_camera, lod_splats
from ..camera import Camera
from ..cloud import SplatCloud
from ..hierarchy import LodShading, uniform_cut


def preview_cloud(hierarchy, budget: int) -> SplatCloud | None:
    """At most ``budget`` splats standing in for the whole model while the camera moves.

    The finest level-uniform cut of the LOD hierarchy that fits the budget
    (:func:`~surfsplat.hierarchy.uniform_cut`): the nodes' representative splats,
    whose ellipses cover their subtrees' disks (Pajarola 2003, sec. 3.4), so the
    preview has no holes; fixed, so it does not flicker. None when the model has
    no more than ``budget`` splats (or ``budget`` is 0): it is drawn whole.
    """
    if budget <= 0 or len(hierarchy.points) <= budget:
        return None
    return hierarchy.node_splats(uniform_cut(hierarchy, budget), lod_shading="flat")


#: Progressive refinement under a point budget: the still view is drawn with the budget divided by
#: these factors in turn (each frame cross-faded into the next), the largest first.
REFINE_STEPS = (16, 4, 1)
#: ... but no step below this many splats (a smaller first step would only blur).
REFINE_MIN = 20_000


def refinement_budgets(point_budget: int | None) -> list[int | None]:
    """The budgets of the progressive refinement of a still view: ``[None]`` without a budget (one
    frame, the whole LOD cut), else ``point_budget / REFINE_STEPS`` from coarse to fine, at
    least :data:`REFINE_MIN` each (duplicates dropped), ending with ``point_budget``."""
    if point_budget is None:
        return [None]
    steps = sorted({max(min(REFINE_MIN, point_budget), point_budget // k) for k in REFINE_STEPS})
    return steps


class LevelOfDetail:
    """View-dependent level of detail for the viewer's full-quality frames (Pajarola 2003, sec. 5.1).

    Holds the model's point-octree; per frame it selects the cut for the camera and
    the screen tolerance tau (nodes whose projected ellipse is at most tau pixels are
    drawn as one splat; frustum culling, and back-face culling when the render
    options ask for it), within a point budget when given (Potree's priority), gathers the
    splats and uploads them, replacing the previous cut. With ``hybrid`` (the model's points
    carry the ``nonplanar`` attribute) non-planar splats are drawn as points facing the eye
    (:func:`surfsplat.api.hybrid_splats`). A cut is reused while the camera, tau, culling,
    budget and hybrid switch stay the same.
    """

    def __init__(self, renderer, hierarchy, lod_shading: LodShading = DEFAULT_LOD_SHADING, model=None):
        self.renderer, self.hierarchy, self.lod_shading = renderer, hierarchy, lod_shading
        self.model = hierarchy if model is None else model
        self._key = None
        self._splats = None
        self.count = 0
        self.select_ms = 0.0

    def __call__(self, camera: Camera, lod_tolerance: float, cull_backfaces: bool, point_budget: int | None = None,
                 hybrid: bool = False):
        """(GpuSplats or None when nothing is visible, number of splats drawn)."""
        key = (camera, float(lod_tolerance), bool(cull_backfaces), point_budget, bool(hybrid))
        if key != self._key:
            start = time.perf_counter()
            cloud, selection = lod_splats(self.hierarchy, camera, lod_tolerance, cull_backfaces=cull_backfaces,
                                          lod_shading=self.lod_shading, point_budget=point_budget)
            if hybrid and len(cloud):
                cloud = hybrid_splats(self.model, self.hierarchy, cloud, selection, local_camera(cloud, camera))
            self.select_ms = 1000.0 * (time.perf_counter() - start)
            self.release()
            self._splats = self.renderer.upload(cloud) if len(cloud) else None
            self.count, self._key = len(cloud), key
        return self._splats, self.count

    def release(self) -> None:
        """Free the uploaded cut."""
        if self._splats is not None:
            self._splats.release()
        self._splats, self._key, self.count = None, None, 0


def recolor(hierarchy, colors: np.ndarray | None, node_colors: np.ndarray | None = None) -> None:
    """Give ``hierarchy`` (in place) new point colours ((P,) rows in its point order, or None) and
    node colours: ``node_colors`` as given, or None for the mean of each node's point colours
    (:meth:`~surfsplat.hierarchy.Hierarchy.set_colors`)."""
    hierarchy.set_colors(colors, node_colors)
