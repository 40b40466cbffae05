"""Per-block choices of a frame (Renderer._drawn_ranges): blocks of splats that cannot reach the view are
not drawn (GpuSplats.visible_blocks), and blocks of quads whose own nearest depth makes every splat small
enough are drawn as GL_POINTS (point_scale).

The culling is checked against NumPy (every splat of a dropped block lies wholly before the near plane,
beyond the far one, or projects beyond a side of the grown view) and against the frames drawn without it
(identical); the promotion against the frames drawn with the global choice (quads and points rasterize
the same boxes by different rules: colours within 1/255 but at a few pixels, as the global choice
already gives between its points and all quads).
"""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import Camera
from surfsplat.lighting import Lights
from surfsplat.rendering import renderer as renderer_module
from surfsplat.rendering.gpu_splats import BLOCK, merge_ranges
from surfsplat.rendering.options import RenderOptions, VisibilityOptions
from surfsplat.rendering.renderer import FRUSTUM_MARGIN_PX, Renderer, point_radius

TECHNIQUES = ("ewa", "blend", "phong", "perspective", "flat", "points")


@pytest.fixture(scope="module")
def torus():
    return scenes.torus(640, 160)   # 102,400 splats: 25 blocks


def close_view(cloud, width=120, height=96):
    """From just above the tube, looking along it: part of the torus off the sides, part behind the eye."""
    camera = Camera(eye=(1.15, -0.35, 0.55), target=(0.6, 0.9, 0.0), up=(0, 0, 1), fov=50, width=width,
                    height=height)
    return camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))


def global_ranges(self, splats, camera, technique, options, supersample, tile=None):
    """The ranges before the per-block choices: the radius classes' quads and points, every block."""
    return splats.draw_ranges(camera, point_radius(camera, splats, technique, options, supersample, self.point_px))


def test_merge_ranges():
    assert merge_ranges([(10, 5), (0, 10), (20, 3), (15, 5)]) == [(0, 23)]
    assert merge_ranges([(8, 2), (0, 4)]) == [(0, 4), (8, 2)]
    assert merge_ranges([]) == []


@pytest.mark.parametrize("tile", [None, (0, 0, 60, 48), (60, 48, 60, 48), (30, 10, 20, 70)])
def test_dropped_blocks_hold_only_splats_outside_the_view(gl_renderer, torus, tile):
    """NumPy: every splat (its parallelogram's four corners) of a block visible_blocks drops lies before
    the near plane, beyond the far one, or in front of the eye and projected beyond one side of the image
    (or of the tile drawn) grown by the margin; a close view drops some blocks, a distant one none."""
    gpu = gl_renderer.upload(torus)
    try:
        position, u, v = (np.frombuffer(gpu.buffers[k].read(), "f4").reshape(-1, 3).astype(np.float64)
                          for k in ("position", "u", "v"))
        far = Camera(eye=(0.0, -6.0, 4.0), target=(0, 0, 0), up=(0, 0, 1), fov=40, width=120, height=96)
        far = gpu.gpu_camera(far.with_clip_from_bounds(*torus.bounds(), margin=float(torus.radii.max())))
        if tile is None:
            assert gpu.visible_blocks(far, FRUSTUM_MARGIN_PX).all()
        camera = gpu.gpu_camera(close_view(torus))
        visible = gpu.visible_blocks(camera, FRUSTUM_MARGIN_PX, tile)
        assert 0 < np.count_nonzero(~visible) < len(visible)
        dropped = np.concatenate([np.arange(b * BLOCK, min((b + 1) * BLOCK, gpu.count))
                                  for b in np.flatnonzero(~visible)])
        m, f = camera.view_matrix, camera.focal_px
        corners = np.stack([(position[dropped] + su * u[dropped] + sv * v[dropped]) @ m[:3, :3].T + m[:3, 3]
                            for su in (-1, 1) for sv in (-1, 1)], axis=1)   # (n, 4, 3) camera space
        depth = -corners[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            px = f * corners[..., :2] / depth[..., None]
        x0, y0, w, h = tile or (0, 0, camera.width, camera.height)
        center = np.array([camera.width, camera.height]) / 2
        low = np.array([x0, y0]) - center - FRUSTUM_MARGIN_PX        # the grown rectangle, from the center
        high = np.array([x0 + w, y0 + h]) - center + FRUSTUM_MARGIN_PX
        ahead = (depth > 0).all(axis=1)
        beyond = np.zeros(len(dropped), bool)
        for axis in (0, 1):
            beyond |= ahead & ((px[..., axis] > high[axis]).all(axis=1) | (px[..., axis] < low[axis]).all(axis=1))
        outside = (depth < camera.near).all(axis=1) | (depth > camera.far).all(axis=1) | beyond
        assert outside.all()
    finally:
        gpu.release()


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_culled_frames_equal_the_full_draw(gl_renderer, torus, monkeypatch, technique):
    """The close view drawn with blocks dropped (and no promotion) against every block drawn: the same
    frame bit for bit (a dropped splat has no fragment in the image), with fewer splats given."""
    camera = close_view(torus)
    options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))
    gpu = gl_renderer.upload(torus)
    given = []

    def culled_only(self, splats, cam, tech, opts, supersample, tile=None):
        quads, points = global_ranges(self, splats, cam, tech, opts, supersample)
        visible = splats.visible_blocks(cam, FRUSTUM_MARGIN_PX * supersample, tile)
        quads, points = splats.split_blocks(quads, visible)[1], splats.split_blocks(points, visible)[1]
        given.append(sum(n for _, n in quads + points))
        return quads, points

    try:
        monkeypatch.setattr(Renderer, "_drawn_ranges", global_ranges)
        full = gl_renderer.render(gpu, camera, technique, Lights(), options)
        monkeypatch.undo()
        monkeypatch.setattr(Renderer, "_drawn_ranges", culled_only)
        culled = gl_renderer.render(gpu, camera, technique, Lights(), options)
        monkeypatch.undo()
    finally:
        gpu.release()
    assert 0 < given[0] < len(torus) - BLOCK
    assert full.alpha.sum() > 0.1 * full.alpha.size   # the view shows the torus
    for name in ("color", "depth", "weight", "alpha"):
        a, b = getattr(full, name), getattr(culled, name)
        assert np.array_equal(np.nan_to_num(a, nan=-7.0), np.nan_to_num(b, nan=-7.0)), name


