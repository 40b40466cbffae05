"""The OpenGL context: one headless EGL context per process, created on first use."""

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


def renderer_name(ctx: moderngl.Context) -> str:
    """'GL_RENDERER (GL_VERSION)' of a context, for benchmark tables and `info`."""
    return f"{ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})"
