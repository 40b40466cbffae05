"""Meshes are surfaces: welding, crease-aware normals, reading mesh formats, and sampled surface splats
against the ground-truth mesh rasterizer (surfsplat.io.surface, surfsplat.geometry.sampling)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from surfsplat import InputError, SplatCloud, metrics
from surfsplat.pipeline import as_splats, auto_camera
from surfsplat.geometry.sampling import (MAX_SAMPLES, samples_for_pixels, samples_for_spacing, surface_splats,
                                         view_spacing)
from surfsplat.io import Mesh, load, load_input, load_mesh
from surfsplat.io.mesh import area_weighted_normals
from surfsplat.io.surface import (auto_sharp_angle, crease_normals, dihedral_angles, face_adjacency,
                                  shading_normals, weld, weld_map)
from surfsplat.lighting import Lights
from surfsplat.rendering.mesh import render_mesh


def soup_of(mesh: Mesh) -> Mesh:
    """Every triangle with its own three vertices (as STL stores a mesh), no normals."""
    return Mesh(mesh.vertices[mesh.faces.reshape(-1)], np.arange(3 * len(mesh.faces)).reshape(-1, 3))


def icosphere(subdivisions: int = 3) -> Mesh:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    return Mesh(sphere.vertices, sphere.faces)


def cylinder(sections: int = 32) -> Mesh:
    """Closed cylinder, radius 1, height 2 along z: side facets 360/sections degrees apart, 90-degree rims."""
    c = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=sections)
    return Mesh(c.vertices, c.faces)


def angle_deg(a, b) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    cos = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def triangle_set(mesh: Mesh) -> set:
    """The triangles as sets of corner positions (rotation of the corners ignored, winding kept)."""
    out = set()
    for tri in mesh.vertices[mesh.faces].round(6).tolist():
        k = min(range(3), key=lambda i: tri[i])
        out.add(tuple(map(tuple, tri[k:] + tri[:k])))
    return out


# -- welding ---------------------------------------------------------------------------------------


def test_welding_a_triangle_soup_gives_the_connected_mesh_back():
    sphere = icosphere(2)
    soup = soup_of(sphere)
    assert len(face_adjacency(soup.faces)[0]) == 0                    # a soup: no face shares an edge
    welded = weld(soup)
    assert len(welded.vertices) == len(sphere.vertices)
    assert welded.merged_vertices == 3 * len(sphere.faces) - len(sphere.vertices) and welded.collapsed_faces == 0
    assert triangle_set(welded) == triangle_set(sphere)               # same triangles, same winding
    pairs, _, edges = face_adjacency(welded.faces)
    assert len(pairs) == 3 * len(sphere.faces) // 2                  # closed: every edge has two faces
    assert len(np.unique(edges, axis=0)) == len(edges)
    # the tolerance is relative to the model's size: jitter of 1e-8 of the diagonal welds, 1e-4 does not
    rng = np.random.default_rng(0)
    diagonal = np.linalg.norm(np.ptp(sphere.vertices, axis=0))
    for jitter, merged in ((1e-8, True), (1e-4, False)):
        noisy = Mesh(soup.vertices + rng.normal(scale=jitter * diagonal / 3, size=soup.vertices.shape), soup.faces)
        assert (len(weld(noisy).vertices) == len(sphere.vertices)) == merged
    scaled = Mesh(soup.vertices * 1e4, soup.faces)
    assert len(weld(scaled).vertices) == len(sphere.vertices)
    assert weld(sphere) is sphere                                      # nothing to merge: unchanged


def test_weld_keeps_split_normals_per_corner_and_averages_colors():
    box = trimesh.creation.box()
    split = box.copy()
    split.unmerge_vertices()                                         # 36 vertices, each face its own
    normals = np.repeat(box.face_normals, 3, axis=0)                 # the file's per-face normals
    colors = np.tile([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], (18, 1))
    mesh = Mesh(split.vertices, split.faces, vertex_normals=normals, vertex_colors=colors)
    welded = weld(mesh)
    assert len(welded.vertices) == 8 and welded.merged_vertices == 28 and welded.vertex_normals is None
    np.testing.assert_allclose(welded.corner_normals, np.repeat(box.face_normals[:, None], 3, axis=1), atol=1e-6)
    np.testing.assert_allclose(shading_normals(welded), welded.corner_normals)
    assert np.all((welded.vertex_colors >= 0) & (welded.vertex_colors <= 1))
    np.testing.assert_allclose(welded.vertex_colors.sum(axis=1), 1.0, atol=1e-6)
    # merged vertices whose normals agree keep one normal per vertex
    smooth = soup_of(icosphere(1))
    radial = smooth.vertices / np.linalg.norm(smooth.vertices, axis=1, keepdims=True)
    merged = weld(Mesh(smooth.vertices, smooth.faces, vertex_normals=radial))
    assert merged.corner_normals is None and merged.vertex_normals.shape == merged.vertices.shape
    # faces that collapse onto an edge are dropped and counted
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-9, 0, 0]], dtype=np.float64)
    collapsed = weld(Mesh(v, [[0, 1, 2], [0, 3, 2]]))
    assert len(collapsed.faces) == 1 and collapsed.collapsed_faces == 1 and collapsed.merged_vertices == 1


def test_weld_map_chains_and_rejects_bad_tolerances():
    v = np.array([[0, 0, 0], [0.4, 0, 0], [0.8, 0, 0], [5, 0, 0]], dtype=np.float64)
    np.testing.assert_array_equal(weld_map(v, 0.5), [0, 0, 0, 1])      # chains merge
    np.testing.assert_array_equal(weld_map(v, 0.0), [0, 1, 2, 3])
    with pytest.raises(InputError, match="tolerance"):
        weld_map(v, -1.0)


# -- crease-aware normals -------------------------------------------------------------------------


def test_crease_normals_on_a_cube_are_the_face_normals():
    box = trimesh.creation.box()
    mesh = Mesh(box.vertices, box.faces)
    corners = crease_normals(mesh, 30.0)
    np.testing.assert_allclose(corners, np.repeat(mesh.face_normals()[:, None], 3, axis=1), atol=1e-6)
    angles, _ = dihedral_angles(mesh)
    np.testing.assert_allclose(angles[angles > 1], 90.0, atol=1e-6)   # 12 edges at 90, the diagonals at 0
    assert (angles > 1).sum() == 12
    # with no sharp edge: one normal per vertex, the angle-weighted one (the cube's diagonal), which
    # area weights miss (a corner touches one or two triangles of each face)
    smooth = crease_normals(mesh, None)
    diagonal = mesh.vertices[mesh.faces] / np.linalg.norm(mesh.vertices[mesh.faces], axis=2, keepdims=True)
    np.testing.assert_allclose(smooth, diagonal, atol=1e-6)
    assert angle_deg(area_weighted_normals(mesh.vertices, mesh.faces)[mesh.faces], diagonal).max() > 5


def test_crease_normals_on_a_sphere_are_the_smooth_ones():
    sphere = icosphere(3)
    corners = crease_normals(sphere, 30.0)
    radial = sphere.vertices[sphere.faces]
    assert angle_deg(corners, radial).max() < 0.5
    # every corner at a vertex shares one normal: continuous shading
    per_vertex = np.zeros((len(sphere.vertices), 3))
    per_vertex[sphere.faces.reshape(-1)] = corners.reshape(-1, 3)
    np.testing.assert_allclose(corners, per_vertex[sphere.faces], atol=1e-6)
    np.testing.assert_allclose(crease_normals(sphere, None), corners, atol=1e-6)
    np.testing.assert_allclose(corners, crease_normals(soup_of(sphere), 30.0), atol=1e-6)


def test_crease_normals_smooth_a_cylinder_side_and_keep_its_rims_sharp():
    mesh = cylinder(32)
    corners = crease_normals(mesh, 30.0).astype(np.float64)
    position = mesh.vertices[mesh.faces].astype(np.float64)
    side = np.abs(mesh.face_normals()[:, 2]) < 0.5
    radial = position[side] * [1, 1, 0]
    assert angle_deg(corners[side], radial).max() < 0.01               # smooth: the exact cylinder normals
    np.testing.assert_allclose(np.abs(corners[~side, :, 2]), 1.0, atol=1e-6)   # caps stay flat
    # plain vertex normals (area-weighted over all faces) instead tilt the side's rim corners by 18 degrees
    rim = area_weighted_normals(mesh.vertices, mesh.faces)[mesh.faces][side]
    assert angle_deg(rim, radial).max() > 10
    assert auto_sharp_angle(mesh) == 30.0


def test_auto_sharp_angle_is_none_for_a_noisy_scan():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    rng = np.random.default_rng(1)
    bumps = sphere.vertices * (1 + rng.normal(scale=0.01, size=(len(sphere.vertices), 1)))
    mesh = Mesh(bumps, sphere.faces)
    angles, _ = dihedral_angles(mesh)
    assert (angles > 30).sum() > 50                                   # noise spikes above 30 degrees
    assert auto_sharp_angle(mesh) is None
    assert auto_sharp_angle(Mesh(trimesh.creation.box().vertices, trimesh.creation.box().faces)) == 30.0


# -- reading ---------------------------------------------------------------------------------------


def test_stl_off_glb_gltf_read(tmp_path):
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    box.visual.vertex_colors = np.tile([255, 0, 0, 255], (len(box.vertices), 1))
    for ext in ("stl", "off", "glb", "gltf"):
        path = tmp_path / f"box.{ext}"
        box.export(path)
        mesh = load_input(path)
        assert isinstance(mesh, Mesh), ext
        assert len(mesh.vertices) == 8 and len(mesh.faces) == 12, ext
        assert np.isclose(mesh.face_areas().sum(), box.area), ext
        assert triangle_set(mesh) == triangle_set(Mesh(box.vertices, box.faces)), ext
        raw = load_mesh(path)
        assert raw.merged_vertices == 0 and len(raw.faces) == 12
        cloud = load(path)                                           # vertices as points still work
        assert isinstance(cloud, SplatCloud) and len(cloud) == len(raw.vertices)
        if ext == "stl":
            assert len(raw.vertices) == 36 and mesh.merged_vertices == 28   # STL: a triangle soup
        if ext in ("glb", "gltf"):
            np.testing.assert_allclose(mesh.vertex_colors, np.tile([1.0, 0.0, 0.0], (8, 1)))


def test_glb_scene_transforms_and_normals(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=2)
    scene = trimesh.Scene()
    shift = trimesh.transformations.translation_matrix([5.0, 0.0, 0.0])
    turn = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])
    scene.add_geometry(sphere, node_name="a", transform=shift)
    scene.add_geometry(sphere, node_name="b", transform=turn)
    path = tmp_path / "two.glb"
    path.write_bytes(trimesh.exchange.gltf.export_glb(scene, include_normals=True))
    mesh = load_mesh(path)
    assert len(mesh.faces) == 2 * len(sphere.faces)
    centers = np.sort(mesh.vertices[:, 0].reshape(2, -1).mean(axis=1))
    np.testing.assert_allclose(centers, [0.0, 5.0], atol=1e-6)
    assert mesh.vertex_normals is not None                           # the file's normals, placed
    outward = mesh.vertices - np.where(mesh.vertices[:, :1] > 2.5, [5.0, 0, 0], 0.0)
    assert angle_deg(mesh.vertex_normals, outward).max() < 1.0          # trimesh's normals of the icosphere


@pytest.mark.parametrize("ext, content, problem", [
    ("stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\nendloop\n", "STL file"),
    ("off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n", "cannot read OFF"),
    ("glb", b"glTF\x02\x00\x00\x00garbage", "cannot read GLB"),
    ("off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "face index outside the range"),
])
def test_bad_mesh_files_name_the_file(tmp_path, ext, content, problem):
    path = tmp_path / f"bad.{ext}"
    path.write_bytes(content)
    for reader in (load_input, load_mesh):
        with pytest.raises(InputError, match=rf"bad\.{ext}") as info:
            reader(path)
        assert problem in str(info.value)


def test_load_input_tells_a_mesh_from_a_point_cloud(tmp_path):
    box = trimesh.creation.box()
    box.export(tmp_path / "box.ply")
    assert isinstance(load_input(tmp_path / "box.ply"), Mesh)
    trimesh.PointCloud(box.vertices).export(tmp_path / "points.ply")
    assert isinstance(load_input(tmp_path / "points.ply"), SplatCloud)
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    assert isinstance(load_input(tmp_path / "points.obj"), SplatCloud)
    with pytest.raises(InputError, match=r"box\.e58: unknown file type"):
        load_input(tmp_path / "box.e58")
    with pytest.raises(InputError, match=r"nothing\.stl: no such file"):
        load_input(tmp_path / "nothing.stl")


# -- sampling and the density rule --------------------------------------------------------------------


def test_density_rule():
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    mesh = Mesh(box.vertices, box.faces)                             # area 6
    assert samples_for_spacing(mesh, 0.1) == 600
    assert samples_for_spacing(mesh, 0.1, max_samples=100) == 100
    assert samples_for_spacing(mesh, 1e-9) == MAX_SAMPLES
    with pytest.raises(InputError, match="spacing"):
        samples_for_spacing(mesh, 0.0)
    camera = auto_camera(SplatCloud(mesh.vertices), 400, 400)
    depth = np.linalg.norm(np.asarray(camera.eye) - np.asarray(camera.target))  # the target is the center here
    assert np.isclose(view_spacing(mesh, camera, 2.0), 2.0 * depth / camera.focal_px, rtol=1e-6)
    assert samples_for_pixels(mesh, 2.0, camera=camera) == samples_for_spacing(mesh, view_spacing(mesh, camera, 2.0))
    # without a camera the diagonal (sqrt 3) spans image_size pixels
    assert samples_for_pixels(mesh, 1.0, image_size=100) == int(np.ceil(6 / (np.sqrt(3) / 100) ** 2))


def test_surface_splats_of_a_cylinder():
    mesh = cylinder(32)
    splats = surface_splats(mesh, 20_000, seed=3)
    assert len(splats) == 20_000 and splats.has_splats and splats.clip_lines is not None
    np.testing.assert_allclose(np.linalg.norm(splats.normals, axis=1), 1.0, atol=1e-5)
    assert np.abs(np.einsum("ij,ij->i", splats.u, splats.normals)).max() < 1e-4
    # side samples: the smooth cylinder normal (interpolated crease normals), not the facet's
    p = splats.positions.astype(np.float64)
    side = np.abs(p[:, 2]) < 0.99
    assert angle_deg(splats.normals[side], p[side] * [1, 1, 0]).max() < 1.0
    clipped = (np.abs(splats.clip_lines[:, 0, :2]).sum(axis=1) > 0)
    assert clipped.mean() > 0.02 and (np.abs(p[clipped, 2]) > 0.8).all()   # lines only near the rims
    again = surface_splats(soup_of(mesh), 20_000, seed=3)           # a soup samples like the mesh
    np.testing.assert_array_equal(again.positions, splats.positions)
    np.testing.assert_allclose(again.normals, splats.normals, atol=1e-6)
    smooth = surface_splats(icosphere(3), 5000)                       # "auto": no sharp edges, no lines
    assert smooth.clip_lines is None


def test_surface_splats_interpolate_colors_and_reject_bad_input():
    box = trimesh.creation.box()
    colors = (box.vertices > 0).astype(np.float64)                   # red/green/blue by octant
    splats = surface_splats(Mesh(box.vertices, box.faces, vertex_colors=colors), 3000)
    expected = splats.positions.astype(np.float64) + 0.5             # linear in position on the unit box
    np.testing.assert_allclose(splats.colors, expected, atol=1e-5)
    with pytest.raises(InputError, match="sharp_angle"):
        surface_splats(Mesh(box.vertices, box.faces), 100, sharp_angle=200)
    with pytest.raises(InputError, match="no faces"):
        surface_splats(Mesh(box.vertices, np.zeros((0, 3))), 100)


# -- pictures against the ground truth -------------------------------------------------------------------


@pytest.fixture(scope="module")
def featuretype(shared_data):
    path = shared_data / "featuretype.ply"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return path


def test_sampled_cad_part_matches_render_mesh(renderer, featuretype):
    """featuretype.ply sampled at the default density (0.75 px spacing, 194 k splats) against
    render_mesh, 256 x 256, ewa.

    Measured on llvmpipe: PSNR 32.1 dB inside the eroded silhouette, 0 holes, 0 leaks; its
    vertices as splats (the old default): 12.2 dB inside, 5,054 holes."""
    mesh = load_input(featuretype)
    camera = auto_camera(SplatCloud(mesh.vertices), 256, 256)
    truth = render_mesh(mesh, camera, renderer=renderer)
    splats = surface_splats(mesh, samples_for_pixels(mesh, camera=camera))
    result = metrics.compare(renderer.render(splats, camera, "ewa", Lights()), truth)
    assert result["holes"] == 0
    assert result["psnr_inner"] >= 30.0, result
    vertices = as_splats(load(featuretype))
    old = metrics.compare(renderer.render(vertices, camera, "ewa", Lights()), truth)
    assert old["psnr_inner"] < 20.0 and old["holes"] > 100, old


def test_sampled_triangle_soup_matches_the_welded_mesh(renderer, featuretype):
    """A triangle soup of the CAD part (no normals, as STL stores it) sampled, against the
    welded mesh's picture (crease-aware normals): as good as the part itself (measured
    31.9 dB inside, 0 holes); the soup itself renders exactly as the welded mesh."""
    soup = soup_of(load_mesh(featuretype))
    welded = weld(soup)
    assert len(welded.vertices) == 1722 and welded.merged_vertices == 3 * 3476 - 1722
    camera = auto_camera(SplatCloud(soup.vertices), 256, 256)
    truth = render_mesh(welded, camera, renderer=renderer)
    np.testing.assert_array_equal(render_mesh(soup, camera, renderer=renderer).color, truth.color)
    splats = surface_splats(soup, samples_for_pixels(soup, camera=camera))
    result = metrics.compare(renderer.render(splats, camera, "ewa", Lights()), truth)
    assert result["holes"] == 0
    assert result["psnr_inner"] >= 30.0, result
    # its vertices as splats draw crossed needles with holes everywhere
    needles = SplatCloud(soup.vertices, normals=np.repeat(soup.face_normals(), 3, axis=0))
    old = metrics.compare(renderer.render(as_splats(needles), camera, "ewa", Lights()), truth)
    assert old["psnr_inner"] < 20.0 and old["holes"] > 1000, old


def test_open_boundaries_clip_the_splats_at_the_outline():
    """A flat square (two triangles, open boundary all round): with boundary clip lines no splat
    reaches past the square's edges by more than the margin (a quarter of its radius); without
    them splats stick out by up to their radius."""
    square = Mesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    reach, radius = {}, 0.0
    for boundaries in (True, False):
        splats = surface_splats(square, 4000, boundaries=boundaries)
        theta = np.linspace(0, 2 * np.pi, 64, endpoint=False)
        s, t = np.cos(theta), np.sin(theta)                           # the splats' rims, (s, t) coordinates
        rim = (splats.positions[:, None, :] + s[None, :, None] * splats.u[:, None, :]
               + t[None, :, None] * splats.v[:, None, :])             # (N, 64, 3)
        kept = np.ones(rim.shape[:2], dtype=bool)
        if splats.clip_lines is not None:
            for line in (0, 1):
                a, b, c = (splats.clip_lines[:, line, i][:, None] for i in range(3))
                kept &= a * s + b * t + c >= -1e-6
        reach[boundaries] = float(np.abs(rim[kept][:, :2]).max()) - 1.0
        radius = float(splats.radii.max())
    assert reach[True] <= 0.25 * radius + 1e-6 and reach[False] > 0.8 * radius, (reach, radius)


def test_a_mesh_behind_the_eye_is_sampled_as_if_seen_not_at_the_cap():
    from surfsplat.camera import Camera
    box = trimesh.creation.box()
    mesh = Mesh(box.vertices.astype(np.float32), box.faces.astype(np.int32))
    facing = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), width=32, height=32)
    away = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 20.0), width=32, height=32)
    seen = samples_for_pixels(mesh, camera=facing)
    assert seen < 10_000 and samples_for_pixels(mesh, camera=away) == seen   # was MAX_SAMPLES (2,000,000)
