"""The ``points`` technique held against the NumPy reference of its footprint (reference.point_footprint)."""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import reference
from surfsplat.camera import Camera
from surfsplat.cloud import SplatCloud
from surfsplat.lighting import Lights
from surfsplat.rendering.options import RenderOptions
from surfsplat.rendering.points import POINT_SIZE_RANGE
from surfsplat.rendering.techniques import TECHNIQUES

UNLIT = Lights(enabled=False)
CAMERA = Camera(eye=(0.1, -0.05, 4.0), target=(0, 0, 0), width=96, height=80, fov=30, near=0.5, far=10.0)


def points(positions, radii, colors=None, normals=None) -> SplatCloud:
    positions = np.asarray(positions, float)
    n = len(positions)
    radii = np.broadcast_to(np.asarray(radii, float), (n,))
    colors = np.full((n, 3), 0.8) if colors is None else colors
    normals = np.tile([0.0, 0.0, 1.0], (n, 1)) if normals is None else np.asarray(normals, float)
    u = np.zeros((n, 3))
    v = np.zeros((n, 3))
    u[:, 0], v[:, 1] = radii, radii
    return SplatCloud(positions, normals, colors, u, v)


def reference_coverage(camera: Camera, cloud: SplatCloud, supersample: int = 1):
    """(H, W) sub-pixel masks of each point by the reference, and the margin to the disk's rim (pixels)."""
    big = camera.resized(camera.width * supersample, camera.height * supersample)
    p = reference.to_camera(big, cloud.positions)
    centers = reference.project(big, p)
    diameters = reference.point_diameter(big, p, cloud.radii, POINT_SIZE_RANGE, supersample)
    pixels = reference.pixel_centers(big)
    masks = np.stack([reference.point_footprint(c, d, pixels) for c, d in zip(centers, diameters)])
    rim = np.stack([np.abs(np.linalg.norm(pixels - c, axis=-1) - d / 2) for c, d in zip(centers, diameters)])
    return masks, rim, diameters, p


def test_points_is_listed():
    assert TECHNIQUES["points"].name == "points" and not TECHNIQUES["points"].blended


@pytest.mark.parametrize("radius", [1e-4, 0.004, 0.01, 0.03, 0.2, 5.0])
def test_single_point_footprint_matches_reference(renderer, radius):
    """Center pixel and size: the covered pixels are the reference's, from 1 pixel to the 64-pixel clamp."""
    rng = np.random.default_rng(int(radius * 1e4))
    cloud = points(rng.uniform(-0.3, 0.3, (1, 3)), radius)
    frame = renderer.render(cloud, CAMERA, "points", UNLIT)
    masks, rim, diameters, p = reference_coverage(CAMERA, cloud)
    covered = frame.weight > 0
    ambiguous = rim[0] < 1e-3   # pixel centers on the rim (float32 vs float64)
    np.testing.assert_array_equal(covered[~ambiguous], masks[0][~ambiguous])
    assert covered.sum() >= 1
    assert POINT_SIZE_RANGE[0] <= diameters[0] <= POINT_SIZE_RANGE[1]
    if radius <= 1e-4:   # clamped to one pixel: exactly the pixel holding the projected center
        assert covered.sum() == 1
    # opaque, unlit albedo, the center's depth
    np.testing.assert_allclose(frame.color[covered], 0.8, atol=1e-6)
    np.testing.assert_allclose(frame.depth[covered], -p[0, 2], rtol=1e-5)


