"""The renderer: GPU buffers of a SplatCloud and the pipeline's passes (DESIGN.md).

1. visibility: depth only, offset by epsilon along the viewing rays, with the
   exact per-fragment depth of each splat's plane (Guennebaud 2003, sec. 5), and per pixel the
   side and offset depth of the nearest disk (``glsl/visibility.glsl``); a full-screen pass then
   marks the uncovered pixels between covered ones (``cracks.frag``);
2. accumulation: depth test against pass 1 without depth writes, additive
   blending of ``(w * color, w)`` and ``(w * depth, w * normal)`` into float targets;
3. normalization: a full-screen pass dividing by the accumulated weight (eq. 18).

Opaque techniques draw once with a plain z-buffer and share pass 3. Each frame's passes are planned
from the technique's declared capabilities (``technique.py``) and the options, then run in order
(:mod:`~surfsplat.rendering.passes`, :meth:`Renderer.plan`).

Speed and memory (benchmarks/bench_render.py): splats are uploaded ordered by radius class, so each
frame draws the large ones as instanced quads (tight boxes) and the small ones as GL_POINTS (where the
technique declares a ``point_footprint``), one vertex per splat (``point_radius``, ``splat_primitive.glsl``),
in draw calls of ``draw_batch`` splats; the read-back is the normalization pass's color, weight, depth sum
and alpha only (24 bytes per sub-pixel), read into reused buffers and written straight into the Frame's
top-down rows. What llvmpipe pays for is
fragments (``benchmarks/results/render_passes.md``): a disk's window box is its ellipse's exact box
(``disk_vertex.glsl``), options that add work to every fragment are defines (``EDGE_COVERAGE``:
llvmpipe runs a branch on a false uniform), a fragment reads one texel of the visibility record, and
only the targets a frame writes are attached and cleared.

The process-wide renderer of the headless context is :func:`default_renderer`
(created on first use); :func:`reset_default_renderer` releases it and the context.
"""

from __future__ import annotations

import warnings
import zlib
from pathlib import Path
from typing import Iterable, Sequence

import moderngl
import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError, RenderError
from ..io.atomic import memory_limit
from ..lighting import MAX_LIGHTS, Lights
from .context import gl_flush, headless_context, reset_headless_context
from . import compute_visibility
from .passes import (EDGE_COVERAGE_DEFINE, OPTIONAL_FRAME_UNIFORMS, POINT_SPLAT_PX, SIDE_TEXTURE_UNIT, FrameInputs,
                     FILL_ITERATIONS, FramePlan, computes_first_pass, fill_gap, fill_reach, plan_frame, point_radius,
                     point_scale)
from .edl import apply_edl
from .frame import Frame
from .gpu_splats import GpuSplats, merge_ranges, ordered_buffers, radius_classes, splat_arrays
from .options import RenderOptions
from .shaders import (GLSL_VERSION, PASS_ACCUMULATION, PASS_OPAQUE, PASS_VISIBILITY,
                      BuiltProgram, build_compute, build_program, undeclared)
from .technique import Technique
from .tiles import MAX_TILE, SubPixels, box_reduce, check_supersample, tile_rects, tile_side
from .techniques import get_technique
from .uniform_blocks import FrameBlocks

__all__ = ["GpuSplats", "Renderer", "default_renderer", "reset_default_renderer", "OPTIONAL_FRAME_UNIFORMS",
           "PASS_OPAQUE", "PASS_VISIBILITY", "PASS_ACCUMULATION", "POINT_SPLAT_PX", "point_radius", "point_scale"]

#: Pixels drawn around each tile and cropped (fringe clipping looks at each pixel's neighbours; the
#: edge coverage of normalize.frag at the neighbours, up to 4 sub-pixels away at K = 8, of its neighbours);
#: a frame with the fill pass adds its reach per iteration (``passes.fill_reach``: it reads the pixels that far).
TILE_MARGIN = 5
#: Memory a render holds per splat (the upload's sorting and copies, the driver's buffers and one draw
#: call's primitives; measured on llvmpipe by benchmarks/bench_render.py --memory: 31-83 B per splat,
#: 1M and 5M splats; these add margin), per output pixel (the Frame, the image a caller writes) and per
#: sub-pixel of a tile (the targets, 156 B with the compute passes' two images and the fill pass's two
#: sets, and the read-back buffers, 24 B): :func:`render_memory`.
BYTES_PER_SPLAT = 160
BYTES_PER_PIXEL = 100
BYTES_PER_SUBPIXEL = 184


