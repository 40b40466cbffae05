"""Ground truth: the triangle-mesh renderer (render/mesh.py) and the image metrics (metrics.py).

The mesh renderer is held against analytic images (the exact ray-cast sphere,
plane depth and coverage of a single triangle computed in NumPy) and tied to
the splat renderer's conventions by rendering points sampled on the same mesh.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_render import exact_sphere, sphere_rays

from surfsplat import metrics, reference
from surfsplat.camera import Camera, frame_bounds
from surfsplat.cloud import DEFAULT_ALBEDO
from surfsplat.errors import InputError
from surfsplat.io.mesh import Mesh, area_weighted_normals
from surfsplat.io.surface import weld
from surfsplat.lighting import Lights
from surfsplat.rendering.frame import Frame
from surfsplat.rendering.mesh import render_mesh

UNLIT = Lights(enabled=False)
SPHERE_CAMERA = dict(width=512, height=512, radius=1.0)


@pytest.fixture(scope="module")
def icosphere() -> Mesh:
    """Unit icosphere, 5 subdivisions: 20480 faces, edges 0.035..0.041."""
    trimesh = pytest.importorskip("trimesh")
    ico = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    return Mesh(ico.vertices, ico.faces)


def sphere_coverage(cam: Camera, supersample: int) -> np.ndarray:
    """Exact fraction of a pixel's supersample grid that hits the unit sphere."""
    disc = sphere_rays(cam, supersample)[3]
    s = supersample
    return (disc > 0).reshape(cam.height, s, cam.width, s).mean(axis=(1, 3))


# -- the icosphere against the exact sphere -----------------------------------------------


def test_icosphere_matches_exact_sphere(renderer, icosphere):
    """Measured on llvmpipe (512 x 512, 4 x 4 supersampling, headlight):
    69.6 dB inside the eroded silhouette, 50.0 dB over both silhouettes (the
    inscribed polytope covers 0.036 px less along the rim), SSIM 0.99991;
    flat shading 50.3 dB inside."""
    lights = Lights()
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), **SPHERE_CAMERA)
    frame = render_mesh(icosphere, cam, lights, supersample=4, renderer=renderer)
    truth, hit = exact_sphere(cam, lights, supersample=4)
    inner = metrics.erode(hit, 2)
    assert inner.sum() > 150_000
    assert metrics.psnr(frame.color, truth, inner) >= 60.0
    assert metrics.psnr(frame.color, truth, inner | frame.mask) >= 45.0
    assert metrics.ssim(frame.color, truth, inner) > 0.999

    # silhouette: coverage within a quarter pixel of the exact one, masks within 1 px
    coverage = sphere_coverage(cam, 4)
    assert np.abs(frame.weight - coverage).max() <= 0.25
    assert metrics.leaks(frame, coverage > 0, dilate_px=1) == 0
    assert metrics.holes(frame, coverage > 0, erode_px=1) == 0
    assert (frame.weight[metrics.erode(coverage > 0, 2)] == 1.0).all()

    # flat shading shows the facets
    flat = render_mesh(icosphere, cam, lights, supersample=4, smooth=False, renderer=renderer)
    assert metrics.psnr(flat.color, truth, inner) < metrics.psnr(frame.color, truth, inner) - 10.0
    np.testing.assert_array_equal(flat.weight, frame.weight)


def test_icosphere_depth_within_tessellation_error(renderer, icosphere):
    """Camera-space depth at pixel centers (supersample 1) against the exact ray/sphere depth:
    the inscribed polytope lies behind the sphere by at most its sagitta along the normal,
    ``sagitta / cos`` along a ray meeting the sphere at angle theta."""
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), width=256, height=256, radius=1.0)
    frame = render_mesh(icosphere, cam, UNLIT, supersample=1, renderer=renderer)
    assert frame.camera.near is not None and frame.camera.far is not None
    d, center, b, disc = sphere_rays(frame.camera)
    t = b - np.sqrt(np.maximum(disc, 0))
    depth = t * -d[..., 2]
    cos = np.abs(np.sum((t[..., None] * d - center) * d, axis=-1))
    corner = icosphere.vertices[icosphere.faces[:, 0]].astype(np.float64)
    sagitta = 1.0 - np.abs(np.sum(icosphere.face_normals() * corner, axis=1)).min()  # ~2.9e-4
    inner = metrics.erode(disc > 0, 2)
    err = frame.depth - depth
    assert np.isfinite(frame.depth[inner]).all()
    assert (err[inner] > -1e-5).all()
    assert (err[inner] <= sagitta / cos[inner] + 1e-5).all()
    assert err[inner & (cos > 0.9)].max() < 1.2 * sagitta
    assert np.isinf(frame.depth[disc <= 0]).all()


