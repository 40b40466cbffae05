"""A frame as a plan of passes, built from the technique's declarations and the render options.

:func:`plan_frame` reads a :class:`~surfsplat.rendering.technique.Technique`'s capabilities (blended or
opaque, ``point_footprint``, ``compute_visibility`` / ``compute_opaque``, ``edge_coverage``,
``edge_fringe``), never its shader files' names, and lists the passes of one frame with the splat
ranges each draws; :meth:`Renderer.draw <surfsplat.rendering.renderer.Renderer.draw>` runs them in
order. A blended technique (Guennebaud 2003: visibility, accumulation, normalization):

1. ``clear``: the accumulation targets and the visibility record;
2. ``compute_visibility`` (where declared, asked for and available): the small splats' visibility as
   compute shaders (:mod:`~surfsplat.rendering.compute_visibility`);
3. ``visibility``: the other splats' nearest disks by MIN blending (``glsl/visibility.glsl``);
4. ``cracks``: the visibility record copied with its cracks marked (``cracks.frag``);
5. ``accumulation``: every splat, additive blending of weighted colors, depths, normals;
6. ``normalization``: a full-screen pass dividing by the weight (eq. 18);
7. ``fill`` (where ``RenderOptions.fill_holes``): the holes between front-surface pixels filled in
   screen space (``fill.frag``, :func:`fill_gap`).

An opaque one: ``clear``, ``opaque`` (a plain z-buffer), ``compute_opaque`` (where declared, asked for
and available: the small splats' nearest disks computed, then written by ``opaque_resolve.frag``),
``normalization`` and ``fill``. Each pass is a small frozen object: its ``name``, the ``(first, count)`` ranges it
draws as instanced ``quads`` and as GL_POINTS ``points`` (or ``computed``), and ``run(renderer, frame)``
(``renderer``: the :class:`~surfsplat.rendering.renderer.Renderer` drawing the frame, whose programs,
vertex arrays and draw batches the passes use; ``frame``: :class:`FrameInputs`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import ClassVar

import moderngl
import numpy as np

from ..camera import Camera
from ..reference import prefilter_variance
from . import compute_visibility
from .gpu_splats import GpuSplats
from .options import RenderOptions
from .shaders import (COMPUTE_GLSL_VERSION, NO_DEPTH, PASS_ACCUMULATION, PASS_OPAQUE, PASS_VISIBILITY)
from .technique import Technique

#: The frame-wide uniforms (``Renderer.frame_uniforms``) that only the splat programs
#: declare: the normalization pass and the ground-truth mesh program lack them, so setting
#: them there is no error. This is the one documented optional set of frame-wide uniforms;
#: a technique lists its own optional ones in ``Technique.optional_uniforms``.
OPTIONAL_FRAME_UNIFORMS = frozenset({"u_depth_epsilon", "u_cull_backfaces", "u_deferred", "u_separate_sides",
                                     "u_side", "u_supersample", "u_clip_fringe"})
#: The define compiling edge coverage into the accumulation and normalization passes
#: (``VisibilityOptions.edge_coverage``): a define, since llvmpipe pays for a branch on a false uniform
#: (20% of the accumulation pass on the bunny).
EDGE_COVERAGE_DEFINE = "EDGE_COVERAGE"
#: Texture unit of the side target during the accumulation pass (units 0 and 1 serve pass 3).
SIDE_TEXTURE_UNIT = 2
#: Texture unit of the coverage target during pass 3.
COVER_TEXTURE_UNIT = 3
#: Splats whose window box is at most this many sub-pixels wide (estimated per frame from their radius
#: class and the nearest depth of the cloud's bounds) are drawn as one GL_POINTS point each, the
#: others as instanced quads (tight bounds for large or slanted splats), where the technique declares a
#: ``point_footprint``. A point runs the vertex shader once per splat instead of four times; its square
#: covers the box, so a slanted splat costs at most this squared in fragments. Measured on llvmpipe
#: (random spheres at 1024x1024, CPU time per frame, all quads against this limit): 12 px splats
#: 338 -> 263 ms (ewa), 38 px splats 163 -> 158 ms; a limit of 128 made the 38 px ones slower (186 ms).
POINT_SPLAT_PX = 64.0
#: Widest hole (output pixels) the ``fill`` pass fills (``RenderOptions.fill_holes``, ``fill.frag``):
#: the gaps splats sized to just cover leave are a pixel or two; a gap of 4 pixels and more is a hole
#: of the surface, kept.
FILL_GAP_PX = 3
#: The most sub-pixels the ``fill`` pass searches along each direction (supersampled frames: the gap is
#: ``FILL_GAP_PX * K`` sub-pixels up to it): each sub-pixel reads 8 x this many texels.
MAX_FILL_GAP = 12
#: Depth tolerance of the ``fill`` pass in pixels: two pixels' surfaces are apart where their depths
#: differ by more than ``FILL_DEPTH_PX * z / focal_px`` (the depth a surface at 83 degrees to the
#: viewing ray changes by across the widest gap): a hole's pixels showing a surface farther behind are
#: filled from the front surface around them; a valley of one surface is left as it is.
FILL_DEPTH_PX = 24.0
#: How much longer than the gap a crack may run along the one axis that does not enclose a pixel enclosed
#: along the 3 others (``fill.frag``'s FILL_REACH = this times the gap): a crack of up to 9 pixels (at
#: K = 1) is closed; a slit or bay opening into the background beyond a silhouette is not (frag's jagged
#: scan border: 16 pixels of real background slits were filled with 3 axes alone).
FILL_REACH_FACTOR = 3
#: Passes of the ``fill`` rule, each on the last one's pixels (a later pass fills the pixels only the
#: earlier ones' fills enclose). One: on the default 512 x 512 pictures of the bunny, the CAD part, frag,
#: the LAS sample, the torus and a faulty scan, further passes filled more only among the faulty scan's
#: random vegetation points (174 pixels, 233 with two, 270 with five), and each costs as much as the first
#: (37 ms at 512 x 512 on llvmpipe, the torus; its normalization pass: 13 ms).
FILL_ITERATIONS = 1
#: Side in pixels of the blocks whose farthest visible depth the accumulation pass's vertex shaders test
#: each splat against (``HizPass``, ``hiz.glsl``: a splat behind it wherever its box reaches is not drawn;
#: boxes over more than 2 x 2 blocks are drawn). 0: no such test.
HIZ_BLOCK = 8
#: Texture unit of the ``hiz`` target during the accumulation pass.
HIZ_TEXTURE_UNIT = 6
#: Texture units of the normalization pass's three targets during the ``fill`` pass.
NORM_COLOR_UNIT, NORM_DEPTH_UNIT, NORM_Z_UNIT = 0, 1, 2


def fill_depth(gap: int) -> float:
    """The ``fill`` pass's depth tolerance in the sub-pixels of a frame filling gaps of ``gap`` sub-pixels:
    :data:`FILL_DEPTH_PX` scaled as the gap (the same slopes at any supersampling)."""
    return FILL_DEPTH_PX * gap / FILL_GAP_PX


def fill_reach(gap: int) -> int:
    """The farthest the ``fill`` pass looks along a pixel's 4th axis, sub-pixels (:data:`FILL_REACH_FACTOR`)."""
    return FILL_REACH_FACTOR * int(gap)


