"""The browser viewer's shaders: the package's own ``rendering/glsl`` files composed for GLSL ES 3.00.

WebGL2 runs the desktop renderer's raster passes (``docs/guides/web.md``): the same files, composed by
the same :func:`surfsplat.rendering.shaders.compose` with :data:`~surfsplat.rendering.shaders.GLSL_ES_VERSION`
(``#version 300 es`` and the default precisions), the same pass ids and shared constants. Each program
is a (vertex, fragment) pair and its defines, as :mod:`surfsplat.rendering.passes` builds them for a
frame drawn without compute shaders, in one tile (large splats as quads, the others as GL_POINTS:
:data:`POINT_PROGRAMS`):

- the blended techniques (:data:`BLENDED_TECHNIQUES`: ``ewa``, ``perspective``, ``phong``, ``blend``): each
  technique's declared vertex and fragment files with ``PASS`` = visibility and accumulation, then
  ``cracks.frag`` and ``normalize.frag`` (Guennebaud 2003: visibility splatting, accumulation,
  normalization), the accumulation and normalization with ``EDGE_COVERAGE`` (``normalize_edges``): the
  desktop's default edge coverage (``VisibilityOptions.edge_coverage``), the accumulation writing the
  splats' pixel coverage into a third float target by additive blending;
- ``flat``: ``disk.vert``/``flat.frag``, one opaque pass, then ``normalize.frag``;
- ``points``: ``points.vert``/``points.frag``, one opaque pass, ``normalize.frag``, then eye-dome
  lighting (``edl.frag``, the formula of :mod:`surfsplat.rendering.edl`);
- ``fill``: after the normalization of every technique, the desktop's screen-space hole filling
  (``fill.frag``, ``RenderOptions.fill_holes``, on by default) with the gap and reach of a frame drawn one
  sample a pixel (:func:`surfsplat.rendering.passes.fill_gap`); ``fill_K`` those of K x K sub-pixels;
- ``downsample``: a supersampled page's sub-pixels reduced to the canvas (``downsample.frag``, the twin of
  :func:`surfsplat.rendering.tiles.box_reduce`), before eye-dome lighting.

The splat programs are built with ``HYBRID_POINTS``: a per-splat ``in_nonplanar`` attribute
(the page's ``nonplanar`` stream, exported where the view plan draws the model hybrid) turns a splat into
a disk facing the eye in the vertex shader (``splat_vertex.glsl``, ``facing_axes``), what
:func:`surfsplat.rendering.hybrid.facing_points` does to the desktop's splats on the CPU each frame.
Unbound, the attribute reads 0: every splat a surface splat. ``points`` draws round points already.

What does not port: the compute passes (``visibility.comp``, ``opaque_resolve.frag``: WebGL2 has no
compute shaders, SSBOs or image atomics; the raster path draws the same pictures) and the accumulation
pass's block culling (``hiz.frag``, a speed-up that leaves the picture as it is: not drawn on the page).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..rendering.edl import NEIGHBOURS
from ..rendering.options import TechniqueName
from ..rendering.options import RenderOptions
from ..rendering.passes import EDGE_COVERAGE_DEFINE, fill_gap, fill_reach
from ..rendering.shaders import GLSL_ES_VERSION, PASS_ACCUMULATION, PASS_OPAQUE, PASS_VISIBILITY, PROLOGUE, compose
from ..rendering.uniform_blocks import FRAME_BLOCKS, block_layout
from ..rendering.shaders import read_source
from ..rendering.techniques import get_technique


@dataclass(frozen=True)
class WebProgram:
    """One program of the browser viewer: its files, defines and composed ES sources."""

    name: str
    vertex: str
    fragment: str
    defines: tuple[tuple[str, object], ...]
    vertex_text: str
    fragment_text: str
    files: tuple[str, ...]


#: The most sub-pixels per output pixel along each axis the page draws (``supersample``; float targets of
#: 1024 x 768 pixels at 4 x 4 sub-pixels take about 1.2 GB).
MAX_PAGE_SUPERSAMPLE = 4
#: The blended techniques the browser viewer draws (visibility, cracks, accumulation, normalization).
BLENDED_TECHNIQUES: tuple[TechniqueName, ...] = ("ewa", "perspective", "phong", "blend")


def _programs() -> dict[str, tuple[str, str, dict[str, object]]]:
    programs: dict[str, tuple[str, str, dict[str, object]]] = {}
    for name in BLENDED_TECHNIQUES:
        technique = get_technique(name)
        programs[f"{name}_visibility"] = (technique.vertex, technique.fragment,
                                          {"PASS": PASS_VISIBILITY, "HYBRID_POINTS": 1})
        programs[f"{name}_accumulation"] = (technique.vertex, technique.fragment,
                                            {"PASS": PASS_ACCUMULATION, "HYBRID_POINTS": 1, EDGE_COVERAGE_DEFINE: 1})
    programs.update({
        "cracks": ("fullscreen.vert", "cracks.frag", {}),
        "normalize": ("fullscreen.vert", "normalize.frag", {}),
        "normalize_edges": ("fullscreen.vert", "normalize.frag", {EDGE_COVERAGE_DEFINE: 1}),
        "downsample": ("fullscreen.vert", "downsample.frag", {}),
        "flat": ("disk.vert", "flat.frag", {"PASS": PASS_OPAQUE, "HYBRID_POINTS": 1}),
        "points": ("points.vert", "points.frag", {"PASS": PASS_OPAQUE}),
        "edl": ("fullscreen.vert", "edl.frag", {"EDL_NEIGHBOURS": NEIGHBOURS}),
    })
    for k in range(1, MAX_PAGE_SUPERSAMPLE + 1):   # the fill pass of each supersampling (its gap: a define)
        gap = fill_gap(RenderOptions(), k)
        programs[fill_program(k)] = ("fullscreen.vert", "fill.frag", {"FILL_GAP": gap, "FILL_REACH": fill_reach(gap)})
    return programs


def fill_program(supersample: int) -> str:
    """The name of the fill pass's program of a page drawn with ``supersample`` sub-pixels a pixel per axis."""
    return "fill" if supersample == 1 else f"fill_{supersample}"


