"""Point formats: point text (.xyz/.pts/.csv/.txt), PCD, trained Gaussian-splat PLYs."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

import surfsplat
from surfsplat import InputError
from surfsplat.pipeline import CameraSpec
from surfsplat.io import CLOUD_EXTENSIONS, load, load_input
from surfsplat.io.gaussians import SH_C0, SIGMA_SCALE, DroppedGaussiansWarning, quaternion_matrices
from surfsplat.lighting import Lights

# -- point text ----------------------------------------------------------------


def test_text_extensions_are_known():
    for ext in (".xyz", ".pts", ".csv", ".txt", ".pcd"):
        assert ext in CLOUD_EXTENSIONS


def test_xyz_three_columns(tmp_path):
    path = tmp_path / "a.xyz"
    path.write_text("0 0 0\n1 0 0\n0 1 0.5\n")
    cloud = load(path)
    np.testing.assert_allclose(cloud.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0.5]])
    assert cloud.normals is None and cloud.colors is None


def test_xyz_normals_then_colors_by_column_count(tmp_path):
    path = tmp_path / "a.xyz"
    path.write_text("0 0 0 0 0 1 255 0 0\n1 0 0 0 1 0 0 255 0\n")
    cloud = load(path)
    np.testing.assert_allclose(cloud.normals, [[0, 0, 1], [0, 1, 0]])
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 1, 0]])


def test_six_columns_are_normals_when_unit_else_colors(tmp_path):
    (tmp_path / "n.xyz").write_text("0 0 0 0 0 1\n1 0 0 1 0 0\n")
    (tmp_path / "c.xyz").write_text("0 0 0 255 128 0\n1 0 0 0 0 255\n")
    assert load(tmp_path / "n.xyz").normals is not None
    colors = load(tmp_path / "c.xyz").colors
    np.testing.assert_allclose(colors, [[1, 128 / 255, 0], [0, 0, 1]], atol=1e-6)


def test_csv_with_header_by_name(tmp_path):
    path = tmp_path / "a.csv"
    path.write_text("red,x,y,z,green,blue,intensity\n255,1,2,3,0,0,7\n0,4,5,6,255,0,8\n")
    cloud = load(path)
    np.testing.assert_allclose(cloud.positions, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 1, 0]])


def test_cloudcompare_commented_header(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("//X,Y,Z,Nx,Ny,Nz\n0,0,0,0,0,1\n1,1,1,0,0,1\n")
    cloud = load(path)
    np.testing.assert_allclose(cloud.normals, [[0, 0, 1], [0, 0, 1]])


def test_pts_count_line_and_intensity(tmp_path):
    path = tmp_path / "scan.pts"
    path.write_text("2\n0 0 0 -100 255 0 0\n1 2 3 50 0 0 255\n")
    cloud = load(path)
    np.testing.assert_allclose(cloud.positions, [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 0, 1]])


@pytest.mark.parametrize("text, match", [
    ("0 0 0\n1 0\n", "malformed"),
    ("0 0 0\n1 a 0\n", "malformed"),
    ("0 0 0 0 0\n", "5 columns"),
    ("# only a comment\n", "no points"),
    ("a,b,c\n1,2,3\n", "positions"),
])
def test_malformed_text_names_the_file(tmp_path, text, match):
    path = tmp_path / "bad.xyz"
    path.write_text(text)
    with pytest.raises(InputError, match=match) as info:
        load(path)
    assert "bad.xyz" in str(info.value)


# -- PCD -----------------------------------------------------------------------


def _pcd_header(fields, sizes, types, n, data):
    return (f"# .PCD v0.7\nVERSION 0.7\nFIELDS {' '.join(fields)}\nSIZE {' '.join(map(str, sizes))}\n"
            f"TYPE {' '.join(types)}\nCOUNT {' '.join('1' for _ in fields)}\nWIDTH {n}\nHEIGHT 1\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n")


def _packed(rgb):
    bits = (np.uint32(rgb[0]) << 16) | (np.uint32(rgb[1]) << 8) | np.uint32(rgb[2])
    return np.array([bits], dtype=np.uint32).view(np.float32)[0]


def test_pcd_binary_with_normals_and_packed_rgb(tmp_path):
    fields = ["x", "y", "z", "normal_x", "normal_y", "normal_z", "curvature", "rgb"]
    dtype = np.dtype([(f, "<f4") for f in fields])
    rows = np.zeros(2, dtype)
    rows["x"] = [0, 1]
    rows["z"] = [2, 3]
    rows["normal_z"] = 1
    rows["rgb"] = [_packed((255, 0, 0)), _packed((0, 0, 255))]
    path = tmp_path / "a.pcd"
    path.write_bytes(_pcd_header(fields, [4] * 8, ["F"] * 8, 2, "binary").encode() + rows.tobytes())
    cloud = load(path)
    np.testing.assert_allclose(cloud.positions, [[0, 0, 2], [1, 0, 3]])
    np.testing.assert_allclose(cloud.normals, [[0, 0, 1], [0, 0, 1]])
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 0, 1]])


def test_pcd_ascii_with_integer_rgb_and_nan_points(tmp_path):
    body = "0 0 0 16711680\n1 1 1 255\nnan nan nan 0\n"
    path = tmp_path / "a.pcd"
    path.write_text(_pcd_header(["x", "y", "z", "rgb"], [4, 4, 4, 4], ["F", "F", "F", "U"], 3, "ascii") + body)
    with pytest.warns(UserWarning, match="dropped 1 of 3"):
        cloud = load(path)
    np.testing.assert_allclose(cloud.colors, [[1, 0, 0], [0, 0, 1]])


@pytest.mark.parametrize("data, body, match", [
    ("binary_compressed", b"\0" * 16, "binary_compressed"),
    ("binary", b"\0" * 5, "truncated"),
    ("ascii", b"0 0\n", "rows"),
])
def test_malformed_pcd_names_the_file(tmp_path, data, body, match):
    path = tmp_path / "bad.pcd"
    path.write_bytes(_pcd_header(["x", "y", "z"], [4, 4, 4], ["F"] * 3, 1, data).encode() + body)
    with pytest.raises(InputError, match=match) as info:
        load(path)
    assert "bad.pcd" in str(info.value)


def test_not_a_pcd(tmp_path):
    path = tmp_path / "bad.pcd"
    path.write_text("hello world\n")
    with pytest.raises(InputError, match="bad.pcd: not a PCD"):
        load(path)


# -- trained Gaussians ---------------------------------------------------------


def _quat_about_z(angle):
    return np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])


def write_gaussians(path, positions, quats, log_scales, f_dc, opacity_logit):
    n = len(positions)
    names = ["x", "y", "z", "nx", "ny", "nz"] + [f"f_dc_{i}" for i in range(3)] + \
        [f"f_rest_{i}" for i in range(9)] + ["opacity"] + [f"scale_{i}" for i in range(log_scales.shape[1])] + \
        [f"rot_{i}" for i in range(4)]
    data = np.zeros(n, dtype=[(name, "f4") for name in names])
    for i, c in enumerate("xyz"):
        data[c] = positions[:, i]
    for i in range(3):
        data[f"f_dc_{i}"] = f_dc[:, i]
    data["opacity"] = opacity_logit
    for i in range(log_scales.shape[1]):
        data[f"scale_{i}"] = log_scales[:, i]
    for i in range(4):
        data[f"rot_{i}"] = quats[:, i]
    PlyData([PlyElement.describe(data, "vertex")]).write(str(path))


def disc_of_gaussians(path, *, three_d=True, colour=(0.9, 0.2, 0.1)):
    """A 21 x 21 grid of flat Gaussians in the z = 0 plane, plus two transparent ones."""
    g = np.linspace(-1, 1, 21)
    xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    n = len(xy) + 2
    positions = np.column_stack([np.concatenate([xy, [[5, 5], [6, 6]]]), np.zeros(n)])
    angle = 0.3
    quats = np.tile(_quat_about_z(angle) * 2.0, (n, 1))  # not normalized in the file
    sigma = np.array([0.08, 0.06, 0.001]) if three_d else np.array([0.08, 0.06])
    log_scales = np.tile(np.log(sigma), (n, 1))
    if three_d:  # the largest axis stored second (rotation column 1): the loader sorts
        log_scales = log_scales[:, [1, 0, 2]]
        quats = np.tile(_quat_about_z(angle), (n, 1))
    f_dc = np.tile((np.array(colour) - 0.5) / SH_C0, (n, 1))
    opacity = np.full(n, 3.0)
    opacity[-2:] = -10.0  # sigmoid(-10) = 4.5e-5 < 1/255
    write_gaussians(path, positions, quats, log_scales, f_dc, opacity)
    return angle, sigma


@pytest.mark.parametrize("three_d", [True, False])
def test_gaussian_ply_becomes_splats(tmp_path, three_d):
    path = tmp_path / "point_cloud.ply"
    angle, sigma = disc_of_gaussians(path, three_d=three_d)
    with pytest.warns(DroppedGaussiansWarning, match="dropped 2 of 443"):
        cloud = load(path)
    assert len(cloud) == 441 and cloud.has_splats
    np.testing.assert_allclose(cloud.colors, np.tile([0.9, 0.2, 0.1], (441, 1)), atol=1e-5)
    np.testing.assert_allclose(np.abs(cloud.normals[:, 2]), 1.0, atol=1e-6)
    if three_d:
        # axes sorted: largest (sigma 0.08) along rotation column 1, next (0.06) along column 0
        rot = quaternion_matrices(_quat_about_z(angle)[None])[0]
        np.testing.assert_allclose(np.abs(cloud.u[0] @ rot[:, 1]), SIGMA_SCALE * 0.08, rtol=1e-5)
        np.testing.assert_allclose(np.abs(cloud.v[0] @ rot[:, 0]), SIGMA_SCALE * 0.06, rtol=1e-5)
    else:
        rot = quaternion_matrices(_quat_about_z(angle)[None])[0]
        np.testing.assert_allclose(cloud.u[0], SIGMA_SCALE * 0.08 * rot[:, 0], atol=1e-6)
        np.testing.assert_allclose(cloud.v[0], SIGMA_SCALE * 0.06 * rot[:, 1], atol=1e-6)
        np.testing.assert_allclose(cloud.normals[0], rot[:, 2], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(cloud.u, axis=1), SIGMA_SCALE * 0.08, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(cloud.v, axis=1), SIGMA_SCALE * 0.06, rtol=1e-5)
    # right-handed: u x v along the normal
    cross = np.cross(cloud.u, cloud.v)
    assert np.all(np.einsum("ij,ij->i", cross, cloud.normals) > 0)
    with pytest.warns(DroppedGaussiansWarning):
        assert not isinstance(load_input(path), surfsplat.io.Mesh)


def test_incomplete_gaussian_properties_read_as_plain_points(tmp_path):
    data = np.zeros(2, dtype=[(n, "f4") for n in ("x", "y", "z", "opacity", "scale_0", "scale_1",
                                                   "rot_0", "rot_1", "rot_2")])
    data["rot_0"] = 1
    path = tmp_path / "bad.ply"
    PlyData([PlyElement.describe(data, "vertex")]).write(str(path))
    # rot_3 missing: not detected as Gaussians; read as plain points
    assert load(path).u is None


@pytest.mark.gl
def test_gaussian_disc_renders_its_colour_in_the_middle(tmp_path):
    path = tmp_path / "point_cloud.ply"
    disc_of_gaussians(path, three_d=True, colour=(0.9, 0.2, 0.1))
    camera = CameraSpec(eye=(0, 0, 4), target=(0, 0, 0), up=(0, 1, 0), fov=40.0)
    with pytest.warns(DroppedGaussiansWarning):
        frame = surfsplat.render(str(path), camera, width=64, height=64, lights=Lights(enabled=False),
                                 background=(0, 0, 0))
    color = np.asarray(frame.color)
    middle = color[24:40, 24:40, :3].reshape(-1, 3)
    np.testing.assert_allclose(np.median(middle, axis=0), [0.9, 0.2, 0.1], atol=0.05)
    # the disc spans |x|, |y| <= 1.16; the view's corners (+-1.46) are outside it: background
    np.testing.assert_allclose(color[0, 0, :3], 0.0, atol=1e-6)
    np.testing.assert_allclose(color[-1, -1, :3], 0.0, atol=1e-6)
