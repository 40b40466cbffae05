"""The frame's uniform blocks (rendering/uniform_blocks.py): the std140 layout read from camera.glsl and
lighting.glsl is the driver's (a shader reads back every member as written), and the renderer's programs
take the camera and the lights from the one buffer instead of per-program uniforms."""

from __future__ import annotations

import moderngl
import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import frame_bounds
from surfsplat.errors import RenderError
from surfsplat.lighting import MAX_LIGHTS, Lights
from surfsplat.rendering.options import RenderOptions
from surfsplat.rendering.shaders import compose
from surfsplat.rendering.uniform_blocks import FRAME_BLOCKS, FrameBlocks, block_layout

# Every member of both blocks, read back by transform feedback.
READBACK_VERT = """#include "camera.glsl"
#include "lighting.glsl"
in float in_dummy;
out vec4 out_view_col3;
out vec4 out_tile;
out vec4 out_viewport_near_far;
out vec4 out_focal_lights;      // focal, number of lights, lighting, dummy
out vec3 out_light_last;
out vec4 out_material;
void main() {
    out_view_col3 = u_view[3];
    out_tile = u_tile;
    out_viewport_near_far = vec4(u_viewport, u_near_far);
    out_focal_lights = vec4(u_focal, float(u_num_lights), u_lighting ? 1.0 : 0.0, in_dummy);
    out_light_last = u_light_dirs[MAX_LIGHTS - 1];
    out_material = u_material;
}
"""
VARYINGS = ["out_view_col3", "out_tile", "out_viewport_near_far", "out_focal_lights", "out_light_last",
            "out_material"]


def test_std140_layout_of_mixed_members():
    source = """layout(std140) uniform Mixed {
        float a;      // 0
        vec3 b;       // 16 (vec3 aligned to 16)
        float c;      // 28 (fits after the vec3)
        vec2 d;       // 32
        vec3 e[MAX_LIGHTS];   // 48, stride 16
        mat4 f;       // 48 + 16 * MAX_LIGHTS
        bool g;
    };"""
    layout = block_layout("Mixed", source)
    offsets = {m.name: m.offset for m in layout.members}
    assert offsets == {"a": 0, "b": 16, "c": 28, "d": 32, "e": 48, "f": 48 + 16 * MAX_LIGHTS,
                       "g": 112 + 16 * MAX_LIGHTS}
    assert layout.size == 128 + 16 * MAX_LIGHTS
    with pytest.raises(RenderError, match="needs"):
        layout.pack({"a": 1.0})
    with pytest.raises(RenderError, match="cannot lay out"):
        block_layout("Odd", "layout(std140) uniform Odd { dmat3 x; };")


def test_a_shader_reads_back_every_member(renderer, tmp_path):
    """Values written by FrameBlocks.bind are the ones a program sees: the layout is the driver's."""
    ctx = renderer.ctx
    blocks = FrameBlocks(ctx)
    (tmp_path / "readback.vert").write_text(READBACK_VERT, encoding="utf-8")
    program = ctx.program(vertex_shader=compose("readback.vert", search_path=[tmp_path]).text, varyings=VARYINGS)
    blocks.attach(program)
    dirs = np.arange(3 * MAX_LIGHTS, dtype="f4").reshape(MAX_LIGHTS, 3) / 7.0
    view = np.arange(16, dtype="f4") * 0.25 - 1.0
    values = {"u_view": tuple(view), "u_tile": (1.0, 2.0, 30.0, 40.0), "u_viewport": (640.0, 480.0),
              "u_near_far": (0.5, 9.0), "u_focal": 321.5, "u_light_dirs": [tuple(d) for d in dirs],
              "u_material": (0.1, 0.7, 0.3, 24.0), "u_num_lights": 3, "u_lighting": True,
              "u_other": 5.0}   # not a member: ignored
    vbo, out = ctx.buffer(np.zeros(1, "f4")), ctx.buffer(reserve=4 * 23)
    vao = ctx.vertex_array(program, [(vbo, "f", "in_dummy")])
    try:
        blocks.bind(values)
        renderer.park()
        vao.transform(out, moderngl.POINTS, vertices=1)
        got = np.frombuffer(out.read(), "f4")
    finally:
        for thing in (vao, vbo, out, program):
            thing.release()
        blocks.release()
    np.testing.assert_array_equal(got[0:4], view[12:16])   # column 3 of the column-major matrix
    np.testing.assert_array_equal(got[4:8], values["u_tile"])
    np.testing.assert_array_equal(got[8:12], values["u_viewport"] + values["u_near_far"])
    np.testing.assert_array_equal(got[12:15], (321.5, 3.0, 1.0))
    np.testing.assert_array_equal(got[16:19], dirs[-1])
    np.testing.assert_array_equal(got[19:23], np.float32(values["u_material"]))


def test_frame_programs_read_the_blocks(renderer):
    """After a frame, the camera, the lights and the options are no program's own uniforms: each program
    that uses them has the blocks, bound to their binding points; the buffer holds this frame's view
    matrix and options."""
    cloud = scenes.torus(100, 40)
    camera = frame_bounds(*cloud.bounds(), width=48, height=40, direction=(0.3, -0.8, 0.6))
    frame = renderer.render(cloud, camera, "ewa", Lights())
    assert frame.mask.any()
    programs = [built.program for built in renderer._programs.values()]
    users = [p for p in programs if "Camera" in p]
    assert len(users) >= 3   # splat programs, cracks, normalization
    for program in programs:
        for name in renderer._blocks.members:   # camera, lights, options
            assert name not in program
        for name, (_, binding) in FRAME_BLOCKS.items():
            if name in program:
                assert program[name].binding == binding
    blocks = renderer._blocks
    view = np.frombuffer(blocks.buffer.read(size=64, offset=blocks.offsets["Camera"]), "f4")
    local = renderer._uploaded.gpu_camera(camera.with_clip_from_bounds(*cloud.bounds(),
                                                                         margin=float(cloud.radii.max())))
    np.testing.assert_array_equal(view, local.view_matrix.T.astype("f4").ravel())
    assert {"u_view", "u_light_dirs", "u_depth_epsilon", "u_deferred"} <= renderer._blocks.members
    options = renderer.render(cloud, camera, "ewa", Lights(), RenderOptions(deferred=True), supersample=2)
    assert options.mask.any()
    epsilon, k, *flags = np.frombuffer(blocks.buffer.read(size=24, offset=blocks.offsets["Options"]), "<u4")
    assert np.float32(RenderOptions().visibility.depth_epsilon).view("<u4") == epsilon
    assert np.float32(2.0).view("<u4") == k and flags[-1] == 1   # u_supersample, u_deferred