def fill_gap(options: RenderOptions, supersample: int = 1) -> int:
    """The widest gap the ``fill`` pass fills, in sub-pixels (0: no fill pass)."""
    return min(FILL_GAP_PX * int(supersample), MAX_FILL_GAP) if options.fill_holes else 0


def point_scale(camera: Camera, technique: Technique, options: RenderOptions, supersample: int = 1,
                point_px: float = POINT_SPLAT_PX) -> float:
    """The largest splat radius drawn as a GL_POINTS point, per unit of depth (both in the units of
    ``camera``, the GPU frame's): a splat of radius r nearer than z is a point where ``r <= scale * z``,
    its window box at most ``point_px`` sub-pixels wide anywhere in the view (0: every splat is a quad,
    also where the technique declares no ``point_footprint``).

    The box of a splat of radius r at depth z is at most ``2 sqrt(2) r f / (z cos phi)`` wide (the
    parallelogram's corners; phi the largest angle off the axis in the image) plus a pixel of rounding;
    a "filtered_disk" footprint adds its prefilter (Guennebaud 2003, eq. 6: ``+ 2 sqrt(2 c h)``); an
    "adaptive" one is a round point ``2 r f / z`` wide, at least ``min_point_px`` output pixels. The
    estimate only selects the primitive: a point's fragments are tested as exactly as a quad's.
    """
    footprint = technique.point_footprint
    if footprint is None or point_px <= 0:
        return 0.0
    f = float(camera.focal_px)
    stretch = float(np.hypot(1.0, np.hypot(camera.width, camera.height) / (2.0 * f)))   # 1 / cos(phi)
    side = point_px - 1.0
    if footprint == "filtered_disk":
        side -= 2.0 * np.sqrt(2.0 * options.filter.cutoff * prefilter_variance(options.filter.prefilter))
    if footprint == "adaptive":
        side = point_px - 1.0   # the diameter 2 r f / z, clamped from below by the smallest size
        if technique.min_point_px * supersample > side:
            return 0.0
        return side / (2.0 * f * stretch)
    return max(side, 0.0) / (2.0 * np.sqrt(2.0) * f * stretch)


