"""The renderer: GPU buffers of a SplatCloud and the pipeline's passes (DESIGN.md).

1. visibility: depth only, offset by epsilon along the viewing rays, with the
   exact per-fragment depth of each splat's plane (Guennebaud 2003, sec. 5);
2. accumulation: depth test against pass 1 without depth writes, additive
   blending of ``(w * color, w)`` and ``(w * depth, w * normal)`` into float targets;
3. normalization: a full-screen pass dividing by the accumulated weight (eq. 18).

Opaque techniques draw once with a plain z-buffer and share pass 3.

The process-wide renderer of the headless context is :func:`default_renderer`
(created on first use); :func:`reset_default_renderer` releases it and the context.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Sequence

import moderngl
import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError, RenderError
from ..io.atomic import memory_limit
from ..lighting import MAX_LIGHTS, Lights
from .context import headless_context, reset_headless_context
from .edl import apply_edl
from .frame import Frame
from .options import RenderOptions
from .shaders import PASS_ACCUMULATION, PASS_OPAQUE, PASS_VISIBILITY, BuiltProgram, build_program, undeclared
from .technique import Technique
from .tiles import MAX_SUPERSAMPLE, MAX_TILE, SubPixels, box_reduce, tile_rects, tile_side
from .techniques import get_technique

__all__ = ["GpuSplats", "Renderer", "default_renderer", "reset_default_renderer", "OPTIONAL_FRAME_UNIFORMS",
           "PASS_OPAQUE", "PASS_VISIBILITY", "PASS_ACCUMULATION"]

#: The frame-wide uniforms (:meth:`Renderer.frame_uniforms`) that only the splat programs
#: declare: the normalization pass and the ground-truth mesh program lack them, so setting
#: them there is no error. This is the one documented optional set of frame-wide uniforms;
#: a technique lists its own optional ones in ``Technique.optional_uniforms``.
OPTIONAL_FRAME_UNIFORMS = frozenset({"u_depth_epsilon", "u_cull_backfaces", "u_deferred", "u_separate_sides",
                                     "u_side", "u_supersample", "u_clip_fringe"})
#: Pixels drawn around each tile and cropped (fringe clipping looks at each pixel's neighbours).
TILE_MARGIN = 1
#: Texture unit of the side target during the accumulation pass (units 0 and 1 serve pass 3).
SIDE_TEXTURE_UNIT = 2
#: Memory a render holds per splat (host copies and the driver's buffers; measured on llvmpipe: about 93 B per
#: splat, 145 B per pixel at 1024x1024, 400 MB for 1M splats at 1024x1024; these add margin),
#: per output pixel (the Frame, its flipped copies, the image written) and per sub-pixel of a tile
#: (the float targets, their read-back): :func:`render_memory`.
BYTES_PER_SPLAT = 320
BYTES_PER_PIXEL = 100
BYTES_PER_SUBPIXEL = 80


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


@dataclass
class GpuSplats:
    """A SplatCloud uploaded to the GPU: one buffer per attribute, float32.

    The buffers hold the cloud's local coordinates times ``scale`` (a power of two, see
    :func:`gpu_scale`); ``origin`` (float64) is the cloud's world position of its zero, ``bounds``
    and ``max_radius`` are in world units. Cameras given to the renderer are world cameras:
    :meth:`local_camera` is the view the GPU draws with.
    """

    buffers: dict[str, moderngl.Buffer]
    count: int
    bounds: tuple[np.ndarray, np.ndarray]
    max_radius: float
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float = 1.0
    _vaos: dict = field(default_factory=dict)

    def local_camera(self, camera: Camera) -> Camera:
        """The world ``camera`` in the buffers' frame: eye and target moved by ``-origin`` in float64,
        then scaled by ``scale`` (exact: a power of two), so the GPU composes its float32 transform
        from numbers of the size of the model wherever it sits."""
        return camera.translated(-self.origin).scaled(self.scale)

    def release(self) -> None:
        """Free the GPU buffers."""
        for vao in self._vaos.values():
            vao.release()
        for buffer in self.buffers.values():
            buffer.release()
        self._vaos.clear()
        self.buffers.clear()


#: Largest magnitude of a splat's coordinates and axes: their squares stay finite in float32.
MAX_COORDINATE = 1e18

#: Local extents (model units) the renderer draws as they are; a model outside this range is drawn
#: scaled by a power of two to about unit size (:func:`gpu_scale`): the shaders' products of axes
#: (a splat's normal is ``u x v``, its squared length a 4th power) leave float32's range for
#: splat radii below ~1e-9 or above ~1e9; within 1e-6..1e6 the picture is drawn bit for bit as given.
GPU_EXTENT_RANGE = (2.0 ** -20, 2.0 ** 20)


def gpu_scale(cloud: SplatCloud) -> float:
    """The power of two the renderer scales a cloud's local coordinates (and the camera) by: 1 when
    their extent (and largest splat radius) is within :data:`GPU_EXTENT_RANGE`, else the one
    bringing it to about 1 (exact in float32)."""
    if len(cloud) == 0:
        return 1.0
    lo, hi = cloud.positions.min(axis=0), cloud.positions.max(axis=0)
    extent = float(np.max(hi.astype(np.float64) - lo))
    if cloud.u is not None:
        extent = max(extent, float(cloud.radii.max()))
    if not np.isfinite(extent) or extent <= 0 or GPU_EXTENT_RANGE[0] <= extent <= GPU_EXTENT_RANGE[1]:
        return 1.0
    return float(2.0 ** -np.round(np.log2(extent)))


def _check_gpu_values(arrays: dict[str, np.ndarray]) -> None:
    """InputError for splats the GPU cannot draw: non-finite values, zero normals, coordinates or axes
    beyond :data:`MAX_COORDINATE` (``SplatCloud.validated`` drops the first two kinds)."""
    for name, values in arrays.items():
        values = np.asarray(values)
        with np.errstate(invalid="ignore", over="ignore"):
            bad = ~np.isfinite(values).all(axis=-1)
            if name in ("position", "u", "v"):
                bad |= (np.abs(values) > MAX_COORDINATE).any(axis=-1)
            if name == "normal":
                bad |= ~(np.einsum("ij,ij->i", values, values) > 0)
        if bad.any():
            limit = f" or beyond +-{MAX_COORDINATE:g}" if name in ("position", "u", "v") else ""
            raise InputError(f"{int(bad.sum()):,} splats have non-finite{limit} {name} values"
                             f"{' (or zero normals)' if name == 'normal' else ''}; SplatCloud.validated() drops "
                             f"invalid splats")


def _with_clip_planes(camera: Camera, splats: GpuSplats) -> Camera:
    """The camera with near/far set from the splats' bounds where it has none."""
    if camera.near is None or camera.far is None:
        return camera.with_clip_from_bounds(*splats.bounds, margin=splats.max_radius)
    return camera


