"""The GPU pipeline held against the NumPy reference (reference.py) and analytic ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from surfsplat import metrics, reference, scenes
from surfsplat.camera import Camera, frame_bounds
from surfsplat.cloud import SplatCloud
from surfsplat.errors import InputError
from surfsplat.lighting import Lights
from surfsplat.rendering.options import FilterOptions, RenderOptions, VisibilityOptions

UNLIT = Lights(enabled=False)
CULL_BACKFACES = RenderOptions(visibility=VisibilityOptions(cull_backfaces=True))


def single_splat(normal, u, v, color=(1.0, 1.0, 1.0), position=(0.0, 0.0, 0.0)) -> SplatCloud:
    return SplatCloud([position], [normal], [color], [u], [v])


def test_camera_projection_matches_view_matrix():
    cam = Camera(eye=(1.0, 2.0, 3.0), target=(0.2, -0.1, 0.3), up=(0, 1, 0), fov=50, width=320, height=200)
    target_cam = reference.to_camera(cam, np.array([cam.target]))
    # the target lies on the optical axis, at the principal point
    np.testing.assert_allclose(target_cam[0, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(reference.project(cam, target_cam)[0], cam.principal_point)
    # the top edge of the image is at the vertical half field of view
    top = np.array([[0.0, np.tan(np.radians(25)), -1.0]])
    np.testing.assert_allclose(reference.project(cam, top)[0], (160.0, 200.0))


def test_ewa_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    cam = Camera(eye=(0, 0, 4.0), target=(0, 0, 0), width=256, height=256)
    p = reference.to_camera(cam, rng.uniform(-1, 1, (20, 3)))
    u, v = rng.normal(size=(20, 3)) * 0.1, rng.normal(size=(20, 3)) * 0.1
    jac = reference.ewa_jacobian(cam, p, u, v)
    h = 1e-6
    du = (reference.project(cam, p + h * u) - reference.project(cam, p - h * u)) / (2 * h)
    dv = (reference.project(cam, p + h * v) - reference.project(cam, p - h * v)) / (2 * h)
    np.testing.assert_allclose(jac[:, :, 0], du, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(jac[:, :, 1], dv, rtol=1e-5, atol=1e-6)


def test_ewa_bounds_are_the_tight_box_of_the_cutoff_ellipse():
    rng = np.random.default_rng(2)
    jac = rng.normal(size=(50, 2, 2)) * 5
    for cutoff in (0.5, 1.0, 2.0):
        var = reference.ewa_variance(jac, cutoff)
        half = reference.ewa_half_extent(var, cutoff)
        # boundary of 0.5 x^T V^-1 x = c: x = sqrt(2c) L (cos a, sin a) with V = L L^T
        chol = np.linalg.cholesky(var)
        angle = np.linspace(0, 2 * np.pi, 20001)
        circle = np.stack([np.cos(angle), np.sin(angle)])
        boundary = np.sqrt(2 * cutoff) * chol @ circle  # (50, 2, K)
        np.testing.assert_allclose(np.abs(boundary).max(axis=2), half, rtol=1e-6)


@pytest.mark.parametrize("tilt", [0.0, 55.0, 75.0])
@pytest.mark.parametrize("prefilter", [True, False])
def test_single_ewa_splat_weights_match_reference(renderer, tilt, prefilter):
    """Frontal and slanted splats: the accumulated weight equals the reference kernel at pixel centers."""
    a = np.radians(tilt)
    normal = (0.0, np.sin(a), np.cos(a))
    u = (0.3, 0.0, 0.0)
    v = (0.0, 0.15 * np.cos(a), -0.15 * np.sin(a))
    cloud = single_splat(normal, u, v, position=(0.1, -0.05, 0.0))
    cam = Camera(eye=(0.2, 0.1, 3.0), target=(0, 0, 0), width=96, height=80, fov=30, near=0.5, far=10.0)
    # the papers' full footprint (over the background the fringe beyond the disk is clipped by default, and
    # edge coverage weighs the rim pixels by their area: tests/test_edges.py)
    options = RenderOptions(filter=FilterOptions(prefilter=prefilter),
                            visibility=VisibilityOptions(clip_fringe=False, edge_coverage=False))
    frame = renderer.render(cloud, cam, "ewa", UNLIT, options)

    p = reference.to_camera(cam, cloud.positions)
    uc, vc = reference.to_camera_dir(cam, cloud.u), reference.to_camera_dir(cam, cloud.v)
    jac = reference.ewa_jacobian(cam, p, uc, vc)
    var = reference.ewa_variance(jac, options.filter.cutoff, prefilter)
    offsets = reference.pixel_centers(cam)[None] - reference.project(cam, p)[:, None, None, :]
    expected = reference.ewa_weight(var, jac, offsets, options.filter.cutoff)[0]
    assert expected.max() > 0.1
    # Pixels exactly on the cutoff contour may fall either way in float32.
    inv = np.linalg.inv(var)[0]
    beta = 0.5 * np.einsum("...i,ij,...j->...", offsets[0], inv, offsets[0])
    decided = np.abs(beta - options.filter.cutoff) > 1e-3
    np.testing.assert_allclose(frame.weight[decided], expected[decided], rtol=2e-4, atol=1e-6)
    # the bounding quad is tight enough to keep every pixel the kernel reaches
    assert ((expected > 0) & decided & (frame.weight == 0)).sum() == 0
    # the white splat normalizes to white wherever it has weight
    np.testing.assert_allclose(frame.color[frame.mask], 1.0, atol=1e-5)


@pytest.mark.parametrize("tilt", [0.0, 60.0, 80.0])
def test_flat_disk_footprint_and_depth_match_ray_cast(renderer, tilt):
    a = np.radians(tilt)
    normal = (np.sin(a), 0.0, np.cos(a))
    u = (0.4 * np.cos(a), 0.0, -0.4 * np.sin(a))
    v = (0.0, 0.25, 0.0)
    cloud = single_splat(normal, u, v)
    cam = Camera(eye=(0.3, 0.2, 2.5), target=(0, 0, 0), width=90, height=70, fov=35, near=0.5, far=10.0)
    frame = renderer.render(cloud, cam, "flat", UNLIT)

    p = reference.to_camera(cam, cloud.positions)
    n = reference.to_camera_dir(cam, cloud.normals)
    uc, vc = reference.to_camera_dir(cam, cloud.u), reference.to_camera_dir(cam, cloud.v)
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))[None]
    t = reference.ray_plane_distance(rays, p, n)
    st = reference.splat_coordinates(rays, t, p, uc, vc)[0]
    r2 = np.sum(st**2, axis=-1)
    inside, decided = r2 <= 1.0, np.abs(r2 - 1.0) > 1e-4
    assert inside.sum() > 50
    np.testing.assert_array_equal(frame.mask[decided], inside[decided])
    np.testing.assert_allclose(frame.depth[inside & decided], t[0][inside & decided], rtol=1e-5)


def test_lighting_matches_reference(renderer):
    """A frontal splat lit by an oblique light: its color is the Blinn-Phong reference at its center."""
    lights = Lights(directions=((0.3, 0.5, 1.0),), shininess=8.0)
    cloud = single_splat((0, 0, 1.0), (0.2, 0, 0), (0, 0.2, 0), color=(0.9, 0.5, 0.2))
    cam = Camera(eye=(0.0, 0.0, 2.0), target=(0, 0, 0), width=64, height=64, near=0.5, far=5.0)
    per_splat = renderer.render(cloud, cam, "ewa", lights)
    view = cam.view_matrix[:3, :3]
    p = reference.to_camera(cam, cloud.positions)
    n = reference.to_camera_dir(cam, cloud.normals)
    light_dirs = lights.world_directions(cam) @ view.T
    expected = reference.shade(cloud.colors, n, -p / np.linalg.norm(p), light_dirs, lights)
    np.testing.assert_allclose(per_splat.color[32, 32], np.clip(expected[0], 0, 1), atol=1e-5)
    # deferred: lit at the pixel's own point of the splat, seen along its own ray
    deferred = renderer.render(cloud, cam, "ewa", lights, RenderOptions(deferred=True))
    ray = reference.pixel_rays(cam, reference.pixel_centers(cam))[32, 32]
    q = ray * reference.ray_plane_distance(ray[None, None], p, n)[0, 0]
    at_pixel = reference.shade(cloud.colors, n, -q[None] / np.linalg.norm(q), light_dirs, lights)
    np.testing.assert_allclose(deferred.color[32, 32], np.clip(at_pixel[0], 0, 1), atol=1e-5)
    assert np.abs(deferred.color[32, 32] - per_splat.color[32, 32]).max() > 1e-4   # the highlight moves


def test_visibility_hides_the_back_surface(renderer):
    """Two parallel planes: only the front one's color is blended; no bleeding of the back one."""
    front = scenes.checkerboard(60, size=1.0)
    front.colors[:] = (1.0, 0.0, 0.0)
    back = scenes.checkerboard(60, size=1.5)
    back.positions[:, 2] -= 0.3
    back.colors[:] = (0.0, 0.0, 1.0)
    both = SplatCloud(*[np.concatenate([getattr(front, f), getattr(back, f)])
                        for f in ("positions", "normals", "colors", "u", "v")])
    cam = Camera(eye=(0.2, 0.1, 2.0), target=(0, 0, 0), width=128, height=128, fov=40)
    for technique in ("ewa", "flat"):
        frame = renderer.render(both, cam, technique, UNLIT)
        center = frame.color[40:88, 40:88]
        assert center[..., 0].min() > 0.999 and center[..., 2].max() < 1e-3, technique
        assert (frame.color[2:10, 2:10, 2] > 0.999).all(), "the back plane shows around the front one"