def point_radius(camera: Camera, splats: GpuSplats, technique: Technique, options: RenderOptions,
                 supersample: int = 1, point_px: float = POINT_SPLAT_PX) -> float:
    """Largest splat radius (GPU units) drawn as a GL_POINTS point anywhere in this frame
    (:func:`point_scale` at the nearest depth of the splats' bounds, at least the near plane's;
    ``camera``: the GPU frame's; 0: every splat is a quad). Blocks farther away may be points with
    larger splats (``Renderer._drawn_ranges``)."""
    scale = point_scale(camera, technique, options, supersample, point_px)
    if scale <= 0:
        return 0.0
    lo, hi = splats.gpu_bounds
    lo, hi = lo - splats.max_radius * splats.scale, hi + splats.max_radius * splats.scale
    corners = np.array(list(itertools.product(*zip(lo, hi))))
    view = camera.view_matrix
    depth = -(corners @ view[:3, :3].T + view[:3, 3])[:, 2]
    return scale * max(float(camera.near), float(depth.min()))


def computes_first_pass(technique: Technique, options: RenderOptions, has_compute: bool) -> bool:
    """Whether a frame runs the small splats' first pass as compute shaders: the technique declares it
    (``compute_visibility`` if blended, ``compute_opaque`` if opaque), ``options.compute`` asks for it and
    the context has OpenGL 4.3 (``has_compute``)."""
    declared = technique.compute_visibility if technique.blended else technique.compute_opaque
    return bool(options.compute and has_compute and declared)


def uses_edge_coverage(technique: Technique, options: RenderOptions) -> bool:
    """Whether a frame writes and reads the splats' pixel coverage: asked for and declared."""
    return bool(technique.edge_coverage and options.visibility.edge_coverage)


@dataclass(frozen=True)
class FrameInputs:
    """What the passes of one frame read.

    Attributes:
        splats: the GPU splats drawn.
        technique: the technique drawing them.
        targets: the renderer's targets of the tile's size (``Renderer._ensure_targets``).
        frame: the frame-wide uniforms (``Renderer.frame_uniforms``) set per program: those not in the
            frame's uniform blocks (``Renderer.bind_frame_uniforms``, bound before the passes run).
        uniforms: ``frame``, the technique's and the splats' own uniforms: those of the splat programs.
        optional: uniform names the splat programs may lack.
        defines: the splat programs' defines (the splats' and ``EDGE_COVERAGE``).
        accumulation: the framebuffer of the accumulation (or opaque) pass.
        output: the framebuffer the last pass (normalization or fill) writes; None: the ``out`` targets.
        background: RGB in [0, 1].
    """

    splats: GpuSplats
    technique: Technique
    targets: dict
    frame: dict
    uniforms: dict
    optional: frozenset
    defines: dict
    accumulation: moderngl.Framebuffer
    output: moderngl.Framebuffer
    background: tuple


