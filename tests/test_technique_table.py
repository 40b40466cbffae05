"""The renderer plans a frame from the technique's declared capabilities (rendering/passes.py), never from
its shader files' names: a technique defined here, with its own shaders in a search path, gets every
path it declares (GL_POINTS for the small splats, the compute passes, edge coverage, the edge fringe)
and loses each one it declares off; the built-in techniques' plans follow their declarations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import frame_bounds
from surfsplat.errors import InputError
from surfsplat.lighting import Lights
from surfsplat.rendering import compute_visibility
from surfsplat.rendering.options import RenderOptions, VisibilityOptions
from surfsplat.rendering.passes import EDGE_COVERAGE_DEFINE, FILL_GAP_PX
from surfsplat.rendering.renderer import Renderer
from surfsplat.rendering.shaders import compose
from surfsplat.rendering.technique import Technique
from surfsplat.rendering.techniques import TECHNIQUES

# A vertex shader of its own: the splat's exact disk box, through the shared includes.
TOY_VERT = """// Test technique: each splat's disk box, a quad or (POINT_PRIMITIVE) one GL_POINTS point.
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "disk_vertex.glsl"
#include "splat_primitive.glsl"

void main() {
    Splat s;
    vec2 lo, hi;
    if (!camera_splat(s) || !disk_bounds(s, lo, hi)) { gl_Position = CULLED; return; }
    emit_box(lo, hi);
}
"""

# Blended: a box kernel of weight u_toy_weight over the ray-cast disk, the splat's lit colour.
TOY_BOX_FRAG = """// Test technique: constant weight over each disk.
#include "camera.glsl"
#include "splat_fragment.glsl"

uniform float u_toy_weight;
flat in vec3 v_color;
flat in vec3 v_normal;

void main() {
    vec3 ray = pixel_ray(FRAG_PX);
    float z;
    if (!ray_disk(ray, z)) discard;
#if PASS == PASS_ACCUMULATION
    if (behind_nearest(z)) discard;
#endif
    emit(ray, z, u_toy_weight, v_color, v_normal);
}
"""

# Opaque: the lit disk at its exact depth, what opaque_resolve.frag writes (compute_opaque may be declared).
TOY_DISK_FRAG = """// Test technique: opaque lit disks.
#include "camera.glsl"
#include "splat_fragment.glsl"

flat in vec3 v_color;
flat in vec3 v_normal;

void main() {
    vec3 ray = pixel_ray(FRAG_PX);
    float z;
    if (!ray_disk(ray, z)) discard;
    emit(ray, z, 1.0, v_color, v_normal);
}
"""

BOX = Technique(name="toy_box", vertex="toy.vert", fragment="toy_box.frag", blended=True,
                uniforms=lambda options: {"u_toy_weight": 0.5}, point_footprint="disk", compute_visibility=True,
                edge_coverage=True, edge_fringe=False)
#: The same technique with every capability declared off.
BOX_OFF = replace(BOX, point_footprint=None, compute_visibility=False, edge_coverage=False)
DISK = Technique(name="toy_disk", vertex="toy.vert", fragment="toy_disk.frag", blended=False,
                 point_footprint="disk", compute_opaque=True)
DISK_OFF = replace(DISK, point_footprint=None, compute_opaque=False)

EDGES = RenderOptions(visibility=VisibilityOptions(edge_coverage=True))
NO_EDGES = RenderOptions(visibility=VisibilityOptions(edge_coverage=False))


@pytest.fixture(scope="module")
def toy_renderer(tmp_path_factory):
    """A renderer whose search path holds the toy technique's shaders."""
    folder = tmp_path_factory.mktemp("toy_glsl")
    for name, text in (("toy.vert", TOY_VERT), ("toy_box.frag", TOY_BOX_FRAG), ("toy_disk.frag", TOY_DISK_FRAG)):
        (folder / name).write_text(text, encoding="utf-8")
    renderer = Renderer(search_path=[folder])
    yield renderer
    renderer.release()


@pytest.fixture(scope="module")
def scene():
    """12,000 small splats (3 blocks; every disk a few pixels wide) and a view of them."""
    cloud = scenes.torus(200, 60)
    camera = frame_bounds(*cloud.bounds(), width=96, height=80, direction=(0.3, -0.8, 0.6))
    return cloud, camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))


