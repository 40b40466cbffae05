"""Antialiased silhouettes without supersampling: a rim pixel's alpha is the area of the
pixel the splats' disks cover (``VisibilityOptions.edge_coverage``, splat_fragment.glsl, normalize.frag).

References: the exact area of a pixel box on one side of a straight line (brute force on a fine grid,
and its closed form, ``reference.halfplane_coverage``, the NumPy twin of the shader's
``halfplane_coverage``); the exact sphere ray-cast on 8 x 8 sub-samples per pixel.
"""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import Camera, Lights, RenderOptions, SplatCloud, VisibilityOptions, metrics, reference, scenes
from surfsplat.rendering.renderer import Renderer

UNLIT = Lights(enabled=False)
EDGE_ON = RenderOptions(visibility=VisibilityOptions(edge_coverage=True))
EDGE_OFF = RenderOptions(visibility=VisibilityOptions(edge_coverage=False))


@pytest.fixture(scope="module")
def renderer():
    return Renderer()


halfplane_coverage = reference.halfplane_coverage   # the shader's formula, NumPy (and PyTorch) twin


def test_halfplane_coverage_is_the_area_of_the_box_beside_the_line():
    rng = np.random.default_rng(0)
    angles = np.concatenate([[0.0, np.pi / 4, np.pi / 2, 1e-4], rng.uniform(0, 2 * np.pi, 40)])
    n = np.stack([np.cos(angles), np.sin(angles)], -1)
    d = rng.uniform(-0.9, 0.9, len(angles))
    g = (np.arange(400) + 0.5) / 400 - 0.5   # 160,000 sample points of the box
    x, y = np.meshgrid(g, g)
    brute = np.array([np.mean(ni[0] * x + ni[1] * y <= di) for ni, di in zip(n, d)])
    np.testing.assert_allclose(halfplane_coverage(d, n), brute, atol=3e-3)
    # the straight edge through the center halves the box; the box's corners bound the ramp
    np.testing.assert_allclose(halfplane_coverage(np.zeros(3), n[:3]), 0.5)
    assert halfplane_coverage(np.array([0.71]), n[1:2])[0] == 1.0
    assert halfplane_coverage(np.array([-0.5]), n[:1])[0] == 0.0


def clipped_plane(angle_deg: float, spacing: float = 0.02, offset: float = 0.045, seed: int = 0):
    """Splats on a jittered grid of the plane z = 0 (radius 1.1 spacing: no holes), cut at the line
    through (offset, 0, 0) at ``angle_deg`` by clip lines (Zwicker 2004, sec. 5): the surface is the
    half-plane ``m . (q - q0) <= 0``. Returns the cloud, q0 and m."""
    rng = np.random.default_rng(seed)
    g = np.arange(-0.6, 0.6, spacing)
    x, y = np.meshgrid(g, g)
    p = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    p[:, :2] += rng.uniform(-0.3, 0.3, (len(p), 2)) * spacing
    a = np.radians(angle_deg)
    m, q0 = np.array([np.cos(a), np.sin(a), 0.0]), np.array([offset, 0.0, 0.0])
    r = 1.1 * spacing
    keep = (p - q0) @ m <= r
    p = p[keep]
    k = len(p)
    u, v = np.tile([r, 0.0, 0.0], (k, 1)), np.tile([0.0, r, 0.0], (k, 1))
    # kept where a s + b t + c >= 0, with q = p + s u + t v: -(m.u) s - (m.v) t - m.(p - q0) >= 0
    line = np.column_stack([-(u @ m), -(v @ m), -((p - q0) @ m)])
    lines = np.stack([line, np.tile([0.0, 0.0, 1.0], (k, 1))], axis=1)
    cloud = SplatCloud(p, np.tile([0.0, 0.0, 1.0], (k, 1)), np.full((k, 3), 0.8), u, v, clip_lines=lines)
    return cloud, q0, m