def sphere_rays(cam: Camera, supersample: int = 1):
    """Unit rays through the (sub)pixel centers, the unit sphere's camera-space center, and the
    ray/sphere terms ``b = d . c`` and discriminant ``b^2 - (|c|^2 - 1)`` (a hit where > 0)."""
    big = cam.resized(cam.width * supersample, cam.height * supersample)
    rays = reference.pixel_rays(big, reference.pixel_centers(big))
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    center = reference.to_camera(big, np.zeros((1, 3)))[0]
    b = d @ center
    disc = b * b - (center @ center - 1.0)
    return d, center, b, disc


def exact_sphere(cam: Camera, lights: Lights, albedo=0.8, supersample: int = 1):
    """Color and coverage of the unit sphere at the origin, ray-cast per pixel in NumPy."""
    big = cam.resized(cam.width * supersample, cam.height * supersample)
    d, center, b, disc = sphere_rays(cam, supersample)
    hit = disc > 0
    t = b - np.sqrt(np.maximum(disc, 0))
    n = t[..., None] * d - center
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    light_dirs = lights.world_directions(big) @ big.view_matrix[:3, :3].T
    color = np.clip(reference.shade(np.full(n.shape, albedo), n, -d, light_dirs, lights), 0, 1)
    color[~hit] = 1.0
    s = supersample
    color = color.reshape(cam.height, s, cam.width, s, 3).mean(axis=(1, 3))
    hit = hit.reshape(cam.height, s, cam.width, s).all(axis=(1, 3))
    return color, hit


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((a - b)[mask] ** 2)))


