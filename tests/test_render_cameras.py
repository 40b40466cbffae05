"""``render INPUT --cameras FILE``: one image per camera; ``--depth OUT.png``: 16-bit depth with its scale."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from PIL import Image

from surfsplat.camera import Camera
from surfsplat.cli import main
from surfsplat.io import save_ply
from surfsplat.io.camera_formats import opencv_from_camera
from surfsplat.io.depth_image import NEAR_KEY, load_depth_png, save_depth_png

from test_cli import noisy_sphere, run

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): the tests render through the command line


def write_rig(path, cameras):
    entries = []
    for i, camera in enumerate(cameras):
        K, R, t = opencv_from_camera(camera)
        entries.append({"name": f"v{i}", "K": K.tolist(), "R": R.tolist(), "t": t.tolist(),
                        "width": camera.width, "height": camera.height})
    path.write_text(json.dumps({"cameras": entries}))


def test_depth_png_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    near, far = 1.5, 9.0
    depth = rng.uniform(near, far, size=(40, 30))
    depth[0, :5] = np.inf
    path = save_depth_png(depth, near, far, tmp_path / "d.png")
    with Image.open(path) as image:
        assert image.mode.startswith("I") and float(image.text[NEAR_KEY]) == near
        assert np.asarray(image)[0, 0] == 0
    back = load_depth_png(path)
    assert np.isinf(back[0, :5]).all()
    finite = np.isfinite(depth)
    assert np.abs(back[finite] - depth[finite]).max() <= (far - near) / 65535


def test_render_every_camera_of_a_file(tmp_path, capsys):
    ply = save_ply(noisy_sphere(), tmp_path / "points.ply")
    cameras = [Camera(eye=(0, 0, 4), target=(0, 0, 0), fov=40, width=64, height=48),
               Camera(eye=(4, 0, 0), target=(0, 0, 0), fov=40, width=32, height=32)]
    rig = tmp_path / "rig.json"
    write_rig(rig, cameras)
    status = main(["render", str(ply), "--cameras", str(rig), "-o", str(tmp_path / "out_{name}.png"),
                   "--depth", str(tmp_path / "depth_{name}.png")])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert f"-> {tmp_path / 'out_v0.png'}" in out + err and f"-> {tmp_path / 'depth_v1.png'}" in out + err
    assert np.asarray(Image.open(tmp_path / "out_v0.png")).shape[:2] == (48, 64)
    assert np.asarray(Image.open(tmp_path / "out_v1.png")).shape[:2] == (32, 32)
    depth = load_depth_png(tmp_path / "depth_v0.png")
    assert abs(depth[24, 32] - 3.0) < 0.05   # a unit sphere 4 units away on the optical axis
    assert np.isinf(depth[0, 0])


def test_cameras_output_checks_come_first(tmp_path, capsys):
    ply = save_ply(noisy_sphere(300), tmp_path / "points.ply")
    rig = tmp_path / "rig.json"
    write_rig(rig, [Camera(width=16, height=16), Camera(eye=(3, 0, 0), width=16, height=16)])
    status, _, err = run(capsys, "render", ply, "--cameras", rig, "-o", tmp_path / "out.png")
    assert status == 2 and "{name}" in err
    os.link(ply, tmp_path / "out_v1.png")   # the second view's output is the input file itself
    status, _, err = run(capsys, "render", ply, "--cameras", rig, "-o", tmp_path / "out_{name}.png")
    assert status == 2 and "out_v1.png" in err and not (tmp_path / "out_v0.png").exists()
    status, _, err = run(capsys, "render", ply, "--cameras", rig, "-o", tmp_path / "o_{name}.png",
                         "--depth", tmp_path / "d_{name}.tif")
    assert status == 2 and "OUT.png" in err