@dataclass(frozen=True)
class ClearPass:
    """Clear the accumulation targets (with the coverage target where edge coverage writes it: only the
    targets a frame writes are cleared) and, for a blended technique, the visibility record."""

    name: ClassVar[str] = "clear"
    visibility: bool

    def run(self, renderer, frame: FrameInputs) -> None:
        accumulation = frame.accumulation
        accumulation.use()
        accumulation.depth_mask = True
        accumulation.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if self.visibility:   # no disk (glsl/visibility.glsl)
            frame.targets["fbo_visibility"].clear(NO_DEPTH, NO_DEPTH, 0.0, 0.0)
        renderer.ctx.enable(moderngl.DEPTH_TEST)
        renderer.ctx.disable(moderngl.CULL_FACE)


@dataclass(frozen=True)
class SplatPass:
    """A raster pass of the technique's program (``PASS``): the ``quads`` ranges as instanced quads, the
    ``points`` ranges as GL_POINTS (the large splats first in the buffers, then the small ones)."""

    name: ClassVar[str] = ""
    pass_id: ClassVar[int] = PASS_OPAQUE
    quads: tuple = ()
    points: tuple = ()

    def run(self, renderer, frame: FrameInputs) -> None:
        self.begin(renderer, frame)
        ctx, technique = renderer.ctx, frame.technique
        defines, uniforms = {"PASS": self.pass_id} | frame.defines | self.defines(), frame.uniforms | self.uniforms()
        if self.quads:
            program = renderer.program(technique.vertex, technique.fragment, defines)
            renderer.set_uniforms(program, uniforms, frame.optional)
            for start, count in self.quads:
                renderer._draw_quads(frame.splats, program, technique, count, start)
        if self.points:
            program = renderer.program(technique.vertex, technique.fragment, defines | {"POINT_PRIMITIVE": 1})
            renderer.set_uniforms(program, uniforms | {"u_max_point": renderer._max_point}, frame.optional)
            ctx.enable(moderngl.PROGRAM_POINT_SIZE)
            renderer._draw_points(frame.splats, program, technique, self.points)
            ctx.disable(moderngl.PROGRAM_POINT_SIZE)

    def begin(self, renderer, frame: FrameInputs) -> None:
        """The pass's framebuffer and fixed-function state."""

    def defines(self) -> dict:
        """The pass's own defines of the technique's programs (beyond ``PASS`` and the frame's)."""
        return {}

    def uniforms(self) -> dict:
        """The pass's own uniforms of the technique's programs (beyond the frame's)."""
        return {}


@dataclass(frozen=True)
class VisibilityPass(SplatPass):
    """Blended pass 1: per pixel the nearest depths by MIN blending (``visibility.glsl``)."""

    name: ClassVar[str] = "visibility"
    pass_id: ClassVar[int] = PASS_VISIBILITY

    def begin(self, renderer, frame: FrameInputs) -> None:
        frame.targets["fbo_visibility"].use()
        renderer.ctx.disable(moderngl.DEPTH_TEST)
        renderer.ctx.enable(moderngl.BLEND)
        renderer.ctx.blend_equation = moderngl.MIN


@dataclass(frozen=True)
class AccumulationPass(SplatPass):
    """Blended pass 2: additive blending, tested against the cracks-marked visibility record."""

    name: ClassVar[str] = "accumulation"
    pass_id: ClassVar[int] = PASS_ACCUMULATION
    hiz_block: int = 0   # a HizPass ran: whole splats behind its blocks' depths are not drawn (hiz.glsl)

    def begin(self, renderer, frame: FrameInputs) -> None:
        ctx = renderer.ctx
        frame.targets["cracks"].use(location=SIDE_TEXTURE_UNIT)
        if self.hiz_block:
            frame.targets["hiz"].use(location=HIZ_TEXTURE_UNIT)
        fbo = frame.accumulation
        fbo.use()
        fbo.depth_mask = False
        ctx.disable(moderngl.DEPTH_TEST)   # the shaders' test (behind_nearest, splat_fragment.glsl)
        ctx.enable(moderngl.BLEND)
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.blend_func = moderngl.ONE, moderngl.ONE

    def defines(self) -> dict:
        return {"HIZ_BLOCK": self.hiz_block} if self.hiz_block else {}

    def uniforms(self) -> dict:
        return {"u_hiz": HIZ_TEXTURE_UNIT} if self.hiz_block else {}


