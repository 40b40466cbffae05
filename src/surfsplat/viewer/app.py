"""The interactive viewer: a glfw window drawing with the same Renderer as ``surfsplat render``.

Frame loop (one thread; glfw callbacks only record input, the loop acts on it):

1. input (:mod:`~surfsplat.viewer.keys`) -> :class:`~surfsplat.viewer.camera_control.CameraController`
   (orbit, pan, zoom, fly) and settings (technique, prefilter, lighting, culling, EDL, colouring,
   LOD tolerance);
2. rendering, off-screen, into RGBA8 textures of the window's framebuffer size:
   - while the camera moves (and for ``SETTLE_S`` after its last change), where full quality
     is too slow to follow (over ``PREVIEW_ABOVE_S`` a frame), a cheap *preview*:
     technique ``flat`` (one pass) on at most ``MotionOptions.budget`` splats (fixed coarse cuts of the
     LOD hierarchy, :func:`preview_levels`: after each preview the next is drawn one level coarser
     or finer to keep ``MotionOptions.fps``, :func:`~surfsplat.viewer.detail.next_preview_level`),
     optionally at a lower internal resolution (``MotionOptions.scale``);
   - once the camera has been still for ``SETTLE_S``, one *full-quality* frame with the chosen
     technique (the LOD cut of :class:`~surfsplat.viewer.detail.LevelOfDetail`); it is kept and
     shown again, not re-rendered, until something changes. Under a point budget the still view
     is refined progressively (:func:`~surfsplat.viewer.detail.refinement_budgets`): each step is
     drawn into the ``full`` target while the previous one moves to ``previous``;
3. presenting: the preview (or the previous refinement step) cross-faded into the full frame over
   ``FADE_S`` (no pop), then the HUD; with ``record`` the shown frame goes to the
   :class:`~surfsplat.viewer.recorder.Recorder`.

Why this preview: on Mesa's llvmpipe (2 cores) the cost of a frame is about proportional to
the number of splats (vertex and setup bound), not to the pixels: 1 M splats at 1280x720
take 0.7 s with ``flat``, 1.6-1.9 s with ``ewa``, and halving the resolution saves only
20-30%. Cutting the splat count is what makes moving interactive; the LOD hierarchy
(Pajarola 2003, :class:`LevelOfDetail`) draws fewer splats where they are small on screen.

Rendering off-screen also gives screenshots without the HUD, independent of the window's
pixel ownership, and lets a still view be re-shown without re-rendering. With eye-dome lighting
on, full-quality frames go through ``Renderer.render`` (EDL needs the depth image: read back,
shaded in NumPy, written to the ``full`` texture); previews do not get it.

A chunked hierarchy (``surfsplat build --chunked``) is previewed by the splats opening it read,
and the cut of a still view, which reads cells from disk, is made in a background thread
(:mod:`~surfsplat.viewer.streaming`): until it arrives the loop keeps drawing the new view's
preview and handling input, then cross-fades to it as above.

Modules: ``settings`` (constants, :class:`MotionOptions`, :class:`ViewStats`), ``window``
(:func:`open_window`), ``keys`` (input), ``detail`` (LOD cut, preview, recolouring),
``streaming`` (background cuts of chunked hierarchies), ``recorder``, ``hud``, ``camera_control``,
``screenshots``; this one is the frame loop.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import moderngl
import numpy as np

from .. import defaults, progress
from ..camera import Camera
from ..geometry.preprocess import NONPLANAR
from ..errors import InputError
from ..io.video import check_video_path
from ..lighting import Lights
from ..pipeline import CameraSpec, LodOptions, SourceOptions, View, check_image_size, check_render_args, check_source
from ..rendering.frame import check_background, check_image_path
from ..rendering.options import RenderOptions, TechniqueName
from ..rendering.renderer import Renderer
from . import camera_control as cc
from .detail import (LevelOfDetail, next_preview_level, preview_cloud, preview_levels, recolor,
                     refinement_budgets)
from .hud import Hud, viewer_program
from .keys import HELP, ViewerInput
from .recorder import Recorder
from .screenshots import save_image
from .settings import (FADE_S, FPS_INTERVAL_S, MOTION_MODES, PREVIEW_ABOVE_S, SETTLE_S, MotionOptions, ViewStats,
                       technique_names)
from .streaming import STREAM_POLL_S
from .window import open_window

#: The viewer's off-screen targets (textures and their framebuffers).
TARGETS = ("full_fbo", "preview_fbo", "previous_fbo", "full", "preview", "previous")

__all__ = ["MOTION_MODES", "LevelOfDetail", "MotionOptions", "ViewStats", "Viewer", "open_window", "preview_cloud",
           "view"]


class Viewer(ViewerInput):
    """The window, its input state and its frame loop (see the module docstring).

    Built by :func:`view`; usable directly for tests that drive it frame by frame.
    """

    def __init__(self, glfw, window, ctx, plan: View, camera: Camera | CameraSpec | None, *,
                 technique: TechniqueName, lights: Lights, options: RenderOptions, background,
                 motion: MotionOptions = MotionOptions(), hud: bool = True, record: Path | None = None):
        self.glfw, self.window, self.ctx = glfw, window, ctx
        self.renderer = Renderer(ctx)
        self.techniques = technique_names()
        self.technique = technique
        self.lights, self.options, self.background = lights, options, tuple(background)
        self.plan = plan
        tolerance = plan.lod.tolerance
        automatic = tolerance is None or isinstance(tolerance, str)   # "auto": the default tolerance's cut
        self.lod_tolerance = defaults.LOD_TOLERANCE if automatic else float(tolerance)
        self.motion, self.motion_scale = motion.mode, float(motion.scale)
        # progressive refinement of a still view under a point budget: budgets[refine] is drawn
        self.point_budget, self.hybrid = plan.lod.point_budget, plan.hybrid
        self.budgets, self.refine = refinement_budgets(self.point_budget), 0

        # a mesh's surface sampled for the window's width; the hierarchy built once when the model is a cloud
        plan.sample(None, image_size=max(glfw.get_framebuffer_size(window)))
        tree = plan.tree()
        hierarchy = tree.data
        cloud = hierarchy.points   # of a chunked hierarchy: its preview splats (framing, motion)
        self.chunked = not tree.in_memory
        self.lod = LevelOfDetail(self.renderer, tree, plan.lod.shading, on_gpu=plan.strategy() == "gpu")
        self.model_splats = hierarchy.point_count if self.chunked else len(cloud)
        self.model_bounds = cloud.bounds()
        self.motion_budget, self.motion_fps = int(motion.budget), float(motion.fps)
        # colour by (C): the attributes the hierarchy's points keep (a chunked hierarchy: those its
        # cells keep, applied as each view is read)
        names = hierarchy.attributes if self.chunked else (cloud.attributes or {})
        self.color_modes = ["own colours", "elevation"] + [name for name in sorted(names) if name != NONPLANAR]
        self._chunked_base = hierarchy if self.chunked else None
        self.color_index, self._own_colors = 0, cloud.colors
        self.preview_splats, self.preview_ladder, self.preview_level = None, [], 0
        self._preview_start: float | None = None   # when the last preview's rendering started
        self._upload_preview()

        fb_w, fb_h = glfw.get_framebuffer_size(window)
        fb_w, fb_h = max(fb_w, 1), max(fb_h, 1)
        spec = camera if isinstance(camera, CameraSpec) else CameraSpec()
        up = tuple(float(x) for x in (camera.up if isinstance(camera, Camera) else spec.up or plan.up))
        lo, hi = cloud.bounds()
        scene_radius = 0.5 * float(np.linalg.norm(hi - lo)) or 1.0
        home_spec = CameraSpec(up=up, fov=camera.fov if isinstance(camera, Camera) else spec.fov)

        def home(width: int, height: int) -> Camera:
            return plan.camera(home_spec, width, height)

        start = plan.camera(camera, fb_w, fb_h).resized(fb_w, fb_h)
        self.controller = cc.CameraController(start, home, scale=scene_radius, up=np.asarray(up))

        self.present_program = viewer_program(ctx, "fullscreen.vert", "present.frag")
        self._present_vao = ctx.vertex_array(self.present_program, [])
        self.hud = Hud(ctx, scale=max(glfw.get_window_content_scale(window)[0], 1.0)) if hud else None
        self.show_hud = hud

        self._targets: dict | None = None
        self.size = (fb_w, fb_h)
        self._make_targets()

        # versions: every change bumps `version`; a frame is valid for the version it was made for
        self.version, self.full_version, self.preview_version = 1, 0, 0
        self.moved_at = -math.inf        # time of the last camera change
        self.fade_from: float | None = None  # start of the preview -> full cross-fade
        self.showing_preview = False
        self._rendered_camera = self.controller.camera
        self._actions: list[tuple] = []
        self._buttons: set[str] = set()
        self._cursor: tuple[float, float] | None = None
        self._pending_size: tuple[int, int] | None = None
        self.should_quit = False
        # counters for the HUD and the stats
        self.preview_frames = self.full_frames = 0
        self.drawn = 0
        self.last_render_s = {"preview": 0.0, "full": 0.0}
        self._fps_window_start, self._fps_count, self.fps = time.perf_counter(), 0, None
        self._message: tuple[str, float] | None = None
        self.recorder = Recorder(record) if record is not None else None
        self._install_callbacks()

    # -- resources -----------------------------------------------------------

    def _make_targets(self) -> None:
        """(Re)create the off-screen color targets for the current framebuffer size."""
        ctx = self.ctx
        if self._targets is not None:
            ctx.screen.use()  # park on the default framebuffer while freeing (see Renderer)
            for name in TARGETS:
                self._targets[name].release()
        w, h = self.size
        pw, ph = max(1, round(w * self.motion_scale)), max(1, round(h * self.motion_scale))
        full, preview = ctx.texture((w, h), 4), ctx.texture((pw, ph), 4)
        full.filter = (moderngl.NEAREST, moderngl.NEAREST)  # shown 1:1
        preview.filter = (moderngl.LINEAR, moderngl.LINEAR)  # bilinear upscaling of a lower resolution
        previous = ctx.texture((w, h), 4)   # the last refinement step, faded out under the next
        previous.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._targets = {"full": full, "preview": preview, "previous": previous, "preview_size": (pw, ph),
                         "full_fbo": ctx.framebuffer([full]), "preview_fbo": ctx.framebuffer([preview]),
                         "previous_fbo": ctx.framebuffer([previous])}
        self.fade_source = "preview"

    def release(self) -> None:
        """Free every GPU resource the viewer made (the window itself is :func:`view`'s)."""
        self.ctx.screen.use()
        for name in TARGETS:
            self._targets[name].release()
        if self.recorder is not None:
            path = self.recorder.close()
            if path is not None:
                progress.message(f"recorded {self.recorder.frames} frames -> {path}")
        for splats in self.preview_ladder:
            splats.release()
        self.lod.close()
        if self.hud is not None:
            self.hud.release()

    def _upload_preview(self) -> None:
        """(Re)upload the motion previews (:func:`preview_levels`, the finest may be the whole model),
        starting from the finest."""
        for splats in self.preview_ladder:
            splats.release()
        hierarchy = self.lod.hierarchy
        levels = preview_levels(hierarchy, self.motion_budget) if self.motion != "off" else [None]
        clouds = [hierarchy.points if level is None else level for level in levels]
        with progress.stage(f"uploading {' + '.join(f'{len(c):,}' for c in clouds)} preview splats"):
            self.preview_ladder = [self.renderer.upload(cloud) for cloud in clouds]
        self.preview_level = len(self.preview_ladder) - 1
        self.preview_splats = self.preview_ladder[self.preview_level]

    def cycle_colors(self) -> str:
        """Colour the model by the next of :attr:`color_modes` (its own colours, elevation along the
        view's up axis, each attribute: ASPRS classes for ``classification``, else viridis over the
        2nd-98th percentiles, :func:`surfsplat.colors.colorize`); returns the mode's name."""
        self.color_index = (self.color_index + 1) % len(self.color_modes)
        name = self.color_modes[self.color_index]
        if self.chunked:   # a copy coloured as its cells are read, its preview coloured now
            base = self._chunked_base
            self.lod.set_hierarchy(base if self.color_index == 0 else
                                   base.colorized(name, up=tuple(self.controller.up)))
            self._upload_preview()
            self.preview_version = 0
            return name
        if self.color_index == 0:
            colors = self._own_colors
            node_colors = None   # averaged per node
        else:   # the hierarchy's points carry the attributes; nodes by majority class or mean colour
            colored = self.lod.hierarchy.colorized(name, up=tuple(self.controller.up))
            colors, node_colors = colored.points.colors, colored.node_colors
        recolor(self.lod.hierarchy, colors, node_colors)
        self.lod.release()
        self._upload_preview()
        self.preview_version = 0
        return name

    # -- rendering -------------------------------------------------------------

    @property
    def use_preview(self) -> bool:
        """Whether camera motion is drawn as a preview (see ``motion`` in :func:`view`)."""
        if self.motion == "auto":
            last = self.last_render_s["full"]
            return last == 0.0 or last > PREVIEW_ABOVE_S  # unknown yet, or too slow to keep up
        return self.motion != "off"

    def render(self, full: bool) -> None:
        """Render the current view off-screen: full quality, or the motion preview."""
        camera = self.controller.camera
        if full:
            splats, self.drawn = self.lod(*self._cut_args(self.refine))
            technique, fbo = self.technique, self._targets["full_fbo"]
        else:
            splats, self.drawn = self.preview_splats, self.preview_splats.count
            technique = self.technique if self.motion == "same" else "flat"
            fbo = self._targets["preview_fbo"]
            camera = camera.resized(*self._targets["preview_size"])
        start = time.perf_counter()
        if splats is None:  # nothing in view
            fbo.use()
            fbo.clear(*self.background, 0.0)
        elif full and self.options.edl is not None:
            # eye-dome lighting needs the depth: the Frame path (read back, EDL in NumPy, written back)
            frame = self.renderer.render(splats, camera, technique, self.lights, self.drawn_options(),
                                         self.background)
            rgba = np.concatenate([frame.image(), np.full(frame.alpha.shape + (1,), 255, np.uint8)], axis=2)
            self._targets["full"].write(np.ascontiguousarray(rgba[::-1]).tobytes())
        else:
            self.renderer.draw(splats, camera, technique, self.lights, self.drawn_options(), self.background,
                               output=fbo)
        self.ctx.finish()  # llvmpipe works asynchronously: wait, so frame times are real
        self.last_render_s["full" if full else "preview"] = time.perf_counter() - start
        if not full:   # keep moving frames at the target rate: the next preview coarser or finer
            # the whole frame: from the previous preview's start, when previews follow each other
            previous, self._preview_start = self._preview_start, start
            frame_s = start - previous if previous is not None and start - previous < SETTLE_S else None
            self.preview_level = next_preview_level(self.preview_level, [s.count for s in self.preview_ladder],
                                                    self.last_render_s["preview"], self.motion_fps, frame_s)
            self.preview_splats = self.preview_ladder[self.preview_level]
        if full:
            self.full_frames += 1
            self.full_version = self.version
        else:
            self.preview_frames += 1
            self.preview_version = self.version
        self._fps_count += 1

    @property
    def culling(self) -> bool:
        """Whether back faces are culled now: as the options say, or where automatic (None) when the
        model is a closed surface and the eye is outside its bounds."""
        return self.plan.culls(self.controller.camera, self.options, self.technique)

    def drawn_options(self) -> RenderOptions:
        """The render options of the current frame, automatic culling resolved (:attr:`culling`)."""
        o = self.options
        return replace(o, visibility=replace(o.visibility, cull_backfaces=self.culling))

    def _cut_args(self, refine: int) -> tuple:
        """The LOD cut of the current view at refinement step ``refine`` (:class:`LevelOfDetail`'s arguments)."""
        return (self.controller.camera, self.lod_tolerance, self.culling, self.budgets[refine], self.hybrid)

    def full_image(self) -> np.ndarray:
        """(H, W, 3) uint8 full-quality image of the current view (rendered first if out of date)."""
        if self.full_version != self.version:
            self.render(full=True)
        w, h = self.size
        data = np.frombuffer(self._targets["full"].read(), dtype=np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(data[::-1, :, :3])  # GL rows start at the bottom

    def screen_image(self) -> np.ndarray:
        """(H, W, 3) uint8 of what the window's back buffer shows (image and HUD): tests, recordings."""
        w, h = self.size
        data = np.frombuffer(self.ctx.screen.read(viewport=(0, 0, w, h), components=3), dtype=np.uint8)
        # moderngl names GL_COLOR_ATTACHMENT0 as the window's read buffer, which GL refuses
        # (GL_INVALID_OPERATION; the back buffer is read all the same): clear the flag, or the
        # renderer's next error check would report it
        _ = self.ctx.error
        return np.ascontiguousarray(data.reshape(h, w, 3)[::-1])

    def present(self, mix: float) -> None:
        """Draw the preview/full mix (0: preview, 1: full) and the HUD into the window's back buffer."""
        screen = self.ctx.screen
        screen.viewport = (0, 0, *self.size)
        screen.use()
        program = self.present_program
        self._targets[self.fade_source].use(location=0)
        self._targets["full"].use(location=1)
        program["u_preview"].value, program["u_full"].value = 0, 1
        program["u_mix"].value = float(mix)
        program["u_viewport"].value = tuple(map(float, self.size))
        self._present_vao.render(vertices=3)
        if self.hud is not None and self.show_hud:
            self.hud.update(self.status_text(), self.help_text())
            self.hud.draw(self.size)
        if self.recorder is not None:
            self.recorder.add(self.screen_image)

    # -- HUD text ---------------------------------------------------------------

    def _count_frames(self, now: float) -> None:
        elapsed = now - self._fps_window_start
        if elapsed >= FPS_INTERVAL_S:
            self.fps = self._fps_count / elapsed if self._fps_count else None
            self._fps_window_start, self._fps_count = now, 0

    def status_text(self) -> str:
        """The HUD's status panel (changes only when a shown value changes)."""
        on = {True: "on", False: "off", None: "auto"}   # culling None: automatic (closed surfaces)
        preview = self.showing_preview
        ms = 1000.0 * self.last_render_s["preview" if preview else "full"]
        rate = f"{self.fps:.1f} fps" if self.fps is not None else "idle"
        quality = (f"{'reading cells' if self.lod.pending else 'moving'}: preview "
                   f"({'flat' if self.motion != 'same' else self.technique}, "
                   f"{self.preview_splats.count:,} splats)" if preview else "full quality")
        if self.chunked and not preview:
            quality += f" ({self.lod.cells_loaded} cells in the cut)"
        lines = [
            f"{self.technique}{'   hybrid' if self.hybrid else ''}   {self.drawn:,} splats"
            f"{self._budget_text()}   {rate}   ({ms:.0f} ms/frame)",
            f"prefilter {on[self.options.filter.prefilter]}   lighting {on[self.lights.enabled]}   "
            f"culling {on[self.options.visibility.cull_backfaces]}"
            f"{' (on)' if self.options.visibility.cull_backfaces is None and self.culling else ''}   "
            f"EDL {on[self.options.edl is not None]}   "
            f"LOD tolerance {self.lod_tolerance:.3g} px "
            f"({self.lod.select_ms:.0f} ms to select)",
            f"{self.controller.mode} mode   {quality}   H: help",
        ]
        if self._message is not None:
            if time.perf_counter() < self._message[1]:
                lines.append(self._message[0])
            else:
                self._message = None
        return "\n".join(lines)

    def _budget_text(self) -> str:
        if self.point_budget is None:
            return ""
        step = f", refining {self.refine + 1}/{len(self.budgets)}" if self.refine + 1 < len(self.budgets) else ""
        return f" (budget {self.budgets[self.refine]:,}{step})"

    def help_text(self) -> str:
        """The key list shown on H."""
        numbers = ", ".join(f"{i + 1} {name}" for i, name in enumerate(self.techniques[:9]))
        return HELP.format(numbers=numbers)

    # -- loops -------------------------------------------------------------------

    def run_interactive(self) -> ViewStats:
        """The frame loop until the window is closed (or Esc / Q)."""
        self.glfw.swap_interval(1)
        start, frames = time.perf_counter(), 0
        self._last_step = start
        while not (self.glfw.window_should_close(self.window) or self.should_quit):
            if self.step():
                frames += 1
        seconds = time.perf_counter() - start
        return self._stats(frames, seconds)

    def step(self, wait: bool = True) -> bool:
        """One turn of the interactive loop: input, render what is out of date, present, then
        wait for events (``wait``; else only poll). Returns False when quitting instead."""
        glfw = self.glfw
        now = time.perf_counter()
        keys_held = self._held_keys(min(now - getattr(self, "_last_step", now), 0.1))
        self._last_step = now
        self._process_input(now)
        if self.should_quit:
            return False
        moving = now - self.moved_at < SETTLE_S and self.use_preview
        if moving:
            if self.preview_version != self.version:
                self.render(full=False)
                self.showing_preview, self.fade_from = True, None
        elif self.full_version != self.version:
            self.refine = 0
            if not self.lod.ready(*self._cut_args(0)):
                # a chunked model's cells are read in the background: show this view's preview meanwhile
                if self.preview_version != self.version:
                    self.render(full=False)
                self.showing_preview, self.fade_from = True, None
            else:
                self.render(full=True)
                if self.showing_preview:
                    self.fade_source = "preview"
                    self.fade_from = time.perf_counter()  # cross-fade preview -> full, no pop
                self.showing_preview = False
        elif (self.fade_from is None and self.refine + 1 < len(self.budgets)
              and self.lod.ready(*self._cut_args(self.refine + 1))):
            self._refine_step()
        mix = 0.0 if self.showing_preview else 1.0
        if self.fade_from is not None:
            mix = min(1.0, (time.perf_counter() - self.fade_from) / FADE_S)
            if mix >= 1.0:
                self.fade_from = None
        self._count_frames(time.perf_counter())
        self.present(mix)
        glfw.swap_buffers(self.window)
        # Sleep until something can change: poll while animating, else wait for input
        # (waking at the end of the settle time, and twice a second for the HUD).
        if not wait or keys_held or self.fade_from is not None or self._actions or self._buttons:
            glfw.poll_events()
        elif self.lod.pending:   # look again for the cells being read soon
            glfw.wait_events_timeout(STREAM_POLL_S)
        elif moving:
            glfw.wait_events_timeout(max(0.005, SETTLE_S - (time.perf_counter() - self.moved_at)))
        else:
            glfw.wait_events_timeout(FPS_INTERVAL_S)
        return True

    def _refine_step(self) -> None:
        """Draw the still view with the next budget of the refinement and cross-fade it in from
        the previous step (kept in the ``previous`` target): no popping."""
        t = self._targets
        t["full"], t["previous"] = t["previous"], t["full"]
        t["full_fbo"], t["previous_fbo"] = t["previous_fbo"], t["full_fbo"]
        self.refine += 1
        self.render(full=True)
        self.fade_source, self.fade_from = "previous", time.perf_counter()

    def run_scripted(self, frames: int, orbit_deg: float, screenshot: Path | None) -> ViewStats:
        """Render ``frames`` frames, turning the eye ``orbit_deg`` degrees about the up axis before
        each; save the last view at full quality (no HUD) to ``screenshot``.

        Every frame is rendered (nothing is re-shown), so the frame rate measures rendering:
        previews while orbiting (where :attr:`use_preview`), full quality with ``orbit_deg`` = 0.
        One full-quality frame and one preview are rendered first, untimed: shaders compile
        and motion "auto" measures the full quality's speed.
        """
        glfw, win = self.glfw, self.window
        glfw.swap_interval(0)  # measure rendering, not the monitor's refresh
        # the script alone moves the camera: mouse input would make the result depend on the user
        glfw.set_cursor_pos_callback(win, None)
        glfw.set_scroll_callback(win, None)
        self.refine = len(self.budgets) - 1   # scripted frames draw the whole budget at once
        if self.recorder is not None:
            self.recorder.realtime = False   # one video frame per scripted frame
        self.render(full=True)
        if self.use_preview:
            self.render(full=False)
        self.preview_frames = self.full_frames = self._fps_count = 0
        moving = orbit_deg != 0 and self.use_preview
        done = 0
        start = time.perf_counter()
        for _ in range(frames):
            glfw.poll_events()
            self._actions = [a for a in self._actions if a[0] == "quit"]  # only Esc/Q count here
            self._process_input(time.perf_counter())
            if glfw.window_should_close(win) or self.should_quit:
                break
            if orbit_deg:
                self.controller.camera = cc.orbit(self.controller.camera, orbit_deg, 0.0, self.controller.up)
                self._process_input(time.perf_counter())
            self.render(full=not moving)
            self.showing_preview = moving
            self._count_frames(time.perf_counter())
            self.present(0.0 if moving else 1.0)
            glfw.swap_buffers(win)
            done += 1
        seconds = time.perf_counter() - start
        stats = self._stats(done, seconds)
        if screenshot is not None:
            stats.screenshot = save_image(self.full_image(), screenshot)
        return stats

    def _stats(self, frames: int, seconds: float) -> ViewStats:
        return ViewStats(frames, seconds, frames / seconds if seconds > 0 else 0.0, self.preview_frames,
                         self.full_frames, self.model_splats, self.preview_splats.count, self.size)


def view(source, camera: Camera | CameraSpec | None = None, *, technique: TechniqueName = "ewa",
         size: tuple[int, int] = defaults.WINDOW_SIZE, lights: Lights | None = None,
         background=defaults.BACKGROUND, options: RenderOptions | None = None, lod: LodOptions | None = None,
         motion: MotionOptions | None = None, hud: bool = True, frames: int | None = None, orbit: float = 0.0,
         screenshot=None, title: str | None = None, source_options: SourceOptions | None = None,
         record=None) -> ViewStats:
    """Open an interactive window on a splat model (press H in it for the keys).

    Args:
        source: anything :func:`surfsplat.render` takes: a SplatCloud, a hierarchy, a
            point/splat/mesh file (made into splats as ``source_options`` say), a hierarchy file,
            a chunked hierarchy directory (cells read in the background per still view) or
            ``"demo:NAME"`` for a built-in scene (``demo:torus``, ...).
        camera: the first view: a Camera (its size is replaced by the window's) or a
            :class:`~surfsplat.pipeline.CameraSpec` (eye, target, up, fov); None or a spec without an
            eye frames the model automatically (also what R returns to). Orbits turn about
            the camera's up axis (the data's own without one).
        technique: the starting technique (T and 1..9 switch).
        size: window size (width, height) in screen coordinates; the image has the
            framebuffer's size (larger on HiDPI screens).
        lights: as for :func:`surfsplat.render`.
        background: as for :func:`surfsplat.render`.
        options: as for :func:`surfsplat.render`.
        lod: the level of detail (:class:`~surfsplat.pipeline.LodOptions`): the model's point-octree
            (built on loading, or a ``.npz`` from ``surfsplat build``) is cut per view where nodes
            project to at most ``tolerance`` pixels (default 1; +/- change it in the window); with a
            ``point_budget`` at most that many splats per frame (Potree's priority), a still view
            refined progressively from a sixteenth of the budget up, each step cross-faded in
            (:data:`~.detail.REFINE_STEPS`); ``mode`` "auto" cuts an in-memory hierarchy on the GPU
            where it can (:func:`surfsplat.pipeline.lod.lod_strategy`).
        motion: what is drawn while the camera moves (:class:`MotionOptions`).
        hud: show the heads-up display (status; help on H).
        frames: scripted mode: render ``frames`` frames (with ``orbit`` and ``screenshot``), close.
        orbit: scripted mode: turn the eye ``orbit`` degrees about ``up`` before each frame.
        screenshot: scripted mode: save the last view at full quality without the HUD to this
            path (if given). ``screenshot`` alone means one frame.
        title: window title (default: the input's name).
        source_options: how the source becomes splats (:class:`~surfsplat.pipeline.SourceOptions`:
            raw points preprocessed, a mesh's surface sampled once on loading for the window's size,
            hybrid drawing of non-planar points: on for LiDAR files by default).
        record: write the frames the window shows to this .gif, .mp4 or .webm
            (:mod:`~surfsplat.viewer.recorder`; scripted mode: one video frame per frame).

    Returns:
        :class:`ViewStats` (frames, seconds, frame rate, ...).

    Raises:
        RenderError: no display (the message points to ``surfsplat render`` and ``xvfb-run``),
            or OpenGL 3.3 is not available.
        InputError: bad arguments or input data.
    """
    names = technique_names()
    if technique not in names:
        raise InputError(f"unknown technique {technique!r}; choose one of {', '.join(names)}")
    motion = motion or MotionOptions()
    options = options or RenderOptions()
    lod = lod or LodOptions()
    if lod.tolerance is not None and not (isinstance(lod.tolerance, (int, float)) and lod.tolerance > 0):
        raise InputError(f"the viewer's LOD tolerance must be a positive number of pixels, got {lod.tolerance!r}")
    width, height = check_image_size(*size, limit=defaults.MAX_WINDOW_SIDE, what="window")
    check_render_args(technique=technique, background=background, options=options, lights=lights)
    if record is not None:
        record = check_video_path(record)
    if screenshot is not None:
        screenshot = check_image_path(screenshot)
        frames = 1 if frames is None else frames
    if frames is not None and int(frames) < 1:
        raise InputError(f"--frames must be at least 1, got {frames}")
    if orbit and frames is None:
        raise InputError("--orbit is for the scripted mode: give --frames N too")
    if not math.isfinite(orbit):
        raise InputError(f"orbit must be a finite number of degrees per frame, got {orbit}")
    background = check_background(background)
    if title is None:
        title = source if isinstance(source, str) else (Path(source).name if isinstance(source, Path)
                                                          else type(source).__name__)
    check_source(source)
    # The window before loading: without a display, fail before a possibly long load.
    glfw, window, ctx = open_window(width, height, f"surfsplat - {title}")
    viewer = None
    try:
        ctx.clear(*background)
        glfw.swap_buffers(window)
        glfw.poll_events()
        plan = View(source, source_options=source_options, lod=lod, interactive=True)
        viewer = Viewer(glfw, window, ctx, plan, camera, technique=technique, lights=lights or Lights(),
                        options=options, background=background, motion=motion, hud=hud, record=record)
        if frames is None:
            stats = viewer.run_interactive()
        else:
            stats = viewer.run_scripted(int(frames), float(orbit), screenshot)
            progress.message(
                f"{stats.frames} frames of {stats.splats:,} splats at {stats.size[0]}x{stats.size[1]} in "
                f"{stats.seconds:.2f} s: {stats.fps:.2f} frames/s "
                f"({f'preview, last {stats.preview_splats:,} splats' if stats.preview_frames else technique}, "
                f"{ctx.info['GL_RENDERER']})")
            if stats.screenshot is not None:
                progress.message(f"screenshot -> {stats.screenshot}")
        return stats
    finally:
        if viewer is not None:
            viewer.release()
        ctx.release()
        glfw.destroy_window(window)
        glfw.terminate()
        glfw.set_error_callback(None)
