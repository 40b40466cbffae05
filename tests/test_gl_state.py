"""The ``renderer`` fixture (tests/conftest.py) hands each test the session renderer in a clean state: what
a test leaves on the shared context (capabilities, blend and depth functions, fill mode, polygon offset,
the bound framebuffer, the cached upload) is undone before the next one. The two tests run in this order:
the first leaves everything dirty, the second finds it clean and draws the first one's clean picture."""

from __future__ import annotations

import ctypes
import ctypes.util

import moderngl
import numpy as np
import pytest
from conftest import reset_gl_state

from surfsplat import scenes
from surfsplat.camera import Camera

GL_BLEND, GL_DEPTH_TEST, GL_CULL_FACE = 0x0BE2, 0x0B71, 0x0B44
GL_RASTERIZER_DISCARD, GL_PROGRAM_POINT_SIZE = 0x8C89, 0x8642
GL_DRAW_FRAMEBUFFER_BINDING, GL_BLEND_SRC_RGB, GL_BLEND_DST_RGB = 0x8CA6, 0x80C9, 0x80C8
GL_BLEND_EQUATION_RGB, GL_DEPTH_FUNC, GL_POLYGON_MODE, GL_FRONT_FACE, GL_CULL_FACE_MODE = (
    0x8009, 0x0B74, 0x0B40, 0x0B46, 0x0B45)
GL_POINT_SIZE, GL_POLYGON_OFFSET_FACTOR, GL_POLYGON_OFFSET_UNITS = 0x0B11, 0x8038, 0x2A00
GL_LESS, GL_FILL, GL_CCW, GL_BACK = 0x0201, 0x1B02, 0x0901, 0x0405

CAMERA = Camera(eye=(0.4, 0.3, 3.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=40.0, width=64, height=48)
#: What the first test leaves behind for the second: its picture drawn in a clean state, its framebuffer.
LEFT = {}


def gl_library() -> ctypes.CDLL:
    """The system's OpenGL library (GLVND's libGL or libOpenGL), whose calls reach the current context."""
    for name in ("GL", "OpenGL"):
        path = ctypes.util.find_library(name)
        if path:
            library = ctypes.CDLL(path)
            library.glIsEnabled.restype = ctypes.c_ubyte
            return library
    pytest.fail("no OpenGL library (libGL or libOpenGL) to query the context's state with")


def gl_state(ctx: moderngl.Context) -> dict:
    """The context's state as OpenGL reports it (glIsEnabled, glGetIntegerv, glGetFloatv)."""
    gl = gl_library()

    def integers(name: int, count: int = 1) -> tuple:
        values = (ctypes.c_int * 4)()
        gl.glGetIntegerv(ctypes.c_uint(name), values)
        return tuple(values[:count])

    def floats(name: int) -> float:
        value = (ctypes.c_float * 4)()
        gl.glGetFloatv(ctypes.c_uint(name), value)
        return value[0]

    state = {"enabled": {name for name, cap in (("blend", GL_BLEND), ("depth test", GL_DEPTH_TEST),
                                                ("cull face", GL_CULL_FACE), ("discard", GL_RASTERIZER_DISCARD),
                                                ("point size", GL_PROGRAM_POINT_SIZE))
                         if gl.glIsEnabled(ctypes.c_uint(cap))},
             "framebuffer": integers(GL_DRAW_FRAMEBUFFER_BINDING)[0],
             "blend func": (integers(GL_BLEND_SRC_RGB)[0], integers(GL_BLEND_DST_RGB)[0]),
             "blend equation": integers(GL_BLEND_EQUATION_RGB)[0], "depth func": integers(GL_DEPTH_FUNC)[0],
             "polygon mode": integers(GL_POLYGON_MODE)[0], "front face": integers(GL_FRONT_FACE)[0],
             "cull face mode": integers(GL_CULL_FACE_MODE)[0], "point size": floats(GL_POINT_SIZE),
             "polygon offset": (floats(GL_POLYGON_OFFSET_FACTOR), floats(GL_POLYGON_OFFSET_UNITS))}
    assert ctx.error == "GL_NO_ERROR"
    return state


def clean_state(renderer) -> dict:
    """A fresh moderngl context's state (OpenGL's defaults, moderngl's blend function) with the renderer's
    own 1x1 framebuffer bound."""
    return {"enabled": set(), "framebuffer": renderer._parking.glo, "blend func": moderngl.DEFAULT_BLENDING,
            "blend equation": moderngl.FUNC_ADD, "depth func": GL_LESS, "polygon mode": GL_FILL,
            "front face": GL_CCW, "cull face mode": GL_BACK, "point size": 1.0, "polygon offset": (0.0, 0.0)}


def dirty(ctx: moderngl.Context, target: moderngl.Framebuffer) -> None:
    """Change everything :func:`reset_gl_state` resets, as a careless test could."""
    ctx.enable_only(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.RASTERIZER_DISCARD
                    | moderngl.PROGRAM_POINT_SIZE)
    ctx.blend_func = moderngl.ONE, moderngl.ONE
    ctx.blend_equation = moderngl.MAX
    ctx.depth_func = ">="
    ctx.wireframe = True
    ctx.polygon_offset = (1.0, 2.0)
    ctx.point_size = 4.0
    ctx.front_face = "cw"
    ctx.cull_face = "front"
    target.use()


def test_first_a_test_leaves_the_shared_renderer_dirty(renderer):
    ctx = renderer.ctx
    assert gl_state(ctx) == clean_state(renderer)
    cloud = scenes.sphere(2000)
    LEFT["image"] = renderer.render(cloud, CAMERA, "ewa").color
    assert (LEFT["image"] < 0.9).any(axis=-1).sum() > 300   # the sphere is drawn
    target = ctx.framebuffer([ctx.renderbuffer((4, 4))])
    dirty(ctx, target)
    state = gl_state(ctx)
    # every entry differs from the clean state: the queries see what the reset has to undo
    assert [key for key, value in clean_state(renderer).items() if state[key] == value] == []
    reset_gl_state(renderer)
    assert gl_state(ctx) == clean_state(renderer) and renderer._uploaded is None
    # dirty again, and left so: an upload in the cache, another framebuffer bound
    renderer.render(cloud, CAMERA, "flat")
    dirty(ctx, target)
    assert renderer._uploaded is not None and ctx.fbo is target
    LEFT["framebuffer"] = target


def test_then_the_next_test_finds_it_clean(renderer):
    ctx = renderer.ctx
    assert gl_state(ctx) == clean_state(renderer)
    assert renderer._uploaded is None and ctx.fbo is renderer._parking
    image = renderer.render(scenes.sphere(2000), CAMERA, "ewa").color
    if "image" in LEFT:   # run after the test above: the same picture as in its clean state
        np.testing.assert_array_equal(image, LEFT["image"])
        LEFT.pop("framebuffer").release()   # not bound any more: releasing it is safe
