"""In-memory objects in (surfsplat.io.objects.from_object) and SplatCloud conversions both ways."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from surfsplat import InputError, SplatCloud
from surfsplat.io import Mesh
from surfsplat.io.objects import from_object, to_open3d, to_trimesh


def test_array_of_positions():
    cloud = from_object(np.arange(12, dtype=np.float64).reshape(4, 3))
    assert isinstance(cloud, SplatCloud) and len(cloud) == 4


def test_wrong_array_shape_is_refused():
    with pytest.raises(InputError, match=r"ndarray.*\(N, 3\)"):
        from_object(np.zeros((4, 2)))


def test_dict_of_columns_with_uint8_colors_and_extras():
    extras = {}
    cloud = from_object({"x": [0.0, 1.0], "y": [0, 0], "z": [0, 0], "nx": [0, 0], "ny": [0, 0], "nz": [1, 1],
                         "red": np.array([255, 0], np.uint8), "green": np.array([0, 255], np.uint8),
                         "blue": np.array([0, 0], np.uint8), "radius": [0.5, 0.25],
                         "intensity": [7, 8]}, extras=extras)
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 1, 0]])
    np.testing.assert_allclose(cloud.radii, [0.5, 0.25], rtol=1e-6)
    assert list(extras) == ["intensity"]


def test_structured_array_with_rgb_floats():
    data = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("r", "f4"), ("g", "f4"), ("b", "f4")])
    data["x"] = [0, 1, 2]
    data["g"] = 0.5
    cloud = from_object(data)
    np.testing.assert_allclose(cloud.colors[:, 1], 0.5)


def test_positions_column_and_incomplete_group():
    cloud = from_object({"positions": np.zeros((2, 3)), "colors": np.ones((2, 3))})
    assert cloud.colors is not None
    with pytest.raises(InputError, match="nx ny present but nz missing"):
        from_object({"positions": np.zeros((2, 3)), "nx": [0, 0], "ny": [0, 0]})
    with pytest.raises(InputError, match="dict.*no positions"):
        from_object({"a": [1, 2]})


def test_dataframe_if_pandas():
    pandas = pytest.importorskip("pandas")
    frame = pandas.DataFrame({"x": [0.0, 1.0], "y": [0.0, 1.0], "z": [0.0, 2.0], "label": ["a", "b"]})
    extras = {}
    cloud = from_object(frame, extras=extras)
    assert len(cloud) == 2 and "label" in extras


def test_duck_typed_dataframe():
    class Column:
        def __init__(self, values):
            self.values = np.asarray(values)

        def to_numpy(self):
            return self.values

    class Frame:
        columns = ["X", "Y", "Z"]

        def __getitem__(self, name):
            return Column([0.0, 1.0, 2.0])

        def to_numpy(self):
            raise AssertionError("columns are read one by one")

    assert len(from_object(Frame())) == 3


def test_trimesh_mesh_becomes_a_mesh():
    box = trimesh.creation.box(extents=(1, 2, 3))
    mesh = from_object(box)
    assert isinstance(mesh, Mesh) and len(mesh.faces) == 12
    np.testing.assert_allclose(mesh.bounds()[1], [0.5, 1, 1.5])


def test_trimesh_pointcloud_round_trip():
    points = np.random.default_rng(0).random((20, 3))
    colors = np.tile(np.array([255, 0, 0, 255], np.uint8), (20, 1))
    cloud = from_object(trimesh.PointCloud(points, colors=colors))
    np.testing.assert_allclose(cloud.colors, np.tile([1, 0, 0], (20, 1)))
    back = to_trimesh(cloud)
    assert isinstance(back, trimesh.PointCloud)
    np.testing.assert_allclose(back.vertices, points, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(back.colors)[:, :3], colors[:, :3])


class FakeOpen3DCloud:
    """The attribute names of open3d.geometry.PointCloud (Vector3dVector converts with np.asarray)."""

    def __init__(self, points, normals=(), colors=()):
        self.points, self.normals, self.colors = points, list(normals), list(colors)


class FakeOpen3DMesh:
    def __init__(self, vertices, triangles, vertex_normals=(), vertex_colors=()):
        self.vertices, self.triangles = vertices, triangles
        self.vertex_normals, self.vertex_colors = list(vertex_normals), list(vertex_colors)


def test_open3d_like_pointcloud():
    cloud = from_object(FakeOpen3DCloud(np.zeros((3, 3)) + [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                                        normals=np.tile([0, 0, 1.0], (3, 1)), colors=np.full((3, 3), 0.25)))
    np.testing.assert_allclose(cloud.normals, np.tile([0, 0, 1], (3, 1)))
    np.testing.assert_allclose(cloud.colors, 0.25)
    bare = from_object(FakeOpen3DCloud(np.zeros((2, 3))))
    assert bare.normals is None and bare.colors is None


def test_open3d_like_mesh():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    mesh = from_object(FakeOpen3DMesh(vertices, np.array([[0, 1, 2], [1, 3, 2]]),
                                      vertex_colors=np.full((4, 3), 0.5)))
    assert isinstance(mesh, Mesh) and len(mesh.faces) == 2
    np.testing.assert_allclose(mesh.vertex_colors, 0.5)
    with pytest.raises(InputError, match="vertex_colors must have shape"):
        from_object(FakeOpen3DMesh(vertices, np.array([[0, 1, 2]]), vertex_colors=np.zeros((2, 3))))


def test_anything_else_is_refused_with_the_type_and_the_accepted_list():
    with pytest.raises(InputError, match="cannot render a set; accepted: a SplatCloud"):
        from_object({1, 2})


def test_splatcloud_and_mesh_pass_through():
    cloud = SplatCloud(np.zeros((2, 3)))
    assert len(from_object(cloud)) == 2
    mesh = Mesh(np.eye(3), np.array([[0, 1, 2]]))
    assert isinstance(from_object(mesh), Mesh)


def test_to_dict_round_trips_both_forms():
    rng = np.random.default_rng(1)
    normals = np.tile([0, 0, 1.0], (5, 1))
    cloud = SplatCloud.from_arrays(rng.random((5, 3)), normals, rng.random((5, 3)), radius=np.full(5, 0.1))
    for columns in (False, True):
        back = SplatCloud.from_dict(cloud.to_dict(columns=columns))
        for name in ("positions", "normals", "colors", "u", "v"):
            np.testing.assert_array_equal(getattr(back, name), getattr(cloud, name))
    assert set(cloud.to_dict(columns=True)) >= {"x", "y", "z", "nx", "red", "ux", "vz"}


def test_from_arrays_radius_needs_normals():
    with pytest.raises(InputError, match="radius needs normals"):
        SplatCloud.from_arrays(np.zeros((2, 3)), radius=[1, 1])


def test_to_open3d_without_open3d_is_a_clear_error():
    try:
        import open3d  # noqa: F401
    except ImportError:
        with pytest.raises(InputError, match="needs Open3D"):
            to_open3d(SplatCloud(np.zeros((2, 3))))
    else:
        out = to_open3d(SplatCloud(np.zeros((2, 3))))
        assert len(np.asarray(out.points)) == 2


@pytest.mark.gl
def test_render_takes_arrays_tables_and_trimesh_objects():
    """The front door: surfsplat.render of an ndarray, a dict of columns and a trimesh mesh."""
    import trimesh

    import surfsplat

    rng = np.random.default_rng(0)
    sphere = rng.normal(size=(4000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    for source in (sphere, {"x": sphere[:, 0], "y": sphere[:, 1], "z": sphere[:, 2]},
                   trimesh.creation.icosphere(subdivisions=3)):
        frame = surfsplat.render(source, width=64, height=64)
        assert 0.3 < frame.mask.mean() < 0.9, type(source).__name__
    with pytest.raises(surfsplat.InputError, match="cannot render a int"):
        surfsplat.render(42)