@pytest.mark.parametrize("technique", ["ewa", "perspective"])
@pytest.mark.parametrize("angle", [0.0, 23.0, 45.0])
def test_straight_edge_alpha_is_the_analytic_half_plane_coverage(renderer, technique, angle):
    cloud, q0, m = clipped_plane(angle)
    cam = Camera(eye=(0.0, 0.0, 3.0), target=(0, 0, 0), width=96, height=96, fov=30, near=0.5, far=10.0)
    on = renderer.render(cloud, cam, technique, UNLIT, EDGE_ON)
    off = renderer.render(cloud, cam, technique, UNLIT, EDGE_OFF)
    # the edge in the image: the projection of the line (a straight line), outward normal toward m
    a, b, c = reference.project(cam, reference.to_camera(cam, np.array([q0, q0 + 0.1 * np.cross(m, [0, 0, 1]),
                                                                           q0 + 0.01 * m])))
    t = (b - a) / np.linalg.norm(b - a)
    normal = np.array([-t[1], t[0]])
    normal *= np.sign(normal @ (c - a))
    centers = reference.pixel_centers(cam)
    d = -(centers - a) @ normal   # signed distance of each pixel center, > 0 inside the surface
    expected = halfplane_coverage(d, np.broadcast_to(normal, d.shape + (2,)))
    # the part of the edge away from the plane's other borders (the image's central rows and columns)
    rows = np.abs(centers[..., 1] - cam.height / 2) < 25
    rim = rows & (np.abs(d) < 1.5)
    assert rim.sum() > 80
    err_on, err_off = np.abs(on.alpha - expected)[rim], np.abs(off.alpha - expected)[rim]
    # outside the exact half-plane CDF; inside the grid-aligned ramp 1/2 + d (normalize.frag): <= 0.08 off
    assert err_on.max() < 0.09 and err_on.mean() < 0.015, (err_on.max(), err_on.mean())
    assert err_off.mean() > 4 * err_on.mean()   # all-or-nothing coverage is far from it
    # inside (1.5 px from the edge) fully covered, outside nothing
    assert (on.alpha[rows & (d > 1.5) & (np.abs(centers[..., 0] - 48) < 25)] == 1).all()
    assert (on.alpha[rows & (d < -1.0)] == 0).all() and (on.weight[rows & (d < -1.0)] == 0).all()
    # the composited color is the surface's over the background by that alpha
    np.testing.assert_allclose(on.color[rim], (0.8 * on.alpha[rim] + (1 - on.alpha[rim]))[:, None]
                               * np.ones(3), atol=1e-5)


def exact_sphere_alpha(cam: Camera, ss: int = 8) -> np.ndarray:
    """Coverage of each pixel by the unit sphere at the origin: ray-cast on ss x ss sub-pixel centers."""
    big = cam.resized(cam.width * ss, cam.height * ss)
    rays = reference.pixel_rays(big, reference.pixel_centers(big))
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    center = reference.to_camera(big, np.zeros((1, 3)))[0]
    b = d @ center
    hit = b * b - (center @ center - 1.0) >= 0
    return hit.reshape(cam.height, ss, cam.width, ss).mean(axis=(1, 3))


@pytest.mark.parametrize("technique", ["ewa", "perspective"])
@pytest.mark.parametrize("count", [60_000, 5_000])
def test_sphere_rim_alpha_approaches_the_exact_coverage_without_holes(renderer, technique, count):
    """Splats of 0.8 and 2.7 px radius: the rim's alpha within a few percent of the exact sphere's coverage
    (measured 9.7 and 14.7 px of summed error, against 94 and 97 for all-or-nothing coverage), no bias
    (tangent disks reaching past the curved rim are squeezed), no hole inside."""
    cam = Camera(eye=(0.0, 0.3, 3.2), target=(0, 0, 0), width=128, height=128, fov=40)
    cloud = scenes.sphere(count)
    exact = exact_sphere_alpha(cam)
    on = renderer.render(cloud, cam, technique, UNLIT, EDGE_ON)
    off = renderer.render(cloud, cam, technique, UNLIT, EDGE_OFF)
    rim = (exact > 0) & (exact < 1) | (on.alpha > 0) & (on.alpha < 1)
    err_on, err_off = np.abs(on.alpha - exact)[rim].sum(), np.abs(off.alpha - exact)[rim].sum()
    assert err_on < 0.25 * err_off, (err_on, err_off)
    assert abs((on.alpha - exact).sum()) < 0.03 * rim.sum()   # neither fatter nor thinner
    # inside, coverage stays 1 exactly where all-or-nothing coverage had it: no holes opened
    inner = metrics.erode(exact == 1, 1)
    assert (on.alpha[inner] == 1).all() and metrics.holes(on, exact > 0) == 0
    np.testing.assert_array_equal(on.color[inner], off.color[inner])
    assert (on.alpha[exact == 0] < 0.5).all() and (on.alpha[metrics.dilate(exact > 0, 1) == 0] == 0).all()


