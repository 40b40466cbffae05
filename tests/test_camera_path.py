"""Camera paths through key views: the Catmull-Rom spline's properties (through the keys, C1, linear
precision, closed loops, constant speed), cameras along it, camera files with a list, and
``surfsplat turntable --path``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image, ImageSequence

from surfsplat.camera import Camera
from surfsplat.camera_path import catmull_rom, interpolate_cameras, path_parameters
from surfsplat.cli import main
from surfsplat.errors import InputError
from surfsplat.io import save_ply
from surfsplat.io.camera_file import load_camera, load_camera_list, save_camera, save_cameras
from surfsplat.io.camera_formats import load_cameras
from surfsplat.scenes import sphere

KEYS = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.5], [3.0, 1.5, -1.0], [4.0, -1.0, 0.0], [2.0, -2.0, 2.0]])
VIEWS = [Camera(eye=(3.0, 0.5, 0.0), target=(0.0, 0.0, 0.0), fov=40.0, width=64, height=48),
         Camera(eye=(0.0, 1.5, 3.0), target=(0.1, 0.0, 0.0), fov=30.0, width=64, height=48),
         Camera(eye=(-2.0, 0.2, 1.0), target=(0.0, 0.3, 0.0), up=(0.1, 1.0, 0.0), fov=45.0, width=64, height=48)]


@pytest.mark.parametrize("closed", [False, True])
def test_the_spline_passes_through_the_keys(closed):
    span = len(KEYS) if closed else len(KEYS) - 1
    t = np.arange(span + 1, dtype=np.float64)
    expected = np.concatenate([KEYS, KEYS[:1]]) if closed else KEYS
    assert np.abs(catmull_rom(KEYS, t, closed=closed) - expected).max() < 1e-12


@pytest.mark.parametrize("closed", [False, True])
def test_the_spline_is_c1_with_the_catmull_rom_tangents(closed):
    k = len(KEYS)
    joints = range(1, k + 1) if closed else range(1, k - 1)
    for i in joints:
        left = catmull_rom(KEYS, [i - 1e-9], closed=closed, derivative=True)
        right = catmull_rom(KEYS, [min(i + 1e-9, k if closed else k - 1)], closed=closed, derivative=True)
        tangent = 0.5 * (KEYS[(i + 1) % k] - KEYS[(i - 1) % k])
        assert np.abs(left - right).max() < 1e-6 and np.abs(left[0] - tangent).max() < 1e-6
    # the derivative is the derivative of the points (central differences)
    t = np.linspace(0.05, k - 1.05, 37)
    h = 1e-6
    numeric = (catmull_rom(KEYS, t + h, closed=closed) - catmull_rom(KEYS, t - h, closed=closed)) / (2 * h)
    assert np.abs(numeric - catmull_rom(KEYS, t, closed=closed, derivative=True)).max() < 1e-5


def test_evenly_spaced_keys_on_a_line_give_the_line_at_constant_speed():
    a, b = np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.7, -1.1])
    keys = a + b * np.arange(4)[:, None]
    t = np.linspace(0.0, 3.0, 31)
    assert np.abs(catmull_rom(keys, t) - (a + b * t[:, None])).max() < 1e-12


def test_constant_speed_spaces_the_frames_evenly():
    keys = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [5.0, 0.0, 1.0], [5.5, 3.0, 1.0]])   # uneven intervals
    points = catmull_rom(keys, path_parameters(keys, 60, constant_speed=True))
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert steps.max() / steps.min() < 1.01
    uneven = np.linalg.norm(np.diff(catmull_rom(keys, path_parameters(keys, 60)), axis=0), axis=1)
    assert uneven.max() / uneven.min() > 3   # without it, each key interval gets the same time
    assert np.abs(points[[0, -1]] - keys[[0, -1]]).max() < 1e-9


def test_cameras_along_the_path():
    cameras = interpolate_cameras(VIEWS, 9)   # 4 frames per key interval: frames 0, 4, 8 are the keys
    assert len(cameras) == 9
    for frame, key in ((0, VIEWS[0]), (4, VIEWS[1]), (8, VIEWS[2])):
        c = cameras[frame]
        assert np.allclose(c.eye, key.eye, atol=1e-12) and np.allclose(c.target, key.target, atol=1e-12)
        assert abs(c.fov - key.fov) < 1e-9
        assert np.allclose(c.view_matrix, key.view_matrix, atol=1e-9)   # the same view (up made orthogonal)
    for c in cameras:
        forward = np.subtract(c.target, c.eye)
        assert abs(np.dot(c.up, forward)) < 1e-9 and abs(np.linalg.norm(c.up) - 1) < 1e-12
        assert (c.width, c.height) == (64, 48) and c.near is None
    resized = interpolate_cameras(VIEWS, 5, closed=True, width=32, height=20)
    assert {(c.width, c.height) for c in resized} == {(32, 20)} and np.allclose(resized[0].eye, VIEWS[0].eye)
    with pytest.raises(InputError, match="at least 2 key cameras"):
        interpolate_cameras(VIEWS[:1], 10)
    with pytest.raises(InputError, match="frames >= 2"):
        interpolate_cameras(VIEWS, 1)
    looking_up = [Camera(eye=(0, 0, 0), target=(0, 1, 0), up=(0, 0, 1)), Camera(eye=(0, 0, 1), target=(0, 0, 2))]
    with pytest.raises(InputError, match="parallel to the view direction"):
        interpolate_cameras(looking_up, 3)


def test_camera_files_hold_a_list(tmp_path):
    path = save_cameras([("start", VIEWS[0]), ("middle", VIEWS[1]), ("end", VIEWS[2])], tmp_path / "keys.json")
    views = load_camera_list(path)
    assert [name for name, _ in views] == ["start", "middle", "end"]
    assert all(c == v for (_, c), v in zip(views, VIEWS))
    assert load_cameras(path) == views
    with pytest.raises(InputError, match="list of cameras"):
        load_camera(path)
    one = save_camera(VIEWS[1], tmp_path / "one.json")
    assert load_camera_list(one) == [("one", VIEWS[1])]
    data = json.loads(path.read_text())
    data["cameras"][1]["eye"] = data["cameras"][1]["target"]
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"keys.json: bad camera \(camera 1\)"):
        load_camera_list(path)


@pytest.mark.gl
def test_cli_turntable_along_a_path(tmp_path, capsys):
    cloud = save_ply(sphere(4000, radius=0.8), tmp_path / "sphere.ply")
    keys = save_cameras(VIEWS, tmp_path / "keys.json")
    out = tmp_path / "fly.gif"
    status = main(["turntable", str(cloud), "--path", str(keys), "--frames", "5", "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 0, err
    assert "5 frames on a path through 3 key views" in err and f"-> {out}" in err
    frames = [np.asarray(f.convert("RGB"), dtype=np.float64) for f in ImageSequence.Iterator(Image.open(out))]
    assert len(frames) == 5 and frames[0].shape == (48, 64, 3)
    # the path's first and last frames are the key views: the same pictures as stills from them
    for frame, key in ((frames[0], VIEWS[0]), (frames[4], VIEWS[2])):
        still = tmp_path / "still.png"
        camera = save_camera(key, tmp_path / "key.json", overwrite=True)
        assert main(["-q", "render", str(cloud), "--camera", str(camera), "-o", str(still), "--force"]) == 0
        assert np.abs(frame - np.asarray(Image.open(still), dtype=np.float64)).mean() < 3.0   # GIF palette
    assert not np.array_equal(frames[0], frames[2])
    status = main(["-q", "turntable", str(cloud), "--path", str(keys), "--elevation", "10",
                   "-o", str(tmp_path / "x.gif")])
    assert status == 2 and "--elevation" in capsys.readouterr().err
    status = main(["-q", "turntable", str(cloud), "--loop", "-o", str(tmp_path / "x.gif")])
    assert status == 2 and "give --path" in capsys.readouterr().err