# -- single primitives, exact -----------------------------------------------------------


def flat_quad(color=(0.2, 0.6, 0.9), z=0.0, half=0.5) -> Mesh:
    v = [(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)]
    return Mesh(v, [(0, 1, 2), (0, 2, 3)], vertex_colors=[color] * 4)


@pytest.mark.parametrize("smooth", [True, False])
def test_unlit_quad_returns_vertex_colors(renderer, smooth):
    color, background = np.array([0.2, 0.6, 0.9]), np.array([0.1, 0.3, 0.5])
    cam = Camera(eye=(0.3, -0.2, 2.0), target=(0, 0, 0), width=80, height=64, fov=40)
    frame = render_mesh(flat_quad(color), cam, UNLIT, background=background, supersample=4,
                        smooth=smooth, renderer=renderer)
    full, empty = frame.weight == 1.0, frame.weight == 0.0
    edge = ~full & ~empty
    assert full.sum() > 1000 and empty.sum() > 1000 and edge.sum() > 50
    np.testing.assert_allclose(frame.color[full], np.broadcast_to(color, (full.sum(), 3)), atol=1e-6)
    np.testing.assert_array_equal(frame.color[empty], np.broadcast_to(background.astype("f4"), (empty.sum(), 3)))
    # edges: the color composited over the background by coverage
    w = frame.weight[edge][:, None]
    np.testing.assert_allclose(frame.color[edge], w * color + (1 - w) * background, atol=1e-6)


def test_default_albedo_without_vertex_colors(renderer):
    quad = flat_quad()
    quad.vertex_colors = None
    cam = Camera(eye=(0.0, 0.0, 2.0), target=(0, 0, 0), width=32, height=32)
    frame = render_mesh(quad, cam, UNLIT, supersample=1, renderer=renderer)
    np.testing.assert_allclose(frame.color[frame.mask], DEFAULT_ALBEDO, atol=1e-6)


TRIANGLE = np.array([(-0.8, -0.6, 0.3), (0.9, -0.35, -0.4), (0.05, 0.8, 0.1)])
TRIANGLE_CAMERA = Camera(eye=(0.3, 0.2, 2.6), target=(0, 0, 0), width=96, height=80, fov=40, near=0.5, far=10.0)


def triangle_setup(cam: Camera, supersample: int):
    """Edge functions of the projected triangle at the (sub)pixel centers, row 0 at the top.

    Returns the edge values (3, H, W) normalized to window-pixel distances of
    the supersampled grid, and that grid's camera.
    """
    big = cam.resized(cam.width * supersample, cam.height * supersample)
    corners = reference.project(big, reference.to_camera(big, TRIANGLE))
    px = reference.pixel_centers(big)
    dist = []
    for i in range(3):
        a, b = corners[i], corners[(i + 1) % 3]
        e = b - a
        cross = e[0] * (px[..., 1] - a[1]) - e[1] * (px[..., 0] - a[0])
        dist.append(cross / np.linalg.norm(e))
    e1, e2 = corners[1] - corners[0], corners[2] - corners[0]
    return np.array(dist) * np.sign(e1[0] * e2[1] - e1[1] * e2[0]), big