@pytest.mark.parametrize("technique", ("ewa", "flat", "phong"))
def test_near_blocks_of_quads_far_away_become_points(gl_renderer, monkeypatch, technique):
    """A large model seen from inside its bounds: the global choice (nearest depth of the bounds: the
    near plane) draws the classes of large splats as quads everywhere; the per-block choice draws the
    distant blocks of them as points, each splat's box within the point limit (NumPy), with the same
    picture up to the quads' and points' rasterization rules."""
    cloud = scenes.torus(640, 160)
    camera = Camera(eye=(1.0, 0.0, 0.0), target=(-1.0, 0.1, 0.0), up=(0, 0, 1), fov=60, width=120, height=96)
    camera = camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))
    renderer = Renderer(point_px=12.0)   # small points: the global choice makes most splats quads
    gpu = renderer.upload(cloud)
    chosen = []
    original = Renderer._drawn_ranges

    def spy(self, splats, cam, tech, opts, supersample, tile=None):
        ranges = original(self, splats, cam, tech, opts, supersample, tile)
        chosen.append((ranges, cam))
        return ranges

    try:
        options = RenderOptions()
        monkeypatch.setattr(Renderer, "_drawn_ranges", global_ranges)
        before = renderer.render(gpu, camera, technique, Lights(), options)
        global_quads, _ = global_ranges(renderer, gpu, gpu.gpu_camera(camera),
                                        renderer_module.get_technique(technique), options, 1)
        monkeypatch.undo()
        monkeypatch.setattr(Renderer, "_drawn_ranges", spy)
        after = renderer.render(gpu, camera, technique, Lights(), options)
        monkeypatch.undo()
        (quads, points), local = chosen[0]
        n_global = sum(n for _, n in global_quads)
        n_quads = sum(n for _, n in quads)
        assert n_quads < 0.75 * n_global
        promoted = sorted(set(i for f, n in points for i in range(f, f + n))
                          & set(i for f, n in global_quads for i in range(f, f + n)))
        assert promoted
        idx = np.array(promoted)
        p, u, v = (np.frombuffer(gpu.buffers[k].read(), "f4").reshape(-1, 3)[idx].astype(np.float64)
                   for k in ("position", "u", "v"))
        m = local.view_matrix
        px = np.stack([local.focal_px * q[:, :2] / -q[:, 2:]
                       for q in ((p + su * u + sv * v) @ m[:3, :3].T + m[:3, 3] for su in (-1, 1) for sv in (-1, 1))])
        assert ((px.max(axis=0) - px.min(axis=0)).max(axis=1) <= renderer.point_px).all()
    finally:
        gpu.release()
        renderer.release()
    differ = np.abs(before.color - after.color).max(axis=-1)
    assert differ.max() < (0.02 if technique != "flat" else 1.0)
    assert np.mean(differ > 1.0 / 255) < 0.002
    assert np.array_equal(before.alpha > 0, after.alpha > 0)


@pytest.mark.parametrize("technique", ("ewa", "flat"))
def test_tiles_draw_their_own_blocks(gl_renderer, torus, monkeypatch, technique):
    """A frame drawn in 2 x 2 tiles gives each tile only the blocks that can reach it (fewer splats in all
    than four whole frames) and equals the frame drawn at once."""
    camera = close_view(torus)
    gpu = gl_renderer.upload(torus)
    given = []
    original = Renderer._drawn_ranges

    def counted(self, *a):
        quads, points = original(self, *a)
        given.append(sum(n for _, n in quads + points))
        return quads, points

    try:
        monkeypatch.setattr(Renderer, "_drawn_ranges", counted)
        whole = gl_renderer.render(gpu, camera, technique, Lights())
        tiled = gl_renderer.render(gpu, camera, technique, Lights(), max_tile=64)
    finally:
        gpu.release()
    assert len(given) == 5 and sum(given[1:]) < 4 * given[0]
    for name in ("color", "depth", "alpha"):
        a, b = getattr(whole, name), getattr(tiled, name)
        assert np.allclose(np.nan_to_num(a, nan=-7.0), np.nan_to_num(b, nan=-7.0), atol=1e-5), name


@pytest.mark.parametrize("margin", [0.0, -1.0, float("nan")])
def test_a_margin_that_is_not_positive_is_a_clear_error(gl_renderer, torus, margin):
    from surfsplat.errors import InputError

    gpu = gl_renderer.upload(torus)
    try:
        with pytest.raises(InputError, match="margin must be a positive number of pixels"):
            gpu.visible_blocks(gpu.gpu_camera(close_view(torus)), margin)
    finally:
        gpu.release()
