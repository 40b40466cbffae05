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
def test_forward_image_matches_opengl_ewa():
    import surfsplat

    cloud = scenes.sphere(5000, color="bands")
    camera = sphere_camera(128)
    # the differentiable renderer draws the papers' rims, not OpenGL's default edge coverage (limitations guide)
    gl = surfsplat.render(cloud, camera, options=surfsplat.RenderOptions(
        visibility=surfsplat.VisibilityOptions(edge_coverage=False)))
    splats, cam = Splats.from_cloud(cloud), DiffCamera.from_camera(camera)
    with torch.no_grad():
        frame = render_frame(splats, cam)
        hard = render_frame(splats, cam, options=DiffOptions(edge_softness=0.0, depth_softness=0.0))
    image = frame.color.numpy()
    # measured (float32) 42.4 dB: soft rims of 0.02 px, the silhouette pixels differ; 143 dB with the hard tests
    assert metrics.psnr(image, gl.color) >= 39.0
    assert metrics.psnr(hard.color.numpy(), gl.color) >= 80.0
    # no hole, no spill: the covered pixels are OpenGL's exactly with hard rims
    assert np.array_equal(hard.alpha.numpy() > 0.5, gl.alpha > 0.5)
    assert int(((frame.alpha.numpy() > 0.5) != (gl.alpha > 0.5)).sum()) <= 0.005 * (gl.alpha > 0.5).sum()


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
def test_the_visibility_filter_keeps_the_pairs_of_the_formulas(dtype):
    # the differentiable pass leaves out the pairs whose soft depth test passes less than min_visibility,
    # chosen by per-splat dot products; the formulas (surfsplat.reference) on every pair choose the same
    cloud = scenes.sphere(3000, color="bands")
    camera = DiffCamera.from_camera(Camera(eye=(0.3, 0.5, 3.0), width=64, height=48, fov=45), dtype=dtype)
    options = DiffOptions(edge_softness=0.5, depth_softness=0.3)
    table, box = render_module._splat_table(Splats.from_cloud(cloud, dtype=dtype), camera, Lights(), options)
    sid, ix, iy = render_module._band_pairs(box, 0, camera.height)
    pixel = iy * camera.width + ix
    npix = camera.width * camera.height
    terms = render_module._pair_terms(table, sid, ix, iy, pixel, npix, camera, options)
    expected = torch.isfinite(terms["hit"]) & (terms["hit"] > 0) & (terms["vis"] >= options.min_visibility)
    kept = render_module._visible_pairs(table, sid, ix, iy, pixel, npix, camera, options)
    assert 0.2 * len(sid) < int(expected.sum()) < 0.8 * len(sid)   # the far side of the sphere is left out
    assert torch.equal(kept, expected)
