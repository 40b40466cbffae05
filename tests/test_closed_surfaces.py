"""Closed meshes: detection, outward splats, automatic back-face culling (surfsplat.geometry.closed)."""

import numpy as np
import pytest
import trimesh
from scipy import ndimage

import surfsplat
from surfsplat import CameraSpec, RenderOptions, VisibilityOptions
from surfsplat.geometry.closed import (closed_orientation, consistent_winding, eye_outside, flipped_normals,
                                       is_closed_surface, outward_splats)
from surfsplat.geometry.sampling import surface_splats
from surfsplat.io.mesh import Mesh
from surfsplat.io.surface import weld

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): most tests render through the API


def sphere(inward: bool = False, subdivisions: int = 3) -> Mesh:
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    faces = s.faces[:, ::-1] if inward else s.faces
    return Mesh(np.asarray(s.vertices, np.float32), np.asarray(faces, np.int64))


def test_winding_consistency_and_closedness():
    closed = sphere()
    assert consistent_winding(closed.faces) and is_closed_surface(closed)
    assert is_closed_surface(sphere(inward=True))   # closed either way; orientation is the splats' business
    flipped = closed.faces.copy()
    flipped[7] = flipped[7, ::-1]
    assert not consistent_winding(flipped)
    # welding turns a stray face (or a soup's random winding) to agree with its neighbours
    assert consistent_winding(weld(Mesh(closed.vertices, flipped)).faces)
    assert is_closed_surface(Mesh(closed.vertices, flipped))
    soup_v = closed.vertices[closed.faces].reshape(-1, 3)
    soup_f = np.arange(len(soup_v)).reshape(-1, 3)
    turn = np.random.default_rng(3).random(len(soup_f)) < 0.5
    soup_f[turn] = soup_f[turn][:, ::-1]
    welded = weld(Mesh(soup_v, soup_f))
    assert consistent_winding(welded.faces) and is_closed_surface(Mesh(soup_v, soup_f))
    assert len(welded.faces) == len(closed.faces)
    v = closed.vertices
    for z in (0.0, -0.5, -0.8):   # hemisphere and larger caps: open however few edges are on the rim
        cap = closed.faces[(v[closed.faces][:, :, 2] > z).any(axis=1)]
        assert not is_closed_surface(Mesh(v, cap))
    one_hole = closed.faces[1:]   # one face missing: a small hole still counts as closed
    assert is_closed_surface(Mesh(v, one_hole))
    assert not is_closed_surface(Mesh(v, one_hole), max_hole=0.0)
    grid = trimesh.creation.box().subdivide().subdivide().subdivide()   # a dense sheet: few rim edges
    top = grid.faces[(grid.vertices[grid.faces][:, :, 2] > 0.49).all(axis=1)]
    assert not is_closed_surface(Mesh(np.asarray(grid.vertices, np.float32), top))


@pytest.mark.parametrize("inward", [False, True])
def test_outward_splats_point_out_of_the_solid(inward):
    splats = outward_splats(surface_splats(sphere(inward), 4000, seed=1))
    p = splats.positions - splats.positions.mean(axis=0)
    assert (np.einsum("nd,nd->n", p, splats.normals) > 0).all()


def rim_psnr(frame, truth) -> float:
    covered = np.isfinite(truth.depth)
    rim = ndimage.binary_dilation(covered != ndimage.binary_erosion(covered), iterations=2)
    mse = ((frame.color - truth.color) ** 2).mean(axis=-1)[rim].mean()
    return 10 * np.log10(1.0 / mse)


def test_inward_closed_mesh_renders_whole_and_culled_without_a_dark_rim():
    """An inward-wound closed mesh (as the Stanford bunny) is drawn whole and culled by default (its
    splats are oriented outward, so automatic culling keeps the visible side; tests/test_culling_holes.py).
    Without edge coverage its silhouette band matches the mesh better culled than two-sided, whose
    back-side splats make a dark rim (measured 22.9 against 22.1 dB); with it (the default) the culled
    picture is 2.7 dB above the two-sided picture without it (the defaults before): 24.8 dB. Two-sided
    with edge coverage measures 26.5 dB on this coarse polygon (the back side's disks, sticking out past
    it, fill the band where the polygon's silhouette lies outside the front's disks): culling may cost
    the band at most that, never a hole (evenly spread samples at 1.76 spacings)."""
    mesh = sphere(inward=True, subdivisions=2)   # coarse: flat disks stick out past the polygon
    camera = CameraSpec(eye=(0.0, 0.4, 3.2), target=(0.0, 0.0, 0.0))
    kw = dict(width=160, height=160, supersample=2,
              source_options=surfsplat.SourceOptions(samples=40_000))
    truth = surfsplat.render_mesh(mesh, camera, width=160, height=160)
    auto = surfsplat.render(mesh, camera, **kw)
    two_sided = surfsplat.render(mesh, camera, options=RenderOptions(
        visibility=VisibilityOptions(cull_backfaces=False)), **kw)
    culled = surfsplat.render(mesh, camera, options=RenderOptions(
        visibility=VisibilityOptions(cull_backfaces=True)), **kw)
    covered = np.isfinite(truth.depth)
    assert np.isfinite(culled.depth)[covered].mean() > 0.995   # the front is kept
    assert np.array_equal(auto.mask, culled.mask) and not np.array_equal(auto.mask, two_sided.mask)
    before = surfsplat.render(mesh, camera, options=RenderOptions(
        visibility=VisibilityOptions(cull_backfaces=False, edge_coverage=False)), **kw)
    assert rim_psnr(auto, truth) > rim_psnr(before, truth) + 2.0
    assert rim_psnr(auto, truth) > rim_psnr(two_sided, truth) - 2.5
    hard_culled = surfsplat.render(mesh, camera, options=RenderOptions(
        visibility=VisibilityOptions(cull_backfaces=True, edge_coverage=False)), **kw)
    assert rim_psnr(hard_culled, truth) > rim_psnr(before, truth) + 0.5