def test_single_triangle_coverage_is_exact(renderer):
    """Coverage = fraction of the 4 x 4 subsample centers inside the projected triangle,
    wherever no subsample lies within 0.01 subsample pixels of an edge."""
    s = 4
    frame = render_mesh(Mesh(TRIANGLE, [(0, 1, 2)]), TRIANGLE_CAMERA, UNLIT, supersample=s, renderer=renderer)
    dist, _ = triangle_setup(TRIANGLE_CAMERA, s)
    inside = (dist > 0).all(axis=0)
    near_edge = (np.abs(dist) < 0.01).any(axis=0)
    h, w = TRIANGLE_CAMERA.height, TRIANGLE_CAMERA.width
    expected = inside.reshape(h, s, w, s).mean(axis=(1, 3))
    decided = ~near_edge.reshape(h, s, w, s).any(axis=(1, 3))
    assert decided.mean() > 0.99
    np.testing.assert_array_equal(frame.weight[decided], expected[decided])
    fractional = (expected > 0) & (expected < 1)
    assert fractional.sum() > 100  # the edges are antialiased
    assert (frame.weight[expected == 1] == 1).all() and (frame.weight[expected == 0] == 0).all()
    assert set(np.unique(frame.weight * s * s)) <= set(range(s * s + 1))


def test_single_triangle_depth_color_and_lighting_at_pixel_centers(renderer):
    """Supersample 1: depth is the exact plane depth (linear, model units), vertex colors
    interpolate perspective-correctly (barycentrics of the 3D hit point), lighting is
    the NumPy Blinn-Phong reference of the face normal per pixel."""
    cam = TRIANGLE_CAMERA
    colors = np.eye(3)
    tri = Mesh(TRIANGLE, [(0, 1, 2)], vertex_colors=colors)
    unlit = render_mesh(tri, cam, UNLIT, supersample=1, renderer=renderer)
    dist, _ = triangle_setup(cam, 1)
    inside = (dist > 0.01).all(axis=0)
    assert inside.sum() > 1000
    np.testing.assert_array_equal(unlit.weight[inside], 1.0)

    p = reference.to_camera(cam, TRIANGLE)
    n = np.cross(p[1] - p[0], p[2] - p[0])
    n /= np.linalg.norm(n)
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))
    t = reference.ray_plane_distance(rays[None], p[:1], n[None])[0]
    np.testing.assert_allclose(unlit.depth[inside], t[inside], rtol=1e-5)
    # barycentric coordinates of the hit points = the interpolated unlit colors
    hits = t[..., None] * rays
    area = np.cross(p[1] - p[0], p[2] - p[0]) @ n
    bary = np.stack([np.cross(p[(k + 2) % 3] - p[(k + 1) % 3], hits - p[(k + 1) % 3]) @ n / area
                     for k in range(3)], axis=-1)
    np.testing.assert_allclose(unlit.color[inside], bary[inside], atol=2e-5)

    lights = Lights(directions=((0.3, 0.5, 1.0), (-0.6, 0.2, 0.4)), shininess=8.0)
    lit = render_mesh(Mesh(TRIANGLE, [(0, 1, 2)]), cam, lights, supersample=1, renderer=renderer)
    view = hits / -np.linalg.norm(hits, axis=-1, keepdims=True)
    dirs = lights.world_directions(cam) @ cam.view_matrix[:3, :3].T
    expected = reference.shade(np.full(view.shape, DEFAULT_ALBEDO), np.broadcast_to(n, view.shape), view,
                               dirs, lights)
    np.testing.assert_allclose(lit.color[inside], np.clip(expected, 0, 1)[inside], atol=2e-5)


def test_image_orientation_row_zero_is_top(renderer):
    """A quad in the camera's upper left appears at small rows and columns."""
    quad = Mesh([(-0.9, 0.3, 0), (-0.3, 0.3, 0), (-0.3, 0.9, 0), (-0.9, 0.9, 0)], [(0, 1, 2), (0, 2, 3)])
    cam = Camera(eye=(0, 0, 3.0), target=(0, 0, 0), width=64, height=48)
    rows, cols = np.nonzero(render_mesh(quad, cam, UNLIT, supersample=1, renderer=renderer).mask)
    assert rows.max() < 24 and cols.max() < 32


def test_tiles_join_seamlessly(renderer, icosphere):
    """Images larger than a tile are drawn in tiles; 64-px tiles give the one-tile image."""
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), width=100, height=75, radius=1.0)
    whole = render_mesh(icosphere, cam, supersample=3, renderer=renderer)
    tiled = render_mesh(icosphere, cam, supersample=3, renderer=renderer, max_tile=64)
    np.testing.assert_array_equal(tiled.weight, whole.weight)
    np.testing.assert_allclose(tiled.color, whole.color, atol=1e-5)
    np.testing.assert_allclose(tiled.depth[whole.mask], whole.depth[whole.mask], rtol=1e-5)