def test_blend_draws_only_inside_its_disks_so_edge_coverage_leaves_it_unchanged(renderer):
    """blend (and phong) fragments never reach beyond a disk, so no pixel learns its distance to the rim:
    its rims stay all or nothing rather than guessed from one disk (which undercovers)."""
    cam = Camera(eye=(0.0, 0.3, 3.2), target=(0, 0, 0), width=96, height=96, fov=40)
    cloud = scenes.sphere(20_000)
    on = renderer.render(cloud, cam, "blend", UNLIT, EDGE_ON)
    off = renderer.render(cloud, cam, "blend", UNLIT, EDGE_OFF)
    np.testing.assert_array_equal(on.alpha > 0, off.alpha > 0)
    assert np.abs(on.alpha - off.alpha).sum() < 0.01 * off.alpha.sum()


@pytest.mark.parametrize("technique", ["ewa", "perspective"])
def test_occlusion_edges_over_another_surface_keep_full_coverage(renderer, technique):
    """The rim of a front plane over a plane behind it is not blended with the background: only the
    silhouette over the background gets fractional alpha (no halo of background colour)."""
    def plane(n, z, half, color, shift=0.0):
        s = (np.arange(n) + 0.5) / n * 2 * half - half
        x, y = np.meshgrid(s + shift, s)
        k = x.size
        r = 1.5 * half / n
        return SplatCloud(np.column_stack([x.ravel(), y.ravel(), np.full(k, z)]), np.tile([0.0, 0.0, 1.0], (k, 1)),
                          np.tile(color, (k, 1)), np.tile([r, 0, 0], (k, 1)), np.tile([0, r, 0], (k, 1)))

    front = plane(40, 0.3, 0.35, (0.1, 0.9, 0.1), shift=-0.12)
    back = plane(80, 0.0, 0.8, (0.1, 0.1, 0.9))
    cloud = SplatCloud(np.concatenate([front.positions, back.positions]),
                       np.concatenate([front.normals, back.normals]), np.concatenate([front.colors, back.colors]),
                       np.concatenate([front.u, back.u]), np.concatenate([front.v, back.v]))
    cam = Camera(eye=(0.0, 0.0, 3.0), target=(0, 0, 0), width=80, height=80, fov=40, near=0.5, far=10.0)
    frame = renderer.render(cloud, cam, technique, UNLIT, EDGE_ON, background=(1.0, 0.0, 0.0))
    inside_back = metrics.erode(frame.mask, 3)
    assert (frame.alpha[inside_back] == 1).all()
    assert frame.color[inside_back][:, 0].max() < 0.11 + 1e-4   # no red from the background
    rim = (frame.alpha > 0) & (frame.alpha < 1)
    assert rim.sum() > 40   # the outer silhouette of the back plane is antialiased


def test_supersampled_alpha_is_the_mean_of_the_sub_pixel_coverages(renderer):
    cloud, _, _ = clipped_plane(23.0)
    cam = Camera(eye=(0.0, 0.0, 3.0), target=(0, 0, 0), width=48, height=48, fov=30, near=0.5, far=10.0)
    k = 2
    small = renderer.render(cloud, cam, "ewa", UNLIT, EDGE_ON, supersample=k)
    big = renderer.render(cloud, cam.resized(cam.width * k, cam.height * k), "ewa", UNLIT, EDGE_ON)
    blocks = (cam.height, k, cam.width, k)
    np.testing.assert_allclose(small.alpha, big.alpha.reshape(blocks).mean(axis=(1, 3)), atol=1e-6)
    np.testing.assert_allclose(small.color, big.color.reshape(*blocks, 3).mean(axis=(1, 3)), atol=1e-6)


@pytest.mark.parametrize("technique, k", [("ewa", 2), ("perspective", 2), ("ewa", 4)])
def test_tiles_meet_without_seams_with_edge_coverage(renderer, technique, k):
    """The rim's alpha reads neighbours (K / 2 sub-pixels away) and their neighbours: tiles are drawn with
    a margin (TILE_MARGIN) that holds them, so tiled and untiled renders agree bit for bit."""
    cloud = scenes.torus(200, 80)
    cam = Camera(eye=(0.4, 2.2, 2.4), target=(0, 0, 0), width=90, height=70, fov=40)
    whole = renderer.render(cloud, cam, technique, Lights(), EDGE_ON, supersample=k)
    tiled = renderer.render(cloud, cam, technique, Lights(), EDGE_ON, supersample=k, max_tile=32)
    assert ((whole.alpha > 0) & (whole.alpha < 1)).sum() > 100
    for name in ("color", "depth", "weight", "alpha"):
        np.testing.assert_array_equal(getattr(tiled, name), getattr(whole, name), err_msg=name)
