"""What the viewer draws: the view-dependent LOD cut of its full-quality frames and the motion preview."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..pipeline import Model, hybrid_splats, local_camera
from ..camera import Camera
from ..cloud import SplatCloud
from ..hierarchy import LodShading, uniform_cut
from ..hierarchy.chunked import ChunkedHierarchy
from ..hierarchy.sequential import drawn_mask, sequential_layout
from ..rendering.sequential import upload_sequential
from .streaming import CellStreamer


def preview_cloud(hierarchy, budget: int) -> SplatCloud | None:
    """At most ``budget`` splats standing in for the whole model while the camera moves.

    The finest level-uniform cut of the LOD hierarchy that fits the budget
    (:func:`~surfsplat.hierarchy.uniform_cut`): the nodes' representative splats,
    whose ellipses cover their subtrees' disks (Pajarola 2003, sec. 3.4), so the
    preview has no holes; fixed, so it does not flicker. None when the model has
    no more than ``budget`` splats (or ``budget`` is 0): it is drawn whole.

    A chunked hierarchy is previewed by what opening it read, never by its cells: its preview
    splats (``hierarchy.points``, a uniform cut of every cell made by the build, at most about
    200k), always whole (None): cutting them again through an octree built over them gives
    oversized node ellipses sticking out of the surface, and thinning them leaves halos.
    """
    if budget <= 0 or len(hierarchy.points) <= budget or isinstance(hierarchy, ChunkedHierarchy):
        return None
    return hierarchy.node_splats(uniform_cut(hierarchy, budget), lod_shading="flat")


#: The coarsest motion preview level has at least this many splats (a coarser one would hardly be
#: faster: a frame's fixed costs, clearing, presenting and the HUD, dominate below it on llvmpipe).
PREVIEW_MIN = 1_000
#: Share of a frame's time (1 / the target rate) a preview's rendering is assumed to take when the
#: time of the whole frame is not known yet (the first preview after a still view).
PREVIEW_SHARE = 0.75
#: A finer preview level is taken only if its predicted frame time is below this share of the
#: target's (hysteresis: no flipping between two levels).
PREVIEW_HEADROOM = 0.8


def preview_levels(hierarchy, budget: int) -> list[SplatCloud | None]:
    """The motion previews from coarse to fine: the finest is :func:`preview_cloud` (None: the
    whole model), each coarser one the finest level-uniform cut with at most a quarter of the next
    one's splats (a whole octree level: often fewer), none under :data:`PREVIEW_MIN` (all hole-free like
    :func:`preview_cloud`). A chunked hierarchy has one level: what opening it read."""
    finest = preview_cloud(hierarchy, budget)
    levels = [finest]
    if budget <= 0 or isinstance(hierarchy, ChunkedHierarchy):
        return levels
    count = len(hierarchy.points) if finest is None else len(finest)
    while count // 4 >= PREVIEW_MIN:
        coarser = hierarchy.node_splats(uniform_cut(hierarchy, count // 4), lod_shading="flat")
        if not PREVIEW_MIN <= len(coarser) < count:
            break
        levels.insert(0, coarser)
        count = len(coarser)
    return levels


def next_preview_level(level: int, counts: list[int], render_s: float, fps: float,
                       frame_s: float | None = None) -> int:
    """The preview level (index into ``counts``, splats per level from coarse to fine) to draw next,
    after level ``level`` took ``render_s`` seconds to render within a frame of ``frame_s`` seconds
    (rendering, presenting, HUD, swap; None: not known, taken as ``render_s / PREVIEW_SHARE``), so
    that moving frames keep ``fps`` frames per second: one level coarser when the frame took longer
    than ``1 / fps``; one finer when the frame with the finer level's render time, predicted
    proportional to its splats (an over-estimate: part of a render is fixed), stays within
    :data:`PREVIEW_HEADROOM` of it; else the same. ``fps`` 0: always the finest."""
    if fps <= 0:
        return len(counts) - 1
    target = 1.0 / fps
    frame = render_s / PREVIEW_SHARE if frame_s is None else frame_s
    if frame > target and level > 0:
        return level - 1
    finer = level + 1
    if finer < len(counts):
        predicted = frame + render_s * (counts[finer] / max(counts[level], 1) - 1.0)
        if predicted < PREVIEW_HEADROOM * target:
            return finer
    return level


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


#: A GPU cut (``lod_mode="gpu"``) that hands the GPU at least as many entries as the model has points
#: and keeps at least this fraction of them is drawn as the points alone: their own upload, in Morton
#: order, makes compact blocks for the compute passes and the frustum (the sequential layout orders them
#: by LOD bin, each bin spread over the model) and has no interval test per entry. The picture is the
#: full-resolution model (finer where the cut kept a node). Measured on the 1 M bunny at 1280x720, ewa,
#: the cut against the points alone, alternated (llvmpipe, 2 cores): keeping 73% of the points
#: (the viewer's first view) 731 against 646 ms, 59%: 556 / 536, 40%: 465 / 482, 17%: 339 / 491; a
#: close-up of the head 1,182 against 638 ms.
ALL_POINTS_FRACTION = 0.6

#: Points whose interval test estimates :func:`points_drawn` (every k-th of the layout's points).
POINTS_DRAWN_SAMPLE = 1 << 14


def points_drawn(layout, camera: Camera, lod_tolerance: float) -> float:
    """The fraction of a sequential layout's points (its entries after the nodes) that the interval
    rule draws for ``camera`` (world; near/far set from the entries' bounds where None) at
    ``lod_tolerance`` pixels, each at its own eye distance
    (:func:`~surfsplat.hierarchy.sequential.drawn_mask`, in NumPy), estimated on every k-th point
    (:data:`POINTS_DRAWN_SAMPLE` of them: about a millisecond)."""
    count = len(layout.lod) - layout.node_count
    if count <= 0:
        return 0.0
    sample = np.arange(layout.node_count, len(layout.lod), max(1, count // POINTS_DRAWN_SAMPLE))
    positions = layout.splats.positions[sample].astype(np.float64) + np.asarray(layout.splats.origin, np.float64)
    if camera.near is None:
        lo, hi = layout.splats.bounds()
        camera = camera.with_clip_from_bounds(lo, hi, margin=float(layout.splats.radii.max()))
    distance = np.linalg.norm(positions - np.asarray(camera.eye, np.float64), axis=1)
    drawn = drawn_mask(layout.lod[sample], distance, float(camera.focal_px) / float(lod_tolerance),
                       float(camera.near))
    return float(np.count_nonzero(drawn)) / len(sample)


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

    A chunked hierarchy (:class:`~surfsplat.hierarchy.chunked.ChunkedHierarchy`) is cut by its
    own ``view_splats`` (only the cells the view needs are read) in a background thread
    (:class:`~surfsplat.viewer.streaming.CellStreamer`): :meth:`ready` asks for a view's cut
    without waiting, calling the object waits for it.

    With ``on_gpu`` (the view plan's strategy, :func:`surfsplat.pipeline.lod.lod_strategy`) an
    in-memory hierarchy's views draw its sequential layout (:mod:`surfsplat.rendering.sequential`,
    a GPU cut: 1M bunny at 1280x720 in benchmarks/results/gpu_lod.md), uploaded on first use: a new
    view costs no selection, gather or upload, the vertex shader keeps the cut.
    """

    def __init__(self, renderer, tree: Model, lod_shading: LodShading = "fit", on_gpu: bool = False):
        self.renderer, self.tree, self.hierarchy, self.lod_shading = renderer, tree, tree.data, lod_shading
        self.gpu = bool(on_gpu)
        self._sequential = None   # the GPU layout (lod_mode "gpu"), uploaded on first use
        self._layout = None       # ... and the layout it was uploaded from
        self._points = None       # the hierarchy's points alone, uploaded when a cut keeps most of them
        self.streamer = CellStreamer() if not tree.in_memory else None
        self._key = None
        self._generation = 0   # changes with the hierarchy (set_hierarchy): part of a view's key
        self._splats = None
        self.count = 0
        self.select_ms = 0.0
        self.cells_loaded = 0   # chunked: cells the last cut needed (read or found in the cache)

    def set_hierarchy(self, hierarchy) -> None:
        """Cut ``hierarchy`` from now on (a recoloured chunked model: ``ChunkedHierarchy.colorized``);
        the uploaded cut is dropped and views already read are not reused."""
        self.hierarchy = hierarchy
        self.tree = replace(self.tree, data=hierarchy)
        self._generation += 1
        self.release()

    def _cut(self, camera: Camera, lod_tolerance: float, cull_backfaces: bool, point_budget: int | None):
        """(SplatCloud with the model's origin, selection, milliseconds taken) of a view; ``camera`` in
        world coordinates. A chunked hierarchy's runs in the streamer's thread, the only one touching its cells."""
        start = time.perf_counter()
        cloud, selection = self.tree.cut(camera, lod_tolerance, cull_backfaces=cull_backfaces, shading=self.lod_shading,
                                         point_budget=point_budget)
        return cloud, selection, 1000.0 * (time.perf_counter() - start)

    def ready(self, camera: Camera, lod_tolerance: float, cull_backfaces: bool, point_budget: int | None = None,
              hybrid: bool = False) -> bool:
        """Whether the view's cut can be drawn without waiting: always for an in-memory hierarchy;
        for a chunked one, once its cells have been read in the background (started here if not yet)."""
        key = (camera, float(lod_tolerance), bool(cull_backfaces), point_budget, bool(hybrid), self._generation)
        if self.streamer is None or key == self._key:
            return True
        return self.streamer.poll(key, lambda: self._cut(*key[:4])) is not None

    @property
    def pending(self) -> bool:
        """Whether cells are being read for a view."""
        return self.streamer is not None and self.streamer.pending

    def __call__(self, camera: Camera, lod_tolerance: float, cull_backfaces: bool, point_budget: int | None = None,
                 hybrid: bool = False):
        """(GpuSplats or None when nothing is visible, number of splats drawn); a chunked
        hierarchy's cut is waited for (see :meth:`ready`)."""
        if self.gpu:
            if self._sequential is None:
                self.release()
                layout = sequential_layout(self.hierarchy, self.lod_shading)
                self._sequential = upload_sequential(self.renderer, layout.splats, layout.lod)
                self._layout = layout
            self._sequential.lod_tolerance = float(lod_tolerance)
            start = time.perf_counter()
            self.count = self._sequential.prefix_count(camera)
            if (self.count >= len(self.hierarchy.points)
                    and points_drawn(self._layout, camera, lod_tolerance) >= ALL_POINTS_FRACTION):
                if self._points is None:   # uploaded on first use, in its own (Morton) order
                    self._points = self.renderer.upload(self.hierarchy.points)
                self.count = self._points.count
                self.select_ms = 1000.0 * (time.perf_counter() - start)
                return self._points, self.count
            self.select_ms = 1000.0 * (time.perf_counter() - start)
            return self._sequential, self.count
        key = (camera, float(lod_tolerance), bool(cull_backfaces), point_budget, bool(hybrid), self._generation)
        if key != self._key:
            if self.streamer is not None:
                cloud, selection, self.select_ms = self.streamer.result(key, lambda: self._cut(*key[:4]))
                self.cells_loaded = selection.cells_loaded
            else:
                cloud, selection, self.select_ms = self._cut(*key[:4])
            if hybrid and len(cloud):
                cloud = hybrid_splats(self.tree, cloud, selection, local_camera(cloud, camera))
            self.release()
            self._splats = self.renderer.upload(cloud) if len(cloud) else None
            self.count, self._key = len(cloud), key
        return self._splats, self.count

    def release(self) -> None:
        """Free the uploaded cut (and the GPU layout: recolouring changes it)."""
        if self._splats is not None:
            self._splats.release()
        if self._sequential is not None:
            self._sequential.release()
        if self._points is not None:
            self._points.release()
        self._splats, self._key, self.count, self._sequential = None, None, 0, None
        self._layout, self._points = None, None

    def close(self) -> None:
        """Free the uploaded cut and stop the background reads (the running one is finished)."""
        self.release()
        if self.streamer is not None:
            self.streamer.close()


def recolor(hierarchy, colors: np.ndarray | None, node_colors: np.ndarray | None = None) -> None:
    """Give ``hierarchy`` (in place) new point colours ((P,) rows in its point order, or None) and
    node colours: ``node_colors`` as given, or None for the mean of each node's point colours
    (:meth:`~surfsplat.hierarchy.Hierarchy.set_colors`)."""
    hierarchy.set_colors(colors, node_colors)
