"""Errors carry what failed as attributes (``file``, ``element``, ``row``, ``argument``), set where
the raise site or a loader knows it, with the message text unchanged."""

from __future__ import annotations

import json
import pickle
import warnings

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from surfsplat import InputError, SplatCloud
from surfsplat.camera import Camera
from surfsplat.cloud import InvalidPointsWarning
from surfsplat.colors import ColorOptions
from surfsplat.errors import CONTEXT, RenderError, SurfsplatError, error_context, fill_context
from surfsplat.hierarchy import build_hierarchy, load_hierarchy, save_hierarchy
from surfsplat.io import load, load_mesh
from surfsplat.io.camera_file import CAMERA_FORMAT, CAMERA_FORMAT_VERSION, load_camera_list
from surfsplat.rendering.options import EdlOptions, FilterOptions, KernelOptions, RenderOptions, VisibilityOptions
from surfsplat.scenes import sphere


def write_ply(path, n: int = 20, nan_row: int | None = None, faces=None, text: bool = False):
    """A PLY of ``n`` points on a line (float32 x y z), NaN in ``x`` of ``nan_row``."""
    vertex = np.zeros(n, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    vertex["x"] = np.arange(n)
    vertex["y"] = np.arange(n) % 3
    if nan_row is not None:
        vertex["x"][nan_row] = np.nan
    elements = [PlyElement.describe(vertex, "vertex")]
    if faces is not None:
        face = np.zeros(len(faces), dtype=[("vertex_indices", "i4", (3,))])
        face["vertex_indices"] = faces
        elements.append(PlyElement.describe(face, "face"))
    PlyData(elements, text=text).write(str(path))
    return path


# -- the error classes ---------------------------------------------------------------------------------


def test_attributes_are_optional_keywords_and_leave_the_message_alone():
    plain = InputError("a.ply: bad")
    assert str(plain) == "a.ply: bad" and all(getattr(plain, name) is None for name in CONTEXT)
    full = InputError("a.ply: bad", file="a.ply", element="vertex.x", row=np.int64(7), argument="--k")
    assert str(full) == "a.ply: bad" and full.args == ("a.ply: bad",)
    assert (full.file, full.element, full.row, full.argument) == ("a.ply", "vertex.x", 7, "--k")
    assert type(full.row) is int and full.context() == {"file": "a.ply", "element": "vertex.x", "row": 7,
                                                          "argument": "--k"}
    assert RenderError("no context", argument="technique").argument == "technique"
    back = pickle.loads(pickle.dumps(full))   # across processes (multiprocessing) they survive
    assert type(back) is InputError and str(back) == str(full) and back.context() == full.context()
    with pytest.raises(TypeError):
        InputError("x", line=3)


def test_error_context_fills_only_what_the_raise_site_left_unset():
    with pytest.raises(InputError) as caught, error_context(file="outer.ply", row=3):
        raise InputError("inner.ply: bad", file="inner.ply")
    assert caught.value.file == "inner.ply" and caught.value.row == 3 and str(caught.value) == "inner.ply: bad"
    with pytest.raises(KeyError), error_context(file="x"):   # other exceptions pass untouched
        raise KeyError("k")
    error = fill_context(SurfsplatError("m"), element="e", row=None)
    assert error.element == "e" and error.row is None
    with pytest.raises(TypeError):
        fill_context(SurfsplatError("m"), line=1)


# -- file loaders ------------------------------------------------------------------------------------------


def test_ply_with_a_nan_in_row_7(tmp_path):
    path = write_ply(tmp_path / "nan.ply", nan_row=7)
    with pytest.warns(InvalidPointsWarning) as record:
        cloud = load(path)
    assert len(cloud) == 19
    warning = record[0].message
    assert (warning.file, warning.row, warning.element, warning.count) == (str(path), 7, "positions", 1)
    assert str(warning).startswith(f"{path}: dropped 1 of 20 points")
    # a mesh cannot drop a vertex: its NaN vertex 7 is an error
    mesh = write_ply(tmp_path / "nan_mesh.ply", nan_row=7, faces=[[0, 1, 2], [6, 7, 8]])
    with pytest.raises(InputError, match=r"nan_mesh\.ply: 1 of 20 mesh vertices have non-finite") as caught:
        load_mesh(mesh)
    assert (caught.value.file, caught.value.row, caught.value.element) == (str(mesh), 7, "vertex")


def test_ply_with_every_row_invalid(tmp_path):
    vertex = np.zeros(4, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    vertex["y"] = np.inf
    path = tmp_path / "inf.ply"
    PlyData([PlyElement.describe(vertex, "vertex")]).write(str(path))
    with pytest.raises(InputError, match=r"inf\.ply: no valid points left") as caught:
        load(path)
    assert (caught.value.file, caught.value.row, caught.value.element) == (str(path), 0, "positions")


def test_ply_parse_errors_name_element_property_and_row(tmp_path):
    path = write_ply(tmp_path / "text.ply", n=6, text=True)
    lines = path.read_text().splitlines()
    body = lines.index("end_header") + 1
    lines[body + 3] = "3 oops 0"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"text\.ply: malformed PLY file") as caught:
        load(path)
    assert (caught.value.file, caught.value.element, caught.value.row) == (str(path), "vertex.y", 3)


def test_face_errors_name_the_face(tmp_path):
    path = write_ply(tmp_path / "faces.ply", n=5, faces=[[0, 1, 2], [1, 2, 3], [2, 3, 9]])
    with pytest.raises(InputError, match=r"faces\.ply: face 2 refers to vertex 9") as caught:
        load_mesh(path)
    assert (caught.value.file, caught.value.element, caught.value.row) == (str(path), "face", 2)
    points = write_ply(tmp_path / "points.ply", n=5)
    with pytest.raises(InputError, match=r"points\.ply: PLY file has no faces") as caught:
        load_mesh(points)
    assert caught.value.file == str(points) and caught.value.element == "face"


def test_missing_property_and_file_errors(tmp_path):
    vertex = np.zeros(3, dtype=[("x", "f4"), ("y", "f4")])
    path = tmp_path / "noz.ply"
    PlyData([PlyElement.describe(vertex, "vertex")]).write(str(path))
    with pytest.raises(InputError, match=r"noz\.ply: vertex has x y but is missing z") as caught:
        load(path)
    assert caught.value.file == str(path) and caught.value.element == "vertex.z"
    with pytest.raises(InputError) as caught:
        load(tmp_path / "absent.ply")
    assert caught.value.file == str(tmp_path / "absent.ply")


def test_text_pcd_las_e57_errors_name_the_file(tmp_path):
    text = tmp_path / "points.xyz"
    text.write_text("x y z\n1 2 3\n4 5 6\nseven 8 9\n")
    with pytest.raises(InputError) as caught:
        load(text)
    assert caught.value.file == str(text)
    short = tmp_path / "short.xyz"
    short.write_text("x y\n1 2\n")
    with pytest.raises(InputError, match="short.xyz") as caught:
        load(short)
    assert caught.value.file == str(short) and caught.value.element == "x"
    pcd = tmp_path / "bad.pcd"
    pcd.write_text("VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
                   "DATA ascii\n1 2\n")
    with pytest.raises(InputError, match=r"bad\.pcd: PCD has x y but not all of x y z") as caught:
        load(pcd)
    assert caught.value.file == str(pcd) and caught.value.element == "z"
    for name in ("garbage.las", "garbage.e57"):
        path = tmp_path / name
        path.write_bytes(b"not a point file at all" * 20)
        with pytest.raises(InputError, match=name.replace(".", r"\.")) as caught:
            load(path)
        assert caught.value.file == str(path)


def test_hierarchy_errors_name_the_file_and_array(tmp_path):
    path = save_hierarchy(build_hierarchy(sphere(300, coverage=1.2)), tmp_path / "h.npz")
    with np.load(path) as archive:
        members = {name: archive[name] for name in archive.files}
    members["node_radius"] = members["node_radius"].copy()
    members["node_radius"][5] = np.nan
    bad = tmp_path / "nan.npz"
    np.savez(bad, **members)
    with pytest.raises(InputError, match=r"nan\.npz: array 'node_radius' has non-finite values") as caught:
        load_hierarchy(bad)
    assert (caught.value.file, caught.value.element, caught.value.row) == (str(bad), "node_radius", 5)
    del members["node_u"]
    np.savez(bad, **members)
    with pytest.raises(InputError, match="missing array 'node_u'") as caught:
        load_hierarchy(bad)
    assert (caught.value.file, caught.value.element) == (str(bad), "node_u")


HEAD = {"format": CAMERA_FORMAT, "version": CAMERA_FORMAT_VERSION}


def test_camera_file_errors_name_the_entry_and_field(tmp_path):
    path = tmp_path / "views.json"
    good = {"eye": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40, "width": 64, "height": 64}
    path.write_text(json.dumps({**HEAD, "cameras": [good, {**good, "fov": 500}]}))
    with pytest.raises(InputError, match=r"views\.json: bad camera \(camera 1\)") as caught:
        load_camera_list(path)
    assert (caught.value.file, caught.value.row, caught.value.element) == (str(path), 1, "fov")
    path.write_text(json.dumps({**HEAD, "cameras": [good, {k: v for k, v in good.items() if k != "up"}]}))
    with pytest.raises(InputError, match="lacks 'up'") as caught:
        load_camera_list(path)
    assert (caught.value.row, caught.value.element) == (1, "up")


# -- arrays and arguments ------------------------------------------------------------------------------------


def test_splatcloud_validation_names_rows_and_arrays():
    positions = np.zeros((10, 3))
    positions[:, 0] = np.arange(10)
    normals = np.tile([0.0, 0.0, 1.0], (10, 1))
    normals[4] = 0.0
    with pytest.warns(InvalidPointsWarning) as record:
        SplatCloud(positions, normals).validated("array")
    warning = record[0].message
    assert (warning.file, warning.row, warning.element, warning.count) == (None, 4, "normals", 1)
    with pytest.raises(InputError, match="normals has 3 rows but positions has 10") as caught:
        SplatCloud(positions, normals[:3])
    assert caught.value.argument == "normals"
    with pytest.raises(InputError) as caught:
        SplatCloud(positions, attributes={"label": np.zeros(3)})
    assert caught.value.element == "label"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(SplatCloud(positions, np.tile([0.0, 0.0, 1.0], (10, 1))).validated()) == 10


@pytest.mark.parametrize("make, argument", [
    (lambda: FilterOptions(cutoff=-1.0), "cutoff"),
    (lambda: VisibilityOptions(depth_epsilon=-1.0), "depth_epsilon"),
    (lambda: KernelOptions(name="box"), "name"),
    (lambda: KernelOptions(b=0.0), "b"),
    (lambda: KernelOptions(n=1e9), "n"),
    (lambda: EdlOptions(strength=-1.0), "strength"),
    (lambda: EdlOptions(radius_px=100.0), "radius_px"),
    (lambda: RenderOptions(compute="yes"), "compute"),
    (lambda: RenderOptions(edl="on"), "edl"),
    (lambda: RenderOptions(filter=None), "filter"),
    (lambda: ColorOptions(by=""), "by"),
    (lambda: ColorOptions(by="z", value_range=(2.0, 1.0)), "value_range"),
    (lambda: Camera(fov=0.0), "fov"),
    (lambda: Camera(width=0), "width"),
    (lambda: Camera(height=10 ** 6), "height"),
    (lambda: Camera(eye=(0, 0, np.nan)), "eye"),
    (lambda: Camera(eye=(0, 0, 0)), "target"),
    (lambda: Camera(up=(0, 0, 1)), "up"),
    (lambda: Camera(near=2.0, far=1.0), "far"),
    (lambda: Camera().scaled(-1.0), "factor"),
])
def test_option_checks_name_the_argument(make, argument):
    with pytest.raises(InputError) as caught:
        make()
    assert caught.value.argument == argument, str(caught.value)
    assert caught.value.file is None and caught.value.row is None