def render_memory(splats: int, width: int, height: int, supersample: int = 1, max_tile: int = MAX_TILE) -> int:
    """Estimated bytes :meth:`Renderer.render` holds for ``splats`` splats and a width x height image."""
    tile = min(max_tile, width * supersample) * min(max_tile, height * supersample)
    return splats * BYTES_PER_SPLAT + width * height * BYTES_PER_PIXEL + tile * BYTES_PER_SUBPIXEL


def check_render_memory(splats: int, width: int, height: int, supersample: int = 1,
                        max_tile: int = MAX_TILE) -> None:
    """InputError, before anything is allocated, when the estimate of :func:`render_memory` exceeds the
    memory available (:func:`~surfsplat.io.atomic.memory_limit`)."""
    need, limit = render_memory(splats, width, height, supersample, max_tile), memory_limit()
    if need > limit:
        raise InputError(f"rendering {splats:,} splats at {width}x{height} pixels needs about {need / 2**20:,.0f} "
                         f"MiB, more than the {limit / 2**20:,.0f} MiB of memory available; render a smaller "
                         f"image, fewer splats (a hierarchy with --lod-tolerance) or free memory")


#: Pixels (of the drawn camera's, per sub-pixel factor) by which the view is grown before blocks of
#: splats outside it are skipped (``Renderer._drawn_ranges``): a filter's footprint reaches beyond
#: its disk by about its prefilter radius (sqrt(2 c h), 1.4 px by default) and a point is drawn at
#: least one pixel wide.
FRUSTUM_MARGIN_PX = 8.0
#: Splats per draw call: Mesa llvmpipe bins every primitive of a frame until the frame is flushed
#: (measured: 180 bytes per splat drawn as quads, 300 as points, 1M splats), so the splats are drawn in
#: batches, each handed to the driver by a glFlush and every :data:`FINISH_EVERY`-th waited for by a
#: glFinish: the driver holds a few batches' primitives at a time.
DRAW_BATCH = 1 << 17
#: Batches between two glFinish calls (a glFlush after the others). llvmpipe sets up a batch's
#: primitives on the calling thread and shades them on its own: without the wait the next batch's
#: setup overlaps the shading of the previous ones. Measured on the peers' 1M bunny at 1024x1024, ewa,
#: alternated: a glFinish after every batch 528 ms, every 4th 482 ms, none 446 ms; peak memory of 5M
#: and 10M splats at 256x256: unchanged every 4th, +0.86 GB with glFlush alone.
FINISH_EVERY = 4


def _components(splats: GpuSplats, name: str) -> int:
    """Floats per splat of the attribute buffer ``name``."""
    return splats.buffers[name].size // (4 * splats.count)


def _with_clip_planes(camera: Camera, splats: GpuSplats) -> Camera:
    """The camera with near/far set from the splats' bounds where it has none."""
    if camera.near is None or camera.far is None:
        return camera.with_clip_from_bounds(*splats.bounds, margin=splats.max_radius)
    return camera


def content_key(cloud: SplatCloud) -> tuple:
    """What tells two SplatClouds' GPU copies apart: each array's shape and CRC-32 and the origin (two
    clouds with the same key upload the same buffers; about 30 ms per million splats)."""
    arrays = [cloud.positions, cloud.normals, cloud.colors, cloud.u, cloud.v, cloud.clip_lines, cloud.normal_field]
    key = tuple(None if a is None else (a.shape, zlib.crc32(np.ascontiguousarray(a).data)) for a in arrays)
    return key + (np.asarray(cloud.origin, dtype=np.float64).tobytes(),)