def grid_mesh(n: int) -> Mesh:
    """The square [-1, 1]^2 at z = 0 as an n x n grid of quads: 2 n^2 triangles."""
    x = np.linspace(-1.0, 1.0, n + 1)
    gx, gy = np.meshgrid(x, x)
    vertices = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    i = np.arange(n * n)
    i = (i // n) * (n + 1) + i % n
    a, b, c, d = i, i + 1, i + n + 1, i + n + 2
    return Mesh(vertices, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]))


def test_million_triangles_without_cracks(renderer):
    """1 M triangles in one draw: the covered area is the square's, no crack between triangles."""
    mesh = grid_mesh(708)
    assert len(mesh.faces) > 1_000_000
    cam = Camera(eye=(0.0, 0.0, 3.0), target=(0, 0, 0), width=128, height=128, fov=45)
    frame = render_mesh(mesh, cam, UNLIT, supersample=2, renderer=renderer)
    half = cam.focal_px * 1.0 / 3.0  # the square's half side in pixels
    centers = (np.arange(2 * cam.width) + 0.5) / 2  # subsample centers along either axis
    per_axis = np.count_nonzero(np.abs(centers - cam.width / 2) < half)
    assert frame.weight.sum() == per_axis**2 / 4
    inner = metrics.erode(frame.mask, 1)
    np.testing.assert_array_equal(frame.weight[inner], 1.0)
    np.testing.assert_allclose(frame.color[inner], DEFAULT_ALBEDO, atol=1e-6)
    np.testing.assert_allclose(frame.depth[inner], 3.0, rtol=1e-6)


def test_render_mesh_rejects_bad_input(renderer):
    cam = Camera()
    with pytest.raises(InputError, match="no faces"):
        render_mesh(Mesh(np.zeros((0, 3)), np.zeros((0, 3))), cam, renderer=renderer)
    with pytest.raises(InputError, match="no faces"):
        render_mesh(Mesh(np.eye(3), np.zeros((0, 3))), cam, renderer=renderer)
    with pytest.raises(InputError, match="non-finite"):
        render_mesh(Mesh([(0, 0, 0), (1, 0, 0), (0, np.nan, 0)], [(0, 1, 2)]), cam, renderer=renderer)
    with pytest.raises(InputError, match="vertex 7"):
        render_mesh(Mesh(np.eye(3), [(0, 1, 7)]), cam, renderer=renderer)
    with pytest.raises(InputError, match="supersample"):
        render_mesh(flat_quad(), cam, supersample=0, renderer=renderer)
    with pytest.raises(InputError, match="background"):
        render_mesh(flat_quad(), cam, background=(1, 1), renderer=renderer)
    with pytest.raises(InputError, match="Mesh"):
        render_mesh(np.zeros((3, 3)), cam, renderer=renderer)


# -- the normals the ground truth shades with ---------------------------------------------------


def test_mesh_without_normals_shades_with_crease_normals(renderer):
    """A cube without stored normals: crease-aware normals (its 90-degree edges are sharp) shade
    it exactly as flat shading; the area-weighted vertex normals it had before rounded it off.
    ``sharp_angle=None`` smooths it (one normal per vertex)."""
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    cube = Mesh(box.vertices, box.faces)
    cam = Camera(eye=(1.6, 1.2, 2.2), target=(0, 0, 0), width=96, height=96, fov=40)
    crease = render_mesh(cube, cam, renderer=renderer)
    flat = render_mesh(cube, cam, smooth=False, renderer=renderer)
    np.testing.assert_allclose(crease.color, flat.color, atol=1e-6)
    old = render_mesh(Mesh(box.vertices, box.faces, area_weighted_normals(box.vertices, box.faces)), cam,
                      renderer=renderer)
    assert metrics.psnr(old.color, flat.color, flat.mask) < 30.0
    rounded = render_mesh(cube, cam, sharp_angle=None, renderer=renderer)
    assert metrics.psnr(rounded.color, flat.color, flat.mask) < 30.0
    with pytest.raises(InputError, match="sharp_angle"):
        render_mesh(cube, cam, sharp_angle=0, renderer=renderer)