@pytest.mark.parametrize("technique, min_psnr", [("ewa", 45.0), ("flat", 45.0)])
def test_sphere_against_exact_ray_cast(renderer, technique, min_psnr):
    """Sampled sphere vs exact per-pixel sphere, 512x512: no holes, PSNR asserted.

    Measured on llvmpipe: ewa 57.2 dB, flat 53.8 dB (400 k splats).
    """
    cloud = scenes.sphere(400_000)
    lights = Lights()
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), width=512, height=512, radius=1.0)
    frame = renderer.render(cloud, cam, technique, lights)
    truth, hit = exact_sphere(cam, lights)
    inner = ndimage.binary_erosion(hit, iterations=2)
    assert inner.sum() > 100_000
    assert (inner & ~frame.mask).sum() == 0, "holes inside the silhouette"
    assert (frame.mask & ~ndimage.binary_dilation(hit, iterations=2)).sum() == 0, "splats leak outside"
    assert psnr(frame.image() / 255.0, truth, inner) >= min_psnr


@pytest.mark.parametrize("technique", ["flat", "ewa"])
def test_depth_of_sphere_is_exact(renderer, technique):
    """Per-pixel depth of a sampled sphere against the exact ray/sphere depth."""
    cloud = scenes.sphere(200_000)
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), width=256, height=256, radius=1.0)
    frame = renderer.render(cloud, cam, technique, UNLIT)
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    center = reference.to_camera(cam, np.zeros((1, 3)))[0]
    b = d @ center
    disc = b * b - (center @ center - 1.0)
    inner = ndimage.binary_erosion(disc > 0, iterations=3)
    t = b - np.sqrt(np.maximum(disc, 0))
    depth = t * -d[..., 2]
    normal = t[..., None] * d - center
    cos = np.abs(np.sum(normal * d, axis=-1))  # |n . view ray|
    err = np.abs(frame.depth - depth)
    # tangent disks of radius r lie within r^2 / 2 of the unit sphere, which a
    # ray meeting the surface at angle theta sees as r^2 / (2 cos theta) in depth
    r = np.sqrt(4 * np.pi / 200_000)
    with np.errstate(divide="ignore"):
        bound = r**2 / (2 * cos)
    if technique == "flat":
        assert (err[inner] < 1.05 * bound[inner]).all()
    else:
        # EWA low-pass filters depth over its footprint (the prefilter's ~1.4 px):
        # a tenth of a splat radius where the surface faces the eye, <= 2 r at the rim
        assert err[inner & (cos > 0.8)].max() < 0.1 * r
        assert err[inner].max() < 2 * r