@dataclass(frozen=True)
class HizPass:
    """After the cracks pass: the farthest visible depth of each ``block`` x ``block`` block of the record
    (``hiz.frag``), which the accumulation pass's vertex shaders test whole splats against (``hiz.glsl``)."""

    name: ClassVar[str] = "hiz"
    block: int = HIZ_BLOCK

    def run(self, renderer, frame: FrameInputs) -> None:
        ctx, targets = renderer.ctx, frame.targets
        vao = renderer._fullscreen_pass("hiz.frag", {"HIZ_BLOCK": int(self.block)})
        ctx.disable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND)
        renderer.hiz_framebuffer(int(self.block)).use()
        targets["cracks"].use(location=SIDE_TEXTURE_UNIT)
        renderer.set_uniforms(vao.program, {"u_side": SIDE_TEXTURE_UNIT})
        vao.render(moderngl.TRIANGLES, vertices=3)


@dataclass(frozen=True)
class OpaquePass(SplatPass):
    """The one pass of an opaque technique: a plain z-buffer."""

    name: ClassVar[str] = "opaque"
    pass_id: ClassVar[int] = PASS_OPAQUE

    def begin(self, renderer, frame: FrameInputs) -> None:
        fbo = frame.accumulation
        fbo.use()
        fbo.depth_mask = True
        renderer.ctx.enable(moderngl.DEPTH_TEST)
        renderer.ctx.depth_func = "<"
        renderer.ctx.disable(moderngl.BLEND)


def _compute(renderer, frame: FrameInputs, ranges: tuple, compute_pass: int, defines: dict | None = None,
             uniforms: dict | None = None) -> None:
    """One pass of ``visibility.comp`` (``compute_pass``, with ``defines`` and ``uniforms`` of its own) over
    the splats of ``ranges``."""
    program = renderer.compute_program("visibility.comp", compute_visibility.shader_defines(
        frame.splats.buffers, frame.defines | (defines or {}), compute_pass))
    renderer.set_uniforms(program, frame.uniforms, optional=frame.uniforms)   # the frame's, where declared
    renderer.set_uniforms(program, uniforms or {})
    compute_visibility.dispatch(program, frame.splats.buffers, list(ranges))


@dataclass(frozen=True)
class ComputeVisibilityPass:
    """Blended pass 1 of the small splats as compute shaders (into the two depth images)."""

    name: ClassVar[str] = "compute_visibility"
    computed: tuple = ()

    def run(self, renderer, frame: FrameInputs) -> None:
        compute_visibility.begin(frame.targets)
        _compute(renderer, frame, self.computed, compute_visibility.COMPUTE_VISIBILITY_PASS)


@dataclass(frozen=True)
class CracksPass:
    """Between visibility and accumulation: the visibility record copied into the ``cracks`` target with
    the uncovered pixels between covered ones marked (``cracks.frag``); ``computed``: with the compute
    visibility pass's depths."""

    name: ClassVar[str] = "cracks"
    computed: bool = False

    def run(self, renderer, frame: FrameInputs) -> None:
        ctx, targets = renderer.ctx, frame.targets
        defines = {compute_visibility.COMPUTE_VISIBILITY_DEFINE: 1} if self.computed else {}
        vao = renderer._fullscreen_pass("cracks.frag", defines)
        ctx.disable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND)
        targets["fbo_cracks"].use()
        targets["side"].use(location=SIDE_TEXTURE_UNIT)
        uniforms = {"u_side": SIDE_TEXTURE_UNIT}   # viewport and tile: the Camera block
        if self.computed:
            units = compute_visibility.bind_images(ctx, targets)
            uniforms |= {"u_front_depth": units[0], "u_back_depth": units[1]}
        renderer.set_uniforms(vao.program, uniforms)
        vao.render(moderngl.TRIANGLES, vertices=3)


