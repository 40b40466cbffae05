"""The fast render path: small splats drawn as GL_POINTS, large ones as quads, in one frame.

The primitive only decides which fragments are generated; each fragment is tested as exactly as
before, so a points frame must equal the all-quads frame (renderer.py: ``point_px``, ``radius_classes``).
"""

from __future__ import annotations

from dataclasses import replace

import surfsplat
import numpy as np
import pytest
from scipy import ndimage

from surfsplat import scenes
from surfsplat.camera import Camera, frame_bounds
from surfsplat.cloud import SplatCloud
from surfsplat.lighting import Lights
from surfsplat.metrics import psnr
from surfsplat.rendering.lod_auto import (AUTO, AUTO_LOD_PX, AUTO_MIN_DENSITY, auto_lod_tolerance, auto_merged,
                                      merge_in_pixels, points_per_pixel)
from surfsplat.rendering.options import RenderOptions
from surfsplat.rendering.gpu_splats import CLASSES_PER_OCTAVE, radius_classes
from surfsplat.rendering.renderer import Renderer, point_radius
from surfsplat.rendering.techniques import get_technique

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): renderers of their own on the headless context


@pytest.fixture(scope="module")
def renderers(gl_renderer):
    """(all quads, the default split, all points) on the session's context."""
    made = Renderer(gl_renderer.ctx, point_px=0), Renderer(gl_renderer.ctx, point_px=1e6)
    yield made[0], gl_renderer, made[1]
    for r in made:
        r.release()


@pytest.fixture(scope="module")
def batched(gl_renderer):
    """Draw calls of 1,000 splats: quads (attributes re-bound per batch) and points."""
    made = Renderer(gl_renderer.ctx, point_px=0, draw_batch=1000), Renderer(gl_renderer.ctx, draw_batch=1000)
    yield made
    for r in made:
        r.release()


@pytest.fixture(scope="module")
def mixed_view():
    """A torus of small splats and a few large slanted ones in front of it: both classes in one frame."""
    torus = scenes.torus(160, 64)
    rng = np.random.default_rng(3)
    n = 12
    lo, hi = torus.bounds()
    positions = rng.uniform(lo, hi, (n, 3)).astype("f4")
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    u = np.cross(normals, [0.3, 0.5, 0.8])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(normals, u)
    big = SplatCloud(positions, normals, rng.uniform(0.2, 1.0, (n, 3)), u * 1.2, v * 0.2)
    cloud = SplatCloud(*(np.concatenate([getattr(torus, k), getattr(big, k)])
                         for k in ("positions", "normals", "colors", "u", "v")))
    camera = frame_bounds(*cloud.bounds(), width=120, height=96, direction=(0.3, 0.8, 1.0))
    return cloud, camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))


def test_radius_classes_order_and_bounds():
    radii = np.random.default_rng(0).lognormal(-3.0, 1.5, 5000).astype("f4")
    radii[:3] = 0.0   # degenerate radii share the last class
    order, start, top = radius_classes(radii)
    assert sorted(order.tolist()) == list(range(len(radii)))
    ordered = radii[order]
    assert start[0] == 0 and np.all(np.diff(start) > 0) and np.all(np.diff(top) < 0)
    assert top[0] == pytest.approx(radii.max())
    ends = np.append(start[1:], len(radii))
    for s, e, bound in zip(start, ends, top):
        cls = ordered[s:e]
        assert cls.max() <= bound * (1 + 1e-6)
        if e < len(radii) - 3:   # a full class: every radius within one class width below its bound
            assert cls.min() >= bound * 2.0 ** (-1.0 / CLASSES_PER_OCTAVE) * (1 - 1e-6)
    assert np.all(ordered[-3:] == 0.0)


def test_the_mixed_view_uses_both_primitives(renderers, mixed_view):
    cloud, camera = mixed_view
    _, default, _ = renderers
    gpu = default.upload(cloud)
    try:
        for name in ("ewa", "perspective", "flat", "blend"):
            quads = gpu.quad_count(point_radius(camera, gpu, get_technique(name), RenderOptions()))
            assert 0 < quads < len(cloud) // 10, name   # the large splats, and only they, are quads
        assert gpu.quad_count(0.0) == len(cloud)   # no point radius: every splat a quad
        # a technique without a point shader draws quads only
        quads_only = replace(get_technique("perspective"), point_footprint=None)
        assert gpu.quad_count(point_radius(camera, gpu, quads_only, RenderOptions())) == len(cloud)
    finally:
        gpu.release()


