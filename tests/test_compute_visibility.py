"""The compute passes of the small splats (render/compute_visibility.py, glsl/visibility.comp) and the
upload order.

The compute visibility pass runs the raster visibility pass's own per-splat and per-pixel code and keeps
the same minima, so every blended frame must equal the raster-only frame bit for bit: clip lines, normal
fields, back faces, tiles, sub-pixels, the GPU LOD cut. "flat" keeps per pixel the nearest disk and, of
those at that depth, the first splat, as a depth test in draw order does: its frames equal the raster
ones except where two disks tie (the same depth, another splat's colour). The upload's Morton order
inside each radius class only changes the order in which fragments are summed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import Camera, frame_bounds
from surfsplat.errors import InputError
from surfsplat.geometry.neighbors import spatial_order
from surfsplat.hierarchy import build_hierarchy
from surfsplat.hierarchy.sequential import sequential_layout
from surfsplat.lighting import Lights
from surfsplat.rendering import compute_visibility
from surfsplat.rendering.gpu_splats import radius_classes
from surfsplat.rendering.options import RenderOptions, VisibilityOptions
from surfsplat.rendering.renderer import Renderer
from surfsplat.rendering.sequential import render_sequential

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): renderers of their own on the headless context

BLENDED = ("ewa", "blend", "phong", "perspective")
TECHNIQUES = BLENDED + ("flat",)


def modes(options=RenderOptions()):
    """``options`` drawing every splat through the raster pipeline, then with the compute passes."""
    return replace(options, compute=False), replace(options, compute=True)


@pytest.fixture
def counted(monkeypatch):
    """Splats the compute pass was given, per frame (a list of counts)."""
    counts = []
    original = compute_visibility.dispatch

    def dispatch(program, buffers, ranges):
        counts.append(sum(n for _, n in ranges))
        original(program, buffers, ranges)

    monkeypatch.setattr(compute_visibility, "dispatch", dispatch)
    return counts


def view(cloud, width=96, height=80, direction=(0.4, 0.7, 1.0)):
    camera = frame_bounds(*cloud.bounds(), width=width, height=height, direction=direction)
    return camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))


def assert_same(a, b, technique="ewa"):
    """Bit for bit; "flat": the same depths and coverage, colours equal but where disks tie."""
    for name in ("depth", "weight", "alpha") if technique == "flat" else ("color", "depth", "weight", "alpha"):
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(np.isnan(x), np.isnan(y)), name
        assert np.array_equal(np.nan_to_num(x), np.nan_to_num(y)), name
    if technique == "flat":
        assert np.mean(np.all(a.color == b.color, axis=-1)) > 0.999


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_sharp_cube_equals_raster(gl_renderer, counted, technique):
    """Clip lines (the sphere-cube's edges) and a view where every small splat is computed."""
    cloud = scenes.sphere_cube(20_000)
    camera = view(cloud)
    raster, compute = (gl_renderer.render(cloud, camera, technique, Lights(), options) for options in modes())
    assert counted and counted[-1] > 0.9 * len(cloud)
    assert raster.weight.max() > 0 and (raster.alpha > 0).mean() > 0.2
    assert_same(raster, compute, technique)


@pytest.mark.parametrize("technique", ("ewa", "phong", "flat"))
def test_back_faces_tiles_and_subpixels_equal_raster(gl_renderer, counted, technique):
    """An open sheet seen from both sides without culling (the back record), drawn in several tiles
    at 2x2 sub-pixels, with a normal field (phong)."""
    torus = scenes.torus(120, 48)
    keep = torus.positions[:, 2] > -0.1   # cut open: inner back sides show
    cloud = torus.subset(np.flatnonzero(keep))
    if technique == "phong":
        field = np.random.default_rng(0).uniform(-0.3, 0.3, (len(cloud), 2)).astype("f4")
        cloud = cloud.replace(normal_field=field)
    camera = view(cloud, 70, 60, direction=(0.2, -0.9, -0.6))
    raster, compute = (gl_renderer.render(cloud, camera, technique, Lights(), options, supersample=2, max_tile=48)
                       for options in modes(RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))))
    assert counted and min(counted) > 0
    assert_same(raster, compute, technique)


@pytest.mark.parametrize("technique", ("ewa", "flat"))
def test_gpu_lod_cut_equals_raster(gl_renderer, counted, technique):
    """The sequential layout's ranges (the viewer's GPU LOD cut) split the same way."""
    cloud = scenes.torus(200, 80)
    hierarchy = build_hierarchy(cloud)
    camera = view(cloud, 90, 70)
    layout = sequential_layout(hierarchy)
    frames = [render_sequential(gl_renderer, layout.splats, layout.lod, camera, technique, Lights(), options,
                                (1.0, 1.0, 1.0), 2.0)[0] for options in modes()]
    assert counted and counted[-1] > 0
    assert_same(*frames, technique)


def test_large_splats_stay_raster(gl_renderer, counted):
    """Splats whose box may exceed COMPUTE_SPLAT_PX are drawn, not computed; the frame is the same."""
    cloud = scenes.checkerboard(12)   # 144 splats over the view: tens of pixels each
    camera = view(cloud, 120, 100, direction=(0.0, 0.3, 1.0))
    raster, compute = (gl_renderer.render(cloud, camera, "ewa", Lights(), options) for options in modes())
    assert counted == [] or counted[-1] == 0
    assert (raster.alpha > 0).mean() > 0.3
    assert_same(raster, compute)