@pytest.fixture
def paths(monkeypatch):
    """The splats drawn as GL_POINTS and those given to the compute passes while rendering (counts)."""
    drawn = {"points": 0, "computed": 0}
    draw_points, dispatch = Renderer._draw_points, compute_visibility.dispatch

    def points(self, splats, program, technique, ranges):
        drawn["points"] += sum(n for _, n in ranges)
        draw_points(self, splats, program, technique, ranges)

    def computed(program, buffers, ranges):
        drawn["computed"] += sum(n for _, n in ranges)
        dispatch(program, buffers, ranges)

    monkeypatch.setattr(Renderer, "_draw_points", points)
    monkeypatch.setattr(compute_visibility, "dispatch", computed)
    return drawn


def count(ranges) -> int:
    return sum(n for _, n in ranges)


def indices(ranges) -> set:
    return {i for first, n in ranges for i in range(first, first + n)}


def render(renderer, scene, technique, options=RenderOptions(), drawn=None):
    """The frame, and (with the ``paths`` fixture's dict) the paths it took, reset first."""
    if drawn is not None:
        drawn.update(points=0, computed=0)
    cloud, camera = scene
    frame = renderer.render(cloud, camera, technique, Lights(), options)
    return frame, (dict(drawn) if drawn is not None else None)


def test_toy_technique_gets_every_declared_path(toy_renderer, scene, paths):
    """GL_POINTS for the small splats and the compute visibility pass, planned and taken; the same
    technique declared without them draws every splat as a quad through the raster pipeline, and the
    pictures agree bit for bit (both paths run the same per-pixel code)."""
    gpu = toy_renderer.upload(scene[0])
    try:
        full, off = (toy_renderer.plan(gpu, scene[1], t) for t in (BOX, BOX_OFF))
    finally:
        gpu.release()
    assert full.names == ("clear", "compute_visibility", "visibility", "cracks", "accumulation", "normalization",
                          "fill")
    assert off.names == ("clear", "visibility", "cracks", "accumulation", "normalization", "fill")
    n = len(scene[0])
    accumulated = full.get("accumulation")
    assert count(accumulated.points) > 0.9 * n and count(accumulated.quads) + count(accumulated.points) <= n
    # the first pass: each accumulated splat either computed or rasterized, never both
    vis, computed = full.get("visibility"), full.get("compute_visibility").computed
    assert count(computed) > 0
    assert indices(computed).isdisjoint(indices(vis.quads + vis.points))
    assert indices(computed) | indices(vis.quads + vis.points) == indices(accumulated.quads + accumulated.points)
    for step in off.passes:   # declared off: every splat a quad, nothing computed
        assert not getattr(step, "points", ()) and not getattr(step, "computed", ())
    assert indices(off.get("accumulation").quads) == indices(accumulated.quads + accumulated.points)

    # without edge coverage, which BOX_OFF does not declare (compared on its own below)
    on_frame, on_paths = render(toy_renderer, scene, BOX, NO_EDGES, drawn=paths)
    off_frame, off_paths = render(toy_renderer, scene, BOX_OFF, NO_EDGES, drawn=paths)
    assert on_paths["points"] == count(vis.points) + count(accumulated.points)
    assert on_paths["computed"] == count(computed)
    assert off_paths == {"points": 0, "computed": 0}
    assert on_frame.mask.mean() > 0.1
    for name in ("color", "depth", "weight", "alpha"):
        np.testing.assert_array_equal(getattr(on_frame, name), getattr(off_frame, name), err_msg=name)
    # no compute asked for: the declared compute pass is off, the points stay
    _, raster = render(toy_renderer, scene, BOX, replace(RenderOptions(), compute=False), drawn=paths)
    assert raster["computed"] == 0 and raster["points"] > 0


def test_toy_technique_covers_the_disks_a_builtin_covers(toy_renderer, gl_renderer, scene):
    """The toy's box kernel has weight wherever "phong"'s Gaussian has (the same disks, the same
    visibility), and a constant weight: the accumulated weight is 0.5 times the overlapping disks."""
    toy, _ = render(toy_renderer, scene, BOX)
    phong, _ = render(gl_renderer, scene, "phong")
    np.testing.assert_array_equal(toy.weight > 0, phong.weight > 0)
    covered = toy.weight > 0
    overlaps = toy.weight[covered] / 0.5
    np.testing.assert_allclose(overlaps, np.round(overlaps), atol=1e-4)
    assert overlaps.min() >= 1.0 - 1e-4 and overlaps.max() > 1.5