class Renderer:
    """Renders SplatClouds with any technique of ``techniques.TECHNIQUES`` into Frames.

    Owns shader programs and render targets of one OpenGL context (the
    process-wide headless one unless a context is given, e.g. a window's).

    Args:
        ctx: the OpenGL context; default :func:`~surfsplat.render.context.headless_context`.
        search_path: folders searched for shader files before the package's
            ``glsl/`` (custom or experimental shaders; tests).
    """

    def __init__(self, ctx: moderngl.Context | None = None, *, search_path: Sequence[Path] = ()):
        self.ctx = ctx or headless_context()
        self.search_path = tuple(Path(p) for p in search_path)
        self._programs: dict[tuple, BuiltProgram] = {}
        self._built: dict[int, BuiltProgram] = {}   # id(program) -> its BuiltProgram
        self._quad = self.ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, 1, 1], dtype="f4"))
        self._targets: dict | None = None
        self._non_finite, self._background = 0, np.ones(3, "f4")   # of the render in progress
        self._parking_rb = self.ctx.renderbuffer((1, 1))
        self._parking = self.ctx.framebuffer([self._parking_rb])
        self._fullscreen = self.ctx.vertex_array(self.program("fullscreen.vert", "normalize.frag"), [])

    # -- resources ---------------------------------------------------------

    def program(self, vertex: str, fragment: str, defines: dict[str, object] | None = None) -> moderngl.Program:
        """The linked program of two shader files with ``defines`` (built once, then cached).

        Files come from ``search_path``, then the package's ``glsl/``; see
        :func:`~surfsplat.render.shaders.compose` for includes and the shared defines.

        Raises:
            RenderError: the shaders failed to build; compiler positions name
                the shader file and line (``ewa.vert:8(3): error: ...``).
        """
        key = (vertex, fragment, tuple(sorted((defines or {}).items())))
        built = self._programs.get(key)
        if built is None:
            built = build_program(self.ctx, vertex, fragment, dict(key[2]), search_path=self.search_path)
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
        self._release_targets()
        self._fullscreen.release()
        for built in self._programs.values():
            built.program.release()
        self._programs.clear()
        self._built.clear()
        self._quad.release()
        # leave the default framebuffer bound (see park): the parking framebuffer goes too
        (self.ctx.screen or self.ctx.detect_framebuffer(0)).use()
        self._parking.release()
        self._parking_rb.release()

    def upload(self, cloud: SplatCloud) -> GpuSplats:
        """Copy a preprocessed SplatCloud (normals and tangent axes present) to the GPU."""
        if not cloud.has_splats:
            raise InputError("the SplatCloud has no normals or splat axes; run surfsplat.preprocess() first")
        if len(cloud) == 0:
            raise InputError("the SplatCloud is empty")
        arrays = {"position": cloud.positions, "normal": cloud.normals, "color": cloud.albedo,
                  "u": cloud.u, "v": cloud.v}
        if cloud.clip_lines is not None:
            arrays["clip0"], arrays["clip1"] = cloud.clip_lines[:, 0], cloud.clip_lines[:, 1]
        if cloud.normal_field is not None:
            arrays["normal_field"] = cloud.normal_field
        _check_gpu_values(arrays)
        scale = gpu_scale(cloud)
        if scale != 1.0:   # a power of two: exact
            for name in ("position", "u", "v"):
                arrays[name] = arrays[name] * np.float32(scale)
        arrays["color"] = np.clip(arrays["color"], 0.0, 1.0)
        buffers = {name: self.ctx.buffer(np.ascontiguousarray(a, dtype="f4")) for name, a in arrays.items()}
        return GpuSplats(buffers, len(cloud), cloud.bounds(), float(cloud.radii.max()),
                         origin=np.asarray(cloud.origin, dtype=np.float64), scale=scale)

    def _vao(self, splats: GpuSplats, program: moderngl.Program, technique: Technique) -> moderngl.VertexArray:
        key = id(program)
        if key not in splats._vaos:
            content = [(self._quad, "2f", "in_corner")]
            # attributes without a buffer keep OpenGL's default (0, 0, 0): no clip lines, no normal field
            content += [(splats.buffers[name], "2f/i" if name == "normal_field" else "3f/i", f"in_{name}")
                        for name in technique.attributes if f"in_{name}" in program and name in splats.buffers]
            splats._vaos[key] = self.ctx.vertex_array(program, content)
        return splats._vaos[key]

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
            out = ctx.texture(size, 4, dtype="f4")
            side = ctx.texture(size, 2, dtype="f4")   # side and offset depth of each pixel's nearest disk
            for tex in (accum, aux, out, side):
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._targets = {
                "size": size, "accum": accum, "aux": aux, "depth": depth, "out": out, "side": side,
                "fbo_visibility": ctx.framebuffer([side], depth),
                "fbo_accum": ctx.framebuffer([accum, aux], depth),
                "fbo_out": ctx.framebuffer([out]),
            }
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

    def frame_uniforms(self, camera: Camera, lights: Lights, options: RenderOptions = RenderOptions(),
                       supersample: int = 1) -> dict:
        """The uniforms every splat program reads, for one frame: camera (``camera.glsl``), lights
        (``lighting.glsl``) and the visibility and deferred options; those of
        :data:`OPTIONAL_FRAME_UNIFORMS` are optional where set. ``camera`` needs near/far."""
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

    def draw(self, splats: GpuSplats, camera: Camera, technique: Technique | str = "ewa",
             lights: Lights = Lights(), options: RenderOptions = RenderOptions(),
             background=(1.0, 1.0, 1.0), output: moderngl.Framebuffer | None = None,
             tile: tuple[int, int, int, int] | None = None, supersample: int = 1) -> None:
        """Run the passes of ``technique`` and write the normalized image to ``output``.

        ``output`` defaults to the renderer's float color target (read by
        :meth:`render`); a window passes its own framebuffer. ``tile`` ``(x0, y0, w, h)``
        (window pixels of the camera's image, y up) draws only that rectangle, into
        targets of its size (default: the whole image). ``supersample``: the sub-pixels per
        output pixel along each axis that ``camera`` is drawn at (``u_supersample``).
        ``camera`` is a world camera (see :class:`GpuSplats`).
        """
        technique = get_technique(technique) if isinstance(technique, str) else technique
        camera = splats.local_camera(_with_clip_planes(camera, splats))   # world camera in, GPU frame out
        ctx = self.ctx
        tile = tile or (0, 0, camera.width, camera.height)
        targets = self._ensure_targets(tile[2], tile[3])
        frame = self.frame_uniforms(camera, lights, options, supersample) | {"u_tile": tuple(map(float, tile))}
        uniforms = frame | technique.uniforms(options)
        optional = OPTIONAL_FRAME_UNIFORMS | technique.optional_uniforms
        passes = [PASS_VISIBILITY, PASS_ACCUMULATION] if technique.blended else [PASS_OPAQUE]

        targets["fbo_accum"].use()
        targets["fbo_accum"].depth_mask = True
        targets["fbo_accum"].clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if technique.blended:
            targets["fbo_visibility"].clear(0.5, 0.0, 0.0, 0.0)   # side 0.5: none; depth is cleared above
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        for pass_id in passes:
            program = self.program(technique.vertex, technique.fragment, {"PASS": pass_id})
            self.set_uniforms(program, uniforms, optional)
            if pass_id == PASS_ACCUMULATION:
                targets["side"].use(location=SIDE_TEXTURE_UNIT)
                fbo = targets["fbo_accum"]
                fbo.use()
                fbo.depth_mask = False
                ctx.depth_func = "<="
                ctx.enable(moderngl.BLEND)
                ctx.blend_equation = moderngl.FUNC_ADD
                ctx.blend_func = moderngl.ONE, moderngl.ONE
            else:
                fbo = targets["fbo_visibility" if pass_id == PASS_VISIBILITY else "fbo_accum"]
                fbo.use()
                fbo.depth_mask = True
                ctx.depth_func = "<"
                ctx.disable(moderngl.BLEND)
            self._vao(splats, program, technique).render(moderngl.TRIANGLE_STRIP, vertices=4,
                                                         instances=splats.count)
        targets["fbo_accum"].depth_mask = True
        ctx.disable(moderngl.BLEND)
        ctx.disable(moderngl.DEPTH_TEST)

        # Pass 3: normalization (Guennebaud 2003, eq. 18).
        out = output or targets["fbo_out"]
        out.use()
        normalize = self._fullscreen.program
        targets["accum"].use(location=0)
        targets["aux"].use(location=1)
        self.set_uniforms(normalize, frame | {"u_accum": 0, "u_aux": 1, "u_background": tuple(map(float, background))},
                          OPTIONAL_FRAME_UNIFORMS)
        self._fullscreen.render(moderngl.TRIANGLES, vertices=3)

    def _read_tile(self, width: int, height: int) -> SubPixels:
        """The tile's sub-pixels from the targets of the last :meth:`draw`."""
        targets = self._targets
        color = np.frombuffer(targets["out"].read(), dtype="f4").reshape(height, width, 4)[..., :3]
        accum = np.frombuffer(targets["accum"].read(), dtype="f4").reshape(height, width, 4)
        aux = np.frombuffer(targets["aux"].read(), dtype="f4").reshape(height, width, 4)
        weight = accum[..., 3].copy()
        # non-finite accumulations (degenerate splats): normalize.frag shows the background there;
        # they count as empty and are reported by render()
        bad = ~(np.isfinite(accum).all(axis=-1) & np.isfinite(aux).all(axis=-1) & np.isfinite(color).all(axis=-1))
        if bad.any():
            self._non_finite += int(bad.sum())
            weight[bad] = 0.0
            color = color.copy()
            color[bad] = self._background
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(weight > 0, aux[..., 0] / weight, np.inf).astype("f4")
        return SubPixels(color, weight, depth)

    def render(self, splats: GpuSplats | SplatCloud, camera: Camera, technique: Technique | str = "ewa",
               lights: Lights = Lights(), options: RenderOptions = RenderOptions(),
               background=(1.0, 1.0, 1.0), *, supersample: int = 1, max_tile: int = MAX_TILE) -> Frame:
        """Render into a :class:`Frame` (color, depth, weight, alpha as NumPy arrays).

        ``supersample`` K (1..8): the image is drawn at K times the size and box-filtered per
        pixel (:mod:`surfsplat.render.tiles`); any size is drawn in tiles of at most
        ``max_tile`` sub-pixels. The EWA prefilter and the kernels act on the sub-pixels.
        """
        k = int(supersample)
        if isinstance(supersample, bool) or not 1 <= k <= MAX_SUPERSAMPLE or k != supersample:
            raise InputError(f"supersample must be an integer in 1..{MAX_SUPERSAMPLE}, got {supersample!r}")
        check_render_memory(len(splats) if isinstance(splats, SplatCloud) else splats.count, camera.width,
                            camera.height, k, max_tile)
        uploaded = None
        if isinstance(splats, SplatCloud):
            splats = uploaded = self.upload(splats)
        self._non_finite, self._background = 0, np.asarray(background, "f4")
        try:
            camera = _with_clip_planes(camera, splats)
            big = camera.resized(camera.width * k, camera.height * k)
            m = TILE_MARGIN   # pixels drawn around each tile and cropped: fringe clipping reads neighbours
            side = tile_side(self.ctx, k, max_tile, margin=m)
            w, h = camera.width, camera.height
            color = np.empty((h, w, 3), "f4")
            weight = np.empty((h, w), "f4")
            depth = np.empty((h, w), "f4")
            alpha = np.empty((h, w), "f4")
            for x0, y0, tw, th in tile_rects(big.width, big.height, side):
                self.draw(splats, big, technique, lights, options, background,
                          tile=(x0 - m, y0 - m, tw + 2 * m, th + 2 * m), supersample=k)
                block = np.s_[y0 // k:(y0 + th) // k, x0 // k:(x0 + tw) // k]
                color[block], weight[block], depth[block], alpha[block] = box_reduce(
                    self._read_tile(tw + 2 * m, th + 2 * m).cropped(m), k)
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
            flip = np.s_[::-1]   # window rows run bottom-up, Frame rows top-down
            return Frame(np.ascontiguousarray(color[flip]), np.ascontiguousarray(depth[flip]),
                         np.ascontiguousarray(weight[flip]), camera, alpha=np.ascontiguousarray(alpha[flip]),
                         background=tuple(map(float, background)))
        finally:
            if uploaded is not None:
                uploaded.release()


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