@pytest.mark.parametrize("technique", ("ewa", "flat"))
def test_dispatches_split_at_the_work_group_limit(gl_renderer, counted, monkeypatch, technique):
    """Ranges longer than one dispatch's work groups (65,535 of 64 splats: 4.2 M splats) are run in
    several dispatches: with the limit lowered to 3 groups the frame still equals the raster one."""
    monkeypatch.setattr(compute_visibility, "MAX_COMPUTE_GROUPS", 3)
    cloud = scenes.sphere(3000)
    camera = view(cloud)
    raster, compute = (gl_renderer.render(cloud, camera, technique, Lights(), options) for options in modes())
    assert counted and counted[-1] > 0.9 * len(cloud)
    assert_same(raster, compute, technique)


def test_without_opengl_43_every_splat_is_drawn(gl_renderer, counted, monkeypatch):
    """A context without compute shaders draws the raster passes alone, whatever the option asks."""
    monkeypatch.setattr(compute_visibility, "has_compute", lambda ctx: False)
    fallback = Renderer(gl_renderer.ctx)
    try:
        assert fallback.has_compute is False
        cloud = scenes.sphere(4000)
        frame = fallback.render(cloud, view(cloud), "ewa", Lights())
        assert counted == [] and (frame.alpha > 0).mean() > 0.1
    finally:
        fallback.release()


def test_compute_option_is_checked_and_reachable_from_the_cli(counted, tmp_path):
    """RenderOptions(compute=...) takes a bool; ``--no-compute`` on the command line turns the passes off."""
    with pytest.raises(InputError, match="compute must be True or False"):
        RenderOptions(compute="no")
    from surfsplat.cli import main

    assert main(["-q", "demo", "--scene", "sphere", "-o", str(tmp_path / "a.png"), "--width", "64",
                 "--height", "64"]) == 0
    assert counted and counted[-1] > 0
    counted.clear()
    assert main(["-q", "demo", "--scene", "sphere", "-o", str(tmp_path / "b.png"), "--width", "64",
                 "--height", "64", "--no-compute"]) == 0
    assert counted == []


def test_small_blocks_partition_the_ranges_and_bound_every_box(gl_renderer):
    """GpuSplats.small_blocks and split_blocks: the ranges cut at block boundaries into two parts that cover
    them exactly, and every splat of the small part covers a window box of at most the limit (NumPy: the
    projected corners of its parallelogram, as disk_bounds bounds it); a view from far away makes every
    block small, a close-up leaves the near ones to the raster pass."""
    from surfsplat.rendering.gpu_splats import BLOCK

    cloud = scenes.torus(400, 100)   # 40,000 splats: 10 blocks
    gpu = gl_renderer.upload(cloud)
    try:
        ranges = [(0, 1000), (1500, gpu.count - 1500)]
        want = sorted(i for f, n in ranges for i in range(f, f + n))
        box = 6.0
        for distance, expect_small, expect_others in ((40.0, True, False), (4.0, True, True), (1.5, False, True)):
            eye = distance * np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])   # the torus is at 0
            camera = Camera(eye=tuple(eye), target=(0, 0, 0), up=(0, 0, 1), fov=40, width=200, height=160)
            camera = gpu.gpu_camera(camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max())))
            others, small = gpu.split_blocks(ranges, gpu.small_blocks(camera, box))
            got = sorted(i for f, n in others + small for i in range(f, f + n))
            assert got == want
            assert bool(small) == expect_small and bool(others) == expect_others
            starts = {f for f, _ in ranges}
            assert all(f % BLOCK == 0 or f in starts for f, _ in others + small)   # cut at block boundaries
            if not small:
                continue
            # every small splat's parallelogram projects into a box of at most `box` pixels
            picked = np.concatenate([np.arange(f, f + n) for f, n in small])
            p = np.frombuffer(gpu.buffers["position"].read(), "f4").reshape(-1, 3)[picked].astype(np.float64)
            u = np.frombuffer(gpu.buffers["u"].read(), "f4").reshape(-1, 3)[picked].astype(np.float64)
            v = np.frombuffer(gpu.buffers["v"].read(), "f4").reshape(-1, 3)[picked].astype(np.float64)
            m = camera.view_matrix
            px = []
            for su in (-1, 1):
                for sv in (-1, 1):
                    q = (p + su * u + sv * v) @ m[:3, :3].T + m[:3, 3]
                    px.append(camera.focal_px * q[:, :2] / -q[:, 2:])
            px = np.stack(px)
            width = (px.max(axis=0) - px.min(axis=0)).max(axis=1)
            assert width.max() <= box
    finally:
        gpu.release()


def test_radius_classes_keep_morton_order_inside_each_class():
    rng = np.random.default_rng(4)
    positions = rng.uniform(-1.0, 1.0, (3000, 3))
    radii = rng.choice([0.01, 0.02, 0.05], 3000).astype("f4")
    order, start, top = radius_classes(radii, positions)
    assert sorted(order.tolist()) == list(range(3000))
    plain_order, plain_start, plain_top = radius_classes(radii)
    assert np.array_equal(start, plain_start) and np.array_equal(top, plain_top)
    ends = np.append(start[1:], len(radii))
    rank = np.empty(3000, np.int64)
    rank[spatial_order(positions)] = np.arange(3000)
    for s, e in zip(start, ends):
        members = order[s:e]
        assert np.all(np.diff(rank[members]) > 0)   # the class's splats in Morton order
        assert np.array_equal(np.sort(members), np.sort(plain_order[s:e]))