def test_render_errors_are_clear(renderer):
    with pytest.raises(InputError, match="unknown technique"):
        renderer.render(scenes.sphere(100), Camera(), "nope")
    with pytest.raises(InputError, match="preprocess"):
        renderer.upload(SplatCloud(np.zeros((3, 3))))
    with pytest.raises(InputError, match="field of view"):
        Camera(fov=0)
    with pytest.raises(InputError, match="up vector"):
        Camera(eye=(0, 0, 1), target=(0, 0, 0), up=(0, 0, 2))
    with pytest.raises(InputError, match="cutoff"):
        FilterOptions(cutoff=0)
    with pytest.raises(InputError, match="light"):
        Lights(directions=((0, 0, 0),))


def test_preprocessed_random_sphere_against_exact_ray_cast(renderer):
    """Uniform random points (no normals, no radii) -> preprocess -> ewa, 512x512.

    The whole pipeline: kNN, PCA normals, MST orientation, covariance ellipses.
    Measured: ewa 53.9 dB, flat 36.9 dB, no holes, no leaks (100 k points).
    """
    from surfsplat import preprocess

    p = np.random.default_rng(0).normal(size=(100_000, 3))
    cloud = preprocess(SplatCloud(p / np.linalg.norm(p, axis=1, keepdims=True)))
    lights = Lights()
    cam = frame_bounds((-1, -1, -1), (1, 1, 1), width=512, height=512, radius=1.0)
    truth, hit = exact_sphere(cam, lights)
    inner = ndimage.binary_erosion(hit, iterations=2)
    quality = {}
    for technique in ("ewa", "flat"):
        frame = renderer.render(cloud, cam, technique, lights)
        assert (inner & ~frame.mask).sum() == 0, f"{technique}: holes inside the silhouette"
        assert (frame.mask & ~ndimage.binary_dilation(hit, iterations=2)).sum() == 0
        quality[technique] = psnr(frame.image() / 255.0, truth, inner)
    assert quality["ewa"] >= 45.0
    assert quality["ewa"] > quality["flat"] + 3.0  # blending beats opaque disks