def test_welded_mesh_keeps_the_files_normals(renderer):
    """A crease-split cube with per-face normals (as CAD files store them) renders the same
    before and after welding (its normals kept per corner), and so does its triangle soup
    without normals (crease normals of the welded soup)."""
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1.0, 0.6, 0.4))
    split = box.copy()
    split.unmerge_vertices()
    stored = Mesh(split.vertices, split.faces, vertex_normals=np.repeat(box.face_normals, 3, axis=0))
    welded = weld(stored)
    assert len(welded.vertices) == 8 and welded.corner_normals is not None
    cam = Camera(eye=(1.0, 0.9, 1.6), target=(0, 0, 0), width=96, height=96, fov=40)
    before = render_mesh(stored, cam, renderer=renderer)
    np.testing.assert_allclose(render_mesh(welded, cam, renderer=renderer).color, before.color, atol=1e-6)
    soup = Mesh(split.vertices, split.faces)
    np.testing.assert_allclose(render_mesh(soup, cam, renderer=renderer).color, before.color, atol=1e-6)


# -- the splat renderer against the mesh it was sampled from ------------------------------


def test_splats_sampled_from_mesh_agree_with_mesh(renderer, icosphere):
    """Points sampled on a colored icosphere, preprocessed and EWA-splatted, against
    render_mesh of the same mesh: ties camera, orientation, colors and lighting together.

    Colors vary with position (a flip or mirror of either image would show).
    Measured on llvmpipe (256 x 256, 100 k samples): PSNR 54.4 dB inside the
    eroded silhouette, SSIM 0.917 over both masks, 0 holes, 0 leaks; PSNR over
    both masks 18.7 dB: the splats' rim is not antialiased (normalization
    writes full splat color wherever the weight is > 0, and the EWA prefilter
    widens the silhouette by ~1 px: ~650 pixels the mesh does not cover).
    """
    from surfsplat import preprocess
    from surfsplat.geometry import sample_mesh

    colored = Mesh(icosphere.vertices, icosphere.faces, vertex_colors=0.5 + 0.4 * icosphere.vertices)
    lights = Lights(directions=((0.5, 0.6, 1.0),))
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), width=256, height=256, radius=1.0)
    truth = render_mesh(colored, cam, lights, renderer=renderer)
    cloud = preprocess(sample_mesh(colored, 100_000, seed=1))
    frame = renderer.render(cloud, cam, "ewa", lights)
    result = metrics.compare(frame, truth)
    assert result["holes"] == 0
    assert result["leaks"] == 0
    assert result["psnr_inner"] >= 48.0
    assert result["ssim"] >= 0.85
    assert result["pixels"][1] > 35_000

    # the mirrored splat image does not match: the test sees orientation
    mirrored = Frame(frame.color[::-1].copy(), frame.depth[::-1].copy(), frame.weight[::-1].copy(), frame.camera)
    assert metrics.compare(mirrored, truth)["psnr_inner"] < 30.0


# -- metrics ----------------------------------------------------------------------------


def test_psnr_matches_hand_computation():
    a = np.zeros((4, 5, 3))
    b = a.copy()
    b[1, 2, 0] = 0.1
    b[3, 4] = 0.2
    mse = (0.1**2 + 3 * 0.2**2) / a.size
    assert metrics.psnr(b, a) == pytest.approx(10 * np.log10(1.0 / mse), rel=1e-12)
    assert metrics.psnr(b * 255, a, peak=255.0) < metrics.psnr(b, a, peak=255.0)
    mask = np.zeros((4, 5), dtype=bool)
    mask[1, 2] = mask[0, 0] = True
    assert metrics.psnr(b, a, mask) == pytest.approx(10 * np.log10(1.0 / (0.1**2 / 6)), rel=1e-12)
    mask[1, 2] = False
    assert metrics.psnr(b, a, mask) == float("inf")
    with pytest.raises(InputError, match="no pixel"):
        metrics.psnr(b, a, np.zeros((4, 5), dtype=bool))
    with pytest.raises(InputError, match="shape"):
        metrics.psnr(b, a[:3])


