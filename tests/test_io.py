"""surfsplat.io: PLY / OBJ / LAS reading, PLY writing, Mesh."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from surfsplat import InputError, SplatCloud
from surfsplat.cloud import InvalidPointsWarning
from surfsplat.io import Mesh, load, load_input, load_mesh, save_ply
from surfsplat.io.mesh import area_weighted_normals
from surfsplat.io.ply import circular_axes, fan_triangulate

FIELDS = ("positions", "normals", "colors", "u", "v", "normal_field", "clip_lines")


# -- helpers -----------------------------------------------------------------


def write_vertices(path: Path, columns: dict[str, np.ndarray], fmt: str = "binary_little_endian",
                   faces: list | np.ndarray | None = None, face_prop: str = "vertex_indices") -> Path:
    """Write a PLY with plyfile directly: one vertex element from ``columns``, optional faces."""
    n = len(next(iter(columns.values())))
    records = np.empty(n, dtype=[(name, values.dtype) for name, values in columns.items()])
    for name, values in columns.items():
        records[name] = values
    elements = [PlyElement.describe(records, "vertex")]
    if faces is not None:
        face_records = np.empty(len(faces), dtype=[(face_prop, object)])
        face_records[face_prop] = [np.asarray(f, dtype=np.int32) for f in faces]
        elements.append(PlyElement.describe(face_records, "face", len_types={face_prop: "u1"},
                                            val_types={face_prop: "i4"}))
    text = fmt == "ascii"
    order = {"ascii": "=", "binary_little_endian": "<", "binary_big_endian": ">"}[fmt]
    PlyData(elements, text=text, byte_order=order).write(str(path))
    return path


def unit_rows(rng, n):
    x = rng.normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def random_cloud(rng, n=200, colors_8bit=False) -> SplatCloud:
    """A SplatCloud with every optional array, validated (normals unit as validation leaves them)."""
    normals = unit_rows(rng, n)
    # u, v orthogonal to the normal and not degenerate
    u, v = circular_axes(normals, rng.uniform(0.1, 2.0, n))
    v = v * rng.uniform(0.5, 1.0, (n, 1))
    colors = rng.integers(0, 256, (n, 3)) / 255.0 if colors_8bit else rng.random((n, 3))
    cloud = SplatCloud(positions=rng.normal(size=(n, 3)) * 10, normals=normals, colors=colors, u=u, v=v,
                       normal_field=rng.normal(size=(n, 2)), clip_lines=rng.normal(size=(n, 2, 3)))
    return cloud.validated()


def assert_same_cloud(a: SplatCloud, b: SplatCloud, normals_exact: bool = True) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is None:
            continue
        assert x.dtype == np.float32 and y.dtype == np.float32, name
        if name == "normals" and not normals_exact:
            # validation renormalizes unit normals in float32, which may move them by an ulp
            np.testing.assert_allclose(x, y, rtol=0, atol=3e-7, err_msg=name)
        else:
            assert np.array_equal(x, y), name


# -- round trips ---------------------------------------------------------------


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("colors_8bit", [False, True])
def test_save_load_round_trip_every_field(tmp_path, binary, colors_8bit):
    cloud = random_cloud(np.random.default_rng(1), colors_8bit=colors_8bit)
    path = save_ply(cloud, tmp_path / "all.ply", binary=binary)
    assert path == tmp_path / "all.ply" and path.is_file()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing may be dropped
        back = load(path)
    # the IO layer is lossless; the only change is validation's renormalization of normals,
    # identical to validating the original once more
    assert_same_cloud(cloud.replace(normals=cloud.validated().normals), back)
    assert_same_cloud(cloud, back, normals_exact=False)
    header = PlyData.read(str(path))
    assert header.text == (not binary)
    assert header["vertex"].data.dtype["red"] == (np.uint8 if colors_8bit else np.float32)
    names = header["vertex"].data.dtype.names
    assert names == ("x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "ux", "uy", "uz",
                     "vx", "vy", "vz", "alpha", "beta", "clip0_a", "clip0_b", "clip0_c",
                     "clip1_a", "clip1_b", "clip1_c")


@pytest.mark.parametrize("binary", [True, False])
def test_save_load_round_trip_positions_only(tmp_path, binary):
    positions = np.random.default_rng(2).normal(size=(500, 3)).astype(np.float32) * 1e3
    path = save_ply(SplatCloud(positions=positions), tmp_path / "p.ply", binary=binary)
    back = load(path)
    assert np.array_equal(back.positions, positions)
    assert all(getattr(back, name) is None for name in FIELDS[1:])
    assert PlyData.read(str(path))["vertex"].data.dtype.names == ("x", "y", "z")


def test_save_replaces_unless_told_not_to(tmp_path):
    cloud = SplatCloud(positions=np.zeros((3, 3)))
    path = save_ply(cloud, tmp_path / "out.ply")
    save_ply(SplatCloud(positions=np.ones((5, 3))), path)   # replaced, as image and point-cloud tools do
    assert len(load(path)) == 5
    before = path.read_bytes()
    with pytest.raises(InputError, match="out.ply") as info:
        save_ply(SplatCloud(positions=np.zeros((7, 3))), path, overwrite=False)
    assert "overwrite" in str(info.value)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["out.ply"]   # no temporary file left


def test_save_into_missing_directory_names_file(tmp_path):
    with pytest.raises(InputError, match="nowhere.ply"):
        save_ply(SplatCloud(positions=np.zeros((1, 3))), tmp_path / "missing" / "nowhere.ply")


# -- reading files written by plyfile ----------------------------------------------


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_read_every_field_each_format(tmp_path, fmt):
    rng = np.random.default_rng(3)
    n = 64
    normals = np.eye(3)[rng.integers(0, 3, n)] * rng.choice([-1.0, 1.0], (n, 1))  # exactly unit
    u = np.roll(normals, 1, axis=1) * 0.5
    v = np.roll(normals, 2, axis=1) * 0.25
    pos = rng.normal(size=(n, 3))
    rgb = rng.integers(0, 256, (n, 3))
    field = rng.normal(size=(n, 2))
    clips = rng.normal(size=(n, 6))
    columns = {"x": pos[:, 0].astype("f8"), "y": pos[:, 1].astype("f8"), "z": pos[:, 2].astype("f8"),
               "nx": normals[:, 0].astype("f4"), "ny": normals[:, 1].astype("f4"),
               "nz": normals[:, 2].astype("f4"),
               "red": rgb[:, 0].astype("u1"), "green": rgb[:, 1].astype("u1"), "blue": rgb[:, 2].astype("u1"),
               "confidence": rng.random(n).astype("f4")}
    columns.update({f"{a}{c}": (u if a == "u" else v)[:, k].astype("f4") for a in "uv" for k, c in enumerate("xyz")})
    columns.update({"alpha": field[:, 0].astype("f4"), "beta": field[:, 1].astype("f4")})
    columns.update({f"clip{k}_{c}": clips[:, 3 * k + j].astype("f4") for k in (0, 1) for j, c in enumerate("abc")})
    cloud = load(write_vertices(tmp_path / f"{fmt}.ply", columns, fmt))
    assert np.array_equal(cloud.positions, pos.astype(np.float32))
    assert np.array_equal(cloud.normals, normals.astype(np.float32))
    assert np.array_equal(cloud.colors, (rgb / 255.0).astype(np.float32))
    assert np.array_equal(cloud.u, u.astype(np.float32)) and np.array_equal(cloud.v, v.astype(np.float32))
    assert np.array_equal(cloud.normal_field, field.astype(np.float32))
    assert np.array_equal(cloud.clip_lines, clips.reshape(n, 2, 3).astype(np.float32))


def test_single_clip_line_pads_the_second(tmp_path):
    columns = {"x": np.zeros(2, "f4"), "y": np.zeros(2, "f4"), "z": np.arange(2, dtype="f4"),
               "clip0_a": np.array([1, 2], "f4"), "clip0_b": np.array([3, 4], "f4"), "clip0_c": np.array([5, 6], "f4")}
    cloud = load(write_vertices(tmp_path / "clip.ply", columns, "ascii"))
    assert np.array_equal(cloud.clip_lines[:, 0], [[1, 3, 5], [2, 4, 6]])
    assert np.array_equal(cloud.clip_lines[:, 1], [[0, 0, 1], [0, 0, 1]])


def test_radius_gives_orthogonal_circular_axes(tmp_path):
    rng = np.random.default_rng(4)
    normals = np.concatenate([np.eye(3), -np.eye(3), unit_rows(rng, 100), [[1e-3, 1, 1e-3]]])
    n = len(normals)
    radius = rng.uniform(0.01, 3.0, n)
    columns = {"x": rng.random(n).astype("f4"), "y": rng.random(n).astype("f4"), "z": rng.random(n).astype("f4"),
               "nx": normals[:, 0].astype("f4"), "ny": normals[:, 1].astype("f4"), "nz": normals[:, 2].astype("f4"),
               "radius": radius.astype("f4")}
    cloud = load(write_vertices(tmp_path / "radius.ply", columns))
    r = radius.astype(np.float32)
    np.testing.assert_allclose(np.linalg.norm(cloud.u, axis=1), r, rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(cloud.v, axis=1), r, rtol=1e-6)
    scale = r * r
    assert np.all(np.abs(np.einsum("ij,ij->i", cloud.u, cloud.normals)) < 1e-6 * r)
    assert np.all(np.abs(np.einsum("ij,ij->i", cloud.v, cloud.normals)) < 1e-6 * r)
    assert np.all(np.abs(np.einsum("ij,ij->i", cloud.u, cloud.v)) < 1e-6 * scale)
    # right-handed: u x v points along the normal
    np.testing.assert_allclose(np.cross(cloud.u, cloud.v) / scale[:, None], cloud.normals, atol=1e-5)
    np.testing.assert_allclose(cloud.radii, r, rtol=1e-6)


def test_axes_take_precedence_over_radius_and_bad_radii_are_dropped(tmp_path):
    columns = {"x": np.zeros(3, "f4"), "y": np.zeros(3, "f4"), "z": np.arange(3, dtype="f4"),
               "nx": np.zeros(3, "f4"), "ny": np.zeros(3, "f4"), "nz": np.ones(3, "f4"),
               "radius": np.array([1.0, 0.0, -2.0], "f4")}
    with pytest.warns(InvalidPointsWarning, match="dropped 2 of 3"):
        cloud = load(write_vertices(tmp_path / "r.ply", columns))
    assert len(cloud) == 1
    columns.update({"ux": np.full(3, 2, "f4"), "uy": np.zeros(3, "f4"), "uz": np.zeros(3, "f4"),
                    "vx": np.zeros(3, "f4"), "vy": np.full(3, 3, "f4"), "vz": np.zeros(3, "f4")})
    cloud = load(write_vertices(tmp_path / "uv.ply", columns))
    assert np.array_equal(cloud.u, np.tile([2, 0, 0], (3, 1))) and np.array_equal(cloud.v, np.tile([0, 3, 0], (3, 1)))


def test_radius_without_normals_is_ignored_with_warning(tmp_path):
    columns = {"x": np.zeros(2, "f4"), "y": np.zeros(2, "f4"), "z": np.arange(2, dtype="f4"),
               "radius": np.ones(2, "f4")}
    with pytest.warns(UserWarning, match="radius"):
        cloud = load(write_vertices(tmp_path / "r.ply", columns))
    assert cloud.u is None and cloud.v is None and cloud.normals is None


@pytest.mark.parametrize("dtype, values, expected", [
    ("u1", [0, 51, 255], [0.0, 0.2, 1.0]),
    ("u2", [0, 13107, 65535], [0.0, 0.2, 1.0]),
    ("f4", [0.0, 0.2, 1.0], [0.0, 0.2, 1.0]),
    ("f4", [0.0, 51.0, 255.0], [0.0, 0.2, 1.0]),  # floats above 1 are 0..255
    ("f8", [0.0, 0.5, 0.25], [0.0, 0.5, 0.25]),
])
def test_color_scaling(tmp_path, dtype, values, expected):
    values = np.array(values, dtype=dtype)
    columns = {"x": np.zeros(3, "f4"), "y": np.zeros(3, "f4"), "z": np.arange(3, dtype="f4"),
               "red": values, "green": values[::-1].copy(), "blue": values,
               "alpha": np.full(3, 7, dtype=dtype)}  # alpha without beta: opacity, ignored
    cloud = load(write_vertices(tmp_path / "c.ply", columns, "ascii"))
    np.testing.assert_allclose(cloud.colors[:, 0], expected, atol=1e-7)
    np.testing.assert_allclose(cloud.colors[:, 1], expected[::-1], atol=1e-7)
    assert cloud.colors.dtype == np.float32 and cloud.normal_field is None


def test_nan_rows_dropped_with_count(tmp_path):
    z = np.arange(10, dtype="f4")
    z[[2, 5, 7]] = np.nan
    x = np.zeros(10, "f4")
    x[8] = np.inf
    nz = np.ones(10, "f4")
    nz[1] = 0  # zero-length normal
    columns = {"x": x, "y": np.zeros(10, "f4"), "z": z,
               "nx": np.zeros(10, "f4"), "ny": np.zeros(10, "f4"), "nz": nz}
    with pytest.warns(InvalidPointsWarning, match=r"nan\.ply: dropped 5 of 10") as record:
        cloud = load(write_vertices(tmp_path / "nan.ply", columns))
    assert "4 with non-finite coordinates" in str(record[0].message)
    assert "1 with zero-length" in str(record[0].message)
    assert len(cloud) == 5 and np.isfinite(cloud.positions).all()
    assert np.array_equal(cloud.positions[:, 2], [0, 3, 4, 6, 9])


def test_all_nan_file_raises(tmp_path):
    columns = {c: np.full(4, np.nan, "f4") for c in "xyz"}
    with pytest.raises(InputError, match=r"allnan\.ply.*no valid points"):
        load(write_vertices(tmp_path / "allnan.ply", columns))


def test_empty_vertex_element_raises(tmp_path):
    columns = {c: np.zeros(0, "f4") for c in "xyz"}
    with pytest.raises(InputError, match=r"zero\.ply.*no points"):
        load(write_vertices(tmp_path / "zero.ply", columns))


# -- meshes ----------------------------------------------------------------------

# tetrahedron O, A, B, C with outward faces; hand-computed area-weighted normals:
# face cross products (2 * area * unit normal): OBA (0,0,-2), OAC (0,-3,0), OCB (-6,0,0), ABC (6,3,2)
TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=np.float32)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
TETRA_N = np.array([[-6, -3, -2], [7, 0, 0], [0, 7, 0], [0, 0, 7]], dtype=np.float64) / 7.0


def tetra_columns(extra_vertex=False):
    v = np.vstack([TETRA_V, [[5, 5, 5]]]) if extra_vertex else TETRA_V
    return {c: v[:, k].copy() for k, c in enumerate("xyz")}


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_mesh_without_normals_gets_area_weighted_normals(tmp_path, fmt):
    path = write_vertices(tmp_path / "tetra.ply", tetra_columns(extra_vertex=True), fmt, faces=TETRA_F)
    with pytest.warns(InvalidPointsWarning, match=r"tetra\.ply: dropped 1 of 5 .*zero-length"):
        cloud = load(path)  # the unused vertex has no normal
    assert np.array_equal(cloud.positions, TETRA_V)
    np.testing.assert_allclose(cloud.normals, TETRA_N, atol=1e-6)
    centroid = TETRA_V.mean(axis=0)
    assert np.all(np.einsum("ij,ij->i", cloud.normals, TETRA_V - centroid) > 0)  # outward


def test_polygon_faces_are_fan_triangulated(tmp_path):
    # a unit cube with quad faces, counter-clockwise seen from outside
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float32)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    faces = quads[:-1] + [[1, 5, 7], [1, 7, 3]]  # mixed quads and triangles
    for fmt in ("ascii", "binary_little_endian"):
        path = write_vertices(tmp_path / f"cube_{fmt}.ply", {c: v[:, k].copy() for k, c in enumerate("xyz")},
                              fmt, faces=faces, face_prop="vertex_index")
        mesh = load_mesh(path)
        assert mesh.faces.shape == (12, 3)
        assert np.isclose(mesh.face_areas().sum(), 6.0)
        centers = v[mesh.faces].mean(axis=1) - 0.5
        assert np.all(np.einsum("ij,ij->i", mesh.face_normals(), centers) > 0)
        cloud = load(path)
        expected = (v - 0.5) / np.linalg.norm(v - 0.5, axis=1, keepdims=True)
        assert np.all(np.einsum("ij,ij->i", cloud.normals, expected) > 0.8)


def test_fan_triangulate():
    flat = np.array([0, 1, 2, 10, 11, 12, 13, 14, 20, 21, 22, 23])
    tris = fan_triangulate(flat, np.array([3, 5, 4]))
    assert tris.tolist() == [[0, 1, 2], [10, 11, 12], [10, 12, 13], [10, 13, 14], [20, 21, 22], [20, 22, 23]]


def test_mesh_keeps_stored_normals_and_colors(tmp_path):
    columns = tetra_columns()
    columns.update({"nx": np.zeros(4, "f4"), "ny": np.zeros(4, "f4"), "nz": np.ones(4, "f4"),
                    "red": np.array([0, 255, 0, 51], "u1"), "green": np.zeros(4, "u1"), "blue": np.zeros(4, "u1")})
    path = write_vertices(tmp_path / "tn.ply", columns, faces=TETRA_F)
    cloud = load(path)
    assert np.array_equal(cloud.normals, np.tile([0, 0, 1], (4, 1)))
    mesh = load_mesh(path)
    assert np.array_equal(mesh.vertex_normals, np.tile([0, 0, 1], (4, 1)))
    np.testing.assert_allclose(mesh.vertex_colors[:, 0], [0, 1, 0, 0.2], atol=1e-7)
    assert mesh.faces.dtype == np.int64 and mesh.vertices.dtype == np.float32


def test_mesh_methods():
    mesh = Mesh(TETRA_V, TETRA_F)
    np.testing.assert_allclose(mesh.face_areas(), [1.0, 1.5, 3.0, 3.5])  # |(6,3,2)| / 2 = 3.5
    np.testing.assert_allclose(mesh.face_normals(), [[0, 0, -1], [0, -1, 0], [-1, 0, 0], [6 / 7, 3 / 7, 2 / 7]],
                               atol=1e-7)
    lo, hi = mesh.bounds()
    assert np.array_equal(lo, [0, 0, 0]) and np.array_equal(hi, [1, 2, 3])
    np.testing.assert_allclose(area_weighted_normals(TETRA_V, TETRA_F), TETRA_N, atol=1e-6)
    degenerate = Mesh(TETRA_V, [[0, 1, 1]])
    assert np.array_equal(degenerate.face_normals(), [[0, 0, 0]]) and degenerate.face_areas()[0] == 0
    with pytest.raises(InputError, match="shape"):
        Mesh(np.zeros((3, 2)), TETRA_F)


def test_mesh_validation_errors():
    with pytest.raises(InputError, match="src: mesh has no faces"):
        Mesh(TETRA_V, np.zeros((0, 3))).validated("src")
    with pytest.raises(InputError, match="src: .*non-finite"):
        Mesh(np.vstack([TETRA_V[:3], [[np.nan, 0, 0]]]), TETRA_F).validated("src")
    with pytest.raises(InputError, match="src: face 1 refers to vertex 4"):
        Mesh(TETRA_V, [[0, 1, 2], [0, 1, 4]]).validated("src")
    with pytest.raises(InputError, match="src: face 0 refers to vertex -1"):
        Mesh(TETRA_V, [[0, -1, 2]]).validated("src")


def test_load_mesh_requires_faces(tmp_path):
    path = write_vertices(tmp_path / "points.ply", tetra_columns())
    with pytest.raises(InputError, match=r"points\.ply.*no faces"):
        load_mesh(path)
    with pytest.raises(InputError, match=r"points\.txt.*unknown file type"):
        load_mesh(tmp_path / "points.txt")


# -- OBJ ------------------------------------------------------------------------


def write_obj(path: Path, vertices, faces, normals=None, colors=None) -> Path:
    lines = []
    for k, p in enumerate(vertices):
        extra = "" if colors is None else " " + " ".join(f"{c:.6f}" for c in colors[k])
        lines.append("v " + " ".join(f"{c:.9g}" for c in p) + extra)
    if normals is not None:
        lines += ["vn " + " ".join(f"{c:.9g}" for c in n) for n in normals]
        lines += ["f " + " ".join(f"{i + 1}//{i + 1}" for i in f) for f in faces]
    else:
        lines += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_obj_load_area_weighted_normals(tmp_path):
    path = write_obj(tmp_path / "tetra.obj", TETRA_V, TETRA_F)
    cloud = load(path)
    assert np.array_equal(cloud.positions, TETRA_V)
    np.testing.assert_allclose(cloud.normals, TETRA_N, atol=1e-6)
    assert cloud.colors is None
    mesh = load_mesh(path)
    assert np.array_equal(mesh.faces, TETRA_F) and mesh.vertex_normals is None


def test_obj_load_keeps_file_normals_and_colors(tmp_path):
    normals = np.array([[0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 0, 1]], dtype=np.float32)
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.4, 0.6]])
    path = write_obj(tmp_path / "tn.obj", TETRA_V, TETRA_F, normals=normals, colors=colors)
    cloud = load(path)
    np.testing.assert_allclose(cloud.normals, normals)
    np.testing.assert_allclose(cloud.colors, colors, atol=1 / 255)
    mesh = load_mesh(path)
    np.testing.assert_allclose(mesh.vertex_normals, normals)


@pytest.mark.parametrize("content, problem", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "cannot read OBJ"),
    ("", "no vertices"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite"),
])
def test_obj_errors_name_file(tmp_path, content, problem):
    path = tmp_path / "bad.obj"
    path.write_text(content)
    with pytest.raises(InputError, match=r"bad\.obj") as info:
        load(path)
    assert problem in str(info.value)
    with pytest.raises(InputError, match=r"bad\.obj"):
        load_mesh(path)


def test_obj_without_faces_is_a_point_cloud(tmp_path):
    path = tmp_path / "points.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 2 0\n")
    cloud = load(path)
    assert np.array_equal(cloud.positions, [[0, 0, 0], [1, 0, 0], [0, 2, 0]]) and cloud.normals is None
    with pytest.raises(InputError, match=r"points\.obj: mesh has no faces"):
        load_mesh(path)


# -- malformed files -----------------------------------------------------------------


def good_binary_mesh(path: Path) -> Path:
    rng = np.random.default_rng(5)
    v = rng.random((300, 3)).astype("f4")
    faces = rng.integers(0, 300, (400, 3))
    return write_vertices(path, {c: v[:, k].copy() for k, c in enumerate("xyz")}, faces=faces)


def test_truncated_binary_files(tmp_path):
    mesh = good_binary_mesh(tmp_path / "full.ply")
    data = mesh.read_bytes()
    # cut inside the faces, inside the vertices, and right after the header
    header_end = data.index(b"end_header\n") + len(b"end_header\n")
    for k, cut in enumerate([len(data) - 7, len(data) // 2, header_end + 20, header_end]):
        path = tmp_path / f"cut{k}.ply"
        path.write_bytes(data[:cut])
        with pytest.raises(InputError, match=rf"cut{k}\.ply: malformed PLY file"):
            load(path)
    # polygon mesh (not memory-mapped) cut inside its faces
    cloud = {c: np.zeros(4, "f4") + k for k, c in enumerate("xyz")}
    poly = write_vertices(tmp_path / "poly.ply", cloud, faces=[[0, 1, 2, 3], [0, 1, 2]]).read_bytes()
    (tmp_path / "polycut.ply").write_bytes(poly[:-5])
    with pytest.raises(InputError, match=r"polycut\.ply: malformed PLY file"):
        load(tmp_path / "polycut.ply")


@pytest.mark.parametrize("name, content, problem", [
    ("missing_value.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n0 0 0\n1 1\n2 2 2\n", "row 1"),
    ("extra_value.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n0 0 0\n1 1 1 1\n", "row 1"),
    ("not_a_number.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n0 0 0\n1 one 1\n", "malformed"),
    ("short.ply", "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n0 0 0\n1 1 1\n", "end-of-file"),
    ("blank_line.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n0 0 0\n\n1 1 1\n", "row 1"),
    ("garbage.ply", "this is not a ply file\nat all\n", "malformed"),
    ("bad_header.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty flot x\nend_header\n0\n1\n", "malformed"),
    ("empty.ply", "", "malformed"),
    ("no_vertex.ply", "ply\nformat ascii 1.0\nelement point 1\nproperty float x\nend_header\n0\n",
     "no 'vertex' element"),
    ("no_z.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
     "missing z"),
    ("half_normal.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
     "property float z\nproperty float nx\nproperty float ny\nend_header\n0 0 0 0 1\n", "missing nz"),
    ("bad_index.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
     "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n", "face 1 refers to vertex 3"),
    ("negative_index.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
     "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "vertex -1"),
    ("two_corners.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
     "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n2 0 1\n", "face 1 has 2 vertices"),
    ("no_list.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     "property float z\nelement face 1\nproperty list uchar int corners\nend_header\n"
     "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "vertex_indices"),
])
def test_malformed_ply_names_file_and_problem(tmp_path, name, content, problem):
    path = tmp_path / name
    path.write_bytes(content.encode("ascii"))
    with pytest.raises(InputError) as info:
        load(path)
    message = str(info.value)
    assert name in message and problem in message, message


def test_binary_face_index_out_of_range(tmp_path):
    v = {c: np.zeros(3, "f4") + k for k, c in enumerate("xyz")}
    path = write_vertices(tmp_path / "binidx.ply", v, faces=[[0, 1, 2], [0, 1, 7]])
    with pytest.raises(InputError, match=r"binidx\.ply: face 1 refers to vertex 7"):
        load(path)
    with pytest.raises(InputError, match=r"binidx\.ply: face 1 refers to vertex 7"):
        load_mesh(path)


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(InputError, match=r"nothing\.ply: no such file"):
        load(tmp_path / "nothing.ply")
    (tmp_path / "cloud.e58").write_text("0 0 0\n")  # .xyz is read now (tests/test_formats.py)
    with pytest.raises(InputError, match=r"cloud\.e58: unknown file type '\.e58'"):
        load(tmp_path / "cloud.e58")
    with pytest.raises(InputError, match=r"noext.*unknown file type"):
        load(tmp_path / "noext")


def test_crlf_ascii_and_uppercase_extension(tmp_path):
    text = ("ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float x\r\nproperty float y\r\n"
            "property float z\r\nproperty uchar red\r\nproperty uchar green\r\nproperty uchar blue\r\n"
            "end_header\r\n0 0 0 255 0 0\r\n1 2 3 0 51 0\r\n")
    path = tmp_path / "CRLF.PLY"
    path.write_bytes(text.encode("ascii"))
    cloud = load(path)
    assert np.array_equal(cloud.positions, [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 0.2, 0]], atol=1e-7)


# -- LAS -------------------------------------------------------------------------


def test_las_16_bit_colors_and_precision(tmp_path):
    laspy = pytest.importorskip("laspy")
    las = laspy.create(point_format=3, file_version="1.2")
    las.header.scales = np.array([0.001, 0.001, 0.001])
    las.header.offsets = np.array([0.0, 0.0, 0.0])
    las.x = np.array([1.0, 2.5, -3.25])
    las.y = np.array([0.0, 1.0, 2.0])
    las.z = np.array([10.0, 11.0, 12.0])
    las.red = np.array([0, 65535, 13107], dtype=np.uint16)
    las.green = np.array([65535, 0, 0], dtype=np.uint16)
    las.blue = np.array([0, 0, 256], dtype=np.uint16)
    path = tmp_path / "c16.las"
    las.write(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cloud = load(path)
    np.testing.assert_allclose(cloud.positions, [[1, 0, 10], [2.5, 1, 11], [-3.25, 2, 12]])
    np.testing.assert_allclose(cloud.colors[:, 0], [0, 1, 0.2], atol=1e-7)
    assert cloud.normals is None


def test_las_without_laspy_says_how_to_install(tmp_path, monkeypatch):
    path = tmp_path / "x.las"
    path.write_bytes(b"LASF")
    monkeypatch.setitem(sys.modules, "laspy", None)
    with pytest.raises(InputError, match=r"x\.las.*pip install laspy lazrs"):
        load(path)


def test_malformed_las_names_file(tmp_path):
    pytest.importorskip("laspy")
    path = tmp_path / "junk.las"
    path.write_bytes(b"LASF" + bytes(50))
    with pytest.raises(InputError, match=r"junk\.las: cannot read LAS file"):
        load(path)


# -- the shared development data ---------------------------------------------------


def data_file(shared_data: Path, name: str) -> Path:
    path = shared_data / name
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    return path


def test_bunny(shared_data):
    path = data_file(shared_data, "bunny.ply")
    with pytest.warns(InvalidPointsWarning, match=r"dropped 1113 of 35947 points \(1113 with zero-length"):
        cloud = load(path)
    assert len(cloud) == 35947 - 1113 and cloud.colors is None
    np.testing.assert_allclose(np.linalg.norm(cloud.normals, axis=1), 1, atol=1e-6)
    mesh = load_mesh(path)
    assert mesh.vertices.shape == (35947, 3) and mesh.faces.shape == (69451, 3)
    assert mesh.vertex_normals is None
    assert len(np.unique(mesh.faces)) == 35947 - 1113
    # this copy of the bunny ("modified by flipply") is wound clockwise seen from outside (its
    # signed volume is negative), so the right-hand-rule normals point inward; load keeps them so
    a, b, c = (mesh.vertices[mesh.faces[:, k]].astype(np.float64) for k in range(3))
    assert np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6 < 0
    centered = cloud.positions - cloud.positions.mean(axis=0)
    assert np.mean(np.einsum("ij,ij->i", cloud.normals, centered) < 0) > 0.8


def test_frag_115(shared_data):
    path = data_file(shared_data, "frag_115.ply")
    raw = PlyData.read(str(path))["vertex"].data
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cloud = load(path)
    assert len(cloud) == 64365
    assert np.array_equal(cloud.positions[:, 0], raw["x"])
    expected = (np.column_stack([raw["red"], raw["green"], raw["blue"]]) / 255.0).astype(np.float32)
    assert np.array_equal(cloud.colors, expected)
    raw_n = np.column_stack([raw["nx"], raw["ny"], raw["nz"]])
    np.testing.assert_allclose(cloud.normals, raw_n / np.linalg.norm(raw_n, axis=1, keepdims=True), atol=1e-6)
    mesh = load_mesh(path)
    assert mesh.faces.shape == (127229, 3) and mesh.vertex_colors is not None


def test_featuretype(shared_data):
    path = data_file(shared_data, "featuretype.ply")
    cloud = load(path)
    assert len(cloud) == 5096 and cloud.normals is not None and cloud.colors is None
    assert len(np.unique(cloud.positions, axis=0)) == 1722
    mesh = load_mesh(path)
    assert mesh.faces.shape == (3476, 3)
    # stored per-corner normals agree with the faces' geometric normals (split at creases)
    corner_n = mesh.vertex_normals[mesh.faces].mean(axis=1)
    assert np.mean(np.einsum("ij,ij->i", corner_n, mesh.face_normals()) > 0.99) > 0.95


def test_simple_las(shared_data):
    pytest.importorskip("laspy")
    path = data_file(shared_data, "simple.las")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # georeferenced: float32 precision warning
        cloud = load(path)
    assert len(cloud) == 1065 and cloud.normals is None
    assert np.isclose(cloud.colors.max(), 249 / 255) and cloud.colors.min() >= 0
    assert cloud.world_positions()[:, 0].min() > 6e5  # world coordinates kept (origin + local positions)


def test_saved_real_file_reloads_identically(shared_data, tmp_path):
    cloud = load(data_file(shared_data, "frag_115.ply"))
    path = save_ply(cloud, tmp_path / "frag.ply")
    assert PlyData.read(str(path))["vertex"].data.dtype["red"] == np.uint8  # 8-bit colors stay 8-bit
    back = load(path)
    assert_same_cloud(cloud, back, normals_exact=False)


def test_load_input_ply_with_and_without_faces(tmp_path):
    mesh_path = write_vertices(tmp_path / "tetra.ply", tetra_columns(), faces=TETRA_F)
    mesh = load_input(mesh_path)
    assert isinstance(mesh, Mesh) and np.array_equal(mesh.faces, TETRA_F) and mesh.merged_vertices == 0
    empty = write_vertices(tmp_path / "empty_faces.ply", tetra_columns(), faces=np.zeros((0, 3), int))
    cloud = load_input(empty)                    # an empty face element: a point cloud
    assert isinstance(cloud, SplatCloud) and len(cloud) == 4 and cloud.normals is None
    doubled = {c: np.concatenate([v, v]) for c, v in tetra_columns().items()}
    split = write_vertices(tmp_path / "split.ply", doubled, faces=np.vstack([TETRA_F[:2], TETRA_F[2:] + 4]))
    welded = load_input(split)                   # duplicated vertices are merged and counted
    assert len(welded.vertices) == 4 and welded.merged_vertices == 4
    assert len(load_mesh(split).vertices) == 8 and len(load_mesh(split, welded=True).vertices) == 4


def test_las_with_all_zero_rgb_has_no_colors(tmp_path):
    """Point formats 2/3 always store RGB; a file that leaves it all zero has no colours (drawn in the
    default grey, lit), not a black cloud."""
    laspy = pytest.importorskip("laspy")
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = [0.001] * 3
    las = laspy.LasData(header)
    rng = np.random.default_rng(0)
    las.x, las.y, las.z = rng.random(200), rng.random(200), 0.01 * rng.random(200)
    las.write(tmp_path / "zero_rgb.las")
    assert load(tmp_path / "zero_rgb.las").colors is None
    las.red = np.full(200, 65535, np.uint16)
    las.write(tmp_path / "white.las")
    assert np.allclose(load(tmp_path / "white.las").colors[:, 0], 1.0)