@pytest.mark.parametrize("technique", ["flat", "ewa", "perspective"])
def test_clip_lines_cut_every_technique_footprint(renderer, technique):
    """A slanted splat with two clip lines (a corner): pixels on the cut side get no weight,
    pixels on the kept side keep exactly the unclipped weight (reference.clip_keep). With edge coverage
    (the default) the cut is antialiased over the background: a pixel whose centre lies on the cut side
    is covered at most half."""
    a = np.radians(40)
    normal = (0.0, np.sin(a), np.cos(a))
    u, v = (0.35, 0.0, 0.0), (0.0, 0.3 * np.cos(a), -0.3 * np.sin(a))
    lines = np.array([[[1.0, 0.0, 0.2], [0.3, -1.0, 0.1]]])  # keep s >= -0.2 and t <= 0.3 s + 0.1
    plain = single_splat(normal, u, v)
    clipped = plain.replace(clip_lines=lines)
    cam = Camera(eye=(0.1, 0.2, 2.5), target=(0, 0, 0), width=80, height=80, fov=30, near=0.5, far=10.0)
    footprint = RenderOptions(visibility=VisibilityOptions(edge_coverage=False))
    full = renderer.render(plain, cam, technique, UNLIT, footprint)
    cut = renderer.render(clipped, cam, technique, UNLIT, footprint)
    edges = renderer.render(clipped, cam, technique, UNLIT)

    p = reference.to_camera(cam, plain.positions)
    n = reference.to_camera_dir(cam, plain.normals)
    uc, vc = reference.to_camera_dir(cam, plain.u), reference.to_camera_dir(cam, plain.v)
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))[None]
    st = reference.splat_coordinates(rays, reference.ray_plane_distance(rays, p, n), p, uc, vc)
    keep = reference.clip_keep(st, lines)[0]
    values = lines[0, :, 0] * st[0, ..., None, 0] + lines[0, :, 1] * st[0, ..., None, 1] + lines[0, :, 2]
    decided = (np.abs(values) > 1e-3).all(axis=-1)
    assert (full.weight[~keep & decided] > 0).sum() > 20, "the clip lines cut nothing: test is void"
    assert (cut.weight[~keep & decided] == 0).all()
    np.testing.assert_allclose(cut.weight[keep & decided], full.weight[keep & decided], rtol=1e-6)
    assert edges.alpha[~keep & decided].max() <= 0.5 + 1e-6


def exact_cube(cam: Camera, half: float = 0.5):
    """Face index (-1 where empty) of the axis-aligned cube [-half, half]^3 at each pixel (slab ray cast)."""
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))
    world = rays @ cam.view_matrix[:3, :3]  # camera -> world directions
    eye = np.asarray(cam.eye)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (-half - eye) / world
        t1 = (half - eye) / world
    t_enter = np.minimum(t0, t1)
    entry = t_enter.max(axis=-1)
    hit = (entry <= np.maximum(t0, t1).min(axis=-1)) & (entry > 0)
    axis = t_enter.argmax(axis=-1)
    side = np.take_along_axis(world, axis[..., None], -1)[..., 0] > 0  # entering a -axis face
    face = np.where(hit, 2 * axis + side, -1)
    return face


@pytest.mark.parametrize("technique", ["flat", "ewa", "perspective"])
def test_clipped_cube_has_sharp_edges_and_corners(renderer, technique):
    """Silhouette and edges within 1 px of the analytic cube, no blur across edges,
    no holes at the corners (one flat color per face, unlit; splats ~7 px wide).

    Without clip lines the same splats leak 110-400 px beyond the silhouette and
    mix colors across edges (measured), so both checks below can fail.
    """
    cloud = scenes.cube(60, texture=False)
    cam = Camera(eye=(1.3, 1.1, 1.7), target=(0, 0, 0), width=512, height=512, fov=45)
    # a closed cube: back faces culled, else they blend into the silhouette edges within epsilon
    options = CULL_BACKFACES
    face = exact_cube(cam)
    inside = face >= 0
    uniform = (ndimage.maximum_filter(face, 3) == ndimage.minimum_filter(face, 3)) & inside
    assert np.unique(face[uniform]).size == 3
    # the control without clip lines draws the papers' full footprints (fringe clipping would hide
    # most of the blended footprints' overhang beyond the silhouette, not the one over other faces)
    full = RenderOptions(visibility=VisibilityOptions(cull_backfaces=True, clip_fringe=False, edge_coverage=False))
    for model, sharp in ((cloud, True), (cloud.replace(clip_lines=None), False)):
        frame = renderer.render(model, cam, technique, UNLIT, options if sharp else full)
        assert (ndimage.binary_erosion(inside) & ~frame.mask).sum() == 0, "holes"
        leaks = (frame.mask & ~ndimage.binary_dilation(inside)).sum()
        # pixels whose 3x3 neighbourhood lies on one face show exactly that face's color
        wrong = (np.abs(frame.color[uniform] - scenes.FACE_COLORS[face[uniform]]) > 2e-3).any(axis=1).sum()
        if sharp:
            assert leaks == 0 and wrong == 0, (leaks, wrong)
        elif technique != "flat":  # opaque front disks overhang less than the blended footprints
            assert leaks > 50 and wrong > 20, "the unclipped control should show the overhang"