def test_edge_coverage_and_fringe_follow_the_declarations(toy_renderer, scene):
    """Edge coverage declared: the option compiles EDGE_COVERAGE into the accumulation and normalization
    passes; with the fringe declared too, rim pixels no disk's distance reaches take the largest single
    disk's coverage (fractional alpha, as ewa's), without it they stay covered (as phong's). Edge
    coverage declared off: the option changes nothing. The option is on by default."""
    fringe = replace(BOX, edge_fringe=True)
    gpu = toy_renderer.upload(scene[0])
    try:
        assert toy_renderer.plan(gpu, scene[1], fringe, EDGES).edge_coverage
        assert toy_renderer.plan(gpu, scene[1], fringe).edge_coverage
        assert not toy_renderer.plan(gpu, scene[1], fringe, NO_EDGES).edge_coverage
        assert not toy_renderer.plan(gpu, scene[1], replace(fringe, edge_coverage=False), EDGES).edge_coverage
        for technique in (BOX, fringe):
            normalization = toy_renderer.plan(gpu, scene[1], technique, EDGES).get("normalization")
            assert normalization.edge_fringe is technique.edge_fringe
    finally:
        gpu.release()
    plain, _ = render(toy_renderer, scene, fringe, NO_EDGES)
    assert np.isin(plain.alpha, (0.0, 1.0)).all() and plain.mask.mean() > 0.1
    soft, _ = render(toy_renderer, scene, fringe, EDGES)
    program = toy_renderer._fullscreen_pass("normalize.frag", {EDGE_COVERAGE_DEFINE: 1}).program
    assert program["u_edge_fringe"].value == 1
    rim = (soft.alpha > 0) & (soft.alpha < 1)
    assert rim.sum() > 20
    np.testing.assert_array_equal(soft.alpha > 0, plain.alpha > 0)
    no_fringe, _ = render(toy_renderer, scene, BOX, EDGES)
    assert program["u_edge_fringe"].value == 0
    assert np.isin(no_fringe.alpha, (0.0, 1.0)).all()
    off = replace(fringe, edge_coverage=False)
    without, _ = render(toy_renderer, scene, off, NO_EDGES)
    asked, _ = render(toy_renderer, scene, off, EDGES)
    for name in ("color", "depth", "alpha"):
        np.testing.assert_array_equal(getattr(asked, name), getattr(without, name), err_msg=name)


