"""The differentiable renderer (surfsplat.diff): the shared per-splat formulas on NumPy and PyTorch, the
forward image against the OpenGL ``ewa`` technique, visibility on scenes whose answer is known, and
gradients (gradcheck in float64 for every parameter group)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from surfsplat import metrics, reference, scenes
from surfsplat.camera import Camera
from surfsplat.cloud import SplatCloud
from surfsplat.lighting import Lights

torch = pytest.importorskip("torch")

from surfsplat.diff import DiffCamera, DiffOptions, Splats, render, render_frame, tangent_axes  # noqa: E402

render_module = importlib.import_module("surfsplat.diff.render")   # the package's render is the function

pytestmark = pytest.mark.torch

F64 = torch.float64


@pytest.fixture(autouse=True)
def one_thread():
    """Small tensors: one thread (OpenMP's barriers cost more than they bring, the more on a busy machine)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def random_splats(n: int, seed: int = 0):
    """(p, u, v) of n random camera-space splats in front of the eye, float64 NumPy."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3)) * 0.3 + (0.0, 0.0, -3.0)
    n_ = rng.normal(size=(n, 3))
    u = np.cross(n_, rng.normal(size=(n, 3)))
    v = np.cross(n_, u)
    u *= 0.05 / np.linalg.norm(u, axis=1, keepdims=True)
    v *= 0.03 / np.linalg.norm(v, axis=1, keepdims=True)
    return p, u, v


def test_reference_formulas_agree_on_numpy_and_torch():
    # the one copy of the formulas, run on both namespaces, gives the same numbers
    camera = Camera(width=64, height=48, fov=30, near=0.1, far=10)
    p, u, v = random_splats(40)
    t = [torch.as_tensor(a, dtype=F64) for a in (p, u, v)]
    f, c = camera.focal_px, camera.principal_point
    j_np = reference.ewa_jacobian(camera, p, u, v)
    j_t = reference.jacobian(torch.tensor(f, dtype=F64), *t)
    np.testing.assert_allclose(j_t.numpy(), j_np, rtol=1e-12)
    var = reference.ewa_variance(j_np, 1.3, True)
    np.testing.assert_allclose(reference.ewa_variance(j_t, 1.3, True).numpy(), var, rtol=1e-12)
    offsets = np.random.default_rng(1).normal(size=(40, 5, 2)) * 2
    np.testing.assert_allclose(
        reference.ewa_weight(torch.as_tensor(var), j_t, torch.as_tensor(offsets), 1.3).numpy(),
        reference.ewa_weight(var, j_np, offsets, 1.3), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(reference.project_points(t[0], f, c).numpy(), reference.project(camera, p), rtol=1e-12)
    n = reference.plane_normals(np.cross(u, v), u, v)
    pixels = reference.project(camera, p) + 0.7
    rays = reference.pixel_rays(camera, pixels)
    hit = reference.ray_plane_distance(rays, p, n)
    st = reference.splat_coordinates(rays, hit, p, u, v)
    rays_t = reference.rays_through(torch.as_tensor(pixels), torch.tensor(f, dtype=F64), c)
    hit_t = reference.ray_plane_distance(rays_t, t[0], torch.as_tensor(n))
    np.testing.assert_allclose(hit_t.numpy(), hit, rtol=1e-12)
    np.testing.assert_allclose(reference.splat_coordinates(rays_t, hit_t, *t).numpy(), st, rtol=1e-10, atol=1e-12)
    lights = Lights(directions=((1.0, 0.0, 1.0), (0.0, 1.0, 1.0)))
    albedo = np.random.default_rng(2).random((40, 3))
    view = -p / np.linalg.norm(p, axis=1, keepdims=True)
    shaded = reference.shade(albedo, n, view, np.asarray(lights.directions), lights)
    shaded_t = reference.shade(*(torch.as_tensor(a) for a in (albedo, n, view, np.asarray(lights.directions))), lights)
    np.testing.assert_allclose(shaded_t.numpy(), shaded, rtol=1e-12)


def sphere_camera(size: int) -> Camera:
    return Camera(eye=(0.5, 0.8, 3.0), width=size, height=size, fov=40).with_clip_from_bounds(
        np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]))


@pytest.mark.gl
@pytest.mark.parametrize("edges", [True, False])
def test_forward_image_matches_opengl_ewa(edges):
    import surfsplat

    cloud = scenes.sphere(5000, color="bands")
    camera = sphere_camera(128)
    gl = surfsplat.render(cloud, camera, options=surfsplat.RenderOptions(
        visibility=surfsplat.VisibilityOptions(edge_coverage=edges)))
    splats, cam = Splats.from_cloud(cloud), DiffCamera.from_camera(camera)
    with torch.no_grad():
        frame = render_frame(splats, cam, options=DiffOptions(edge_coverage=edges))
        hard = render_frame(splats, cam, options=DiffOptions(edge_softness=0.0, depth_softness=0.0,
                                                             edge_coverage=edges))
    image = frame.color.numpy()
    if edges:
        # measured (float32) 59.4 dB with the soft rims and depth tests, 129.5 dB with the hard ones; without
        # the rim rule (the papers' all-or-nothing rims) 30.8 dB: the silhouette ring
        assert metrics.psnr(image, gl.color) >= 50.0
        assert metrics.psnr(hard.color.numpy(), gl.color) >= 100.0
        # the rim's alpha is OpenGL's (measured: 5e-5 at most)
        assert np.abs(hard.alpha.numpy() - gl.alpha).max() < 1e-3
        rim = (gl.alpha > 0.02) & (gl.alpha < 0.98)
        assert rim.sum() > 200
    else:
        # measured (float32) 42.4 dB: soft rims of 0.02 px, the silhouette pixels differ; 143 dB with the hard tests
        assert metrics.psnr(image, gl.color) >= 39.0
        assert metrics.psnr(hard.color.numpy(), gl.color) >= 80.0
    # no hole, no spill: the covered pixels are OpenGL's exactly with hard rims
    assert np.array_equal(hard.alpha.numpy() > 0.5, gl.alpha > 0.5)
    assert int(((frame.alpha.numpy() > 0.5) != (gl.alpha > 0.5)).sum()) <= 0.005 * (gl.alpha > 0.5).sum()


def one_disk(dtype=F64):
    """One elliptical splat (semi-axes 0.6 and 0.36, turned 30 degrees) facing the eye at the image centre,
    semi-axes of about 11 and 7 px: (camera, Splats, the NumPy camera-space p, n, u, v)."""
    camera = Camera(eye=(0.0, 0.0, 3.0), width=40, height=36, fov=35, near=0.5, far=10)
    a = np.radians(30.0)
    p = np.array([[0.013, -0.021, 0.0]])
    u = np.array([[np.cos(a), np.sin(a), 0.0]]) * 0.6
    v = np.array([[-np.sin(a), np.cos(a), 0.0]]) * 0.36
    n = np.array([[0.0, 0.0, 1.0]])
    splats = Splats(*(torch.as_tensor(x, dtype=dtype) for x in (p, u, v, [[0.8, 0.5, 0.2]])),
                    normals=torch.as_tensor(n, dtype=dtype))
    return camera, splats, [reference.to_camera(camera, p)] + [reference.to_camera_dir(camera, x) for x in (n, u, v)]


def test_rim_alpha_of_one_disk_is_the_reference_rule():
    # the per-pair coverage and rim distance and the per-pixel rule (reference.py: splat_fragment.glsl's
    # disk_coverage, normalize.frag's edge_alpha) through the renderer's sums: with one splat the soft
    # maxima are its own values. Alone, a disk of 11 x 7 px reaches only about 0.1 px beyond its rim with
    # its filter (the 1 px prefilter added to its size): pixels beyond stay empty, as in OpenGL
    camera, splats, (p, n, u, v) = one_disk()
    with torch.no_grad():
        hard = render_frame(splats, DiffCamera.from_camera(camera, dtype=F64),
                            options=DiffOptions(edge_softness=0.0, depth_softness=0.0)).alpha.numpy()
    # the NumPy reference of the rule (splat_fragment.glsl, normalize.frag) on the pixels of the one splat:
    # its coverage and rim distance where its filter reaches, the centres its disk covers
    f = camera.focal_px
    pixels = reference.pixel_centers(camera)
    offset = pixels - reference.project(camera, p)[0]
    var = reference.ewa_variance(reference.ewa_jacobian(camera, p, u, v))
    reached = reference.ewa_beta(reference.inv2(var)[0], offset) <= 1.0
    cover, distance = reference.disk_coverage(reference.rim_jacobian(f, p, n, u, v)[0], offset)
    rays = reference.pixel_rays(camera, pixels)[None]
    st = reference.splat_coordinates(rays, reference.ray_plane_distance(rays, p, n), p, u, v)[0]
    covered = (st ** 2).sum(-1) <= 1.0
    expected = reference.edge_alpha(covered, np.where(reached, cover, 0.0), np.where(reached, distance, -1e6),
                                    reached)
    np.testing.assert_allclose(hard, np.where(reached, expected, 0.0), atol=1e-9)
    partial = (hard > 1e-6) & (hard < 1.0 - 1e-6)
    assert 10 <= partial.sum() <= 40   # the rim pixels take fractions (all-or-nothing without the rule)


@pytest.mark.parametrize("count", [60_000, 5_000])
def test_sphere_rim_alpha_approaches_the_exact_coverage(count):
    """The rim's alpha against the exact sphere's pixel coverage (8 x 8 ray-cast sub-samples, test_edges.py),
    as the OpenGL passes' is held there: splats of 0.8 and 2.7 px, rim errors a quarter of all-or-nothing
    rims' at most, no bias, inside alpha 1."""
    from test_edges import exact_sphere_alpha

    cam = Camera(eye=(0.0, 0.3, 3.2), target=(0, 0, 0), width=128, height=128, fov=40)
    cloud = scenes.sphere(count)
    exact = exact_sphere_alpha(cam)
    splats, dcam = Splats.from_cloud(cloud), DiffCamera.from_camera(cam)
    with torch.no_grad():
        on = render_frame(splats, dcam, lights=Lights(enabled=False)).alpha.numpy()
        off = render_frame(splats, dcam, lights=Lights(enabled=False),
                           options=DiffOptions(edge_coverage=False)).alpha.numpy()
    rim = (exact > 0) & (exact < 1) | (on > 0) & (on < 1)
    err_on, err_off = np.abs(on - exact)[rim].sum(), np.abs(off - exact)[rim].sum()
    # measured: 9.7 and 14.7 px of summed error with the rule, 94 and 93 px without
    assert err_on < 0.25 * err_off, (err_on, err_off)
    assert abs((on - exact).sum()) < 0.03 * rim.sum()   # neither fatter nor thinner
    inner = metrics.erode(exact == 1, 1)
    assert (on[inner] > 1 - 1e-6).all()
    assert (on[exact == 0] < 0.5).all() and (on[metrics.dilate(exact > 0, 1) == 0] == 0).all()


def test_flat_ray_formulas_are_the_direct_ones():
    # footprint_hits (per-splat coefficients, flat per-pixel products: the differentiable renderer's form)
    # against ray_plane_distance, splat_coordinates and footprint_depth, on NumPy and PyTorch
    camera = Camera(width=64, height=48, fov=30, near=0.1, far=10)
    p, u, v = random_splats(40)
    n = reference.plane_normals(np.cross(u, v), u, v)
    pixels = reference.project(camera, p)[:, None] + np.random.default_rng(5).normal(size=(40, 6, 2)) * (
        np.array([0.8] * 5 + [30.0])[None, :, None])   # near the splats, and far (some rays meet the planes behind)
    rays = reference.pixel_rays(camera, pixels)
    hit = reference.ray_plane_distance(rays, p, n)
    st = reference.splat_coordinates(rays, hit, p, u, v)
    front = hit > 0
    assert 0 < np.sum(~front) and 0.1 < np.mean((st ** 2).sum(-1)[front] <= 1.0) < 0.9
    # a ray meeting the plane behind the eye goes off to the plane's horizon (splat_fragment.glsl's footprint_st)
    horizon = reference.HORIZON * np.stack([(rays * u[:, None]).sum(-1) / (u * u).sum(-1)[:, None],
                                            (rays * v[:, None]).sum(-1) / (v * v).sum(-1)[:, None]], -1)
    st = np.where(front[..., None], st, horizon)
    z = reference.footprint_depth(st.reshape(-1, 2), np.repeat(p, 6, 0), np.repeat(u, 6, 0),
                                  np.repeat(v, 6, 0)).reshape(40, 6)
    coefficients = reference.ray_coefficients(p, n, u, v)[:, :, None]
    for xp_coefficients, x, y in ((coefficients, rays[..., 0], rays[..., 1]),
                                  (torch.as_tensor(coefficients), torch.as_tensor(rays[..., 0]),
                                   torch.as_tensor(rays[..., 1]))):
        got = [np.asarray(a) for a in reference.footprint_hits(xp_coefficients, x, y)]
        np.testing.assert_allclose(got[0], hit, rtol=1e-12)
        np.testing.assert_allclose(np.stack(got[1:3], -1), st, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got[3], z, rtol=1e-12)


def test_edge_coverage_constants_are_the_shaders():
    import re
    from importlib import resources

    glsl = resources.files("surfsplat.rendering").joinpath("glsl", "splat_fragment.glsl").read_text()
    for name in ("COVER_SHARPNESS", "DISTANCE_SHARPNESS", "COVER_REACH", "RIM_SQUEEZE", "RIM_SQUEEZE_FALLOFF"):
        match = re.search(rf"const float {name} = ([0-9.eE+-]+);", glsl)
        assert match is not None and float(match.group(1)) == getattr(reference, name), name


def test_edge_coverage_formulas_agree_on_numpy_and_torch():
    camera = Camera(width=64, height=48, fov=30, near=0.1, far=10)
    p, u, v = random_splats(40)
    n = np.cross(u, v)
    f = camera.focal_px
    jac = reference.rim_jacobian(f, p, n, u, v)
    jac_t = reference.rim_jacobian(torch.tensor(f, dtype=F64), *(torch.as_tensor(a) for a in (p, n, u, v)))
    np.testing.assert_allclose(jac_t.numpy(), jac, rtol=1e-12, atol=1e-15)
    offsets = np.random.default_rng(3).normal(size=(40, 5, 2)) * 3
    jac5 = np.broadcast_to(jac[:, None], (40, 5, 2, 2))
    c, d = reference.disk_coverage(jac5, offsets)
    c_t, d_t = reference.disk_coverage(torch.as_tensor(jac5.copy()), torch.as_tensor(offsets))
    np.testing.assert_allclose(c_t.numpy(), c, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(d_t.numpy(), d, rtol=1e-12, atol=1e-15)
    assert 0.05 < np.mean((c > 0.0) & (c < 1.0)) < 0.95   # the offsets reach the rims
    rng = np.random.default_rng(4)
    covered = rng.random((9, 11)) < 0.6
    cover, distance, reached = rng.random((9, 11)), rng.uniform(-2, 2, (9, 11)), rng.random((9, 11)) < 0.9
    alpha = reference.edge_alpha(covered, cover, distance, reached)
    alpha_t = reference.edge_alpha(*(torch.as_tensor(a) for a in (covered, cover, distance, reached)))
    np.testing.assert_allclose(alpha_t.numpy(), alpha, rtol=1e-12)
    assert np.all(alpha[covered & (alpha < 1.0)] >= cover[covered & (alpha < 1.0)])


def square(z: float, color, n_side: int = 24, size: float = 1.0) -> SplatCloud:
    """A square of n_side^2 touching circular splats in the plane z, facing +z."""
    g = (np.arange(n_side) + 0.5) / n_side * size - size / 2
    x, y = np.meshgrid(g, g)
    pos = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)
    r = size / n_side * 0.75
    n = len(pos)
    return SplatCloud(pos, np.tile([0.0, 0.0, 1.0], (n, 1)), np.tile(color, (n, 1)),
                      np.tile([r, 0.0, 0.0], (n, 1)), np.tile([0.0, r, 0.0], (n, 1)))


def merged(*clouds: SplatCloud) -> Splats:
    parts = [Splats.from_cloud(c, dtype=F64) for c in clouds]
    return Splats(*(torch.cat([getattr(p, k) for p in parts]) for k in ("positions", "u", "v", "colors")),
                  normals=torch.cat([p.normals for p in parts if p.normals is not None]))


def test_visibility_hides_the_farther_of_two_surfaces_and_blends_coincident_ones():
    camera = DiffCamera.from_camera(Camera(eye=(0.0, 0.0, 3.0), width=48, height=48, fov=15), dtype=F64)
    unlit = Lights(enabled=False)
    red, blue = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    radius = 1.0 / 24 * 0.75
    # a red square in front of a blue one 3 radii behind: the blue splats' soft depth factor is
    # sigmoid((D - z) / tau) = sigmoid(-2 band / (0.1 band)) = sigmoid(-20) = 2.1e-9
    image = render(merged(square(0.0, red), square(-3 * radius, blue)), camera, lights=unlit).numpy()
    centre = image[14:34, 14:34]
    hidden = 1.0 / (1.0 + np.exp(20.0))
    assert np.median(centre[..., 2]) == pytest.approx(hidden, rel=0.1)
    assert np.abs(centre - red).max() < 4 * hidden
    # the same squares within a tenth of a band: both blend, half and half (equal weights; a few pixels on
    # the cutoff ellipse of one splat and not of its twin, whose footprint is 0.3% smaller, differ)
    image = render(merged(square(0.0, red), square(-0.1 * radius, blue)), camera, lights=unlit).numpy()
    centre = image[14:34, 14:34]
    assert abs(np.median(centre[..., 0]) - 0.5) < 0.002 and abs(np.median(centre[..., 2]) - 0.5) < 0.002
    assert np.mean(np.abs(centre[..., 0] - 0.5) < 0.01) > 0.95
    # between: a blue square 1.5 radii behind blends by sigmoid(-0.5 band / (0.1 band)) = sigmoid(-5) (soft test)
    image = render(merged(square(0.0, red), square(-1.5 * radius, blue)), camera, lights=unlit).numpy()
    expected = 1.0 / (1.0 + np.exp(5.0))
    assert np.median(image[14:34, 14:34, 2]) == pytest.approx(expected / (1.0 + expected), rel=0.05)


def tiny_scene():
    """A few overlapping, tilted, semi-transparent splats in a 14 x 12 image (float64) and a smooth renderer."""
    camera = DiffCamera.from_camera(Camera(eye=(0.2, 0.3, 3.0), width=14, height=12, fov=20, near=0.5, far=10),
                                    dtype=F64)
    g = torch.Generator().manual_seed(1)
    n = 5
    params = {
        "positions": torch.randn(n, 3, generator=g, dtype=F64) * 0.12,
        "normals": torch.randn(n, 3, generator=g, dtype=F64) * 0.3 + torch.tensor([0.0, 0.0, 1.0], dtype=F64),
        "radii": 0.12 + 0.05 * torch.rand(n, generator=g, dtype=F64),
        "colors": torch.rand(n, 3, generator=g, dtype=F64),
        "opacity": 0.5 + 0.4 * torch.rand(n, generator=g, dtype=F64),
        "omega": torch.tensor([0.01, -0.02, 0.015], dtype=F64),
        "delta": torch.tensor([0.01, 0.0, -0.02], dtype=F64),
        "focal": camera.focal.clone(),
    }
    options = DiffOptions(edge_softness=0.5, depth_softness=0.3, min_visibility=0.0)
    lights = Lights(directions=((0.3, 0.2, 1.0),))

    def image(p):
        u, v = tangent_axes(p["normals"], p["radii"])
        cam = DiffCamera(camera.rotation, camera.translation, p["focal"], camera.width, camera.height,
                         camera.near, camera.far).moved(p["omega"], p["delta"])
        return render(Splats(p["positions"], u, v, p["colors"], p["opacity"], p["normals"]), cam, lights=lights,
                      options=options)

    return params, image


@pytest.mark.parametrize("group", ["positions", "normals", "radii", "colors", "opacity", "omega", "delta", "focal"])
def test_gradients_match_finite_differences(group):
    params, image = tiny_scene()
    covered = (image(params) < 0.999).any(dim=-1).sum()
    assert covered >= 20   # the splats cover part of the image and overlap

    def f(x):
        return image({**params, group: x})

    x = params[group].detach().clone().requires_grad_(True)
    assert torch.autograd.gradcheck(f, (x,), eps=1e-6, atol=1e-5, rtol=1e-3, fast_mode=True)


def test_gradients_of_the_tangent_axes_match_finite_differences():
    params, _ = tiny_scene()
    u, v = tangent_axes(params["normals"], params["radii"])
    v = 0.8 * v   # elliptical: the epsilon band's radius max(|u|, |v|) has a kink where |u| = |v|
    camera = DiffCamera.from_camera(Camera(eye=(0.2, 0.3, 3.0), width=14, height=12, fov=20), dtype=F64)
    options = DiffOptions(edge_softness=0.5, depth_softness=0.3, min_visibility=0.0)

    def f(u, v):
        return render(Splats(params["positions"], u, v, params["colors"]), camera, options=options)

    assert torch.autograd.gradcheck(f, (u.detach().requires_grad_(True), v.detach().requires_grad_(True)),
                                    eps=1e-6, atol=1e-5, rtol=1e-3, fast_mode=True)


def test_tiles_give_the_image_of_one_pass_and_the_same_gradients():
    # bands of rows holding few pairs (memory bounded, checkpointed) change nothing
    cloud = scenes.sphere(400, color="bands")
    camera = DiffCamera.from_camera(sphere_camera(40), dtype=F64)
    splats = Splats.from_cloud(cloud, dtype=F64)
    splats.positions.requires_grad_(True)
    one = render(splats, camera)
    (g_one,) = torch.autograd.grad(one.sum(), splats.positions)
    table, box = render_module._splat_table(splats, camera, Lights(), DiffOptions())
    assert len(render_module._bands(box, camera.height, 1500)) >= 3
    many = render(splats, camera, options=DiffOptions(max_pairs=1500))
    (g_many,) = torch.autograd.grad(many.sum(), splats.positions)
    torch.testing.assert_close(many, one, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(g_many, g_one, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("edges", [True, False])
def test_the_visibility_filter_keeps_the_pairs_of_the_formulas(dtype, edges):
    # the differentiable pass leaves out the pairs whose soft depth test passes less than min_visibility,
    # chosen by per-splat dot products; the formulas (surfsplat.reference) on every pair choose the same
    # (with edge coverage a ray meeting the plane behind the eye is a fringe fragment of the plane's horizon)
    cloud = scenes.sphere(3000, color="bands")
    camera = DiffCamera.from_camera(Camera(eye=(0.3, 0.5, 3.0), width=64, height=48, fov=45), dtype=dtype)
    options = DiffOptions(edge_softness=0.5, depth_softness=0.3, edge_coverage=edges)
    table, box = render_module._splat_table(Splats.from_cloud(cloud, dtype=dtype), camera, Lights(), options)
    sid, ix, iy = render_module._band_pairs(box, 0, camera.height)
    pixel = iy * camera.width + ix
    npix = camera.width * camera.height
    terms = render_module._pair_terms(table, sid, ix, iy, pixel, npix, camera, options)
    drawn = torch.isfinite(terms["hit"]) & ((terms["hit"] > 0) | edges)
    expected = drawn & (terms["vis"] >= options.min_visibility)
    kept = render_module._visible_pairs(table, sid, ix, iy, pixel, npix, camera, options)
    assert 0.2 * len(sid) < int(expected.sum()) < 0.8 * len(sid)   # the far side of the sphere is left out
    assert torch.equal(kept, expected)