def test_backface_culling_drops_exactly_the_far_side(renderer):
    """Seen from outside, a closed sphere looks the same culled; from inside, culling empties it."""
    cloud = scenes.sphere(50_000)
    outside = Camera(eye=(0, 0, 3.0), target=(0, 0, 0), width=128, height=128)
    both = renderer.render(cloud, outside, "ewa", UNLIT)
    culled = renderer.render(cloud, outside, "ewa", UNLIT, CULL_BACKFACES)
    # back splats only reach past the front ones at a few silhouette pixels
    assert (both.mask != culled.mask).sum() <= 8
    interior = ndimage.binary_erosion(culled.mask, iterations=3)
    np.testing.assert_allclose(culled.depth[interior], both.depth[interior], rtol=1e-5)
    inside = Camera(eye=(0, 0, 0.2), target=(0, 0, -1), width=64, height=64, fov=60)
    assert renderer.render(cloud, inside, "flat", UNLIT).mask.all()
    assert not renderer.render(cloud, inside, "flat", UNLIT, CULL_BACKFACES).mask.any()


def exact_sphere_cube(cam: Camera, half: float = 0.5, radius: float = 0.65):
    """Per pixel: 0 where the ray enters the CSG solid (cube & sphere) through the sphere,
    1 through a cube face, -1 where it misses (analytic ray cast)."""
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))
    d = rays @ cam.view_matrix[:3, :3]
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    eye = np.asarray(cam.eye)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (-half - eye) / d, (half - eye) / d
    box_in, box_out = np.minimum(t0, t1).max(-1), np.maximum(t0, t1).min(-1)
    b = d @ eye
    disc = b * b - (eye @ eye - radius**2)
    root = np.sqrt(np.maximum(disc, 0))
    sph_in, sph_out = -b - root, -b + root
    enter, leave = np.maximum(box_in, sph_in), np.minimum(box_out, sph_out)
    hit = (disc > 0) & (enter <= leave) & (enter > 0)
    return np.where(hit, (box_in > sph_in).astype(int), -1)


@pytest.mark.parametrize("technique", ["flat", "ewa", "perspective"])
def test_csg_solid_curved_and_flat_faces_meet_at_sharp_edges(renderer, technique):
    """The CSG demo (cube & sphere): no holes, no leaks, and the flat faces' and the
    sphere's colors do not bleed across the circular edges by more than 1 px.

    The clip lines are straight, the edges circles: opaque `flat` disks leave single-pixel
    cracks where a pixel's ray passes exactly over the edge (1 measured at 384 x 384);
    the blended techniques fill them. Without clip lines the colors bleed over ~5,000 px.
    """
    cloud = scenes.sphere_cube(60_000)
    cam = Camera(eye=(1.2, 0.9, 1.6), target=(0, 0, 0), width=384, height=384, fov=40)
    part = exact_sphere_cube(cam)
    inside = part >= 0
    uniform = (ndimage.maximum_filter(part, 3) == ndimage.minimum_filter(part, 3)) & inside
    colors = np.array([[0.9, 0.55, 0.2], [0.35, 0.55, 0.85]], dtype=np.float32)
    for model, clipped in ((cloud, True), (cloud.replace(clip_lines=None), False)):
        frame = renderer.render(model, cam, technique, UNLIT, CULL_BACKFACES)
        wrong = (np.abs(frame.color[uniform] - colors[part[uniform]]) > 2e-3).any(axis=1).sum()
        if not clipped:
            assert wrong > 1000, "the unclipped control should bleed across the edges"
            continue
        holes = (ndimage.binary_erosion(inside) & ~frame.mask).sum()
        assert holes <= (3 if technique == "flat" else 0), holes
        # the sphere's smooth silhouette is filtered over ~1.4 px like any EWA silhouette
        assert (frame.mask & ~ndimage.binary_dilation(inside, iterations=2)).sum() == 0, "leaks"
        assert wrong == 0


