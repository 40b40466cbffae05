"""Cameras from OpenCV JSON, COLMAP text and NeRF transforms.json: written from a known Camera, read
back, the same projections of known points (within 0.5 px)."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from surfsplat import reference
from surfsplat.camera import Camera
from surfsplat.errors import InputError
from surfsplat.io.camera_file import save_camera
from surfsplat.io.camera_formats import load_cameras, opencv_from_camera

CAMERAS = [
    Camera(eye=(1.0, 2.0, 5.0), target=(0.1, -0.2, 0.3), up=(0.0, 1.0, 0.0), fov=40.0, width=640, height=480),
    Camera(eye=(-3.0, 0.5, -2.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov=65.0, width=300, height=500),
]
RNG = np.random.default_rng(1)
POINTS = RNG.uniform(-1.0, 1.0, size=(50, 3))


def pixels(camera: Camera) -> np.ndarray:
    return reference.project(camera, reference.to_camera(camera, POINTS))


def assert_same_view(original: Camera, loaded: Camera) -> None:
    assert (loaded.width, loaded.height) == (original.width, original.height)
    assert np.abs(pixels(loaded) - pixels(original)).max() < 0.5


def quaternion(R: np.ndarray) -> list[float]:
    """w-first unit quaternion of a rotation matrix (Shepperd's method, the w > 0 branch suffices here
    and the general branch below otherwise)."""
    w = math.sqrt(max(0.0, 1.0 + np.trace(R))) / 2.0
    if w > 1e-3:
        return [w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)]
    i = int(np.argmax(np.diag(R)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = math.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k]) * 2
    q = [0.0] * 4
    q[0], q[1 + i], q[1 + j], q[1 + k] = ((R[k, j] - R[j, k]) / s, s / 4, (R[j, i] + R[i, j]) / s,
                                          (R[k, i] + R[i, k]) / s)
    return q


def test_opencv_matrices_project_like_the_camera():
    for camera in CAMERAS:
        K, R, t = opencv_from_camera(camera)
        x = POINTS @ R.T + t
        u = K[0, 0] * x[:, 0] / x[:, 2] + K[0, 2]
        v = K[1, 1] * x[:, 1] / x[:, 2] + K[1, 2]
        window = np.stack([u + 0.5, camera.height - (v + 0.5)], axis=-1)   # integer centers, rows down -> y up
        assert np.abs(window - pixels(camera)).max() < 1e-6


def test_opencv_json_round_trip(tmp_path):
    entries = []
    for i, camera in enumerate(CAMERAS):
        K, R, t = opencv_from_camera(camera)
        entries.append({"name": f"view{i}", "K": K.tolist(), "R": R.tolist(), "t": t.tolist(),
                        "width": camera.width, "height": camera.height})
    path = tmp_path / "rig.json"
    path.write_text(json.dumps({"cameras": entries}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        views = load_cameras(path)
    assert [name for name, _ in views] == ["view0", "view1"]
    for (_, loaded), camera in zip(views, CAMERAS):
        assert_same_view(camera, loaded)
    single = tmp_path / "one.json"
    single.write_text(json.dumps(entries[0]))
    assert load_cameras(single)[0][0] == "view0"


def write_colmap(folder, model="PINHOLE", extra=()):
    cams, imgs = ["# Camera list"], ["# Image list"]
    for i, camera in enumerate(CAMERAS, 1):
        K, R, t = opencv_from_camera(camera)
        f, cx, cy = K[0, 0], camera.width / 2, camera.height / 2   # COLMAP: pixel corners at integers
        params = [f, f, cx, cy] if model == "PINHOLE" else [f, cx, cy, *extra]
        cams.append(f"{i} {model} {camera.width} {camera.height} " + " ".join(repr(float(p)) for p in params))
        imgs.append(f"{i} " + " ".join(repr(float(v)) for v in (*quaternion(R), *t)) + f" {i} images/img {i}.jpg")
        imgs.append("" if i == 1 else "10.0 20.0 -1 30.0 40.0 7")
    (folder / "cameras.txt").write_text("\n".join(cams) + "\n")
    (folder / "images.txt").write_text("\n".join(imgs) + "\n")


@pytest.mark.parametrize("model, extra", [("PINHOLE", ()), ("SIMPLE_PINHOLE", ()), ("SIMPLE_RADIAL", (0.0,)),
                                          ("RADIAL", (0.01, 0.0))])
def test_colmap_round_trip(tmp_path, model, extra):
    write_colmap(tmp_path, model, extra)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        views = load_cameras(tmp_path / "images.txt")
    assert any("distortion" in str(w.message) for w in caught) == any(extra)
    assert [name for name, _ in views] == ["img 1", "img 2"]
    for (_, loaded), camera in zip(views, CAMERAS):
        assert_same_view(camera, loaded)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert len(load_cameras(tmp_path)) == 2


def nerf_data(with_size=True):
    frames = []
    for i, camera in enumerate(CAMERAS[:1]):
        frames.append({"file_path": f"./train/r_{i}.png",
                       "transform_matrix": np.linalg.inv(camera.view_matrix).tolist()})
    camera = CAMERAS[0]
    angle_x = 2 * math.atan(0.5 * camera.width / camera.focal_px)
    data = {"camera_angle_x": angle_x, "frames": frames}
    if with_size:
        data.update(w=camera.width, h=camera.height)
    return data


def test_nerf_round_trip(tmp_path):
    path = tmp_path / "transforms.json"
    path.write_text(json.dumps(nerf_data()))
    [(name, loaded)] = load_cameras(path)
    assert name == "r_0"
    assert_same_view(CAMERAS[0], loaded)
    path.write_text(json.dumps(nerf_data(with_size=False)))
    with pytest.raises(InputError, match="--width"):
        load_cameras(path)
    [(_, loaded)] = load_cameras(path, width=640, height=480)
    assert_same_view(CAMERAS[0], loaded)
    data = nerf_data()
    del data["camera_angle_x"]
    data["fl_x"] = data["fl_y"] = CAMERAS[0].focal_px
    path.write_text(json.dumps(data))
    assert_same_view(CAMERAS[0], load_cameras(path)[0][1])


def test_surfsplat_camera_file(tmp_path):
    path = save_camera(CAMERAS[1], tmp_path / "view.json")
    assert load_cameras(path) == [("view", CAMERAS[1])]


def test_off_center_principal_point_warns(tmp_path):
    K, R, t = opencv_from_camera(CAMERAS[0])
    K[0, 2] += 3.0
    path = tmp_path / "cv.json"
    path.write_text(json.dumps({"K": K.tolist(), "R": R.tolist(), "t": t.tolist(), "width": 640, "height": 480}))
    with pytest.warns(UserWarning, match="principal point"):
        load_cameras(path)


@pytest.mark.parametrize("text", ["{", "[]", '{"K": [[1, 0, 0]], "R": [], "t": [], "width": 1, "height": 1}',
                                  '{"cameras": [{"K": [[1,0,0],[0,1,0],[0,0,1]]}]}', '{"frames": []}'])
def test_malformed_json_names_the_file(tmp_path, text):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(InputError, match="bad.json"):
        load_cameras(path)


def test_malformed_colmap_names_the_file(tmp_path):
    write_colmap(tmp_path)
    (tmp_path / "cameras.txt").write_text("1 OPENCV 10 10 1 1 5 5 0 0 0 0\n")
    with pytest.raises(InputError, match="cameras.txt:1"):
        load_cameras(tmp_path)
    write_colmap(tmp_path)
    (tmp_path / "images.txt").write_text("1 1 0 0 0 0 0 x 1 a.png\n\n")
    with pytest.raises(InputError, match="images.txt:1"):
        load_cameras(tmp_path)
    (tmp_path / "images.txt").unlink()
    with pytest.raises(InputError, match="images.txt"):
        load_cameras(tmp_path / "cameras.txt")


def test_colmap_points_are_read_with_their_colours_and_bad_lines_named(tmp_path):
    from surfsplat.io.camera_formats import load_colmap_points

    (tmp_path / "points3D.txt").write_text(
        "# 3D point list with one line of data per point:\n"
        "1 0.5 -1.25 3.0 255 128 0 0.7 1 2 3 4\n"
        "2 1e-3 2 -4 0 0 255 1.2\n")
    cloud = load_colmap_points(tmp_path)
    np.testing.assert_allclose(cloud.positions, [[0.5, -1.25, 3.0], [1e-3, 2.0, -4.0]], rtol=1e-6)
    np.testing.assert_allclose(cloud.colors, [[1.0, 128 / 255, 0.0], [0.0, 0.0, 1.0]], rtol=1e-6)
    (tmp_path / "points3D.txt").write_text("1 0.5 -1.25 3.0 255 128 0 0.7\n2 1 2 nan 0 0 0 1\n")
    with pytest.raises(InputError, match=r"points3D.txt:2"):
        load_colmap_points(tmp_path / "points3D.txt")
    (tmp_path / "points3D.txt").write_text("# nothing\n")
    with pytest.raises(InputError, match="no points"):
        load_colmap_points(tmp_path)