def test_opaque_toy_gets_the_compute_passes(toy_renderer, gl_renderer, scene, paths):
    """An opaque technique declaring compute_opaque gets the nearest-disk compute passes and GL_POINTS
    and draws flat's picture; declared off, it draws every splat as a quad, raster, flat's raster picture."""
    gpu = toy_renderer.upload(scene[0])
    try:
        full, off = (toy_renderer.plan(gpu, scene[1], t) for t in (DISK, DISK_OFF))
    finally:
        gpu.release()
    assert full.names == ("clear", "opaque", "compute_opaque", "normalization", "fill")
    assert off.names == ("clear", "opaque", "normalization", "fill")
    assert full.get("normalization").side == off.get("normalization").side == "side"
    assert count(full.get("compute_opaque").computed) > 0 and not off.get("opaque").points

    toy, taken = render(toy_renderer, scene, DISK, drawn=paths)
    assert taken["computed"] == 2 * count(full.get("compute_opaque").computed)   # nearest depth, then splat
    assert taken["points"] == count(full.get("opaque").points)
    toy_off, taken = render(toy_renderer, scene, DISK_OFF, drawn=paths)
    assert taken == {"points": 0, "computed": 0}
    flat, _ = render(gl_renderer, scene, "flat")
    flat_raster, _ = render(gl_renderer, scene, "flat", replace(RenderOptions(), compute=False))
    assert toy.mask.mean() > 0.1
    for name in ("color", "depth", "alpha"):
        np.testing.assert_array_equal(getattr(toy, name), getattr(flat, name), err_msg=name)
        np.testing.assert_array_equal(getattr(toy_off, name), getattr(flat_raster, name), err_msg=name)


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_builtin_plans_follow_their_declarations(gl_renderer, scene, name):
    """Every built-in technique's plan: the blended or opaque passes, GL_POINTS exactly where a point
    footprint is declared, the compute pass exactly where declared and asked for, edge coverage and the
    fringe as declared; every drawn splat is accumulated once."""
    technique = TECHNIQUES[name]
    gpu = gl_renderer.upload(scene[0])
    try:
        plan = gl_renderer.plan(gpu, scene[1], technique, EDGES)
        raster = gl_renderer.plan(gpu, scene[1], technique, replace(EDGES, compute=False))
        unfilled = gl_renderer.plan(gpu, scene[1], technique, replace(EDGES, fill_holes=False))
    finally:
        gpu.release()
    first, last = ("visibility", "accumulation") if technique.blended else ("opaque", "opaque")
    compute = "compute_visibility" if technique.blended else "compute_opaque"
    expected = (["clear", compute, "visibility", "cracks"] + ["hiz"] * technique.hiz_cull + ["accumulation"]
                if technique.blended else ["clear", "opaque", compute])
    declared = technique.compute_visibility if technique.blended else technique.compute_opaque
    if not (declared and gl_renderer.has_compute):
        expected.remove(compute)
    assert plan.names == tuple(expected) + ("normalization", "fill")
    assert plan.get("fill").gap == FILL_GAP_PX and plan.get("normalization").filled
    assert unfilled.names == tuple(expected) + ("normalization",) and not unfilled.get("normalization").filled
    assert compute not in raster.names
    drawn = raster.get(last)   # the compute passes off: every drawn splat rasterized
    assert count(drawn.quads + drawn.points) > 0.5 * len(scene[0])
    assert (count(drawn.points) > 0) == (technique.point_footprint is not None)
    everything = indices(drawn.quads + drawn.points)
    if technique.blended:   # the accumulation draws every splat, computed first pass or not
        assert indices(plan.get(last).quads + plan.get(last).points) == everything
    if compute in plan.names:   # each splat's first pass computed or rasterized, once
        assert count(plan.get(compute).computed) > 0
        split = plan.get(first).quads + plan.get(first).points + plan.get(compute).computed
        assert count(split) == len(everything) and indices(split) == everything
    if technique.blended:   # the accumulation pass tests whole splats against the hiz pass's blocks as declared
        assert plan.get(last).hiz_block == (plan.get("hiz").block if technique.hiz_cull else 0)
    normalization = plan.get("normalization")
    assert normalization.edge_coverage == technique.edge_coverage
    assert normalization.edge_fringe == technique.edge_fringe
    assert normalization.side == ("cracks" if technique.blended else "side")


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_builtin_declarations_match_their_shaders(name):
    """A declared point footprint needs a vertex shader that emits GL_POINTS (splat_primitive.glsl), an
    "adaptive" one a smallest point size; compute visibility and edge coverage need the shared
    splat fragment code (splat_fragment.glsl) the compute pass and the coverage mirror."""
    technique = TECHNIQUES[name]
    vertex = compose(technique.vertex).files
    fragment = compose(technique.fragment).files
    assert ("splat_primitive.glsl" in vertex) == (technique.point_footprint is not None)
    assert (technique.min_point_px > 0) == (technique.point_footprint == "adaptive")
    if technique.compute_visibility or technique.edge_coverage:
        assert "splat_fragment.glsl" in fragment
    # the hiz test's depth bound is that of the shared fragment code's disk depths
    if technique.hiz_cull:
        assert "hiz.glsl" in vertex and "splat_fragment.glsl" in fragment


def test_contradictory_declarations_are_input_errors():
    with pytest.raises(InputError, match="point_footprint"):
        replace(BOX, point_footprint="square")
    with pytest.raises(InputError, match="compute_visibility"):
        replace(DISK, compute_visibility=True)
    with pytest.raises(InputError, match="edge_coverage"):
        replace(DISK, edge_coverage=True)
    with pytest.raises(InputError, match="hiz_cull"):
        replace(DISK, hiz_cull=True)
    with pytest.raises(InputError, match="compute_opaque"):
        replace(BOX, compute_opaque=True)
    with pytest.raises(InputError, match="min_point_px"):
        replace(BOX, min_point_px=-1.0)
