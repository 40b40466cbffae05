"""The GPU side of sequential point trees (Dachsbacher, Vogelgsang & Stamminger 2003): a hierarchy's
entries uploaded once, each frame's LOD cut chosen by the vertex shader.

The layout (``hierarchy/sequential.py``: every node and point with its interval, drawn at eye distance
``d`` when ``R + max(near, s D) <= d < A + max(near, s B)``) is uploaded like a SplatCloud, ordered by
radius class as :meth:`Renderer.upload` orders splats (quads and GL_POINTS stay apart), and each class
in three segments: its nodes by ``D`` ascending, the same nodes again by ``B`` descending, its points
by ``B`` descending (in bins of :data:`BINS_PER_OCTAVE` per octave, each bin in the hierarchy's spatial
order). A frame draws one range of each segment, from the bounds of the model's distance to the eye,
``[d_min, d_max]``, and of the two node segments of a class the shorter range (the first order
bounds the nodes refined everywhere in a close view, the second the nodes too fine for a distant one;
a node's ``D`` and its parent's ``B`` are too loosely related for one order to do both):

- its end: the first entry from which on every upper end is below ``d_min`` (bounded by
  ``max A + max(near, s max B)`` over the rest of the segment, suffix maxima: what ends a points
  segment) or every lower end above ``d_max`` (``min R + max(near, s min D)``, suffix minima: what
  ends a nodes segment, the coarse nodes);
- its start: past the entries of a nodes segment whose upper ends are all below ``d_min`` (prefix
  maxima: the fine nodes, replaced by their children or points in this view).

The bounds are monotone along a segment, so they are tested every :data:`CHECKPOINT_STRIDE`-th entry
(a few thousand numbers for millions of entries; no Python work per node). Every entry drawn runs the
interval test in the vertex shader (``lod_rejected`` in ``glsl/splat_attributes.glsl``, compiled in by
the ``SEQUENTIAL_LOD`` define for every technique) with a frustum test of its bounding sphere.
Moving the camera changes one uniform and the ranges: nothing is uploaded.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from .gpu_splats import GpuSplats, ordered_buffers, radius_classes, splat_arrays
from .renderer import Renderer, _with_clip_planes

#: Entries between two tested ones when a frame's ranges are searched: a range may hold up to this
#: many entries more than needed at each end (each then rejected by its vertex shader).
CHECKPOINT_STRIDE = 256

#: Relative slack on the model's distance range: the shader's float32 distances round either way.
DISTANCE_SLACK = 1e-5

#: Where a hierarchy's LOD cut is chosen (``lod_mode``): "cpu" (``hierarchy.select``, gathered and
#: uploaded per view) or "gpu" (this module).
LodMode = Literal["cpu", "gpu"]

#: The :data:`LodMode` values.
LOD_MODES: tuple[str, ...] = get_args(LodMode)

#: Bins per octave of ``D`` (nodes) and ``B`` (points) in the order of a segment (finer: shorter
#: ranges; coarser: longer runs of entries in the hierarchy's spatial order).
BINS_PER_OCTAVE = 2

#: The define that compiles the interval test into a technique's vertex shader.
SEQUENTIAL_DEFINE = "SEQUENTIAL_LOD"


@dataclass
class GpuSequential(GpuSplats):
    """A sequential layout on the GPU (module docstring): draws as a :class:`GpuSplats` whose frames
    draw one range of each segment (the nodes, then the points, of a radius class), the vertex shader
    keeping the entries of the LOD cut at ``lod_tolerance`` pixels (settable between frames).

    Attributes:
        lod_tolerance: the screen tolerance (pixels) of the cut drawn.
        segment_start: (S,) int64 first entry of each segment; a segment ends where the next begins.
        segment_class: (S,) int64 radius class of each segment (its quads or points).
        segment_kind: (S,) int64 0: the class's nodes by D ascending, 1: the same nodes by B
            descending, 2: its points (a frame draws one of the two node segments of a class).
        checkpoints: (K,) int64 entries tested for the ranges, ascending, each segment's first included.
        checkpoint_segment: (K,) int64 segment of each.
        reach: (K, 2) float64 ``(max B, max A)`` from the checkpoint to its segment's end: no entry
            there reaches farther than ``max A + max(near, s max B)``.
        low: (K, 2) float64 ``(min D, min R)`` from the checkpoint to its segment's end: no entry there
            is drawn nearer than ``min R + max(near, s min D)``.
        before: (K, 2) float64 ``(max B, max A)`` of the entries of its segment before the checkpoint
            (-inf for none).
        last_prefix: entries the last frame drew (all segments).
    """

    lod_tolerance: float = 1.0
    segment_start: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    segment_class: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    segment_kind: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    checkpoints: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    checkpoint_segment: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reach: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    low: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    before: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    last_prefix: int = 0

    def scale_for(self, camera: Camera) -> float:
        """The interval scale ``s = focal_px / lod_tolerance`` of a frame."""
        tolerance = float(self.lod_tolerance)
        if not (np.isfinite(tolerance) and tolerance > 0):
            raise InputError(f"the GPU LOD cut needs a tolerance > 0 pixels, got {self.lod_tolerance!r}")
        return float(camera.focal_px) / tolerance

    def distance_range(self, camera: Camera) -> tuple[float, float]:
        """Nearest and farthest distance (GPU units) from ``camera``'s eye (the GPU frame's) to the box
        of the entries' centres (0 inside it)."""
        lo, hi = self.gpu_bounds
        eye = np.asarray(camera.eye, dtype=np.float64)
        near = np.linalg.norm(np.maximum(np.maximum(lo - eye, eye - hi), 0.0))
        return float(near), float(np.linalg.norm(np.maximum(np.abs(eye - lo), np.abs(eye - hi))))

    def windows(self, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        """``(start, end)``, (S,) int64 each: the range of each segment a frame of ``camera`` (the GPU
        frame's) draws. Past ``end`` every entry's interval lies beyond the nearest distance (its upper
        end is below it) or beyond the farthest (its lower end is above it); before ``start`` every
        upper end is below the nearest distance. Tested at the checkpoints, with bounds monotone
        along a segment (module docstring)."""
        ends = np.append(self.segment_start[1:], self.count).astype(np.int64)
        starts = self.segment_start.astype(np.int64)
        if len(self.checkpoints) == 0:
            return starts, ends
        s, near = self.scale_for(camera), float(camera.near)
        dmin, dmax = self.distance_range(camera)
        dmin, dmax = dmin * (1.0 - DISTANCE_SLACK), dmax * (1.0 + DISTANCE_SLACK)
        with np.errstate(invalid="ignore", over="ignore"):   # the interval ends are monotone in B, A, D, R
            out = np.maximum(near, s * self.reach[:, 0]) + self.reach[:, 1] < dmin
            out |= np.maximum(near, s * self.low[:, 0]) + self.low[:, 1] > dmax
            skip = np.maximum(near, s * self.before[:, 0]) + self.before[:, 1] < dmin
        seg = self.checkpoint_segment
        first = np.flatnonzero(np.diff(seg, prepend=-1))   # each segment's first checkpoint
        end = np.minimum.reduceat(np.where(out, self.checkpoints, ends[seg]), first)
        start = np.maximum.reduceat(np.where(skip, self.checkpoints, starts[seg]), first)
        ends[seg[first]], starts[seg[first]] = end, np.minimum(start, end)
        # of a class's two copies of its nodes, the shorter range
        twin = np.flatnonzero((self.segment_kind[:-1] == 0) & (self.segment_kind[1:] == 1))
        longer = np.where(ends[twin] - starts[twin] > ends[twin + 1] - starts[twin + 1], twin, twin + 1)
        ends[longer] = starts[longer]
        return starts, ends

    def prefix_count(self, camera: Camera) -> int:
        """Entries a frame of the world ``camera`` hands to the GPU (the ranges of all segments)."""
        start, end = self.windows(self.gpu_camera(_with_clip_planes(camera, self)))
        return int((end - start).sum())

    def draw_ranges(self, camera: Camera, point_radius: float) -> tuple[list, list]:
        """Per segment, the range :meth:`windows`, with the quads (classes whose largest radius exceeds
        ``point_radius``) and the points apart."""
        quads, points = [], []
        for c, start, end in zip(self.segment_class.tolist(), *(x.tolist() for x in self.windows(camera))):
            if end > start:
                big = not point_radius > 0 or self.class_radius[c] > point_radius
                (quads if big else points).append((start, end - start))
        self.last_prefix = int(sum(n for _, n in quads + points))
        return quads, points

    def extra_uniforms(self, camera: Camera) -> dict:
        """The interval scale ``u_lod_scale`` of the frame (``camera``: the GPU frame's)."""
        return {"u_lod_scale": self.scale_for(camera)}


def _bins(values: np.ndarray) -> np.ndarray:
    """Bins of :data:`BINS_PER_OCTAVE` per octave of positive ``values``."""
    with np.errstate(divide="ignore"):
        return np.floor(np.log2(np.maximum(values, 1e-300)) * BINS_PER_OCTAVE)


def upload_sequential(renderer: Renderer, splats: SplatCloud, lod: np.ndarray,
                      lod_tolerance: float = 1.0) -> GpuSequential:
    """Copy a sequential layout (``splats``: its entries, ``lod``: (E, 4) intervals ``(R, D, A, B)``,
    as :class:`~surfsplat.hierarchy.sequential.SequentialLayout` holds them) to the GPU in segments
    (module docstring), with the checkpoints of the per-frame range search."""
    if not splats.has_splats:
        raise InputError("the sequential layout's splats have no normals or splat axes")
    lod = np.asarray(lod, dtype=np.float32)
    if len(splats) == 0 or lod.shape != (len(splats), 4):
        raise InputError(f"a sequential layout needs (E, 4) intervals for its E > 0 entries, got {lod.shape} "
                         f"for {len(splats):,} entries")
    arrays, scale = splat_arrays(splats)
    arrays["lod"] = lod * np.float32(scale)   # lengths: scaled with the model
    radii = splats.radii * np.float32(scale)
    order, class_start, class_radius = radius_classes(radii)
    klass = np.repeat(np.arange(len(class_start)), np.diff(np.append(class_start, len(order))))
    r, d, a, b = (arrays["lod"][order, k].astype(np.float64) for k in range(4))
    big = 0.5 * float(np.float32(1e30) * np.float32(scale))   # hierarchy.sequential.BIG, scaled
    # the nodes twice (kind 0: by D ascending, never-drawn ones last; kind 1: by B descending), the
    # points once (kind 2: by B descending); unbounded upper ends first; each bin in layout order (a
    # stable sort keeps the hierarchy's spatial order: neighbours on screen are drawn together)
    nodes = np.flatnonzero(r >= 0)
    order, klass = np.concatenate([order, order[nodes]]), np.concatenate([klass, klass[nodes]])
    kind = np.concatenate([np.where(r >= 0, 0, 2), np.ones(len(nodes), np.int64)])
    r, d, a, b = (np.concatenate([x, x[nodes]]) for x in (r, d, a, b))
    key = np.where(kind == 0, _bins(d), -_bins(b))
    key[(kind > 0) & (a >= big)] = -np.inf
    key[(kind == 0) & (r >= big)] = np.inf
    by = np.lexsort((key, kind, klass))   # class, then the kind, then the key
    order, klass, kind = order[by], klass[by], kind[by]
    buffers, blocks, _ = ordered_buffers(renderer.ctx, arrays, order, radii)
    r, d, a, b = (arrays["lod"][order, k].astype(np.float64) for k in range(4))
    segment_start = np.flatnonzero(np.diff(klass * 3 + kind, prepend=-1))
    ends = np.append(segment_start[1:], len(order))
    reach, low, before = np.empty((len(order), 2)), np.empty((len(order), 2)), np.empty((len(order), 2))
    for s0, s1 in zip(segment_start.tolist(), ends.tolist()):   # per segment (at most 256), not per entry
        for k, column in enumerate((b, a)):
            part = column[s0:s1]
            reach[s0:s1, k] = np.maximum.accumulate(part[::-1])[::-1]
            before[s0:s1, k] = np.concatenate([[-np.inf], np.maximum.accumulate(part)[:-1]])
        for k, column in enumerate((d, r)):
            low[s0:s1, k] = np.minimum.accumulate(column[s0:s1][::-1])[::-1]
    checks = np.unique(np.concatenate([segment_start, np.arange(0, len(order), CHECKPOINT_STRIDE)]))
    # the largest radius of the original points stands for the layout's: point_radius() takes it as the
    # splats' reach beyond the bounds, and a node splat is drawn only where its interval puts it
    # farther than its extent times s from the eye
    points = lod[:, 0] < 0
    extent = float(splats.radii[points].max()) if points.any() else float(class_radius[0]) / scale
    return GpuSequential(buffers, len(order), splats.bounds(), extent, blocks=blocks,
                         class_start=np.searchsorted(klass, np.arange(len(class_radius))), class_radius=class_radius,
                         origin=np.asarray(splats.origin, dtype=np.float64), scale=scale,
                         extra_attributes=("lod",), defines={SEQUENTIAL_DEFINE: 1},
                         lod_tolerance=float(lod_tolerance), segment_start=segment_start.astype(np.int64),
                         segment_class=klass[segment_start].astype(np.int64),
                         segment_kind=kind[segment_start].astype(np.int64), checkpoints=checks.astype(np.int64),
                         checkpoint_segment=(np.searchsorted(segment_start, checks, side="right") - 1).astype(np.int64),
                         reach=reach[checks], low=low[checks], before=before[checks])


_cached: dict = {}


def render_sequential(renderer: Renderer, splats: SplatCloud, lod: np.ndarray, camera: Camera, technique,
                      lights, options, background, lod_tolerance: float, supersample: int = 1):
    """``(Frame, entries given to the GPU)``: :meth:`Renderer.render` of a sequential layout (uploaded
    once, :func:`cached_sequential_upload`) cut at ``lod_tolerance`` output pixels."""
    tolerance = float(lod_tolerance)
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"the GPU LOD cut needs a tolerance > 0 pixels, got {lod_tolerance!r}")
    gpu = cached_sequential_upload(renderer, splats, lod)
    gpu.lod_tolerance = tolerance * int(supersample)   # drawn at K x the focal length: sub-pixels
    frame = renderer.render(gpu, camera, technique, lights, options, background, supersample=supersample)
    return frame, gpu.last_prefix


def cached_sequential_upload(renderer: Renderer, splats: SplatCloud, lod: np.ndarray) -> GpuSequential:
    """:func:`upload_sequential` of a layout, kept for the next call with the same layout arrays (the
    same objects) and renderer: a hierarchy is uploaded once, its frames only draw. One layout is kept
    (the previous one is released when another is uploaded)."""
    key = (id(renderer), id(splats), id(lod))
    held = _cached.get("entry")
    if held is not None and held[0] == key and held[1] is renderer and held[2] is splats and held[3] is lod:
        return held[4]
    if held is not None and held[1] is renderer:
        held[4].release()   # a released renderer's context is gone with its buffers: nothing to free then
    gpu = upload_sequential(renderer, splats, lod)
    _cached["entry"] = (key, renderer, splats, lod, gpu)
    return gpu
