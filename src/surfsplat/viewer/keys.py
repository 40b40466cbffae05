"""The viewer's input: glfw callbacks record keys, buttons and motion; the frame loop applies them.

:class:`ViewerInput` is a mixin of :class:`~surfsplat.viewer.app.Viewer`: the callbacks only
append actions (or move the camera controller), :meth:`ViewerInput._process_input` applies
them once per frame, bumping ``version`` when the image changes.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from .. import progress
from ..rendering.options import EdlOptions
from .screenshots import save_image, unique_screenshot_path
from .settings import TOLERANCE_RANGE, TOLERANCE_STEP

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
O\teye-dome lighting on / off (still views)
C\tcolour by: own colours, elevation, then each attribute
+ / -\tLOD screen tolerance (pixels)
S, Ctrl+S\tscreenshot surfsplat-<time>.png (fly mode: Ctrl+S)
H\tthis help
Esc, Q\tquit (fly mode: Esc)"""



class ViewerInput:
    """Input handling of the :class:`~surfsplat.viewer.app.Viewer` (a mixin: it reads and sets the
    viewer's state)."""

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
        elif key == glfw.KEY_O:
            self._actions.append(("edl",))
        elif key == glfw.KEY_C:
            self._actions.append(("color",))
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
        elif kind == "cull":   # from automatic: the opposite of what it does now, then on / off
            o = self.options
            self.options = replace(o, visibility=replace(o.visibility, cull_backfaces=not self.culling))
        elif kind == "edl":
            o = self.options
            self.options = replace(o, edl=None if o.edl is not None else EdlOptions())
        elif kind == "color":
            name = self.cycle_colors()
            self._message = (f"colour by {name}", time.perf_counter() + 2.0)
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