@dataclass(frozen=True)
class ComputeOpaquePass:
    """The small splats of an opaque technique into the bound targets, with the depth test on: per pixel
    the nearest disk's depth, then the first splat at that depth (two compute passes), then
    ``opaque_resolve.frag`` writes its fragment. After the raster splats: they win ties."""

    name: ClassVar[str] = "compute_opaque"
    computed: tuple = ()
    hiz_block: int = 0   # between the two: the first's depths per block, the second skips splats behind them

    def run(self, renderer, frame: FrameInputs) -> None:
        splats, ctx = frame.splats, renderer.ctx
        compute_visibility.begin(frame.targets)
        _compute(renderer, frame, self.computed, compute_visibility.COMPUTE_OPAQUE_DEPTH)
        ctx.memory_barrier()
        index_defines = {}
        if self.hiz_block:
            units = compute_visibility.bind_images(ctx, frame.targets)
            vao = renderer._fullscreen_pass("hiz.frag", {"HIZ_BLOCK": self.hiz_block, "OPAQUE_DEPTH": 1})
            ctx.disable(moderngl.DEPTH_TEST)
            renderer.hiz_framebuffer(self.hiz_block).use()
            renderer.set_uniforms(vao.program, {"u_opaque_depth": units[0]})
            vao.render(moderngl.TRIANGLES, vertices=3)
            frame.accumulation.use()   # the opaque pass's framebuffer and depth test, for the resolve
            ctx.enable(moderngl.DEPTH_TEST)
            frame.targets["hiz"].use(location=HIZ_TEXTURE_UNIT)
            index_defines = {"HIZ_BLOCK": self.hiz_block}
        _compute(renderer, frame, self.computed, compute_visibility.COMPUTE_OPAQUE_INDEX, index_defines,
                 {"u_hiz": HIZ_TEXTURE_UNIT} if self.hiz_block else {})
        units = compute_visibility.bind_images(renderer.ctx, frame.targets)
        vao = renderer._fullscreen_pass("opaque_resolve.frag", compute_visibility.shader_defines(
            splats.buffers, frame.defines) | {"READ_COLOR": 1}, COMPUTE_GLSL_VERSION)
        renderer.set_uniforms(vao.program, frame.uniforms | {"u_opaque_depth": units[0],
                                                             "u_opaque_index": units[1]}, optional=frame.uniforms)
        compute_visibility.bind_buffers(splats.buffers)
        vao.render(moderngl.TRIANGLES, vertices=3)


@dataclass(frozen=True)
class NormalizationPass:
    """Pass 3 (Guennebaud 2003, eq. 18): the accumulated sums divided by the weight into the output;
    ``side``: the target holding each pixel's nearest disk (``cracks`` after a visibility pass, else
    ``side``); ``edge_coverage``: compiled with ``EDGE_COVERAGE``; ``edge_fringe``: the technique's
    footprints reach beyond its disks (``u_edge_fringe``)."""

    name: ClassVar[str] = "normalization"
    side: str = "cracks"
    edge_coverage: bool = False
    edge_fringe: bool = False
    filled: bool = False   # a fill pass follows: write the ``norm`` targets it reads

    def run(self, renderer, frame: FrameInputs) -> None:
        ctx, targets = renderer.ctx, frame.targets
        frame.accumulation.depth_mask = True
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.disable(moderngl.BLEND)
        ctx.disable(moderngl.DEPTH_TEST)
        out = targets["fbo_norm"] if self.filled else frame.output or targets["fbo_out"]
        out.use()
        vao = renderer._fullscreen_pass("normalize.frag", {EDGE_COVERAGE_DEFINE: 1} if self.edge_coverage else {})
        targets["accum"].use(location=0)
        targets["aux"].use(location=1)
        targets[self.side].use(location=SIDE_TEXTURE_UNIT)
        targets["cover"].use(location=COVER_TEXTURE_UNIT)
        renderer.set_uniforms(vao.program, frame.frame | {"u_accum": 0, "u_aux": 1, "u_side": SIDE_TEXTURE_UNIT,
                                                          "u_cover": COVER_TEXTURE_UNIT,
                                                          "u_edge_fringe": self.edge_fringe,
                                                          "u_background": tuple(map(float, frame.background))},
                              OPTIONAL_FRAME_UNIFORMS)
        vao.render(moderngl.TRIANGLES, vertices=3)