def test_many_points_match_reference_with_z_buffer(renderer):
    """Overlapping points: each pixel shows the nearest point covering it (plain z-buffer)."""
    rng = np.random.default_rng(3)
    n = 60
    colors = rng.uniform(0, 1, (n, 3))
    cloud = points(rng.uniform(-0.6, 0.6, (n, 3)), rng.uniform(0.005, 0.06, n), colors)
    # the footprints themselves: the screen-space fill would close the gaps between overlapping points
    frame = renderer.render(cloud, CAMERA, "points", UNLIT, RenderOptions(fill_holes=False))
    masks, rim, _, p = reference_coverage(CAMERA, cloud)
    depth = np.where(masks, -p[:, 2, None, None], np.inf)
    nearest = depth.argmin(axis=0)
    covered = masks.any(axis=0)
    ambiguous = (np.where(masks | (rim < 1e-3), rim, np.inf) < 1e-3).any(axis=0)
    ok = ~ambiguous
    np.testing.assert_array_equal(frame.weight[ok] > 0, covered[ok])
    sel = ok & covered
    np.testing.assert_allclose(frame.color[sel], colors[nearest[sel]], atol=1e-6)
    np.testing.assert_allclose(frame.depth[sel], depth.min(axis=0)[sel], rtol=1e-5)


def test_supersampled_footprint_and_size_clamp_in_output_pixels(renderer):
    """With K = 2 the footprint is the reference's on the sub-pixels; a tiny point is 1 output pixel wide."""
    cloud = points([[0.013, -0.021, 0.1], [0.3, 0.2, -0.2], [-0.4, 0.1, 0.0]], [1e-5, 0.02, 0.05])
    frame = renderer.render(cloud, CAMERA, "points", UNLIT, supersample=2)
    masks, rim, diameters, _ = reference_coverage(CAMERA, cloud, supersample=2)
    assert diameters[0] == 2.0   # 1 output pixel = 2 sub-pixels
    expected = masks.any(axis=0).reshape(CAMERA.height, 2, CAMERA.width, 2).mean(axis=(1, 3))
    assert (rim.min(axis=0) > 1e-3).all()
    np.testing.assert_allclose(frame.alpha, expected, atol=1e-6)


def test_points_tiled_equals_untiled_bit_for_bit(renderer):
    """Big points crossing tile borders (32 sub-pixels) leave no seam: identical images."""
    rng = np.random.default_rng(5)
    n = 400
    cloud = points(rng.uniform(-0.8, 0.8, (n, 3)), rng.uniform(0.005, 0.08, n), rng.uniform(0, 1, (n, 3)),
                   normals=rng.normal(size=(n, 3)))
    cloud = cloud.replace(normals=cloud.normals / np.linalg.norm(cloud.normals, axis=1, keepdims=True))
    whole = renderer.render(cloud, CAMERA, "points", supersample=2)
    tiled = renderer.render(cloud, CAMERA, "points", supersample=2, max_tile=32)
    for name in ("color", "depth", "weight", "alpha"):
        np.testing.assert_array_equal(getattr(tiled, name), getattr(whole, name))


def test_points_lit_by_normal_else_unlit(renderer):
    """Lit by the point's normal (per point, or deferred), the albedo unlit. (upload rejects zero normals.)"""
    lights = Lights()
    lit = points([[0.0, 0.0, 0.0]], 0.05, normals=[[0.0, 0.6, 0.8]])
    cam = Camera(eye=(0, 0, 4.0), target=(0, 0, 0), width=64, height=64, fov=30, near=0.5, far=10.0)
    frame = renderer.render(lit, cam, "points", lights)
    n = reference.to_camera_dir(cam, lit.normals)
    view = -reference.to_camera(cam, lit.positions)
    view /= np.linalg.norm(view)
    dirs = lights.world_directions(cam) @ cam.view_matrix[:3, :3].T
    expected = np.clip(reference.shade(lit.colors, n, view, dirs, lights), 0, 1)[0]
    np.testing.assert_allclose(frame.color[32, 32], expected, atol=2e-3)
    assert not np.allclose(expected, 0.8)
    frame = renderer.render(lit, cam, "points", UNLIT)   # no lighting: the albedo
    np.testing.assert_allclose(frame.color[32, 32], 0.8, atol=1e-6)
    deferred = renderer.render(lit, cam, "points", lights, RenderOptions(deferred=True))
    np.testing.assert_allclose(deferred.color[32, 32], expected, atol=2e-3)