@pytest.mark.parametrize("technique", ["flat", "phong", "blend", "perspective", "points"])
def test_points_draw_exactly_the_quads_image(renderers, mixed_view, technique):
    cloud, camera = mixed_view
    images = [r.render(cloud, camera, technique, Lights()) for r in renderers]
    assert images[0].mask.mean() > 0.1
    for frame in images[1:]:
        for name in ("color", "depth", "weight", "alpha"):
            np.testing.assert_array_equal(getattr(frame, name), getattr(images[0], name), err_msg=name)


def test_ewa_points_match_quads(renderers, mixed_view):
    """EWA's accumulation box is not pixel-aligned: a quad's rasterizer may drop a pixel center on its
    very edge that the point (snapped to the pixel centers) keeps; nothing else may differ."""
    cloud, camera = mixed_view
    quads, default, points = (r.render(cloud, camera, "ewa", Lights()) for r in renderers)
    for frame in (default, points):
        np.testing.assert_array_equal(frame.mask, quads.mask)
        differ = np.abs(frame.color - quads.color).max(axis=-1) > 1e-5
        assert differ.mean() < 0.005
        np.testing.assert_allclose(frame.color, quads.color, atol=0.03)
        covered = quads.mask
        np.testing.assert_allclose(frame.depth[covered], quads.depth[covered], rtol=1e-3)


@pytest.mark.parametrize("technique", ["flat", "blend"])
def test_batched_draw_calls_draw_the_same_image(renderers, batched, mixed_view, technique):
    """Splats drawn 1,000 per draw call (the driver's memory bound) give the image of one draw call,
    as quads and as points; the order of the splats, and so every sum, is unchanged."""
    cloud, camera = mixed_view
    whole = [r.render(cloud, camera, technique, Lights()) for r in renderers[:2]]
    for one, split in zip(whole, batched):
        parts = split.render(cloud, camera, technique, Lights())
        for name in ("color", "depth", "weight"):
            np.testing.assert_array_equal(getattr(parts, name), getattr(one, name), err_msg=name)


@pytest.mark.parametrize("technique", ["ewa", "flat"])
def test_tiled_points_equal_one_tile(renderers, mixed_view, technique):
    """Points are clipped by their center: each is placed at the center of its box within the tile, so
    splats across tile borders (and the fringe tests' one-pixel margin) are drawn in every tile."""
    cloud, camera = mixed_view
    points = renderers[2]
    whole = points.render(cloud, camera, technique, Lights(), supersample=2)
    tiled = points.render(cloud, camera, technique, Lights(), supersample=2, max_tile=32)
    for name in ("color", "depth", "weight", "alpha"):
        np.testing.assert_array_equal(getattr(tiled, name), getattr(whole, name), err_msg=name)


# -- lod_tolerance="auto" ---------------------------------------------------------------------------

def test_points_per_pixel_counts_points_over_covered_pixels():
    """A grid of 3 x 3 points inside each of 20 x 10 pixels facing the camera: 9 points per pixel,
    whatever the supersampling divides (K = 3: one point per sub-pixel)."""
    camera = Camera(eye=(0.0, 0.0, 5.0), target=(0, 0, 0), up=(0, 1, 0), width=64, height=48, fov=30,
                    near=1.0, far=10.0)
    pixel = 5.0 / camera.focal_px   # model units per pixel at depth 5
    xs, ys = np.meshgrid((np.arange(60) + 0.5) / 3.0 + 3.0, (np.arange(30) + 0.5) / 3.0 + 5.0)   # sub-pixel centres
    points = np.stack([(xs - 32.0) * pixel, (ys - 24.0) * pixel, np.zeros(xs.shape)], axis=-1).reshape(-1, 3)
    points = points.astype("f4")
    assert points_per_pixel(points, camera) == pytest.approx(9.0)
    assert points_per_pixel(points, camera, supersample=3) == pytest.approx(1.0)
    assert points_per_pixel(points + np.float32([0, 0, 10]), camera) == 0.0   # behind the eye
    assert AUTO_MIN_DENSITY <= 9.0 and auto_lod_tolerance(2) == AUTO_LOD_PX / 2
    cloud = SplatCloud(points, normals=np.tile(np.float32([0, 0, 1]), (len(points), 1)))
    cloud = cloud.replace(u=np.tile(np.float32([pixel / 3, 0, 0]), (len(points), 1)),
                          v=np.tile(np.float32([0, pixel / 3, 0]), (len(points), 1)))
    assert len(auto_merged(cloud, camera, supersample=3)) == len(cloud)   # 1 point per sub-pixel: sparse
    merged = auto_merged(cloud, camera)   # 9 points per pixel, merged per half pixel
    assert len(merged) < len(cloud) / 2 and np.isclose(merged.positions.mean(axis=0), points.mean(axis=0),
                                                       atol=pixel).all()