def test_closed_mesh_is_culled_automatically_from_outside_only():
    """The samples of a closed mesh are culled where the eye is outside its bounds (by ewa and
    perspective, whose fringes cover the silhouette pixels only back faces covered), not from inside
    (where the back sides are what is seen), nor the samples of an open mesh; asked, either way."""
    closed = surfsplat.prepare(sphere(inward=True, subdivisions=2))
    outside = closed.camera(CameraSpec(eye=(0.0, 0.4, 3.2), target=(0.0, 0.0, 0.0)), 64, 64)
    inside = closed.camera(CameraSpec(eye=(0.0, 0.0, 0.1), target=(0.0, 0.0, -1.0)), 64, 64)
    assert closed.culls(outside) and not closed.culls(inside)
    assert closed.culls(outside, technique="perspective")
    assert not any(closed.culls(outside, technique=t) for t in ("phong", "blend", "flat", "points"))
    mesh = sphere(subdivisions=2)
    opened = surfsplat.prepare(Mesh(mesh.vertices, mesh.faces[(mesh.vertices[mesh.faces][:, :, 2] < 0.5).all(axis=1)]))
    assert not opened.culls(opened.camera(CameraSpec(eye=(0.0, 0.4, 3.2), target=(0.0, 0.0, 0.0)), 64, 64))
    two_sided = RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))
    assert not closed.culls(outside, two_sided)
    assert opened.culls(inside, RenderOptions(visibility=VisibilityOptions(cull_backfaces=True)))


def test_open_surface_is_drawn_two_sided():
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    back_facing = Mesh(v, np.array([[0, 2, 1], [0, 3, 2]]))   # its normal points away from the eye
    frame = surfsplat.render(back_facing, CameraSpec(eye=(0, 0, 3), target=(0, 0, 0)), width=64, height=64,
                             source_options=surfsplat.SourceOptions(samples=4000))
    assert np.isfinite(frame.depth)[24:40, 24:40].all()


def sphere_cloud(n: int = 20_000, hole_above: float | None = None):
    cloud = outward_splats(surface_splats(sphere(subdivisions=4), n, seed=2))
    if hole_above is not None:
        cloud = cloud.subset(np.flatnonzero(cloud.positions[:, 2] < hole_above))
    return cloud


def test_closed_orientation_of_point_clouds():
    cloud = sphere_cloud()
    assert closed_orientation(cloud) == 1 and closed_orientation(flipped_normals(cloud)) == -1
    assert closed_orientation(surfsplat.demo_scene("torus")) == 1
    # not closed: a sheet, a sphere with a large opening (its inside is seen through it), normals
    # of random sign, no normals
    assert closed_orientation(surfsplat.scenes.checkerboard(n_side=150)) == 0
    assert closed_orientation(sphere_cloud(hole_above=0.6)) == 0
    signs = np.where(np.random.default_rng(1).random(len(cloud.positions)) < 0.5, -1.0, 1.0).astype(np.float32)
    assert closed_orientation(cloud.replace(normals=cloud.normals * signs[:, None])) == 0
    assert closed_orientation(surfsplat.SplatCloud(cloud.positions)) == 0
    lo, hi = cloud.bounds()
    assert eye_outside((lo, hi), hi + 0.1) and not eye_outside((lo, hi), 0.5 * (lo + hi))


def test_closed_point_cloud_is_not_culled_automatically():
    """A closed cloud with inward normals gets its normals turned outward and is drawn two-sided from
    outside (automatic culling never culls: tests/test_culling_holes.py) and from inside; an open one too."""
    inward = flipped_normals(sphere_cloud())
    outside = CameraSpec(eye=(0.0, 0.5, 3.0), target=(0.0, 0.0, 0.0))
    view = surfsplat.prepare(inward)
    assert not view.culls(view.camera(outside, 96, 96)) and closed_orientation(view.sample().points()) == 1
    inside = view.camera(CameraSpec(eye=(0.0, 0.0, 0.1), target=(0.0, 0.0, -1.0)), 96, 96)
    assert not view.culls(inside)
    opened = surfsplat.prepare(sphere_cloud(hole_above=0.6))
    assert not opened.culls(opened.camera(outside, 96, 96))
    kw = dict(width=96, height=96)
    auto = surfsplat.render(inward, outside, **kw)
    two_sided = surfsplat.render(inward, outside, options=RenderOptions(
        visibility=VisibilityOptions(cull_backfaces=False)), **kw)
    covered = np.isfinite(two_sided.depth)
    assert np.isfinite(auto.depth)[covered].mean() > 0.995   # the front is kept
    assert np.abs(auto.color - two_sided.color)[covered].mean() < 0.02
    view_inside = surfsplat.render(inward, CameraSpec(eye=(0.0, 0.0, 0.1), target=(0.0, 0.0, -1.0)), **kw)
    assert np.isfinite(view_inside.depth).mean() > 0.99   # from inside the wall is seen all around
