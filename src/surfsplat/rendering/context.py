"""The OpenGL context: one headless EGL context per process, created on first use.

:func:`reset_headless_context` releases it (the next :func:`headless_context`
creates a new one); ``renderer.reset_default_renderer`` releases the default
renderer with it.
"""

from __future__ import annotations

import ctypes
import ctypes.util

import moderngl

from ..errors import RenderError

_headless: moderngl.Context | None = None
_gl_flush = None   # glFlush of the process's OpenGL library; False: none found


def headless_context() -> moderngl.Context:
    """The process-wide headless OpenGL >= 3.3 context (EGL: the GPU driver, or Mesa llvmpipe)."""
    global _headless
    if _headless is None:
        errors = []
        for kwargs in ({"backend": "egl"}, {}):
            try:
                ctx = moderngl.create_standalone_context(require=330, **kwargs)
                break
            except Exception as exc:  # glcontext raises plain Exceptions with the loader's message
                errors.append(f"{kwargs or 'default'}: {exc}")
        else:
            raise RenderError(
                "could not create a headless OpenGL 3.3 context (" + "; ".join(errors) + "). "
                "Install Mesa's EGL (Debian: libegl1 libegl-mesa0) or a GPU driver with EGL.")
        _headless = ctx
    return _headless


def reset_headless_context() -> None:
    """Release the process-wide headless context, if one exists; the next
    :func:`headless_context` creates a new one. Every OpenGL object made on it
    (renderers, buffers, programs) is unusable afterwards: release them first
    (``Renderer.release``) or drop them."""
    global _headless
    ctx, _headless = _headless, None
    if ctx is not None:
        ctx.release()


def renderer_name(ctx: moderngl.Context) -> str:
    """'GL_RENDERER (GL_VERSION)' of a context, for benchmark tables and `info`."""
    return f"{ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})"


def gl_flush() -> bool:
    """glFlush on the current context (moderngl binds glFinish only): hands the commands issued so
    far to the driver without waiting for them. False where no OpenGL library of the system exports
    it (the caller then waits with ``ctx.finish()``)."""
    global _gl_flush
    if _gl_flush is None:
        _gl_flush = False
        for name in ("GL", "OpenGL", "opengl32"):   # GLVND's libGL / libOpenGL, macOS, Windows
            path = ctypes.util.find_library(name)
            try:
                _gl_flush = ctypes.CDLL(path).glFlush if path else False
            except (OSError, AttributeError):
                continue
            if _gl_flush:
                break
    if not _gl_flush:
        return False
    _gl_flush()
    return True
