"""The interactive viewer: a glfw window drawing with the same Renderer as ``surfsplat render``.

Frame loop (one thread; glfw callbacks only record input, the loop acts on it):

1. input -> :class:`~surfsplat.viewer.camera_control.CameraController` (orbit, pan, zoom, fly) and
   settings (technique, prefilter, lighting, culling, LOD tolerance);
2. rendering, off-screen, into RGBA8 textures of the window's framebuffer size:
   - while the camera moves (and for ``SETTLE_S`` after its last change), where full quality
     is too slow to follow (over ``PREVIEW_ABOVE_S`` a frame), a cheap *preview*:
     technique ``flat`` (one pass) on at most ``MotionOptions.budget`` splats (a fixed coarse cut of the
     LOD hierarchy: :func:`preview_cloud`), optionally at a lower internal
     resolution (``MotionOptions.scale``);
   - once the camera has been still for ``SETTLE_S``, one *full-quality* frame with the chosen
     technique; it is kept and shown again, not re-rendered, until something changes;
3. presenting: the preview cross-faded into the full frame over ``FADE_S`` (no pop), then the HUD.

Why this preview: on Mesa's llvmpipe (2 cores) the cost of a frame is about proportional to
the number of splats (vertex and setup bound), not to the pixels: 1 M splats at 1280x720
take 0.7 s with ``flat``, 1.6-1.9 s with ``ewa``, and halving the resolution saves only
20-30%. Cutting the splat count is what makes moving interactive; the LOD hierarchy
(Pajarola 2003, :class:`LevelOfDetail`) draws fewer splats where they are small on screen.

Rendering off-screen also gives screenshots without the HUD, independent of the window's
pixel ownership, and lets a still view be re-shown without re-rendering.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal, get_args

import moderngl
import numpy as np

from .. import progress
from ..api import (DEFAULT_BACKGROUND, DEFAULT_LOD_SHADING, DEFAULT_LOD_TOLERANCE, CameraSpec, SourceOptions,
                   as_hierarchy, check_background, check_source, load_model, lod_splats, natural_up,
                   resolve_camera)
from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError, RenderError
from ..hierarchy import LodShading, uniform_cut
from ..lighting import Lights
from ..render.options import RenderOptions, TechniqueName
from ..render.renderer import Renderer
from ..render.techniques import TECHNIQUES
from . import camera_control as cc
from .hud import Hud, viewer_program
from ..render.frame import check_image_path
from .screenshots import save_image, unique_screenshot_path

#: Seconds the camera must be still before the full-quality frame replaces the preview.
SETTLE_S = 0.25
#: Seconds of the cross-fade from the preview to the full-quality frame.
FADE_S = 0.15
#: Default (about) number of splats and resolution scale of the motion preview: with ``flat``
#: at 1280x720 (drawn at 640x360) about 5-10 frames/s on llvmpipe with 2 cores. Only used
#: where full quality is slow (motion "auto"), so a GPU usually never shows the preview.
#: LOD screen tolerance range, pixels, and the factor of one +/- step.
TOLERANCE_RANGE = (0.125, 64.0)
TOLERANCE_STEP = math.sqrt(2.0)
#: Seconds between refreshes of the frame counter (and so of the HUD's text).
FPS_INTERVAL_S = 0.5

Motion = Literal["auto", "flat", "same", "off"]
#: The values of :data:`Motion`.
MOTION_MODES = get_args(Motion)
#: With motion "auto", the preview is used only where a full-quality frame takes longer than this
#: (seconds): on a GPU the full quality usually keeps up and is drawn while moving too.
PREVIEW_ABOVE_S = 0.05

NO_DISPLAY = ("cannot open a window: {why}. The viewer needs a display. Without one, render images "
              "with `surfsplat render INPUT -o out.png` (or `surfsplat demo`), or run the viewer under "
              "a virtual X server: `xvfb-run -s '-screen 0 1280x1024x24' surfsplat view INPUT --frames N "
              "--screenshot out.png` (Debian/Ubuntu: apt-get install xvfb)")


@dataclass(frozen=True)
class MotionOptions:
    """What the viewer draws while the camera moves.

    Attributes:
        mode: "flat" (opaque one-pass disks) or "same" (the chosen technique), both on about
            ``budget`` splats at ``scale`` of the resolution; "off": full quality always;
            "auto": "flat" where a full-quality frame takes longer than ``PREVIEW_ABOVE_S``.
        budget: about this many splats at most in the preview (0: all). The default, with
            ``flat`` at 1280x720 drawn at 640x360, gives about 5-10 frames/s on llvmpipe with 2
            cores; only used where full quality is slow, so a GPU usually never shows it.
        scale: internal resolution of the preview, fraction of the window's, in (0, 1].
    """

    mode: Motion = "auto"
    budget: int = 100_000
    scale: float = 0.5

    def __post_init__(self) -> None:
        if self.mode not in MOTION_MODES:
            raise InputError(f"motion must be one of {', '.join(map(repr, MOTION_MODES))}, got {self.mode!r}")
        if not (0.0 < self.scale <= 1.0):
            raise InputError(f"motion scale must be in (0, 1], got {self.scale}")
        if int(self.budget) < 0:
            raise InputError(f"motion budget must be >= 0 splats (0: all), got {self.budget}")


@dataclass
class ViewStats:
    """What a :func:`view` session did.

    Attributes:
        frames: frames presented (scripted mode: the N asked for, unless the window was closed).
        seconds: wall-clock time of those frames (rendering, presenting, HUD, swap), seconds.
        fps: frames / seconds.
        preview_frames, full_frames: how many renders were motion previews / full quality.
        splats: splats in the model; preview_splats: splats drawn in a preview.
        size: (width, height) of the framebuffer, pixels.
        screenshot: the image written by the scripted mode, if any.
    """

    frames: int
    seconds: float
    fps: float
    preview_frames: int
    full_frames: int
    splats: int
    preview_splats: int
    size: tuple[int, int]
    screenshot: Path | None = None


# -- inputs ----------------------------------------------------------------

def technique_names() -> list[str]:
    """The techniques in the order T cycles through them and 1..9 select them."""
    return sorted(TECHNIQUES)


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


class LevelOfDetail:
    """View-dependent level of detail for the viewer's full-quality frames (Pajarola 2003, sec. 5.1).

    Holds the model's point-octree; per frame it selects the cut for the camera and
    the screen tolerance tau (nodes whose projected ellipse is at most tau pixels are
    drawn as one splat; frustum culling, and back-face culling when the render
    options ask for it), gathers the splats and uploads them, replacing the previous
    cut. A cut is reused while the camera, tau and culling stay the same.
    """

    def __init__(self, renderer, hierarchy, lod_shading: LodShading = DEFAULT_LOD_SHADING):
        self.renderer, self.hierarchy, self.lod_shading = renderer, hierarchy, lod_shading
        self._key = None
        self._splats = None
        self.count = 0
        self.select_ms = 0.0

    def __call__(self, camera: Camera, lod_tolerance: float, cull_backfaces: bool):
        """(GpuSplats or None when nothing is visible, number of splats drawn)."""
        key = (camera, float(lod_tolerance), bool(cull_backfaces))
        if key != self._key:
            start = time.perf_counter()
            cloud, _ = lod_splats(self.hierarchy, camera, lod_tolerance, cull_backfaces=cull_backfaces,
                                  lod_shading=self.lod_shading)
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


# -- the window ------------------------------------------------------------

def open_window(width: int, height: int, title: str, visible: bool = True):
    """Create a glfw window with an OpenGL 3.3 core context and a moderngl context on it.

    Returns (glfw module, window, moderngl context). Raises RenderError with
    :data:`NO_DISPLAY`'s advice when glfw is missing, finds no display or the
    window (or its context) cannot be created.
    """
    try:
        import glfw
    except ImportError:
        raise RenderError(NO_DISPLAY.format(why="the glfw package is not installed "
                                            "(pip install 'surfsplat[viewer]')")) from None

    errors: list[str] = []

    def on_error(code, description):
        text = description.decode(errors="replace") if isinstance(description, bytes) else str(description)
        errors.append(text)

    glfw.set_error_callback(on_error)

    def fail(what: str):
        why = what + (f" ({'; '.join(errors)})" if errors else "")
        glfw.terminate()
        glfw.set_error_callback(None)
        return RenderError(NO_DISPLAY.format(why=why))

    if not glfw.init():
        raise fail("glfw found no display")
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)  # required on macOS, harmless elsewhere
    glfw.window_hint(glfw.VISIBLE, visible)
    window = glfw.create_window(int(width), int(height), title, None, None)
    if not window:
        raise fail("the window with an OpenGL 3.3 core context could not be created")
    glfw.make_context_current(window)
    try:
        ctx = moderngl.create_context(require=330)
    except Exception as exc:  # moderngl raises plain Exceptions from its loader
        glfw.destroy_window(window)
        raise fail(f"no OpenGL 3.3 context on the window: {exc}") from None
    return glfw, window, ctx


HELP = """\
left drag\torbit around the target (fly mode: look around)
right / middle drag\tpan
wheel\tzoom (fly mode: move forward / back)
arrows\torbit (fly mode: look)
F\tfly mode on / off: W A S D move, Q E down / up, Shift faster
R\treset the view (automatic framing)
T, Shift+T\tnext / previous technique
1 .. 9\t{numbers}
P\tEWA prefilter on / off
L\tlighting on / off
B\tback-face culling on / off
+ / -\tLOD screen tolerance (pixels)
S, Ctrl+S\tscreenshot surfsplat-<time>.png (fly mode: Ctrl+S)
H\tthis help
Esc, Q\tquit (fly mode: Esc)"""


class Viewer:
    """The window, its input state and its frame loop (see the module docstring).

    Built by :func:`view`; usable directly for tests that drive it frame by frame.
    """

    def __init__(self, glfw, window, ctx, model, camera: Camera | CameraSpec | None, *, technique: TechniqueName,
                 lights: Lights, options: RenderOptions, background, lod_tolerance: float,
                 lod_shading: LodShading = DEFAULT_LOD_SHADING, motion: MotionOptions = MotionOptions(),
                 hud: bool = True, source_options: SourceOptions | None = None):
        self.glfw, self.window, self.ctx = glfw, window, ctx
        self.renderer = Renderer(ctx)
        self.techniques = technique_names()
        self.technique = technique
        self.lights, self.options, self.background = lights, options, tuple(background)
        self.lod_tolerance = float(lod_tolerance)
        self.motion, self.motion_scale = motion.mode, float(motion.scale)

        # built on loading when the model is a cloud (a mesh's surface sampled for the window's width)
        hierarchy = as_hierarchy(model, source_options, image_size=max(glfw.get_framebuffer_size(window)))
        cloud = hierarchy.points
        self.lod = LevelOfDetail(self.renderer, hierarchy, lod_shading)
        self.model_splats = len(cloud)
        small = preview_cloud(hierarchy, int(motion.budget)) if motion.mode != "off" else None
        with progress.stage(f"uploading {len(small or cloud):,} preview splats"):
            self.preview_splats = self.renderer.upload(small if small is not None else cloud)

        fb_w, fb_h = glfw.get_framebuffer_size(window)
        fb_w, fb_h = max(fb_w, 1), max(fb_h, 1)
        spec = camera if isinstance(camera, CameraSpec) else CameraSpec()
        up = tuple(float(x) for x in (camera.up if isinstance(camera, Camera) else spec.up or (0.0, 1.0, 0.0)))
        lo, hi = cloud.bounds()
        scene_radius = 0.5 * float(np.linalg.norm(hi - lo)) or 1.0
        home_spec = CameraSpec(up=up, fov=camera.fov if isinstance(camera, Camera) else spec.fov)

        def home(width: int, height: int) -> Camera:
            return home_spec.camera_for(cloud, width, height)

        start = resolve_camera(model, camera, fb_w, fb_h).resized(fb_w, fb_h)
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
        self._install_callbacks()

    # -- resources -----------------------------------------------------------

    def _make_targets(self) -> None:
        """(Re)create the off-screen color targets for the current framebuffer size."""
        ctx = self.ctx
        if self._targets is not None:
            ctx.screen.use()  # park on the default framebuffer while freeing (see Renderer)
            for name in ("full_fbo", "preview_fbo", "full", "preview"):
                self._targets[name].release()
        w, h = self.size
        pw, ph = max(1, round(w * self.motion_scale)), max(1, round(h * self.motion_scale))
        full, preview = ctx.texture((w, h), 4), ctx.texture((pw, ph), 4)
        full.filter = (moderngl.NEAREST, moderngl.NEAREST)  # shown 1:1
        preview.filter = (moderngl.LINEAR, moderngl.LINEAR)  # bilinear upscaling of a lower resolution
        self._targets = {"full": full, "preview": preview, "preview_size": (pw, ph),
                         "full_fbo": ctx.framebuffer([full]), "preview_fbo": ctx.framebuffer([preview])}

    def release(self) -> None:
        """Free every GPU resource the viewer made (the window itself is :func:`view`'s)."""
        self.ctx.screen.use()
        for name in ("full_fbo", "preview_fbo", "full", "preview"):
            self._targets[name].release()
        self.preview_splats.release()
        self.lod.release()
        if self.hud is not None:
            self.hud.release()

    # -- input -----------------------------------------------------------------

    def _install_callbacks(self) -> None:
        glfw, win = self.glfw, self.window
        glfw.set_key_callback(win, self._on_key)
        glfw.set_char_callback(win, self._on_char)
        glfw.set_mouse_button_callback(win, self._on_button)
        glfw.set_cursor_pos_callback(win, self._on_cursor)
        glfw.set_scroll_callback(win, self._on_scroll)
        glfw.set_framebuffer_size_callback(win, self._on_framebuffer_size)

    def _on_key(self, window, key, scancode, action, mods) -> None:
        glfw = self.glfw
        if action != glfw.PRESS:
            return
        fly = self.controller.mode == "fly"
        ctrl = bool(mods & glfw.MOD_CONTROL)
        if key == glfw.KEY_ESCAPE or (key == glfw.KEY_Q and not fly):
            self._actions.append(("quit",))
        elif key == glfw.KEY_S and (ctrl or not fly):
            self._actions.append(("screenshot",))
        elif fly and key in (glfw.KEY_W, glfw.KEY_A, glfw.KEY_S, glfw.KEY_D, glfw.KEY_Q, glfw.KEY_E):
            return  # movement keys are read each frame (held down)
        elif key == glfw.KEY_F:
            # at once, not queued: the mode decides what the next keys mean (Q, S)
            mode = self.controller.toggle_mode()
            self._message = (f"{mode} mode", time.perf_counter() + 2.0)
        elif key == glfw.KEY_R:
            self._actions.append(("reset",))
        elif key == glfw.KEY_T:
            self._actions.append(("technique", -1 if mods & glfw.MOD_SHIFT else 1))
        elif glfw.KEY_1 <= key <= glfw.KEY_9:
            self._actions.append(("technique_index", key - glfw.KEY_1))
        elif key == glfw.KEY_P:
            self._actions.append(("prefilter",))
        elif key == glfw.KEY_L:
            self._actions.append(("lighting",))
        elif key == glfw.KEY_B:
            self._actions.append(("cull",))
        elif key == glfw.KEY_H:
            self._actions.append(("help",))

    def _on_char(self, window, codepoint) -> None:
        # +/- come as characters: the same on every keyboard layout and on the keypad
        char = chr(codepoint)
        if char in "+=":
            self._actions.append(("tolerance", 1))
        elif char in "-_":
            self._actions.append(("tolerance", -1))

    def _on_button(self, window, button, action, mods) -> None:
        glfw = self.glfw
        name = {glfw.MOUSE_BUTTON_LEFT: "left", glfw.MOUSE_BUTTON_RIGHT: "right",
                glfw.MOUSE_BUTTON_MIDDLE: "middle"}.get(button)
        if name is None:
            return
        if action == glfw.PRESS:
            self._buttons.add(name)
            self._cursor = glfw.get_cursor_pos(window)
        else:
            self._buttons.discard(name)

    def _on_cursor(self, window, x, y) -> None:
        if not self._buttons or self._cursor is None:
            self._cursor = (x, y)
            return
        # cursor positions are in screen coordinates; the camera works in framebuffer pixels (HiDPI)
        win_w, _ = self.glfw.get_window_size(window)
        ratio = self.size[0] / max(win_w, 1)
        dx, dy = (x - self._cursor[0]) * ratio, (y - self._cursor[1]) * ratio
        self._cursor = (x, y)
        button = "left" if "left" in self._buttons else ("right" if "right" in self._buttons else "middle")
        self.controller.drag(button, dx, dy)

    def _on_scroll(self, window, dx, dy) -> None:
        self.controller.scroll(dy)

    def _on_framebuffer_size(self, window, width, height) -> None:
        self._pending_size = (width, height)

    def _held_keys(self, dt: float) -> bool:
        """Keyboard motion for ``dt`` seconds (fly keys, arrows); returns whether any key is held."""
        glfw, win = self.glfw, self.window

        def down(key) -> int:
            return 1 if glfw.get_key(win, key) == glfw.PRESS else 0

        turn = (down(glfw.KEY_LEFT) - down(glfw.KEY_RIGHT), down(glfw.KEY_UP) - down(glfw.KEY_DOWN))
        if self.controller.mode == "fly":
            move = (down(glfw.KEY_W) - down(glfw.KEY_S), down(glfw.KEY_D) - down(glfw.KEY_A),
                    down(glfw.KEY_E) - down(glfw.KEY_Q))
        else:
            move = (0, 0, 0)
        fast = bool(down(glfw.KEY_LEFT_SHIFT) or down(glfw.KEY_RIGHT_SHIFT))
        return self.controller.keys(move, turn, dt, fast)

    def _apply(self, action: tuple) -> None:
        kind = action[0]
        if kind == "quit":
            self.should_quit = True
        elif kind == "screenshot":
            path = save_image(self.full_image(), unique_screenshot_path(), exclusive=True)
            progress.message(f"screenshot -> {path}")
            self._message = (f"saved {path.name}", time.perf_counter() + 3.0)
            return  # the image itself does not change
        elif kind == "reset":
            self.controller.reset()
        elif kind in ("technique", "technique_index"):
            names = self.techniques
            if kind == "technique":
                index = (names.index(self.technique) + action[1]) % len(names)
            elif action[1] < len(names):
                index = action[1]
            else:
                return
            self.technique = names[index]
        elif kind == "prefilter":
            o = self.options
            self.options = replace(o, filter=replace(o.filter, prefilter=not o.filter.prefilter))
        elif kind == "lighting":
            self.lights = replace(self.lights, enabled=not self.lights.enabled)
        elif kind == "cull":
            o = self.options
            self.options = replace(o, visibility=replace(o.visibility, cull_backfaces=not o.visibility.cull_backfaces))
        elif kind == "tolerance":
            lo, hi = TOLERANCE_RANGE
            self.lod_tolerance = float(np.clip(self.lod_tolerance * TOLERANCE_STEP ** action[1], lo, hi))
        elif kind == "help":
            if self.hud is not None:
                self.hud.show_help = not self.hud.show_help
            return  # the image itself does not change
        self.version += 1

    def _process_input(self, now: float) -> None:
        actions, self._actions = self._actions, []
        for action in actions:
            self._apply(action)
        if self._pending_size is not None:
            w, h = self._pending_size
            self._pending_size = None
            if w > 0 and h > 0 and (w, h) != self.size:  # 0 x 0 while minimized: keep the old targets
                self.size = (w, h)
                self.controller.resize(w, h)
                self._make_targets()
        if self.controller.camera != self._rendered_camera:
            self._rendered_camera = self.controller.camera
            self.moved_at = now
            self.version += 1

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
            splats, self.drawn = self.lod(camera, self.lod_tolerance, self.options.visibility.cull_backfaces)
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
        else:
            self.renderer.draw(splats, camera, technique, self.lights, self.options, self.background, output=fbo)
        self.ctx.finish()  # llvmpipe works asynchronously: wait, so frame times are real
        self.last_render_s["full" if full else "preview"] = time.perf_counter() - start
        if full:
            self.full_frames += 1
            self.full_version = self.version
        else:
            self.preview_frames += 1
            self.preview_version = self.version
        self._fps_count += 1

    def full_image(self) -> np.ndarray:
        """(H, W, 3) uint8 full-quality image of the current view (rendered first if out of date)."""
        if self.full_version != self.version:
            self.render(full=True)
        w, h = self.size
        data = np.frombuffer(self._targets["full"].read(), dtype=np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(data[::-1, :, :3])  # GL rows start at the bottom

    def screen_image(self) -> np.ndarray:
        """(H, W, 3) uint8 of what the window's back buffer shows (image and HUD), for tests."""
        w, h = self.size
        data = np.frombuffer(self.ctx.screen.read(viewport=(0, 0, w, h), components=3), dtype=np.uint8)
        return np.ascontiguousarray(data.reshape(h, w, 3)[::-1])

    def present(self, mix: float) -> None:
        """Draw the preview/full mix (0: preview, 1: full) and the HUD into the window's back buffer."""
        screen = self.ctx.screen
        screen.viewport = (0, 0, *self.size)
        screen.use()
        program = self.present_program
        self._targets["preview"].use(location=0)
        self._targets["full"].use(location=1)
        program["u_preview"].value, program["u_full"].value = 0, 1
        program["u_mix"].value = float(mix)
        program["u_viewport"].value = tuple(map(float, self.size))
        self._present_vao.render(vertices=3)
        if self.hud is not None and self.show_hud:
            self.hud.update(self.status_text(), self.help_text())
            self.hud.draw(self.size)

    # -- HUD text ---------------------------------------------------------------

    def _count_frames(self, now: float) -> None:
        elapsed = now - self._fps_window_start
        if elapsed >= FPS_INTERVAL_S:
            self.fps = self._fps_count / elapsed if self._fps_count else None
            self._fps_window_start, self._fps_count = now, 0

    def status_text(self) -> str:
        """The HUD's status panel (changes only when a shown value changes)."""
        on = {True: "on", False: "off"}
        preview = self.showing_preview
        ms = 1000.0 * self.last_render_s["preview" if preview else "full"]
        rate = f"{self.fps:.1f} fps" if self.fps is not None else "idle"
        quality = (f"moving: preview ({'flat' if self.motion != 'same' else self.technique}, "
                   f"{self.preview_splats.count:,} splats)" if preview else "full quality")
        lines = [
            f"{self.technique}   {self.drawn:,} splats   {rate}   ({ms:.0f} ms/frame)",
            f"prefilter {on[self.options.filter.prefilter]}   lighting {on[self.lights.enabled]}   "
            f"culling {on[self.options.visibility.cull_backfaces]}   LOD tolerance {self.lod_tolerance:.3g} px "
            f"({self.lod.select_ms:.0f} ms to select)",
            f"{self.controller.mode} mode   {quality}   H: help",
        ]
        if self._message is not None:
            if time.perf_counter() < self._message[1]:
                lines.append(self._message[0])
            else:
                self._message = None
        return "\n".join(lines)

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
            self.render(full=True)
            if self.showing_preview:
                self.fade_from = time.perf_counter()  # cross-fade preview -> full, no pop
            self.showing_preview = False
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
        elif moving:
            glfw.wait_events_timeout(max(0.005, SETTLE_S - (time.perf_counter() - self.moved_at)))
        else:
            glfw.wait_events_timeout(FPS_INTERVAL_S)
        return True

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
         size: tuple[int, int] = (1280, 720), lights: Lights | None = None, background=DEFAULT_BACKGROUND,
         options: RenderOptions | None = None, lod_tolerance: float = DEFAULT_LOD_TOLERANCE,
         lod_shading: LodShading = DEFAULT_LOD_SHADING, motion: MotionOptions | None = None, hud: bool = True,
         frames: int | None = None, orbit: float = 0.0, screenshot=None, title: str | None = None,
         source_options: SourceOptions | None = None) -> ViewStats:
    """Open an interactive window on a splat model (press H in it for the keys).

    Args:
        source: anything :func:`surfsplat.api.load_model` takes: a SplatCloud, a hierarchy, a
            point/splat/mesh file (made into splats as ``source_options`` say), a hierarchy file
            or ``"demo:NAME"`` for a built-in scene (``demo:torus``, ...).
        camera: the first view: a Camera (its size is replaced by the window's) or a
            :class:`~surfsplat.api.CameraSpec` (eye, target, up, fov); None or a spec without an
            eye frames the model automatically (also what R returns to). Orbits turn about
            the camera's up axis.
        technique: the starting technique (T and 1..9 switch).
        size: window size (width, height) in screen coordinates; the image has the
            framebuffer's size (larger on HiDPI screens).
        lights, background, options: as for :func:`surfsplat.render`.
        lod_tolerance: LOD screen tolerance in pixels (+/- change it): the model's
            point-octree (built on loading, or a ``.npz`` from ``surfsplat build``) is cut
            per view where nodes project to at most that many pixels, see :class:`LevelOfDetail`.
        lod_shading: normal field of coarse LOD splats ("fit", "cone", "flat").
        motion: what is drawn while the camera moves (:class:`MotionOptions`).
        hud: show the heads-up display (status; help on H).
        frames, orbit, screenshot: scripted mode: render ``frames`` frames, turning the eye
            ``orbit`` degrees about ``up`` before each, save the last view at full quality
            without the HUD to ``screenshot`` (if given), close. ``screenshot`` alone means
            one frame.
        title: window title (default: the input's name).
        source_options: how the source becomes splats (:class:`~surfsplat.api.SourceOptions`:
            raw points preprocessed, a mesh's surface sampled once on loading for the window's size).

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
    if not (lod_tolerance > 0 and math.isfinite(lod_tolerance)):
        raise InputError(f"LOD tolerance must be a positive number of pixels, got {lod_tolerance}")
    width, height = (int(x) for x in size)
    if not (1 <= width <= 16384 and 1 <= height <= 16384):
        raise InputError(f"window size must be within 1..16384 pixels, got {width}x{height}")
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
    if not isinstance(camera, Camera):
        spec = camera or CameraSpec()
        camera = spec if spec.up is not None else replace(spec, up=natural_up(source))
    # The window before loading: without a display, fail before a possibly long load.
    glfw, window, ctx = open_window(width, height, f"surfsplat - {title}")
    viewer = None
    try:
        ctx.clear(*background)
        glfw.swap_buffers(window)
        glfw.poll_events()
        model = load_model(source, source_options)
        viewer = Viewer(glfw, window, ctx, model, camera, technique=technique, lights=lights or Lights(),
                        options=options, background=background, lod_tolerance=lod_tolerance,
                        lod_shading=lod_shading, motion=motion, hud=hud, source_options=source_options)
        if frames is None:
            stats = viewer.run_interactive()
        else:
            stats = viewer.run_scripted(int(frames), float(orbit), screenshot)
            progress.message(
                f"{stats.frames} frames of {stats.splats:,} splats at {stats.size[0]}x{stats.size[1]} in "
                f"{stats.seconds:.2f} s: {stats.fps:.2f} frames/s "
                f"({'preview' if stats.preview_frames else technique}, {ctx.info['GL_RENDERER']})")
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