def test_ssim_identity_constants_and_noise():
    rng = np.random.default_rng(3)
    from scipy import ndimage

    image = np.clip(ndimage.gaussian_filter(rng.random((64, 80, 3)), (2, 2, 0)) * 2 - 0.5, 0, 1)
    assert metrics.ssim(image, image) == pytest.approx(1.0, abs=1e-12)
    # constant images: SSIM = (2 a b + C1) / (a^2 + b^2 + C1)
    c1 = (0.01) ** 2
    assert metrics.ssim(np.full((20, 20), 0.3), np.full((20, 20), 0.6)) == \
        pytest.approx((2 * 0.18 + c1) / (0.09 + 0.36 + c1), rel=1e-9)
    values = [metrics.ssim(np.clip(image + rng.normal(0, sigma, image.shape), 0, 1), image)
              for sigma in (0.01, 0.03, 0.1, 0.3)]
    assert all(x > y for x, y in zip(values, values[1:]))
    assert values[0] > 0.9 and values[-1] < 0.5
    luma = metrics.ssim(image, np.clip(image + 0.05, 0, 1), luma=True)
    assert 0.0 < luma < 1.0
    mask = np.zeros(image.shape[:2], dtype=bool)
    mask[:, :40] = True
    noisy = image.copy()
    noisy[:, 50:] = rng.random(noisy[:, 50:].shape)
    assert metrics.ssim(noisy, image, mask) > 0.999 > metrics.ssim(noisy, image)


def test_holes_and_leaks_on_constructed_masks():
    silhouette = np.zeros((40, 40), dtype=bool)
    silhouette[10:30, 10:30] = True
    covered = silhouette.astype(np.float32)
    covered[20, 20] = 0.0        # a hole inside
    covered[10, 15] = 0.0        # on the rim: within erode_px, not a hole
    covered[27, 13] = 0.0        # 3 px inside: a hole
    covered[8, 20] = 0.5         # 2 px outside: within dilate_px, not a leak
    covered[20, 34] = 0.1        # 5 px outside: a leak
    covered[0, 0] = 1.0          # far outside: a leak
    assert metrics.holes(covered, silhouette) == 2
    assert metrics.holes(covered, silhouette, erode_px=0) == 3
    assert metrics.holes(covered, silhouette, erode_px=4) == 1
    assert metrics.leaks(covered, silhouette) == 2
    assert metrics.leaks(covered, silhouette, dilate_px=0) == 3
    assert metrics.leaks(covered, silhouette, dilate_px=5) == 1
    # a silhouette cut by the image border is not eroded there
    assert metrics.holes(np.ones((10, 10)), np.ones((10, 10), dtype=bool)) == 0
    assert metrics.erode(np.ones((10, 10), dtype=bool), 2).all()
    # Frames work too
    cam = Camera(width=40, height=40)
    frame = Frame(np.ones((40, 40, 3), "f4"), np.full((40, 40), np.inf, "f4"), covered, cam)
    assert metrics.holes(frame, silhouette) == 2 and metrics.leaks(frame, silhouette) == 2


def test_compare_reports_masks_as_documented():
    cam = Camera(width=40, height=40)
    ref_weight = np.zeros((40, 40), "f4")
    ref_weight[10:30, 10:30] = 1.0
    ref_color = np.ones((40, 40, 3), "f4")
    ref_color[10:30, 10:30] = 0.5
    reference_frame = Frame(ref_color, np.where(ref_weight > 0, 2.0, np.inf).astype("f4"), ref_weight, cam)
    assert metrics.compare(reference_frame, reference_frame)["psnr"] == float("inf")

    color, weight = ref_color.copy(), ref_weight.copy()
    weight[5, 5], color[5, 5] = 1.0, 0.5      # a leak, counted in psnr but not in psnr_inner
    color[20, 20] = 0.6                       # an error inside
    result = metrics.compare(Frame(color, reference_frame.depth, weight, cam), reference_frame)
    inner = metrics.erode(ref_weight > 0, 2)
    either = inner | (weight > 0)  # the frame's whole silhouette and the leak
    assert result["pixels"] == (int(either.sum()), int(inner.sum())) == (401, 256)
    assert result["psnr_inner"] == pytest.approx(10 * np.log10(256 / 0.01), rel=1e-5)
    assert result["psnr"] == pytest.approx(10 * np.log10(401 / (0.01 + 0.25)), rel=1e-5)
    assert result["holes"] == 0 and result["leaks"] == 1
    assert 0 < result["ssim"] < 1
