"""Techniques phong and blend and the deferred shading option, held against reference.py."""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import reference
from surfsplat.camera import Camera
from surfsplat.cloud import SplatCloud
from surfsplat.errors import InputError
from surfsplat.lighting import Lights
from surfsplat.rendering.options import KernelOptions, RenderOptions, VisibilityOptions

LIGHTS = Lights(directions=((0.4, 0.6, 1.0), (-0.5, 0.2, 0.6)), shininess=16.0, specular=0.4)
CAMERA = Camera(eye=(0.3, 0.25, 2.4), target=(0, 0, 0), width=96, height=88, fov=35, near=0.5, far=10.0)


def tilted_phong_splat(field=(0.7, -0.4), center_tilt=12.0, clip=None) -> SplatCloud:
    """One slanted elliptical splat whose center normal leans away from its plane's normal."""
    a = np.radians(40.0)
    plane_n = np.array([np.sin(a), 0.0, np.cos(a)])
    u = 0.45 * np.array([np.cos(a), 0.0, -np.sin(a)])
    v = np.array([0.0, 0.3, 0.0])
    b = np.radians(center_tilt)
    center = np.cos(b) * plane_n + np.sin(b) * np.array([0.0, 1.0, 0.0])
    return SplatCloud([(0.05, -0.02, 0.0)], [center], [(0.9, 0.6, 0.3)], [u], [v], normal_field=[field],
                      clip_lines=None if clip is None else [clip])


def reference_hits(cloud: SplatCloud, cam: Camera):
    """Per pixel: depth t, normalized (s, t) and camera-space quantities of the single splat."""
    p = reference.to_camera(cam, cloud.positions)
    n = reference.to_camera_dir(cam, cloud.normals)
    uc, vc = reference.to_camera_dir(cam, cloud.u), reference.to_camera_dir(cam, cloud.v)
    plane = reference.plane_normals(n, uc, vc)
    rays = reference.pixel_rays(cam, reference.pixel_centers(cam))[None]
    t = reference.ray_plane_distance(rays, p, plane)
    st = reference.splat_coordinates(rays, t, p, uc, vc)
    return rays[0], t[0], st, n, uc, vc


def expected_colors(cloud, cam, lights, st, n, uc, vc, rays):
    normals = reference.field_normals(n, uc, vc, cloud.normal_field, st)[0]
    view = -rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    light_dirs = lights.world_directions(cam) @ cam.view_matrix[:3, :3].T
    return np.clip(reference.shade(cloud.colors[0], normals, view, light_dirs, lights), 0, 1)


@pytest.mark.parametrize("deferred", [False, True])
def test_phong_splat_matches_reference(renderer, deferred):
    """Footprint from the plane u x v, exact depth, per-pixel normal field lighting, Gaussian weight."""
    cloud = tilted_phong_splat()
    frame = renderer.render(cloud, CAMERA, "phong", LIGHTS, RenderOptions(deferred=deferred))
    rays, t, st, n, uc, vc = reference_hits(cloud, CAMERA)
    r2 = np.sum(st[0] ** 2, axis=-1)
    inside, decided = r2 <= 1.0, np.abs(r2 - 1.0) > 1e-4
    assert inside.sum() > 300
    np.testing.assert_array_equal(frame.mask[decided], inside[decided])
    sel = inside & decided
    np.testing.assert_allclose(frame.depth[sel], t[sel], rtol=1e-5)
    np.testing.assert_allclose(frame.weight[sel], reference.object_space_weight(st[0], 1.0, 2.0)[sel], rtol=1e-4)
    expected = expected_colors(cloud, CAMERA, LIGHTS, st, n, uc, vc, rays)
    np.testing.assert_allclose(frame.color[sel], expected[sel], atol=2e-4)
    # the field really varies the shading: a constant normal would be far off somewhere
    constant = expected_colors(cloud.replace(normal_field=np.zeros((1, 2))), CAMERA, LIGHTS, st, n, uc, vc, rays)
    assert np.abs(constant[sel] - expected[sel]).max() > 0.05


@pytest.mark.parametrize("kernel, a, b, n, sigma", [("pajarola", 6.0, 1.5, 3.0, 0.5), ("pajarola", 4.0, 1.5, 5.0, 0.5),
                                                    ("pajarola", 1.0, 1.5, 2.0, 0.5), ("gaussian", 6.0, 1.5, 3.0, 0.4)])