def test_merge_in_pixels_keeps_surfaces_apart_and_covers_the_points():
    """Two parallel sheets one pixel apart in x but far apart in depth, facing the eye, and a sheet seen
    from behind: merging never mixes them; each merged splat covers its members' centres."""
    camera = Camera(eye=(0.0, 0.0, 5.0), target=(0, 0, 0), up=(0, 1, 0), width=32, height=32, fov=30,
                    near=1.0, far=10.0)
    pixel = 5.0 / camera.focal_px
    g = (np.arange(48) + 0.5) / 4.0 - 6.0
    xs, ys = np.meshgrid(g * pixel, g * pixel)
    sheet = np.stack([xs, ys, np.zeros(xs.shape)], axis=-1).reshape(-1, 3).astype("f4")
    back = sheet + np.float32([0, 0, -1.0])   # 1 unit behind: hundreds of pixel footprints
    positions = np.concatenate([sheet, back])
    normals = np.tile(np.float32([0, 0, 1]), (len(positions), 1))
    u = np.tile(np.float32([pixel / 4, 0, 0]), (len(positions), 1))
    cloud = SplatCloud(positions, normals=normals, u=u, v=np.cross(normals, u))
    merged = merge_in_pixels(cloud, camera)
    assert 2 * 4 * 12 * 12 // 4 <= len(merged) < len(cloud) / 3   # about 4 points per half-pixel bin
    z = merged.positions[:, 2]
    assert set(np.round(z, 5)) == {0.0, -1.0}   # no splat between the sheets
    radius = np.linalg.norm(merged.u, axis=1)
    assert (radius > 0.5 * pixel / 2 * np.sqrt(2) / 2).all()   # at least about the bin's half diagonal
    flipped = cloud.replace(normals=np.concatenate([normals[:len(sheet)], -normals[len(sheet):]]))
    assert set(np.round(merge_in_pixels(flipped, camera).positions[:, 2], 5)) == {0.0, -1.0}
    clipped = cloud.replace(clip_lines=np.zeros((len(cloud), 2, 3), "f4"))
    assert merge_in_pixels(clipped, camera) is clipped   # sharp edges are never merged


def test_auto_lod_merges_dense_views_only():
    """A dense view (many points per pixel) draws merged splats, fewer, with the same picture and no
    hierarchy; a sparse one draws every splat."""
    cloud = scenes.sphere(30_000)
    small = frame_bounds(*cloud.bounds(), width=48, height=48)
    dense = surfsplat.prepare(cloud, lod=surfsplat.LodOptions(tolerance=AUTO)).render(small)
    every = surfsplat.prepare(cloud).render(small)
    assert dense.selection is None and dense.splats < 0.5 * len(cloud)
    inside = ndimage.binary_erosion(every.frame.mask)   # the silhouette may move by a pixel here and there
    assert psnr(dense.frame.color, every.frame.color, inside) > 40.0
    assert (dense.frame.mask != every.frame.mask).sum() <= 3
    large = frame_bounds(*cloud.bounds(), width=256, height=256)
    sparse = surfsplat.prepare(cloud, lod=surfsplat.LodOptions(tolerance=AUTO)).render(large)
    assert sparse.selection is None and sparse.splats == len(cloud)


def test_a_cloud_drawn_again_is_not_uploaded_again(gl_renderer):
    """Frames of one cloud (a turntable, a batch) reuse its GPU copy; a change to its arrays, even in place,
    uploads it anew."""
    renderer = Renderer(gl_renderer.ctx)
    try:
        cloud = scenes.sphere(2000).replace(colors=np.full((2000, 3), 0.8, "f4"))
        camera = frame_bounds(*cloud.bounds(), width=48, height=40)
        first = renderer.render(cloud, camera, "flat", Lights(enabled=False))
        gpu = renderer._uploaded
        again = renderer.render(cloud, camera.resized(40, 40), "flat", Lights(enabled=False))
        assert renderer._uploaded is gpu and again.mask.any()
        cloud.colors[:] = (0.1, 0.9, 0.2)   # in place: same arrays, new bytes
        changed = renderer.render(cloud, camera, "flat", Lights(enabled=False))
        assert renderer._uploaded is not gpu
        np.testing.assert_allclose(changed.color[changed.alpha == 1], np.broadcast_to((0.1, 0.9, 0.2), (int(
            (changed.alpha == 1).sum()), 3)), atol=1e-6)
        assert not np.allclose(first.color, changed.color)
    finally:
        renderer.release()