def grid_plane(n: int, z: float, normal_z: float, color) -> SplatCloud:
    """An n x n grid of touching disks on the plane z (spacing 2 / n), normals (0, 0, normal_z)."""
    s = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(s, s)
    p = np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])
    r = 1.5 / n
    ones = np.ones(n * n)
    return SplatCloud(p, np.column_stack([0 * ones, 0 * ones, normal_z * ones]), np.tile(color, (n * n, 1)),
                      np.column_stack([r * ones, 0 * ones, 0 * ones]), np.column_stack([0 * ones, r * ones, 0 * ones]))


@pytest.mark.parametrize("technique", ["ewa", "perspective", "phong", "blend"])
def test_separate_sides_keep_a_hidden_back_face_out(renderer, technique):
    """A red plane facing the eye and, within the depth epsilon behind it, the back of a blue one:
    blended two-sided they mix; with separate sides (the default) the red front stays red. A plane
    seen only from its back still renders (two-sided, not culled)."""
    front = grid_plane(40, 0.0, 1.0, (1.0, 0.0, 0.0))
    behind = grid_plane(40, -0.02, -1.0, (0.0, 0.0, 1.0))   # 0.02 < epsilon (one radius: 0.0375)
    both = SplatCloud(*(np.concatenate([getattr(front, k), getattr(behind, k)])
                        for k in ("positions", "normals", "colors", "u", "v")))
    cam = Camera(eye=(0.1, 0.05, 3.0), target=(0, 0, 0), width=96, height=96, fov=30)
    mixed = renderer.render(both, cam, technique, UNLIT,
                            RenderOptions(visibility=VisibilityOptions(separate_sides=False)))
    clean = renderer.render(both, cam, technique, UNLIT)
    inner = ndimage.binary_erosion(clean.mask, iterations=4)
    assert inner.sum() > 2000
    assert mixed.color[inner][:, 2].mean() > 0.2                     # the back of the blue plane bleeds in
    assert np.abs(clean.color[inner] - (1.0, 0.0, 0.0)).max() < 1e-3   # not with separate sides
    back_only = renderer.render(behind, cam, technique, UNLIT)
    assert np.abs(back_only.color[ndimage.binary_erosion(back_only.mask, iterations=4)] - (0, 0, 1)).max() < 1e-3


# -- supersampling, tiles, transparency ----------------------------------------------------------

@pytest.fixture(scope="module")
def torus_view():
    cloud = scenes.torus(200, 80)
    cam = frame_bounds(*cloud.bounds(), width=90, height=70, direction=(0.3, 0.8, 1.0))
    return cloud, cam


@pytest.mark.parametrize("technique", ["ewa", "perspective", "phong", "flat"])
def test_tiled_rendering_equals_one_tile(renderer, torus_view, technique):
    cloud, cam = torus_view
    whole = renderer.render(cloud, cam, technique, Lights(), supersample=2)
    tiled = renderer.render(cloud, cam, technique, Lights(), supersample=2, max_tile=32)   # 6 x 5 tiles
    for name in ("color", "depth", "weight", "alpha"):
        np.testing.assert_array_equal(getattr(tiled, name), getattr(whole, name), err_msg=name)


def test_supersampling_is_the_box_filtered_larger_image(renderer, torus_view):
    """Without edge coverage exactly; with it (the default) each sub-pixel's rim alpha looks K / 2
    sub-pixels around (normalize.frag), so the two agree but on rims."""
    cloud, cam = torus_view
    k = 3
    blocks = (cam.height, k, cam.width, k)
    small = renderer.render(cloud, cam, "ewa", Lights(), supersample=k)
    big = renderer.render(cloud, cam.resized(cam.width * k, cam.height * k), "ewa", Lights())
    assert metrics.psnr(small.color, big.color.reshape(*blocks, 3).mean(axis=(1, 3))) > 45.0
    assert abs(small.alpha.sum() - big.alpha.sum() / k ** 2) < 0.002 * small.alpha.sum()
    options = RenderOptions(visibility=VisibilityOptions(edge_coverage=False))
    small = renderer.render(cloud, cam, "ewa", Lights(), options, supersample=k)
    big = renderer.render(cloud, cam.resized(cam.width * k, cam.height * k), "ewa", Lights(), options)
    np.testing.assert_allclose(small.color, big.color.reshape(*blocks, 3).mean(axis=(1, 3)), atol=1e-6)
    np.testing.assert_allclose(small.alpha, big.mask.reshape(blocks).mean(axis=(1, 3)), atol=1e-6)
    np.testing.assert_array_equal(small.depth, big.depth.reshape(blocks).min(axis=(1, 3)))
    edge = (small.alpha > 0) & (small.alpha < 1)
    assert edge.sum() > 50   # the silhouette is antialiased: fractional coverage


