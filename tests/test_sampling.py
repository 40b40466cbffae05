"""surfsplat.geometry.sampling.sample_mesh: uniform area sampling of triangle meshes."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import stats

from surfsplat import InputError
from surfsplat.geometry.sampling import sample_mesh
from surfsplat.io import Mesh, load_mesh


def icosphere(subdivisions=2) -> Mesh:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=2.0)
    return Mesh(sphere.vertices, sphere.faces)


def plane_offsets(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) and plane offsets d (F,) with n . p = d on face f."""
    normals = mesh.face_normals().astype(np.float64)
    return normals, np.einsum("ij,ij->i", normals, mesh.vertices[mesh.faces[:, 0]].astype(np.float64))


def test_samples_lie_on_a_convex_mesh_with_outward_unit_normals():
    mesh = icosphere()
    cloud = sample_mesh(mesh, 20_000, seed=1)
    assert len(cloud) == 20_000 and cloud.u is None and cloud.v is None and cloud.colors is None
    assert cloud.positions.dtype == np.float32 and cloud.normals.dtype == np.float32
    normals, offsets = plane_offsets(mesh)
    # for a convex polyhedron, a point is on the surface iff its largest signed plane distance is 0,
    # and the face attaining it is the face the point lies on
    signed = cloud.positions.astype(np.float64) @ normals.T - offsets  # (n, F)
    assert np.abs(signed.max(axis=1)).max() < 1e-5
    face = signed.argmax(axis=1)
    np.testing.assert_allclose(np.linalg.norm(cloud.normals, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(cloud.normals, normals[face], atol=1e-6)
    assert np.all(np.einsum("ij,ij->i", cloud.normals, cloud.positions) > 0)  # outward


def test_cube_samples_on_faces_with_axis_normals():
    box = trimesh.creation.box(extents=(2, 2, 2))
    cloud = sample_mesh(Mesh(box.vertices, box.faces), 5000, seed=3)
    p = cloud.positions
    assert np.allclose(np.abs(p).max(axis=1), 1.0, atol=1e-6)  # on the surface
    assert np.all(np.abs(p) <= 1 + 1e-6)
    axis = np.abs(p).argmax(axis=1)
    expected = np.zeros_like(p)
    expected[np.arange(len(p)), axis] = np.sign(p[np.arange(len(p)), axis])
    np.testing.assert_allclose(cloud.normals, expected, atol=1e-6)


def stacked_triangles(areas) -> Mesh:
    """Disjoint triangles, face k in the plane z = k, with the given areas."""
    vertices, faces = [], []
    for k, area in enumerate(areas):
        s = np.sqrt(2 * area)  # right triangle with legs s
        vertices += [[0, 0, k], [s, 0, k], [0, s, k]]
        faces.append([3 * k, 3 * k + 1, 3 * k + 2])
    return Mesh(np.array(vertices, dtype=np.float64), np.array(faces))


def test_counts_per_face_proportional_to_area():
    areas = np.array([0.5, 1.0, 2.0, 4.0, 8.0, 0.0, 16.0, 0.25])  # one zero-area face
    n = 200_000
    cloud = sample_mesh(stacked_triangles(areas), n, seed=7)
    face = np.rint(cloud.positions[:, 2]).astype(int)
    counts = np.bincount(face, minlength=len(areas))
    assert counts[5] == 0  # a degenerate face is never chosen
    keep = areas > 0
    expected = n * areas[keep] / areas.sum()
    chi2 = np.sum((counts[keep] - expected) ** 2 / expected)
    assert chi2 < stats.chi2.ppf(0.999, df=keep.sum() - 1)
    np.testing.assert_allclose(counts[keep] / n, areas[keep] / areas.sum(), atol=0.005)


def test_uniform_within_a_triangle():
    # unit right triangle: a uniform density puts 1/4 of the samples in each of the four
    # half-size sub-triangles, and a mean at the centroid
    mesh = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32), np.array([[0, 1, 2]]))
    p = sample_mesh(mesh, 100_000, seed=11).positions.astype(np.float64)
    x, y = p[:, 0], p[:, 1]
    assert np.all(x >= -1e-7) and np.all(y >= -1e-7) and np.all(x + y <= 1 + 1e-6)
    parts = [x > 0.5, y > 0.5, (x + y < 0.5), (x <= 0.5) & (y <= 0.5) & (x + y >= 0.5)]
    fractions = np.array([part.mean() for part in parts])
    np.testing.assert_allclose(fractions, 0.25, atol=0.006)
    np.testing.assert_allclose(p.mean(axis=0), [1 / 3, 1 / 3, 0], atol=0.004)