#: name -> (vertex file, fragment file, defines): every program the browser viewer draws with.
PROGRAMS: dict[str, tuple[str, str, dict[str, object]]] = _programs()

#: The splat programs also built with ``POINT_PRIMITIVE`` (``<name>_points``): small splats as GL_POINTS,
#: one vertex each, as the desktop renderer draws its small splats (``splat_primitive.glsl``).
POINT_PROGRAMS = (*(f"{name}_{step}" for name in BLENDED_TECHNIQUES for step in ("visibility", "accumulation")),
                  "flat", "points")
for _name in POINT_PROGRAMS:
    _vertex, _fragment, _defines = PROGRAMS[_name]
    PROGRAMS[f"{_name}_points"] = (_vertex, _fragment, {**_defines, "POINT_PRIMITIVE": 1})

#: The techniques the browser viewer draws.
WEB_TECHNIQUES: tuple[TechniqueName, ...] = (*BLENDED_TECHNIQUES, "flat", "points")


def web_program(name: str) -> WebProgram:
    """The program ``name`` of :data:`PROGRAMS` composed for GLSL ES 3.00 (one file numbering for its
    two stages, as :func:`surfsplat.rendering.shaders.build_program` composes a desktop program)."""
    vertex, fragment, defines = PROGRAMS[name]
    files = [PROLOGUE]
    vs = compose(vertex, defines, files=files, version=GLSL_ES_VERSION)
    fs = compose(fragment, defines, files=files, version=GLSL_ES_VERSION)
    return WebProgram(name, vertex, fragment, tuple(sorted(defines.items())), vs.text, fs.text, tuple(files))


def web_programs() -> dict[str, WebProgram]:
    """Every program of :data:`PROGRAMS`, composed from the current ``glsl/`` files."""
    return {name: web_program(name) for name in PROGRAMS}


def block_layouts() -> dict:
    """The std140 layouts of the frame's uniform blocks (:data:`~surfsplat.rendering.uniform_blocks.FRAME_BLOCKS`),
    read from their GLSL declarations: block name -> {"binding", "size", "members": [{name, type, length,
    offset}]}, for the viewer to write the same bytes the desktop renderer writes."""
    layouts = {}
    for block, (file, binding) in FRAME_BLOCKS.items():
        layout = block_layout(block, read_source(file))
        layouts[block] = {"binding": binding, "size": layout.size,
                          "members": [{"name": m.name, "type": m.type, "length": m.length, "offset": m.offset}
                                      for m in layout.members]}
    return layouts


def shader_bundle() -> dict:
    """What the viewer's ``shaders.js`` holds: each program's sources and the uniform blocks' layouts."""
    return {"programs": {name: {"vertex": p.vertex_text, "fragment": p.fragment_text, "files": list(p.files)}
                         for name, p in web_programs().items()},
            "blocks": block_layouts()}