@dataclass(frozen=True)
class FillPass:
    """After the normalization pass: the holes between front-surface pixels of up to ``gap`` sub-pixels
    filled from the front surface around them (``fill.frag``; :func:`surfsplat.reference.fill_holes`),
    ``iterations`` times (each reads the last one's pixels: the pixels a hole's first fill encloses)."""

    name: ClassVar[str] = "fill"
    gap: int = FILL_GAP_PX
    iterations: int = FILL_ITERATIONS

    def run(self, renderer, frame: FrameInputs) -> None:
        ctx, targets = renderer.ctx, frame.targets
        ctx.disable(moderngl.BLEND)
        ctx.disable(moderngl.DEPTH_TEST)
        vao = renderer._fullscreen_pass("fill.frag", {"FILL_GAP": int(self.gap), "FILL_REACH": fill_reach(self.gap)})
        renderer.set_uniforms(vao.program, {"u_norm_color": NORM_COLOR_UNIT, "u_norm_depth": NORM_DEPTH_UNIT,
                                            "u_norm_z": NORM_Z_UNIT, "u_fill_depth": fill_depth(self.gap)})
        pairs = ("norm", "fill")   # ping-pong: norm -> fill -> norm ... -> the output
        for i in range(self.iterations):
            source = pairs[i % 2]
            last = i == self.iterations - 1
            (frame.output or targets["fbo_out"] if last else targets[f"fbo_{pairs[(i + 1) % 2]}"]).use()
            targets[f"{source}_color"].use(location=NORM_COLOR_UNIT)
            targets[f"{source}_depth"].use(location=NORM_DEPTH_UNIT)
            targets[f"{source}_z"].use(location=NORM_Z_UNIT)
            vao.render(moderngl.TRIANGLES, vertices=3)


@dataclass(frozen=True)
class FramePlan:
    """The passes of one frame, in order (:func:`plan_frame`)."""

    passes: tuple

    @property
    def names(self) -> tuple[str, ...]:
        """The passes' names, in order."""
        return tuple(step.name for step in self.passes)

    def get(self, name: str):
        """The pass called ``name``; None where the frame has none."""
        return next((step for step in self.passes if step.name == name), None)

    @property
    def edge_coverage(self) -> bool:
        """Whether the frame writes and reads the splats' pixel coverage."""
        return bool(self.get("normalization").edge_coverage)


def plan_frame(technique: Technique, options: RenderOptions, quads: list, points: list,
               computed: list | None = None, raster: tuple[list, list] | None = None,
               supersample: int = 1) -> FramePlan:
    """The passes of a frame of ``technique`` drawing the splat ranges ``quads`` (instanced quads) and
    ``points`` (GL_POINTS), from the technique's declarations and ``options``.

    ``computed``: the ranges whose first pass runs as compute shaders (where
    :func:`computes_first_pass` holds) and ``raster``: the ``(quads, points)`` left to that pass's
    raster draw; None: every splat is drawn. The accumulation pass draws every splat.
    """
    edges = uses_edge_coverage(technique, options)
    raster = (quads, points) if raster is None else raster
    computed = tuple(computed or ())
    vis_quads, vis_points = (tuple(r) for r in raster)
    steps: list = [ClearPass(visibility=technique.blended)]
    if technique.blended:
        if computed:
            steps.append(ComputeVisibilityPass(computed))
        steps += [VisibilityPass(vis_quads, vis_points), CracksPass(bool(computed))]
        if HIZ_BLOCK > 0 and technique.hiz_cull:
            steps.append(HizPass(HIZ_BLOCK))
        steps.append(AccumulationPass(tuple(quads), tuple(points), hiz_block=HIZ_BLOCK if technique.hiz_cull else 0))
    else:
        steps.append(OpaquePass(vis_quads, vis_points))
        if computed:
            steps.append(ComputeOpaquePass(computed, HIZ_BLOCK))
    gap = fill_gap(options, supersample)
    steps.append(NormalizationPass("cracks" if technique.blended else "side", edges, technique.edge_fringe, gap > 0))
    if gap > 0:
        steps.append(FillPass(gap, FILL_ITERATIONS))
    return FramePlan(tuple(steps))