def test_transparent_and_16_bit_output(renderer, torus_view, tmp_path):
    import png
    from PIL import Image

    cloud, cam = torus_view
    background = (0.2, 0.4, 0.9)
    frame = renderer.render(cloud, cam, "ewa", Lights(), background=background, supersample=2)
    rgba = frame.rgba()
    composited = rgba[..., :3] * rgba[..., 3:] + (1 - rgba[..., 3:]) * np.asarray(background)
    np.testing.assert_allclose(composited, frame.color, atol=1e-5)   # over its own background: the frame
    assert (rgba[~frame.mask] == 0).all()
    png8 = frame.save(tmp_path / "t.png", transparent=True)
    assert Image.open(png8).mode == "RGBA"
    np.testing.assert_array_equal(np.asarray(Image.open(png8)), frame.image(transparent=True))
    png16 = frame.save(tmp_path / "t16.png", transparent=True, bit_depth=16)
    width, height, rows, info = png.Reader(filename=str(png16)).read()
    assert info["bitdepth"] == 16 and info["alpha"] and (width, height) == (cam.width, cam.height)
    read = np.vstack([np.asarray(r, dtype=np.uint16) for r in rows]).reshape(height, width, 4)
    np.testing.assert_array_equal(read, frame.image(transparent=True, bit_depth=16))
    with pytest.raises(InputError, match="no alpha channel"):
        frame.save(tmp_path / "t.jpg", transparent=True)
    with pytest.raises(InputError, match="supersample"):
        renderer.render(cloud, cam, "ewa", Lights(), supersample=17)


def test_clip_fringe_ends_footprints_at_the_surface(renderer):
    """With clip_fringe (the default), a lone ewa splat's prefiltered fringe over the background is dropped (no
    weight outside its disk), while inside a plane of touching splats the fringes still blend. (Without edge
    coverage: with it, the rim pixels beyond the disk take their area coverage, tests/test_edges.py.)"""
    cloud = single_splat((0.0, 0.0, 1.0), (0.3, 0.0, 0.0), (0.0, 0.2, 0.0))
    cam = Camera(eye=(0.0, 0.0, 3.0), target=(0, 0, 0), width=80, height=80, fov=30, near=0.5, far=10.0)
    clipped = RenderOptions(visibility=VisibilityOptions(clip_fringe=True, edge_coverage=False))
    full = renderer.render(cloud, cam, "ewa", UNLIT,
                           RenderOptions(visibility=VisibilityOptions(clip_fringe=False, edge_coverage=False)))
    lone = renderer.render(cloud, cam, "ewa", UNLIT, clipped)
    p = reference.to_camera(cam, cloud.positions)
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam).reshape(-1, 2))[None]
    t = reference.ray_plane_distance(rays, p, reference.to_camera_dir(cam, cloud.normals))
    st = reference.splat_coordinates(rays, t, p, reference.to_camera_dir(cam, cloud.u),
                                     reference.to_camera_dir(cam, cloud.v))[0]
    inside_disk = (np.sum(st ** 2, axis=-1) <= 1.0).reshape(cam.height, cam.width)
    assert (full.mask & ~inside_disk).sum() > 5            # the prefilter's fringe reaches beyond the disk
    assert not (lone.mask & ~inside_disk).any()              # clipped: nothing beyond it
    np.testing.assert_array_equal(lone.weight[inside_disk], full.weight[inside_disk])
    plane = grid_plane(40, 0.0, 1.0, (0.8, 0.5, 0.2))
    a = renderer.render(plane, cam, "ewa", Lights(),
                        RenderOptions(visibility=VisibilityOptions(clip_fringe=False, edge_coverage=False)))
    b = renderer.render(plane, cam, "ewa", Lights(), clipped)
    inner = ndimage.binary_erosion(a.mask, iterations=3)
    np.testing.assert_array_equal(a.color[inner], b.color[inner])