def test_blend_kernel_weights_match_reference(renderer, kernel, a, b, n, sigma):
    cloud = tilted_phong_splat(field=(0.0, 0.0))
    options = RenderOptions(kernel=KernelOptions(name=kernel, a=a, b=b, n=n, sigma=sigma))
    frame = renderer.render(cloud, CAMERA, "blend", Lights(enabled=False), options)
    _, _, st, *_ = reference_hits(cloud, CAMERA)
    r = b * np.sqrt(np.sum(st[0] ** 2, axis=-1))
    if kernel == "pajarola":
        psi = np.exp(-a * (r / b) ** n)   # Pajarola 2003, EQ 12
    else:
        psi = np.exp(-r ** 2 / (2 * sigma ** 2))   # EQ 11
    psi = np.where(r <= b, psi, 0.0)
    decided = np.abs(r / b - 1.0) > 1e-4
    np.testing.assert_allclose(frame.weight[decided], psi[decided], rtol=2e-4, atol=1e-7)
    # unlit, one splat: the normalized color is its albedo wherever it has weight
    np.testing.assert_allclose(frame.color[frame.mask], np.broadcast_to(cloud.colors[0], (frame.mask.sum(), 3)),
                               atol=1e-5)


def test_bad_kernel_options_are_rejected():
    with pytest.raises(InputError, match="kernel"):
        KernelOptions(name="box")
    with pytest.raises(InputError, match="kernel a"):
        KernelOptions(a=-1.0)
    with pytest.raises(InputError, match="kernel sigma"):
        KernelOptions(sigma=0.0)
    # so narrow that the rim weight underflows: holes, so refused (Pajarola's widest example is a = 50)
    with pytest.raises(InputError, match="too narrow"):
        KernelOptions(a=1000.0)
    with pytest.raises(InputError, match="too narrow"):
        KernelOptions(name="gaussian", sigma=0.1)
    KernelOptions(a=50.0)


@pytest.mark.parametrize("technique", ["phong", "blend", "flat"])
def test_clip_lines_cut_object_space_techniques(renderer, technique):
    clip = [[1.0, 0.5, 0.1], [0.0, 0.0, 1.0]]
    cloud = tilted_phong_splat(clip=clip)
    frame = renderer.render(cloud, CAMERA, technique, Lights(enabled=False))
    _, t, st, *_ = reference_hits(cloud, CAMERA)
    keep = reference.clip_keep(st, cloud.clip_lines)[0]
    value = st[0] @ np.array(clip[0][:2]) + clip[0][2]
    r2 = np.sum(st[0] ** 2, axis=-1)
    inner = (r2 < 0.95) & (np.abs(value) > 0.02)
    assert (inner & keep).sum() > 100 and (inner & ~keep).sum() > 100
    assert frame.mask[inner & keep].all()
    assert not frame.mask[inner & ~keep].any()


@pytest.mark.parametrize("technique", ["ewa", "perspective", "flat"])
def test_deferred_shading_lights_the_blended_normal(renderer, technique):
    """One splat with a constant normal: deferred = per-pixel Blinn-Phong of that normal."""
    cloud = tilted_phong_splat(field=(0.0, 0.0), center_tilt=0.0)
    frame = renderer.render(cloud, CAMERA, technique, LIGHTS, RenderOptions(deferred=True))
    rays, t, st, n, uc, vc = reference_hits(cloud, CAMERA)
    expected = expected_colors(cloud, CAMERA, LIGHTS, st, n, uc, vc, rays)
    # pixels covered whole (edge coverage composites the rim's over the background)
    sel = (frame.alpha >= 1.0) & (np.sum(st[0] ** 2, axis=-1) < 0.98)
    assert sel.sum() > 300
    np.testing.assert_allclose(frame.color[sel], expected[sel], atol=2e-4)


def test_backface_culling_is_conservative_for_normal_fields(renderer):
    """Seen from behind its plane, a splat is culled unless a normal of its field faces the eye."""
    base = dict(positions=[(0.0, 0.0, 0.0)], normals=[(0.0, 0.0, -1.0)], colors=[(1.0, 1.0, 1.0)],
                u=[(0.4, 0.0, 0.0)], v=[(0.0, 0.4, 0.0)])
    cam = Camera(eye=(1.6, 0.0, 2.0), target=(0, 0, 0), width=64, height=64, near=0.5, far=10.0)
    options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=True))
    for technique in ("phong", "ewa", "flat"):
        assert renderer.render(SplatCloud(**base), cam, technique, options=options).mask.sum() == 0
        assert renderer.render(SplatCloud(**base), cam, technique).mask.sum() > 100
    # n(s, 0) = (0, 0, -1) - 2 s (1, 0, 0): at s = -1 the rim normal (2, 0, -1) faces the eye
    tilted = SplatCloud(**base, normal_field=[(-2.0, 0.0)])
    assert renderer.render(tilted, cam, "phong", options=options).mask.sum() > 100
    mild = SplatCloud(**base, normal_field=[(-0.3, 0.0)])
    assert renderer.render(mild, cam, "phong", options=options).mask.sum() == 0