def test_deterministic_for_a_seed():
    mesh = icosphere(1)
    a = sample_mesh(mesh, 1000, seed=5)
    b = sample_mesh(mesh, 1000, seed=5)
    c = sample_mesh(mesh, 1000, seed=6)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.normals, b.normals)
    assert not np.array_equal(a.positions, c.positions)


def test_colors_are_interpolated():
    sphere = trimesh.creation.icosphere(subdivisions=1)
    v = np.asarray(sphere.vertices)
    color = lambda p: 0.5 + 0.5 * p @ np.array([[1, 0, 0], [0, 0.5, 0], [0.2, 0.3, 0.4]]).T  # noqa: E731
    mesh = Mesh(v, sphere.faces, vertex_colors=color(v))
    cloud = sample_mesh(mesh, 3000, seed=2)
    # a linear function of position is reproduced exactly by barycentric interpolation
    np.testing.assert_allclose(cloud.colors, color(cloud.positions.astype(np.float64)), atol=1e-6)
    assert cloud.colors.dtype == np.float32


def test_vertex_normals_orient_face_normals():
    sphere = trimesh.creation.icosphere(subdivisions=1)
    inward = np.asarray(sphere.faces)[:, ::-1]  # wound clockwise: geometric normals point inward
    bare = sample_mesh(Mesh(sphere.vertices, inward), 2000, seed=4)
    assert np.all(np.einsum("ij,ij->i", bare.normals, bare.positions) < 0)
    outward = np.asarray(sphere.vertices)  # unit sphere: the vertex normal is the position
    oriented = sample_mesh(Mesh(sphere.vertices, inward, vertex_normals=outward), 2000, seed=4)
    assert np.array_equal(oriented.positions, bare.positions)
    np.testing.assert_allclose(oriented.normals, -bare.normals)
    assert np.all(np.einsum("ij,ij->i", oriented.normals, oriented.positions) > 0)


@pytest.mark.parametrize("n", [0, -5, 2.5, True, "10"])
def test_bad_counts(n):
    with pytest.raises(InputError, match="n must"):
        sample_mesh(icosphere(0), n)


def test_zero_area_and_invalid_meshes():
    flat = Mesh(np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2]]), np.array([[0, 1, 2], [0, 0, 1]]))
    with pytest.raises(InputError, match="zero total area"):
        sample_mesh(flat, 10)
    with pytest.raises(InputError, match="no faces"):
        sample_mesh(Mesh(np.zeros((3, 3)), np.zeros((0, 3))), 10)
    with pytest.raises(InputError, match="refers to vertex 3"):
        sample_mesh(Mesh(np.eye(3), np.array([[0, 1, 3]])), 10)


def test_numpy_integer_count_and_single_sample():
    cloud = sample_mesh(icosphere(0), np.int64(1))
    assert len(cloud) == 1


def test_sample_real_mesh(shared_data):
    path = shared_data / "frag_115.ply"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    mesh = load_mesh(path)
    cloud = sample_mesh(mesh, 50_000, seed=0)
    assert len(cloud) == 50_000 and cloud.colors is not None
    lo, hi = mesh.bounds()
    assert np.all(cloud.positions >= lo - 1e-6) and np.all(cloud.positions <= hi + 1e-6)
    assert np.all(cloud.colors >= 0) and np.all(cloud.colors <= 1 + 1e-6)
    # oriented by the scan's vertex normals
    assert np.isfinite(cloud.normals).all()
    validated = cloud.validated("samples")
    assert len(validated) == 50_000


def test_smooth_normals_interpolate_the_vertex_normals():
    """On an icosphere with radial vertex normals the interpolated normal is far closer to the sphere's."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    mesh = Mesh(sphere.vertices, sphere.faces, vertex_normals=sphere.vertices / 2.0)
    face = sample_mesh(mesh, 5000, seed=4)
    smooth = sample_mesh(mesh, 5000, seed=4, smooth_normals=True)
    np.testing.assert_array_equal(face.positions, smooth.positions)
    np.testing.assert_allclose(np.linalg.norm(smooth.normals, axis=1), 1.0, atol=1e-6)
    radial = smooth.positions / np.linalg.norm(smooth.positions, axis=1, keepdims=True)
    err_face = np.degrees(np.arccos(np.clip(np.sum(face.normals * radial, axis=1), -1, 1)))
    err_smooth = np.degrees(np.arccos(np.clip(np.sum(smooth.normals * radial, axis=1), -1, 1)))
    assert err_smooth.mean() < 0.25 * err_face.mean()
    # without stored vertex normals, the area-weighted ones (radial on an icosphere, to ~1 degree)
    area = sample_mesh(Mesh(sphere.vertices, sphere.faces), 5000, seed=4, smooth_normals=True)
    err_area = np.degrees(np.arccos(np.clip(np.sum(area.normals * radial, axis=1), -1, 1)))
    assert err_area.mean() < 0.25 * err_face.mean()
