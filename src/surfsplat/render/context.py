"""The OpenGL context: one headless EGL context per process, created on first use.

:func:`reset_headless_context` releases it (the next :func:`headless_context`
creates a new one); ``renderer.reset_default_renderer`` releases the default
renderer with it.
"""

from __future__ import annotations

import moderngl

from ..errors import RenderError

_headless: moderngl.Context | None = None


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
