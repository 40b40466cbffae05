"""Opening the viewer's glfw window with an OpenGL 3.3 core context (and the advice when there is no display)."""

from __future__ import annotations

import moderngl

from ..errors import RenderError

NO_DISPLAY = ("cannot open a window: {why}. The viewer needs a display. Without one, render images "
              "with `surfsplat render INPUT -o out.png` (or `surfsplat demo`), or run the viewer under "
              "a virtual X server: `xvfb-run -s '-screen 0 1280x1024x24' surfsplat view INPUT --frames N "
              "--screenshot out.png` (Debian/Ubuntu: apt-get install xvfb)")


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
        glfw.set_error_callback(None)  # type: ignore[arg-type]  # None removes the callback
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