class Renderer:
    """Renders SplatClouds with any technique of ``techniques.TECHNIQUES`` into Frames.

    Owns shader programs and render targets of one OpenGL context (the
    process-wide headless one unless a context is given, e.g. a window's).

    Args:
        ctx: the OpenGL context; default :func:`~surfsplat.rendering.context.headless_context`.
        search_path: folders searched for shader files before the package's
            ``glsl/`` (custom or experimental shaders; tests).
        point_px: splats whose window box is at most this many sub-pixels wide are drawn as
            GL_POINTS (:data:`POINT_SPLAT_PX`; 0: every splat as an instanced quad).
        draw_batch: splats per draw call (:data:`DRAW_BATCH`).

    Attributes:
        has_compute: the context runs the compute passes (OpenGL 4.3): frames use them where
            ``RenderOptions.compute`` asks (:mod:`~surfsplat.rendering.compute_visibility`).
    """

    def __init__(self, ctx: moderngl.Context | None = None, *, search_path: Sequence[Path] = (),
                 point_px: float = POINT_SPLAT_PX, draw_batch: int = DRAW_BATCH):
        self.ctx = ctx or headless_context()
        self.has_compute = compute_visibility.has_compute(self.ctx)
        self.point_px = float(point_px)
        self.draw_batch = max(1, int(draw_batch))
        self._uploaded: GpuSplats | None = None   # the last SplatCloud render() drew, and its checksums
        self._upload_key: tuple | None = None
        self.search_path = tuple(Path(p) for p in search_path)
        self._blocks = FrameBlocks(self.ctx, self.search_path)   # the frame's uniform blocks (camera, lights)
        self._programs: dict[tuple, BuiltProgram] = {}
        self._built: dict[int, BuiltProgram] = {}   # id(program) -> its BuiltProgram
        self._quad = self.ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, 1, 1], dtype="f4"))
        self._targets: dict | None = None
        self._non_finite, self._background = 0, np.ones(3, "f4")   # of the render in progress
        self._parking_rb = self.ctx.renderbuffer((1, 1))
        self._parking = self.ctx.framebuffer([self._parking_rb])
        self._fullscreen: dict[tuple, moderngl.VertexArray] = {}   # by (fragment shader, defines)
        self._max_point = float(self.ctx.info["GL_POINT_SIZE_RANGE"][1])
        self._unfinished = 0   # batches drawn since the last glFinish (_batch_drawn)

    # -- resources ---------------------------------------------------------

    def program(self, vertex: str, fragment: str, defines: dict[str, object] | None = None,
                version: str = GLSL_VERSION) -> moderngl.Program:
        """The linked program of two shader files with ``defines`` (built once, then cached).

        Files come from ``search_path``, then the package's ``glsl/``; see
        :func:`~surfsplat.rendering.shaders.compose` for includes and the shared defines. ``version``:
        the ``#version`` line (:data:`~surfsplat.rendering.shaders.COMPUTE_GLSL_VERSION` for the passes
        that read the attribute buffers, OpenGL 4.3).

        Raises:
            RenderError: the shaders failed to build; compiler positions name
                the shader file and line (``ewa.vert:8(3): error: ...``).
        """
        key = (vertex, fragment, tuple(sorted((defines or {}).items())))
        key += () if version == GLSL_VERSION else (version,)
        return self._built_once(key, lambda: build_program(self.ctx, vertex, fragment, dict(key[2]),
                                                           search_path=self.search_path, version=version))

    def _built_once(self, key: tuple, build) -> moderngl.Program | moderngl.ComputeShader:
        """The program cached under ``key``, made by ``build()`` (a BuiltProgram) the first time."""
        built = self._programs.get(key)
        if built is None:
            built = build()
            self._blocks.attach(built.program)
            self._programs[key] = built
            self._built[id(built.program)] = built
        return built.program

    def declared_uniforms(self, program: moderngl.Program) -> frozenset[str]:
        """Uniform names declared by the sources of a program built by :meth:`program` (used or not)."""
        return self._built_program(program).uniforms

    def _built_program(self, program: moderngl.Program) -> BuiltProgram:
        built = self._built.get(id(program))
        if built is None or built.program is not program:
            raise RenderError("this program was not built by this renderer (Renderer.program)")
        return built

    def park(self) -> None:
        """Bind the renderer's 1x1 framebuffer, which stays alive.

        Call it before releasing framebuffers you created on the renderer's
        context: moderngl re-binds the current framebuffer after creating one,
        so the bound framebuffer must not be one being freed.
        """
        self._parking.use()

    def release(self) -> None:
        """Free the renderer's GPU objects (programs, targets, buffers); it is unusable afterwards.
        The context stays (it may be shared, e.g. the headless one)."""
        self.forget_upload()
        self._release_targets()
        for vao in self._fullscreen.values():
            vao.release()
        self._fullscreen.clear()
        for built in self._programs.values():
            built.program.release()
        self._programs.clear()
        self._built.clear()
        self._quad.release()
        self._blocks.release()
        # leave the default framebuffer bound (see park): the parking framebuffer goes too
        (self.ctx.screen or self.ctx.detect_framebuffer(0)).use()
        self._parking.release()
        self._parking_rb.release()

    def upload(self, cloud: SplatCloud) -> GpuSplats:
        """Copy a preprocessed SplatCloud (normals and tangent axes present) to the GPU: float32, the
        positions relative to its origin, the splats ordered by radius class (:class:`GpuSplats`)."""
        if not cloud.has_splats:
            raise InputError("the SplatCloud has no normals or splat axes; run surfsplat.preprocess() first")
        if len(cloud) == 0:
            raise InputError("the SplatCloud is empty")
        radii = cloud.radii
        arrays, scale = splat_arrays(cloud, radii)
        radii = radii * np.float32(scale)
        order, class_start, class_radius = radius_classes(radii, cloud.positions)
        buffers, blocks, cones = ordered_buffers(self.ctx, arrays, order, radii)
        return GpuSplats(buffers, len(cloud), cloud.bounds(), float(class_radius[0]) / scale, blocks=blocks,
                         cones=cones,
                         class_start=class_start, class_radius=class_radius,
                         origin=np.asarray(cloud.origin, dtype=np.float64), scale=scale)

    def _upload_cached(self, cloud: SplatCloud, key: tuple | None = None) -> GpuSplats:
        """The GPU copy of ``cloud``: the last one :meth:`render` uploaded when its arrays hold the same
        bytes (:func:`content_key`, about 30 ms per million splats against several hundred for an upload:
        the frames of a turntable or a batch upload a cloud once; ``key``: computed by the caller
        already), else a new upload replacing it."""
        key = content_key(cloud) if key is None else key
        if self._upload_key != key or self._uploaded is None:
            self.forget_upload()
            self._uploaded = self.upload(cloud)
            self._upload_key = key
        return self._uploaded

    def forget_upload(self) -> None:
        """Free the GPU copy of the last SplatCloud :meth:`render` drew (kept for the next frame)."""
        if self._uploaded is not None:
            self._uploaded.release()
        self._uploaded, self._upload_key = None, None

    def _vao(self, splats: GpuSplats, program: moderngl.Program, technique: Technique,
             points: bool = False) -> moderngl.VertexArray:
        """The splats' vertex array for ``program``: one instance per splat of a quad's 4 corners, or
        (``points``) one vertex per splat."""
        key = id(program)
        if key not in splats._vaos:
            step = "" if points else "/i"
            content = [] if points else [(self._quad, "2f", "in_corner")]
            # attributes without a buffer keep OpenGL's default (0, 0, 0): no clip lines, no normal field
            content += [(splats.buffers[name], f"{_components(splats, name)}f{step}", f"in_{name}")
                        for name in technique.attributes + splats.extra_attributes
                        if f"in_{name}" in program and name in splats.buffers]
            splats._vaos[key] = self.ctx.vertex_array(program, content)
        return splats._vaos[key]

    def _drawn_ranges(self, splats: GpuSplats, camera: Camera, technique: Technique, options: RenderOptions,
                      supersample: int, tile: tuple | None = None) -> tuple[list, list]:
        """``(quads, points)``: the ``(first, count)`` ranges of splats a frame draws as instanced quads
        and as GL_POINTS (``camera``: the GPU frame's; ``tile``: the part of its image drawn, None: all).
        Per block of consecutive splats (:attr:`GpuSplats.blocks`), where the splats have them: those
        that cannot reach the tile are not drawn (:meth:`GpuSplats.visible_blocks`: a close view of a
        large model no longer runs the vertex shaders of the splats behind the eye, and each tile of a
        large image draws about its own splats), and a block of quads whose own nearest depth lets all
        its splats be points (:func:`point_scale`) is drawn as points (the global choice takes the
        nearest depth of the whole model)."""
        quads, points = splats.draw_ranges(camera, point_radius(camera, splats, technique, options, supersample,
                                                                self.point_px))
        visible = splats.visible_blocks(camera, FRUSTUM_MARGIN_PX * supersample, tile)
        if visible is None:
            return quads, points
        facing = splats.facing_blocks(camera) if options.visibility.cull_backfaces else None
        if facing is not None:   # blocks whose every splat the shaders would cull as back-facing
            visible &= facing
        quads, points = splats.split_blocks(quads, visible)[1], splats.split_blocks(points, visible)[1]
        scale = point_scale(camera, technique, options, supersample, self.point_px)
        if quads and scale > 0:
            as_points = splats.blocks[:, 6] <= scale * splats.block_depths(camera)
            quads, promoted = splats.split_blocks(quads, as_points)
            points = merge_ranges(points + promoted)
        return quads, points

    def _draw_quads(self, splats: GpuSplats, program: moderngl.Program, technique: Technique, count: int,
                    start: int = 0) -> None:
        """Splats ``start .. start + count`` as instanced quads, ``draw_batch`` instances per draw call
        (the splat attributes re-bound at the batch's offset: OpenGL 3.3 has no base instance)."""
        vao = self._vao(splats, program, technique)
        batch = self.draw_batch
        if count <= batch and start == 0:
            vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=count)
            return
        bound = [(program[f"in_{name}"].location, splats.buffers[name], _components(splats, name))
                 for name in technique.attributes + splats.extra_attributes
                 if f"in_{name}" in program and name in splats.buffers]

        def bind(first: int) -> None:
            for location, buffer, size in bound:
                vao.bind(location, "f", buffer, f"{size}f", offset=4 * size * first, stride=4 * size, divisor=1)

        for first in range(start, start + count, batch):
            bind(first)
            vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=min(batch, start + count - first))
            self._batch_drawn()
        bind(0)

    def _draw_points(self, splats: GpuSplats, program: moderngl.Program, technique: Technique,
                     ranges: Iterable[tuple[int, int]]) -> None:
        """The splats of ``ranges`` (``(first, count)``) as GL_POINTS, ``draw_batch`` per draw call."""
        vao = self._vao(splats, program, technique, points=True)
        for start, count in ranges:
            for first in range(start, start + count, self.draw_batch):
                vao.render(moderngl.POINTS, vertices=min(self.draw_batch, start + count - first), first=first)
                self._batch_drawn()

    def _batch_drawn(self) -> None:
        """After a batch of splats: a glFlush, and every :data:`FINISH_EVERY`-th batch (or where no glFlush
        is found) a glFinish."""
        self._unfinished += 1
        if self._unfinished >= FINISH_EVERY or not gl_flush():
            self.ctx.finish()
            self._unfinished = 0

    def _release_targets(self) -> None:
        if self._targets is not None:
            # moderngl re-binds the current framebuffer after creating one: park on
            # a framebuffer that stays alive, then free framebuffers before textures.
            self.park()
            for name in sorted(self._targets, key=lambda key: not key.startswith("fbo")):
                if hasattr(self._targets[name], "release"):
                    self._targets[name].release()
            self._targets = None

    def _ensure_targets(self, width: int, height: int) -> dict:
        if self._targets is None or self._targets["size"] != (width, height):
            self._release_targets()
            ctx, size = self.ctx, (width, height)
            accum = ctx.texture(size, 4, dtype="f4")
            aux = ctx.texture(size, 4, dtype="f4")
            depth = ctx.depth_texture(size)
            out = ctx.texture(size, 4, dtype="f4")         # normalized color, weight (normalize.frag)
            depth_sum = ctx.texture(size, 2, dtype="f4")   # weighted depth sum, coverage alpha
            cover = ctx.texture(size, 4, dtype="f4")   # soft maxima of the splats' pixel coverages, distances
            side = ctx.texture(size, 2, dtype="f4")   # side and offset depth of each pixel's nearest disk
            cracks = ctx.texture(size, 2, dtype="f4")   # the same with its cracks marked (cracks.frag)
            norm_color = ctx.texture(size, 4, dtype="f4")   # normalize.frag's, where the fill pass follows
            norm_depth = ctx.texture(size, 2, dtype="f4")
            norm_z = ctx.texture(size, 1, dtype="f4")   # the depth alone: what the fill pass searches
            fill_color = ctx.texture(size, 4, dtype="f4")   # between two iterations of the fill pass
            fill_depth = ctx.texture(size, 2, dtype="f4")
            fill_z = ctx.texture(size, 1, dtype="f4")
            for tex in (accum, aux, out, depth_sum, side, cracks, cover, norm_color, norm_depth, norm_z, fill_color,
                        fill_depth, fill_z):
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._targets = {
                "size": size, "accum": accum, "aux": aux, "depth": depth, "out": out, "depth_sum": depth_sum,
                "side": side, "cracks": cracks, "cover": cover, "norm_color": norm_color, "norm_depth": norm_depth,
                "norm_z": norm_z, "fill_color": fill_color, "fill_depth": fill_depth, "fill_z": fill_z,
                "fbo_visibility": ctx.framebuffer([side]),
                "fbo_cracks": ctx.framebuffer([cracks]),
                "fbo_accum": ctx.framebuffer([accum, aux], depth),
                "fbo_accum_cover": ctx.framebuffer([accum, aux, cover], depth),   # with edge coverage
                "fbo_out": ctx.framebuffer([out, depth_sum]),
                "fbo_norm": ctx.framebuffer([norm_color, norm_depth, norm_z]),
                "fbo_fill": ctx.framebuffer([fill_color, fill_depth, fill_z]),
            }
            if self.has_compute:
                self._targets |= compute_visibility.image_targets(ctx, size)
        return self._targets

    # -- drawing -----------------------------------------------------------

    def set_uniforms(self, program: moderngl.Program, values: dict, optional: Iterable[str] = ()) -> None:
        """Set uniforms of a program built by :meth:`program`.

        A name the program's sources do not declare raises RenderError unless
        it is in ``optional`` (a misspelled uniform is never silently dropped);
        declared names the compiler dropped as unused are skipped.
        """
        built = self._built_program(program)
        unknown = undeclared(values, built.uniforms, optional)
        if unknown:
            raise RenderError(f"shader {built.name} declares no uniform {', '.join(unknown)}")
        for name, value in values.items():
            if name in program:
                program[name].value = value

    def bind_frame_uniforms(self, values: dict) -> dict:
        """Write the frame's uniform blocks (``Camera``, ``Lighting``, ``Options``:
        :mod:`~surfsplat.rendering.uniform_blocks`)
        from ``values`` (e.g. :meth:`frame_uniforms` and ``u_tile``) and bind them for every program this
        renderer built; a block none of whose members is given is left as it is. Returns the other
        values: the uniforms each program still sets itself."""
        self._blocks.bind(values)
        return {name: value for name, value in values.items() if name not in self._blocks.members}

    def frame_uniforms(self, camera: Camera, lights: Lights, options: RenderOptions = RenderOptions(),
                       supersample: int = 1) -> dict:
        """The uniforms every splat program reads, for one frame: camera (``camera.glsl``), lights
        (``lighting.glsl``) and the visibility and deferred options; those of
        :data:`OPTIONAL_FRAME_UNIFORMS` are optional where set. ``camera`` needs near/far. All but
        ``u_side`` are members of the frame's uniform blocks (:meth:`bind_frame_uniforms`)."""
        view = camera.view_matrix
        dirs = lights.world_directions(camera) @ view[:3, :3].T
        padded = np.zeros((MAX_LIGHTS, 3))
        padded[: len(dirs)] = dirs
        return {
            "u_view": tuple(view.T.astype("f4").ravel()),  # column-major for GLSL
            "u_viewport": (float(camera.width), float(camera.height)),
            "u_focal": float(camera.focal_px),
            "u_near_far": (float(camera.near), float(camera.far)),
            "u_lighting": bool(lights.enabled),
            "u_num_lights": len(dirs),
            "u_light_dirs": [tuple(map(float, d)) for d in padded],
            "u_material": (lights.ambient, lights.diffuse, lights.specular, lights.shininess),
            "u_depth_epsilon": float(options.visibility.depth_epsilon),
            "u_cull_backfaces": bool(options.visibility.cull_backfaces),
            "u_separate_sides": bool(options.visibility.separate_sides),
            "u_clip_fringe": bool(options.visibility.clip_fringe),
            "u_side": SIDE_TEXTURE_UNIT,
            "u_deferred": bool(options.deferred),
            "u_supersample": float(supersample),   # sub-pixels per output pixel of ``camera``, per axis
        }

    def plan(self, splats: GpuSplats, camera: Camera, technique: Technique | str = "ewa",
             options: RenderOptions = RenderOptions(), tile: tuple[int, int, int, int] | None = None,
             supersample: int = 1) -> FramePlan:
        """The passes :meth:`draw` runs for this frame (``camera``: a world camera, as :meth:`draw`
        takes), with the splat ranges each draws (:mod:`~surfsplat.rendering.passes`)."""
        technique = get_technique(technique) if isinstance(technique, str) else technique
        camera = splats.gpu_camera(_with_clip_planes(camera, splats))
        return self._plan(splats, camera, technique, options, tile or (0, 0, camera.width, camera.height),
                          supersample)

    def _plan(self, splats: GpuSplats, camera: Camera, technique: Technique, options: RenderOptions,
              tile: tuple, supersample: int) -> FramePlan:
        """:meth:`plan` with ``camera`` the GPU frame's: the drawn ranges (:meth:`_drawn_ranges`) and,
        where the first pass runs as compute shaders, the blocks of small splats split off for it."""
        quads, points = self._drawn_ranges(splats, camera, technique, options, supersample, tile)
        if not computes_first_pass(technique, options, self.has_compute):
            return plan_frame(technique, options, quads, points, supersample=supersample)
        small = splats.small_blocks(camera, compute_visibility.COMPUTE_SPLAT_PX)
        (raster_quads, computed_quads), (raster_points, computed_points) = (splats.split_blocks(quads, small),
                                                                            splats.split_blocks(points, small))
        return plan_frame(technique, options, quads, points, computed_quads + computed_points,
                          (raster_quads, raster_points), supersample)

    def draw(self, splats: GpuSplats, camera: Camera, technique: Technique | str = "ewa",
             lights: Lights = Lights(), options: RenderOptions = RenderOptions(),
             background=(1.0, 1.0, 1.0), output: moderngl.Framebuffer | None = None,
             tile: tuple[int, int, int, int] | None = None, supersample: int = 1) -> None:
        """Run the passes of ``technique`` and write the normalized image to ``output``.

        The passes are planned from the technique's declarations and ``options`` (:meth:`plan`,
        :func:`~surfsplat.rendering.passes.plan_frame`), then run in order.
        ``output`` defaults to the renderer's float color target (read by
        :meth:`render`); a window passes its own framebuffer. ``tile`` ``(x0, y0, w, h)``
        (window pixels of the camera's image, y up) draws only that rectangle, into
        targets of its size (default: the whole image). ``supersample``: the sub-pixels per
        output pixel along each axis that ``camera`` is drawn at (``u_supersample``).
        """
        technique = get_technique(technique) if isinstance(technique, str) else technique
        camera = splats.gpu_camera(_with_clip_planes(camera, splats))   # world camera in, GPU frame out
        tile = tile or (0, 0, camera.width, camera.height)
        targets = self._ensure_targets(tile[2], tile[3])
        # the camera, the lights and the options: one buffer for every program of the frame
        frame = self.bind_frame_uniforms(self.frame_uniforms(camera, lights, options, supersample)
                                         | {"u_tile": tuple(map(float, tile))})
        plan = self._plan(splats, camera, technique, options, tile, supersample)
        edges = plan.edge_coverage
        inputs = FrameInputs(
            splats=splats, technique=technique, targets=targets, frame=frame,
            uniforms=frame | technique.uniforms(options) | splats.extra_uniforms(camera),
            optional=OPTIONAL_FRAME_UNIFORMS | technique.optional_uniforms,
            defines=splats.defines | ({EDGE_COVERAGE_DEFINE: 1} if edges else {}),
            # the cover target only where edge coverage writes it: a target is cleared and written per pixel
            accumulation=targets["fbo_accum_cover" if edges else "fbo_accum"],
            output=output, background=background)
        for step in plan.passes:
            step.run(self, inputs)

    def hiz_framebuffer(self, block: int) -> moderngl.Framebuffer:
        """The framebuffer of the ``hiz`` target (``passes.HizPass``): one texel per ``block`` x ``block``
        pixels of the current targets, made once per size."""
        targets = self._targets
        width, height = targets["size"]
        size = (-(-width // block), -(-height // block))
        if targets.get("hiz_size") != size:
            if "fbo_hiz" in targets:
                self.park()
                targets["fbo_hiz"].release()
                targets["hiz"].release()
            hiz = self.ctx.texture(size, 1, dtype="f4")
            hiz.filter = (moderngl.NEAREST, moderngl.NEAREST)
            targets |= {"hiz": hiz, "fbo_hiz": self.ctx.framebuffer([hiz]), "hiz_size": size}
        return targets["fbo_hiz"]

    def _fullscreen_pass(self, fragment: str, defines: dict | None = None,
                         version: str = GLSL_VERSION) -> moderngl.VertexArray:
        """The full-screen triangle drawn with a fragment shader (``normalize.frag``, ``cracks.frag``,
        ``opaque_resolve.frag``) and ``defines``, built once."""
        key = (fragment, tuple(sorted((defines or {}).items())), version)
        if key not in self._fullscreen:
            self._fullscreen[key] = self.ctx.vertex_array(self.program("fullscreen.vert", fragment, defines, version),
                                                          [])
        return self._fullscreen[key]

    def compute_program(self, name: str, defines: dict[str, object] | None = None) -> moderngl.ComputeShader:
        """The compute shader of a file with ``defines`` (built once, then cached; OpenGL 4.3)."""
        key = (name, None, tuple(sorted((defines or {}).items())))
        return self._built_once(key, lambda: build_compute(self.ctx, name, dict(key[2]), search_path=self.search_path))

    def _read_tile(self) -> SubPixels:
        """The tile's sub-pixels from the targets of the last :meth:`draw` (the normalization pass's
        two targets only: 24 bytes per sub-pixel), as views of buffers reused by the next tile."""
        targets = self._targets
        if "read_color" not in targets:   # read-back buffers, reused by every tile of this size
            width, height = targets["size"]
            targets["read_color"] = np.empty((height, width, 4), "f4")
            targets["read_depth"] = np.empty((height, width, 2), "f4")   # depth sum, alpha
        rgbw, depth_alpha = targets["read_color"], targets["read_depth"]
        targets["out"].read_into(rgbw)
        targets["depth_sum"].read_into(depth_alpha)
        color, weight = rgbw[..., :3], rgbw[..., 3]
        depth, alpha = depth_alpha[..., 0], depth_alpha[..., 1]
        # non-finite accumulations (degenerate splats, weight -1): normalize.frag shows the background
        # there; they count as empty and are reported by render()
        bad = weight < 0
        if bad.any():
            self._non_finite += int(np.count_nonzero(bad))
            weight[bad] = 0.0
            alpha[bad] = 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            np.divide(depth, weight, out=depth)
        depth[~(weight > 0)] = np.inf
        return SubPixels(color, weight, depth, alpha)

    def render(self, splats: GpuSplats | SplatCloud, camera: Camera, technique: Technique | str = "ewa",
               lights: Lights = Lights(), options: RenderOptions = RenderOptions(),
               background=(1.0, 1.0, 1.0), *, supersample: int = 1, max_tile: int = MAX_TILE,
               cloud_key: tuple | None = None) -> Frame:
        """Render into a :class:`Frame` (color, depth, weight, alpha as NumPy arrays).

        A SplatCloud is uploaded once for the frames that draw it (:meth:`_upload_cached`; ``cloud_key``:
        its :func:`content_key` where the caller has it already).

        ``supersample`` K (1..16, :func:`~surfsplat.rendering.tiles.check_supersample`): the image is drawn
        at K times the size and box-filtered per pixel (:mod:`surfsplat.rendering.tiles`); any size is drawn
        in tiles of at most ``max_tile`` sub-pixels. The EWA prefilter and the kernels act on the sub-pixels.
        """
        k = check_supersample(supersample)
        check_render_memory(len(splats) if isinstance(splats, SplatCloud) else splats.count, camera.width,
                            camera.height, k, max_tile)
        if isinstance(splats, SplatCloud):
            splats = self._upload_cached(splats, cloud_key)
        self._non_finite, self._background = 0, np.asarray(background, "f4")
        camera = _with_clip_planes(camera, splats)
        big = camera.resized(camera.width * k, camera.height * k)
        # pixels drawn around each tile and cropped: the full-screen passes read neighbours
        m = TILE_MARGIN + FILL_ITERATIONS * fill_reach(fill_gap(options, k))
        side = tile_side(self.ctx, k, max_tile, margin=m)
        w, h = camera.width, camera.height
        # Frame orientation (row 0 at the top): each tile's window rows are written flipped
        color = np.empty((h, w, 3), "f4")
        weight = np.empty((h, w), "f4")
        depth = np.empty((h, w), "f4")
        alpha = np.empty((h, w), "f4")
        for x0, y0, tw, th in tile_rects(big.width, big.height, side):
            self.draw(splats, big, technique, lights, options, background,
                      tile=(x0 - m, y0 - m, tw + 2 * m, th + 2 * m), supersample=k)
            block = np.s_[h - (y0 + th) // k:h - y0 // k, x0 // k:(x0 + tw) // k]
            flipped = (part[::-1] for part in box_reduce(self._read_tile().cropped(m), k))
            color[block], weight[block], depth[block], alpha[block] = flipped
        error = self.ctx.error
        if error != "GL_NO_ERROR":
            raise RenderError(f"OpenGL reported {error} while rendering")
        if self._non_finite:
            warnings.warn(f"{self._non_finite:,} sub-pixels got a non-finite splat weight, color or depth "
                          f"(degenerate splats?) and show the background", RuntimeWarning, stacklevel=2)
        if splats.scale != 1.0:
            depth /= np.float32(splats.scale)   # the GPU drew the model scaled (gpu_scale)
        if not (np.isfinite(color).all() and np.isfinite(weight).all() and np.isfinite(alpha).all()):
            raise RenderError("the rendered image has non-finite pixels")
        if options.edl is not None:   # after tiling: neighbours across tile borders (edl.py)
            color = apply_edl(color, depth, alpha, background, options.edl)
        return Frame(color, depth, weight, camera, alpha=alpha, background=tuple(map(float, background)))


_default: Renderer | None = None


def default_renderer() -> Renderer:
    """The process-wide :class:`Renderer` on the headless context (created on first use).

    ``surfsplat.render()``, ``render_mesh`` and the CLI draw with it, so shader
    programs are compiled once per process.
    """
    global _default
    if _default is None:
        _default = Renderer()
    return _default


def reset_default_renderer() -> None:
    """Release the default renderer and the process-wide headless context.

    Frees their GPU memory (programs, targets; the EGL context); the next
    :func:`default_renderer` creates both anew. Every other object on the
    headless context (other Renderers, GpuSplats, programs) is unusable
    afterwards. Nothing happens when neither exists.
    """
    global _default
    renderer, _default = _default, None
    if renderer is not None:
        renderer.release()
    reset_headless_context()
