"""The shader composer (render/shaders.py): includes, shared defines, #line mapping of compiler
errors, declared uniforms; the renderer's uniform checks and the technique table."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from importlib import resources
from pathlib import Path
from typing import get_args

import numpy as np
import pytest

from surfsplat import lighting, reference, scenes
from surfsplat.camera import Camera
from surfsplat.errors import InputError, RenderError
from surfsplat.lighting import Lights
from surfsplat.rendering import shaders
from surfsplat.rendering.options import (KERNELS, FilterOptions, KernelName, KernelOptions, RenderOptions,
                                      TechniqueName, VisibilityOptions)
from surfsplat.rendering.renderer import OPTIONAL_FRAME_UNIFORMS, Renderer
from surfsplat.rendering.shaders import (LINE_STRIDE, PROLOGUE, SHARED_DEFINES, compose, declared_uniforms,
                                      read_glsl, source_location, translate_log)
from surfsplat.rendering.technique import Technique, filter_uniforms
from surfsplat.rendering.techniques import TECHNIQUES, get_technique

#: Deliberately broken (and some valid) shaders for the error-mapping tests.
TEST_GLSL = Path(__file__).resolve().parent / "glsl"
PACKAGE_GLSL = resources.files("surfsplat.rendering").joinpath("glsl")
SHADER_FILES = sorted(p.name for p in PACKAGE_GLSL.iterdir() if p.name.endswith((".vert", ".frag")))
CAMERA = Camera(eye=(0.3, 0.25, 2.4), target=(0, 0, 0), width=48, height=40, fov=35, near=0.5, far=10.0)


def simulate_line_directives(text: str) -> list[tuple[int, int] | None]:
    """Per line of a composed source, (source string, line) as a GLSL 330 compiler numbers it
    (``#line L S``: the next line is line L of string S); None for the directives."""
    source, line, out = 0, 1, []
    for raw in text.split("\n")[:-1]:
        match = re.fullmatch(r"#line (\d+) (\d+)", raw)
        if match:
            out.append(None)
            line, source = int(match.group(1)), int(match.group(2))
        else:
            out.append((source, line))
            line += 1
    return out


def original_line(file: str, line: int, search_path=()) -> str:
    for folder in search_path:
        if (Path(folder) / file).is_file():
            return (Path(folder) / file).read_text().splitlines()[line - 1]
    return read_glsl(file).splitlines()[line - 1]


def check_line_map(composed, search_path=()) -> int:
    """Every line of a composed source maps back to its file and line; returns the lines checked."""
    numbered = simulate_line_directives(composed.text)
    lines = composed.text.split("\n")[:-1]
    assert len(numbered) == len(lines) == len(composed.origins)
    checked = 0
    for i, (text, position) in enumerate(zip(lines, numbered), 1):
        if position is None:
            assert composed.origin(i) is None and text.startswith("#line ")
            continue
        source, line = position
        k, local = divmod(line, LINE_STRIDE)
        assert source == k, (i, text)  # the source string number names the file too
        file = composed.files[k]
        assert composed.origin(i) == (file, local)
        assert source_location(source, line, composed.files) == (file, local)
        assert source_location(0, line, composed.files) == (file, local)  # Mesa's semantic errors say 0
        if file == PROLOGUE:
            assert text == shaders.GLSL_VERSION or text.startswith("#define ")
        else:
            expected = original_line(file, local, search_path)
            # an include already pasted in stays as an empty line
            assert text == expected or (text == "" and expected.lstrip().startswith("#include")), (i, file, local)
        checked += 1
    return checked


# -- composition -------------------------------------------------------------------


@pytest.mark.parametrize("name", SHADER_FILES)
@pytest.mark.parametrize("defines", [None, {"PASS": 1}])
def test_every_composed_line_maps_to_its_file_and_line(name, defines):
    composed = compose(name, defines)
    assert composed.files[0] == PROLOGUE and composed.files[1] == name
    checked = check_line_map(composed)
    # every line of every file is there (each file once), less the include lines pasted over
    pasted = len(composed.files) - 2
    total = sum(len(read_glsl(f).splitlines()) for f in composed.files[1:])
    assert checked == len(shaders.prologue(defines)) + total - pasted


def test_line_directives_follow_each_include_and_return():
    composed = compose("ewa.vert")
    lines = composed.text.split("\n")
    text = read_glsl("ewa.vert").splitlines()
    includes = [i + 1 for i, line in enumerate(text) if line.startswith("#include")]
    assert len(includes) == 7   # camera, lighting, attributes, splat vertex, primitive, disk, hiz
    k = composed.files.index("ewa.vert")
    for number in includes:  # after each pasted include: back to the next line of ewa.vert
        assert f"#line {k * LINE_STRIDE + number + 1} {k}" in lines
    for file in composed.files[1:]:  # each file starts with its own directive
        j = composed.files.index(file)
        assert f"#line {j * LINE_STRIDE + 1} {j}" in lines
    assert lines[0] == shaders.GLSL_VERSION


def test_stages_share_a_numbering():
    files = [PROLOGUE]
    vs = compose("ewa.vert", files=files)
    fs = compose("ewa.frag", files=files)
    assert vs.files[: len(vs.files)] == fs.files[: len(vs.files)]
    assert fs.files.index("ewa.frag") == len(vs.files)  # new files continue the numbering
    assert fs.files.index("camera.glsl") == vs.files.index("camera.glsl")
    check_line_map(fs)


def test_includes_once_cycles_and_missing_files(tmp_path):
    (tmp_path / "a.glsl").write_text('float a;\n#include "b.glsl"\n#include "b.glsl"\nfloat a2;\n')
    (tmp_path / "b.glsl").write_text("float b;\n")
    composed = compose("a.glsl", search_path=[tmp_path])
    assert composed.text.count("float b;") == 1
    assert check_line_map(composed, [tmp_path]) == len(shaders.prologue()) + 4 + 1 - 1
    (tmp_path / "c.glsl").write_text('#include "d.glsl"\n')
    (tmp_path / "d.glsl").write_text('// d\n#include "c.glsl"\n')
    with pytest.raises(RenderError, match="cycle: c.glsl -> d.glsl -> c.glsl"):
        compose("c.glsl", search_path=[tmp_path])
    (tmp_path / "e.glsl").write_text('// e\n\n#include "nowhere.glsl"\n')
    with pytest.raises(RenderError, match=r"e\.glsl:3: .*nowhere\.glsl"):
        compose("e.glsl", search_path=[tmp_path])
    with pytest.raises(RenderError, match="missing"):
        compose("nowhere.vert")
    (tmp_path / "camera.glsl").write_text("// a shadowing file\n")
    assert "shadowing" in compose("camera.glsl", search_path=[tmp_path]).text  # search path first


# -- shared constants ----------------------------------------------------------------


def test_shared_constants_are_defined_once_in_python():
    assert SHARED_DEFINES["MAX_LIGHTS"] == lighting.MAX_LIGHTS
    assert SHARED_DEFINES["PERSPECTIVE_MAX_CONDITION"] == reference.PERSPECTIVE_MAX_CONDITION
    assert SHARED_DEFINES["PERSPECTIVE_NEAR_FRACTION"] == reference.PERSPECTIVE_NEAR_FRACTION
    assert SHARED_DEFINES["EDGE_ON_TOLERANCE"] == reference.EDGE_ON_TOLERANCE
    assert (SHARED_DEFINES["PASS_OPAQUE"], SHARED_DEFINES["PASS_VISIBILITY"], SHARED_DEFINES["PASS_ACCUMULATION"]) \
        == (shaders.PASS_OPAQUE, shaders.PASS_VISIBILITY, shaders.PASS_ACCUMULATION)
    for name in SHADER_FILES:
        text = compose(name).text
        for key, value in SHARED_DEFINES.items():
            assert f"#define {key} {value!r}\n" in text
    sources = {p.name: p.read_text() for p in PACKAGE_GLSL.iterdir()}
    assert "u_light_dirs[MAX_LIGHTS]" in sources["lighting.glsl"]
    for name, text in sources.items():  # the GLSL files use the names, not the numbers
        assert not re.search(r"PASS\s*==\s*\d", text), name
        assert not re.search(r"u_light_dirs\[\d", text), name
        code = re.sub(r"//[^\n]*", "", text)
        assert "1e4" not in code and "1e-7" not in code and "1e-3" not in code, name
    with pytest.raises(RenderError, match="shared constants"):
        compose("ewa.vert", {"MAX_LIGHTS": 8})
    with pytest.raises(RenderError, match="define name"):
        compose("ewa.vert", {"pass": 1})


# -- compiler messages -------------------------------------------------------------


def test_translate_log_formats():
    files = (PROLOGUE, "ewa.vert", "camera.glsl")
    mesa = "GLSL Compiler failed\n\nvertex_shader\n=============\n0:10008(3): error: `x' undeclared\n" \
           "2:20005(12): error: syntax error\n"
    assert translate_log(mesa, files) == ("GLSL Compiler failed\n\nvertex_shader\n=============\n"
                                          "ewa.vert:8(3): error: `x' undeclared\n"
                                          "camera.glsl:5(12): error: syntax error\n")
    assert translate_log("ERROR: 1:10008: 'x' : undeclared identifier", files) \
        == "ERROR: ewa.vert:8: 'x' : undeclared identifier"
    assert translate_log("0(20003) : error C1008: undefined variable", files) \
        == "camera.glsl:3 : error C1008: undefined variable"
    assert translate_log("0:2(1): error: in a define", files) == "<prologue>:2(1): error: in a define"
    # positions that are not ours stay as they are
    assert translate_log("7:90001(1): error", files) == "7:90001(1): error"
    link = "error: vertex shader output `a' mismatch"
    assert translate_log(link, files) == link


def test_broken_shaders_name_file_and_line(renderer):
    broken = Renderer(renderer.ctx, search_path=[TEST_GLSL])
    try:
        with pytest.raises(RenderError) as info:
            broken.program("broken_undeclared.vert", "plain.frag")
        message = str(info.value)
        assert "broken_undeclared.vert:8(" in message and "not_declared" in message, message
        with pytest.raises(RenderError) as info:
            broken.program("plain.vert", "broken_syntax.frag")
        assert "broken_syntax.frag:6(" in str(info.value), str(info.value)
        with pytest.raises(RenderError) as info:  # an error inside an included file
            broken.program("plain.vert", "includes_broken.frag")
        message = str(info.value)
        assert "broken_lib.glsl:4(" in message and "undefined_in_lib" in message, message
        assert "plain.vert/includes_broken.frag" in message
        with pytest.raises(RenderError, match="missing"):
            broken.program("plain.vert", "no_such_file.frag")
        program = broken.program("plain.vert", "plain.frag")
        assert broken.program("plain.vert", "plain.frag") is program  # cached
    finally:
        broken.release()
    # releasing a renderer leaves the shared context (and the session renderer) working
    assert renderer.render(scenes.sphere(200), CAMERA, "ewa").mask.any()


# -- uniforms ------------------------------------------------------------------------


def test_declared_uniforms_parse_declarations():
    source = """
    uniform vec3 u_light_dirs[MAX_LIGHTS];   // uniform float u_commented;
    /* uniform float u_block_comment; */
    uniform highp float u_a, u_b[2];
    layout(std140) uniform Block { float u_member; };
    uniform sampler2D u_tex;
    float uniformity;
    """
    assert declared_uniforms(source) == {"u_light_dirs", "u_a", "u_b", "u_tex"}


def test_misspelled_uniform_raises(renderer):
    program = renderer.program("ewa.vert", "ewa.frag", {"PASS": 2})
    assert {"u_cutoff", "u_prefilter", "u_view", "u_light_dirs"} <= renderer.declared_uniforms(program)
    with pytest.raises(RenderError, match="declares no uniform u_cutof"):
        renderer.set_uniforms(program, {"u_cutof": 1.0})
    renderer.set_uniforms(program, {"u_cutof": 1.0}, optional={"u_cutof"})  # optional: skipped
    # declared but dropped by the compiler (unused in the visibility pass): skipped silently
    visibility = renderer.program("ewa.vert", "ewa.frag", {"PASS": 1})
    assert "u_prefilter" in renderer.declared_uniforms(visibility) and "u_prefilter" not in visibility
    renderer.set_uniforms(visibility, {"u_prefilter": 1.0})
    # the normalization and mesh programs lack the splat-only frame uniforms: optional by name
    mesh = renderer.program("mesh.vert", "mesh.frag")
    frame = renderer.frame_uniforms(CAMERA, Lights())
    assert OPTIONAL_FRAME_UNIFORMS <= set(frame)
    assert not OPTIONAL_FRAME_UNIFORMS & renderer.declared_uniforms(mesh)
    with pytest.raises(RenderError, match="u_cull_backfaces"):
        renderer.set_uniforms(mesh, frame)
    renderer.set_uniforms(mesh, frame, OPTIONAL_FRAME_UNIFORMS)
    foreign = renderer.ctx.program(vertex_shader=compose("plain.vert", search_path=[TEST_GLSL]).text,
                                   fragment_shader=compose("plain.frag", search_path=[TEST_GLSL]).text)
    with pytest.raises(RenderError, match="not built by this renderer"):
        renderer.set_uniforms(foreign, {})
    foreign.release()


def test_technique_with_a_misspelled_uniform_fails_to_render(renderer):
    typo = Technique("ewa-typo", "ewa.vert", "ewa.frag", blended=True,
                     uniforms=lambda options: filter_uniforms(options) | {"u_prefiltre": 1.0})
    cloud = scenes.sphere(200)
    with pytest.raises(RenderError, match="u_prefiltre"):
        renderer.render(cloud, CAMERA, typo)
    # declared as ewa is (its edge coverage and fringe among them): the same picture
    optional = dataclasses.replace(TECHNIQUES["ewa"], name="ewa-optional", uniforms=typo.uniforms,
                                   optional_uniforms=frozenset({"u_prefiltre"}))
    np.testing.assert_array_equal(renderer.render(cloud, CAMERA, optional).color,
                                  renderer.render(cloud, CAMERA, "ewa").color)


# -- techniques and options ------------------------------------------------------------


def test_technique_table_lists_every_technique():
    assert tuple(TECHNIQUES) == get_args(TechniqueName)
    for name, technique in TECHNIQUES.items():
        assert technique.name == name and get_technique(name) is technique
    with pytest.raises(InputError, match="unknown technique 'nope'; choose one of blend, ewa, flat, perspective"):
        get_technique("nope")


def test_options_by_concern():
    options = RenderOptions()
    assert options.filter == FilterOptions(prefilter=True, cutoff=1.0)
    assert options.visibility == VisibilityOptions(depth_epsilon=1.0, cull_backfaces=None)   # None: automatic
    assert options.kernel == KernelOptions("pajarola", 6.0, 1.5, 3.0, 0.5) and not options.deferred
    assert KERNELS == get_args(KernelName) == ("pajarola", "gaussian")
    assert KernelOptions().exponent() == (6.0, 3.0)
    assert KernelOptions(name="gaussian", b=1.5, sigma=0.5).exponent() == (4.5, 2.0)
    with pytest.raises(InputError, match="depth epsilon"):
        VisibilityOptions(depth_epsilon=-1.0)
    with pytest.raises(InputError, match="must be a FilterOptions"):
        RenderOptions(filter=VisibilityOptions())
    with pytest.raises(TypeError):
        RenderOptions(prefilter=False)  # the flat fields are gone


# -- the default renderer ------------------------------------------------------------


@pytest.mark.gl
def test_default_renderer_and_reset_in_a_fresh_process():
    script = """
from surfsplat import scenes
from surfsplat.camera import Camera
from surfsplat.rendering import context, renderer
a = renderer.default_renderer()
assert renderer.default_renderer() is a and a.ctx is context.headless_context()
cam = Camera(eye=(0, 0, 3), width=32, height=32)
before = a.render(scenes.sphere(300), cam, "ewa").color
renderer.reset_default_renderer()
assert context._headless is None and renderer._default is None
b = renderer.default_renderer()
assert b is not a and b.ctx is context.headless_context()
assert (b.render(scenes.sphere(300), cam, "ewa").color == before).all()
renderer.reset_default_renderer()
renderer.reset_default_renderer()  # nothing to release: no error
print("ok")
"""
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr
