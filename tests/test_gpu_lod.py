"""Level of detail on the GPU: sequential point trees (hierarchy/sequential.py, render/sequential.py)."""

from __future__ import annotations

from pathlib import Path

import surfsplat
import moderngl
import numpy as np
import pytest

from surfsplat import api, pipeline
from surfsplat.pipeline import as_model
from surfsplat.camera import Camera
from surfsplat.cli import main
from surfsplat.errors import InputError
from surfsplat.hierarchy import build_hierarchy
from surfsplat.hierarchy.sequential import BIG, drawn_mask, sequential_layout
from surfsplat.metrics import psnr
from surfsplat.rendering.options import RenderOptions, VisibilityOptions
from surfsplat.rendering.renderer import _with_clip_planes
from surfsplat.rendering.sequential import GpuSequential, upload_sequential
from surfsplat.rendering.shaders import compose
from surfsplat.rendering.uniform_blocks import FrameBlocks
from surfsplat.scenes import checkerboard, demo_scene, sphere
from surfsplat.viewer.detail import LevelOfDetail, recolor

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): every test renders

TEST_GLSL = Path(__file__).resolve().parent / "glsl"
SIZE = 160


def view(cloud, factor: float, size: int = SIZE, turn: float = 0.0) -> Camera:
    """The automatic camera of ``cloud`` with the eye ``factor`` times as far from the target, turned
    ``turn`` degrees about the up axis."""
    cam = pipeline.auto_camera(cloud, size, size)
    if turn:
        cam = api.orbit_cameras(cam, 360, 360.0)[int(turn)]
    target = np.asarray(cam.target)
    eye = target + factor * (np.asarray(cam.eye) - target)
    return Camera(eye=tuple(eye), target=cam.target, up=cam.up, fov=cam.fov, width=size, height=size)


def gpu_model(renderer, cloud):
    h = build_hierarchy(cloud)
    layout = sequential_layout(h)
    return h, layout, upload_sequential(renderer, layout.splats, layout.lod)


@pytest.fixture(scope="module")
def torus(gl_renderer):
    model = gpu_model(gl_renderer, demo_scene("torus"))
    yield model
    model[2].release()


def world_distance(layout, camera: Camera) -> np.ndarray:
    return np.linalg.norm(layout.splats.positions.astype(np.float64) + layout.splats.origin - np.asarray(camera.eye),
                          axis=1)


def cpu_drawn(layout, gpu, camera: Camera, tolerance: float) -> np.ndarray:
    """The NumPy interval rule for ``camera`` (world) with the near plane the renderer draws with."""
    local = gpu.gpu_camera(_with_clip_planes(camera, gpu))
    return drawn_mask(layout.lod, world_distance(layout, camera), local.focal_px / tolerance, local.near / gpu.scale)


def test_the_shader_keeps_exactly_the_entries_of_the_numpy_rule(renderer, torus):
    """Transform feedback of the shared GLSL test (splat_attributes.glsl) over the uploaded buffers
    against drawn_mask on the same float32 values; with the image's tile, the frustum test drops only
    entries whose bounding sphere lies outside the view."""
    _, _, gpu = torus
    ctx = renderer.ctx
    program = ctx.program(vertex_shader=compose("lod_feedback.vert", {"SEQUENTIAL_LOD": 1},
                                                search_path=[TEST_GLSL]).text, varyings=["out_kept"])
    vao = ctx.vertex_array(program, [(gpu.buffers[name], f"{k}f", f"in_{name}")
                                     for name, k in (("position", 3), ("lod", 4), ("u", 3), ("v", 3))])
    radius = np.maximum(*(np.linalg.norm(np.frombuffer(gpu.buffers[name].read(), "f4").reshape(-1, 3), axis=1)
                          for name in ("u", "v")))
    out = ctx.buffer(reserve=4 * gpu.count)
    blocks = FrameBlocks(ctx)
    blocks.attach(program)
    positions = np.frombuffer(gpu.buffers["position"].read(), "f4").reshape(-1, 3).astype(np.float64)
    lod = np.frombuffer(gpu.buffers["lod"].read(), "f4").reshape(-1, 4)
    try:
        for factor, tolerance in ((0.5, 1.0), (1.0, 0.5), (2.0, 2.0), (6.0, 1.0)):
            camera = gpu.gpu_camera(_with_clip_planes(view(torus[0].points, factor), gpu))
            m = camera.view_matrix
            block = {"u_view": tuple(m.T.astype("f4").ravel()), "u_near_far": (camera.near, camera.far),
                     "u_focal": camera.focal_px, "u_viewport": (camera.width, camera.height)}
            program["u_lod_scale"].value = camera.focal_px / tolerance
            renderer.park()   # a complete framebuffer bound (the headless context has none of its own)
            blocks.bind(block | {"u_tile": (0.0, 0.0, camera.width, camera.height)})   # camera.glsl's block
            vao.transform(out, moderngl.POINTS, vertices=gpu.count)
            in_view = np.frombuffer(out.read(), "f4") > 0.5
            # no frustum culling: the interval alone
            blocks.bind(block | {"u_tile": (-1e6, -1e6, 2e6, 2e6)})
            vao.transform(out, moderngl.POINTS, vertices=gpu.count)
            kept = np.frombuffer(out.read(), "f4") > 0.5
            q = positions @ m[:3, :3].T + m[:3, 3]
            d = np.linalg.norm(q, axis=1)
            scale = camera.focal_px / tolerance
            expected = drawn_mask(lod, d, scale, camera.near)
            s, near = np.float32(scale), np.float32(camera.near)
            low = lod[:, 0] + np.maximum(near, s * lod[:, 1])
            high = lod[:, 2] + np.maximum(near, s * lod[:, 3])
            margin = 1e-5 * d   # float32 rounding of the distance: either side is right
            ambiguous = (np.abs(d - low) < margin) | (np.abs(d - high) < margin)
            assert 1000 < expected.sum() < len(d) - 1000
            assert not (kept != expected)[~ambiguous].any()
            assert ambiguous.sum() <= 1e-3 * len(d)
            # frustum: a subset of the interval's entries, holding every one whose sphere is in view
            assert not (in_view & ~kept).any()
            angle = np.arctan2(np.abs(q[:, :2]), -q[:, 2:]) + np.arcsin(np.minimum(radius / d, 1.0))[:, None]
            half_fov = np.arctan(0.5 * np.array([camera.width, camera.height]) / camera.focal_px)
            inside = (q[:, 2] < 0) & (angle < half_fov).all(axis=1)
            assert not (kept & inside & ~in_view).any()
            if factor < 1:
                assert (kept & ~in_view).sum() > 0.05 * kept.sum()   # close up, many are culled
    finally:
        vao.release()
        program.release()
        out.release()
        blocks.release()


@pytest.mark.parametrize("technique", ["flat", "ewa"])
def test_the_gpu_cut_renders_as_the_same_set_drawn_from_the_cpu(renderer, torus, technique):
    """Every technique takes the interval test: the GPU cut against the NumPy-selected entries uploaded
    as a plain cloud (same splats, other order: identical opaque pixels, blended sums equal to
    float32 rounding)."""
    _, layout, gpu = torus
    camera = view(torus[0].points, 0.8)
    gpu.lod_tolerance = 1.0
    mask = cpu_drawn(layout, gpu, camera, 1.0)
    a = renderer.render(gpu, camera, technique)
    b = renderer.render(layout.splats.subset(mask), camera, technique)
    assert np.array_equal(a.mask, b.mask)
    if technique == "flat":   # ties between coplanar overlapping splats go to the first drawn: same depth
        same = np.all(a.color == b.color, axis=-1)
        assert np.array_equal(a.depth[a.mask], b.depth[b.mask])
        assert np.mean(same) > 0.99
    else:
        assert psnr(a.color, b.color) > 60.0


def test_every_point_is_covered_by_a_drawn_entry(torus):
    """No holes by construction (Dachsbacher 2003, sec. 3.2): along every root-to-point path some entry
    passes the interval test, for eyes near, far and inside the model."""
    h, layout, _ = torus
    m = layout.node_count
    center = h.node_positions[0].astype(np.float64) + h.points.origin
    rng = np.random.default_rng(7)
    eyes = [(center + rng.normal(size=3) * rng.uniform(0.5, 20.0), tolerance) for tolerance in (1.0, 3.0)
            for _ in range(8)]   # without the centre gap in r_max, most of these views have holes
    for eye, tolerance in eyes + [(center, 1.0), (center + [5.0, 3.0, 0], 0.3), (center + [40.0, 0, 0], 4.0)]:
        d = np.linalg.norm(layout.splats.positions.astype(np.float64) + layout.splats.origin - eye, axis=1)
        drawn = drawn_mask(layout.lod, d, 1000.0 / tolerance, 1e-3)
        nodes = np.flatnonzero(drawn[:m])
        delta = np.zeros(len(h.points) + 1, dtype=np.int64)
        np.add.at(delta, h.node_point_start[nodes], 1)
        np.add.at(delta, h.node_point_start[nodes] + h.node_point_count[nodes], -1)
        cover = np.cumsum(delta)[:-1] + drawn[m:]
        assert cover.min() >= 1
        assert cover.mean() < 1.5   # overlap only near interval ends
    assert drawn[m:].sum() < 0.01 * len(h.points)   # the farthest eye draws nodes, hardly any point


def test_layout_intervals(torus):
    """Root unbounded above, points unbounded below, every parent reach enlarged by the centre gap."""
    h, layout, _ = torus
    lod, m = layout.lod, layout.node_count
    assert len(layout) == len(h) + len(h.points)
    assert lod[0, 2] == BIG and (lod[m:, 0] == -BIG).all() and (lod[m:, 1] == 0).all()
    assert np.allclose(lod[:m, 1], 2 * h.node_extent)
    leaves = np.flatnonzero(h.is_leaf)
    leaves = leaves[np.argsort(h.node_point_start[leaves])]
    owner = np.repeat(leaves, h.node_point_count[leaves])   # the leaf holding each point
    gap = np.linalg.norm(h.points.positions - h.node_positions[owner], axis=1)
    assert np.allclose(lod[m:, 2], h.node_radius[owner] + gap, rtol=1e-5)
    assert np.array_equal(lod[m:, 3], (2 * h.node_extent[owner]).astype(np.float32))


@pytest.mark.parametrize("scene", ["sphere", "plane"])
def test_no_holes_at_any_distance(renderer, scene):
    """Coverage (summed alpha: edge coverage makes rim pixels fractional) of the GPU cut at one pixel equals
    the full-resolution cloud's within 1%, near and far; at three pixels (coarse node ellipses reach up to
    the tolerance past the rim) the CPU cut's."""
    cloud = sphere(40_000) if scene == "sphere" else checkerboard(200)
    h, _, gpu = gpu_model(renderer, cloud)
    try:
        for factor in (0.7, 2.0, 5.0):
            camera = view(cloud, factor, 200, turn=20)
            full = renderer.render(cloud, camera, "ewa").alpha.sum()
            for tolerance in (1.0, 3.0):
                gpu.lod_tolerance = tolerance
                cut = renderer.render(gpu, camera, "ewa").alpha.sum()
                if tolerance > 1:
                    full = renderer.render(pipeline.lod_splats(h, camera, tolerance)[0], camera, "ewa").alpha.sum()
                assert abs(float(cut) - float(full)) <= 0.01 * full, (factor, tolerance, cut, full)
    finally:
        gpu.release()


@pytest.mark.parametrize("technique", ["ewa", "blend", "flat", "phong", "perspective", "points"])
def test_gpu_cut_matches_the_cpu_cut(technique, torus):
    """PSNR of the GPU cut against hierarchy.select's (lod.py) at the same tolerance, every technique
    (back faces drawn: the CPU cut culls whole back-facing subtrees, the GPU cut each splat in its
    shader, which the points technique does not do; with the default culling, ewa)."""
    h = torus[0]
    camera = view(h.points, 0.9)
    both = RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))
    for options in [both] + ([None] if technique == "ewa" else []):
        gpu = api.render(h, camera, technique=technique, options=options,
                         lod=surfsplat.LodOptions(tolerance=1.0, mode="gpu"))
        cpu = api.render(h, camera, technique=technique, options=options, lod=surfsplat.LodOptions(tolerance=1.0))
        assert gpu.mask.sum() > 0.1 * SIZE * SIZE
        assert psnr(gpu.color, cpu.color) >= 35.0


def test_gpu_cut_matches_the_cpu_cut_far_and_supersampled(torus):
    h = torus[0]
    for factor, supersample, tolerance in ((3.0, 1, 2.0), (1.2, 2, 1.0)):
        camera = view(h.points, factor)
        gpu = surfsplat.prepare(h, lod=surfsplat.LodOptions(tolerance=tolerance, mode="gpu")).render(
            camera, supersample=supersample)
        cpu = surfsplat.prepare(h, lod=surfsplat.LodOptions(tolerance=tolerance)).render(
            camera, supersample=supersample)
        assert psnr(gpu.frame.color, cpu.frame.color) >= 35.0
        assert gpu.splats >= cpu.splats > 0   # the prefix holds at least the cut


def test_the_ranges_hold_the_whole_cut_and_shrink_as_the_camera_moves_away(torus):
    """The ranges a frame draws hold every entry of the cut once (the nodes are uploaded twice, one
    copy drawn), and fewer entries the farther the eye."""
    h, layout, gpu = torus
    gpu.lod_tolerance = 1.0
    positions = np.frombuffer(gpu.buffers["position"].read(), "f4").reshape(-1, 3).astype(np.float64)
    lod = np.frombuffer(gpu.buffers["lod"].read(), "f4").reshape(-1, 4)
    sizes = []
    for factor in (0.5, 2.0, 4.0, 8.0, 16.0, 32.0):
        camera = view(h.points, factor)
        local = gpu.gpu_camera(_with_clip_planes(camera, gpu))
        start, end = gpu.windows(local)
        ranged = np.zeros(gpu.count, dtype=bool)
        for a, b in zip(start, end):
            ranged[a:b] = True
        d = np.linalg.norm(positions - np.asarray(local.eye), axis=1)
        drawn = drawn_mask(lod, d, local.focal_px, local.near)
        cut = cpu_drawn(layout, gpu, camera, 1.0)
        assert (drawn & ranged).sum() == cut.sum() > 0
        sizes.append(gpu.prefix_count(camera))
        assert sizes[-1] == ranged.sum() < len(layout)
    assert all(a >= b for a, b in zip(sizes[1:], sizes[2:]))
    assert sizes[-1] < 0.1 * sizes[1]


def test_bad_requests_are_clear_errors(torus):
    h = torus[0]
    camera = view(h.points, 1.0)
    with pytest.raises(InputError, match="point budget"):
        api.render(h, camera, lod=surfsplat.LodOptions(mode="gpu", point_budget=1000))
    with pytest.raises(InputError, match="LOD mode"):
        api.render(h, camera, lod=surfsplat.LodOptions(mode="fpga"))
    with pytest.raises(InputError, match="tolerance > 0"):
        api.render(h, camera, lod=surfsplat.LodOptions(mode="gpu", tolerance=0.0))


def test_cli_lod_mode(tmp_path):
    out = tmp_path / "gpu.png"
    assert main(["-q", "demo", "-o", str(out), "--width", "64", "--height", "64", "--lod-tolerance", "1",
                 "--lod-mode", "gpu"]) == 0
    assert out.stat().st_size > 0
    assert main(["-q", "demo", "-o", str(out), "--lod-mode", "sometimes"]) == 2


def test_the_viewer_cuts_in_memory_hierarchies_on_the_gpu(renderer):
    """LevelOfDetail with lod_mode "gpu": one upload for every view, the CPU cut under a point budget,
    and a new upload with the new colours after recolouring."""
    h = build_hierarchy(sphere(20_000))
    lod = LevelOfDetail(renderer, as_model(h), on_gpu=True)
    on_cpu = LevelOfDetail(renderer, as_model(h), on_gpu=False)   # the viewer's plan under a point budget
    try:
        near, far = view(h.points, 3.0), view(h.points, 6.0)   # cuts keeping under half the points
        splats, count = lod(near, 1.0, False)
        assert isinstance(splats, GpuSequential) and count == splats.prefix_count(near)
        again, fewer = lod(far, 1.0, False)
        assert again is splats and fewer == splats.prefix_count(far) != count   # no upload, other ranges
        budget, n = on_cpu(near, 1.0, False, point_budget=2000)
        assert not isinstance(budget, GpuSequential) and n <= 2000
        gray = renderer.render(lod(near, 1.0, False)[0], near, "flat").color
        recolor(h, np.tile(np.float32([[1.0, 0.0, 0.0]]), (len(h.points), 1)))
        lod.release()
        red = renderer.render(lod(near, 1.0, False)[0], near, "flat")
        inside = red.mask
        assert np.allclose(gray[inside][:, 0], gray[inside][:, 1], atol=0.02)   # gray before
        assert np.median(red.color[inside][:, 1]) < 0.05 < 0.3 < np.median(red.color[inside][:, 0])   # specular aside
    finally:
        lod.close()
        on_cpu.close()


def test_the_viewer_draws_the_points_alone_where_the_gpu_cut_keeps_them(renderer):
    """A view whose GPU cut hands over at least as many entries as there are points and keeps at least
    ALL_POINTS_FRACTION of them (NumPy: points_drawn) draws the hierarchy's points from their own
    upload, the frame of the plain cloud; a farther view keeps the sequential layout."""
    from surfsplat.viewer.detail import ALL_POINTS_FRACTION, points_drawn

    h = build_hierarchy(sphere(20_000))
    layout = sequential_layout(h)
    lod = LevelOfDetail(renderer, as_model(h), on_gpu=True)
    plain = renderer.upload(h.points)
    try:
        close, mid = view(h.points, 1.0), view(h.points, 3.0)
        assert points_drawn(layout, close, 1.0) >= ALL_POINTS_FRACTION > points_drawn(layout, mid, 1.0) > 0.2
        splats, count = lod(close, 1.0, False)
        assert not isinstance(splats, GpuSequential) and count == len(h.points)
        assert lod(close, 1.0, False)[0] is splats   # uploaded once
        got, want = renderer.render(splats, close, "ewa"), renderer.render(plain, close, "ewa")
        assert np.array_equal(got.color, want.color) and np.array_equal(got.depth, want.depth, equal_nan=True)
        cut, n = lod(mid, 1.0, False)
        assert isinstance(cut, GpuSequential) and n == cut.prefix_count(mid)
        # the NumPy fraction is the shader's rule: the entries the GPU draws are those it counts
        mask = cpu_drawn(layout, cut, mid, 1.0)[layout.node_count:]
        assert abs(mask.mean() - points_drawn(layout, mid, 1.0)) < 0.01
    finally:
        plain.release()
        lod.close()


@pytest.mark.parametrize("technique", ["ewa", "points"])
def test_tiles_see_every_entry_their_pixels_need(renderer, torus, technique):
    """The per-entry frustum test uses each tile's rectangle: drawn in 64-pixel tiles (TILE_MARGIN
    around each) the image equals the one drawn in one piece."""
    _, _, gpu = torus
    gpu.lod_tolerance = 1.0
    camera = view(torus[0].points, 0.6)
    whole = renderer.render(gpu, camera, technique)
    tiled = renderer.render(gpu, camera, technique, max_tile=64)
    assert np.array_equal(whole.mask, tiled.mask)
    assert psnr(whole.color, tiled.color) > 60.0
