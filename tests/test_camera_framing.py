"""The camera a user expects: tight automatic framing, z-up LiDAR, reusable cameras, a warning
when the picture is empty."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

import surfsplat
from surfsplat import reference
from surfsplat.pipeline import auto_camera, natural_up
from surfsplat.camera import Camera, camera_flags, fit_points
from surfsplat.cli import main
from surfsplat.errors import EmptyFrameWarning, InputError
from surfsplat.io import save_ply
from surfsplat.io.camera_file import load_camera, save_camera

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): most tests render through the API and the command line


def projected(cam: Camera, points: np.ndarray) -> np.ndarray:
    return reference.project(cam, reference.to_camera(cam, points))


@pytest.mark.parametrize("size, direction", [((400, 300), (0.4, 0.35, 1.0)), ((200, 500), (-1.0, 0.2, 0.3)),
                                             ((512, 512), (0.0, 1.0, 0.01))])
def test_fit_points_fills_the_limiting_side_and_centers(size, direction):
    rng = np.random.default_rng(1)
    points = rng.normal(size=(5000, 3)) * (3.0, 0.5, 1.0) + (10.0, -2.0, 4.0)   # elongated, off the origin
    w, h = size
    cam = fit_points(points, direction=direction, fov=40, width=w, height=h, fill=0.9)
    xy = projected(cam, points)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    fill = (hi - lo) / (w, h)
    assert np.isclose(fill.max(), 0.9, atol=1e-6)            # the limiting side is filled to 90%
    assert (fill <= 0.9 + 1e-6).all()
    np.testing.assert_allclose(0.5 * (lo + hi), (w / 2, h / 2), atol=1e-6 * max(w, h))   # centered
    assert (-reference.to_camera(cam, points)[:, 2] > cam.near).all()


def test_auto_framing_of_an_elongated_model_fills_the_width():
    cloud = surfsplat.preprocess(surfsplat.SplatCloud(np.random.default_rng(0).uniform((-4, -0.5, -0.3), (4, 0.5, 0.3),
                                                                                       (4000, 3))))
    frame = surfsplat.render(cloud, width=256, height=256)
    cols = np.flatnonzero(frame.mask.any(axis=0))
    assert (cols[-1] - cols[0] + 1) / 256 > 0.85   # the old bounding-sphere framing filled about 60%


def test_las_is_z_up_and_flat_models_are_seen_from_above(tmp_path):
    laspy = pytest.importorskip("laspy")
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 100, (3000, 2))
    z = 5 * np.sin(xy[:, 0] / 15)   # terrain: z is up
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = (0.01, 0.01, 0.01)
    las = laspy.LasData(header)
    las.x, las.y, las.z = xy[:, 0], xy[:, 1], z
    path = tmp_path / "terrain.las"
    las.write(path)
    assert natural_up(path) == (0.0, 0.0, 1.0) and natural_up("x.ply") == (0.0, 1.0, 0.0)
    frame = surfsplat.render(path, width=200, height=150)
    assert frame.camera.up == (0.0, 0.0, 1.0)
    view = np.asarray(frame.camera.eye) - frame.camera.target
    elevation = np.degrees(np.arcsin(view[2] / np.linalg.norm(view)))
    assert 35 < elevation < 55   # an oblique view from above, not along the ground
    assert frame.mask.mean() > 0.3


def test_a_view_of_nothing_warns_with_the_bounds_and_the_camera():
    cloud = surfsplat.demo_scene("sphere")
    away = Camera(eye=(0, 0, 5), target=(0, 0, 10), width=64, height=64)
    with pytest.warns(EmptyFrameWarning, match=r"nothing was drawn: .*bounds are min .* --eye 0 0 5 --target 0 0 10"):
        surfsplat.render(cloud, away)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EmptyFrameWarning)
        surfsplat.render(cloud, width=64, height=64)   # a framed view does not warn


def test_camera_files_round_trip_and_refuse_bad_files(tmp_path):
    cam = Camera(eye=(1.5, 2, 3), target=(0, 0.1, 0), up=(0, 0, 1), fov=33, width=123, height=45, near=0.5, far=9)
    path = save_camera(cam, tmp_path / "cam.json")
    assert load_camera(path) == cam
    with pytest.raises(InputError, match="exists"):
        save_camera(cam, path, overwrite=False)
    other = Camera(eye=(0, 0, 5), target=(0, 0, 0), fov=40, width=20, height=10)
    assert load_camera(save_camera(other, path)) == other   # replaced by default
    (tmp_path / "bad.json").write_text('{"format": "something else"}')
    with pytest.raises(InputError, match="bad.json: not a surfsplat camera file"):
        load_camera(tmp_path / "bad.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(InputError, match="broken.json: not a camera file"):
        load_camera(tmp_path / "broken.json")


def test_cli_prints_the_camera_saves_it_and_reuses_it(tmp_path, capsys):
    ply = save_ply(surfsplat.demo_scene("sphere"), tmp_path / "sphere.ply")
    first, again, flags_png = tmp_path / "a.png", tmp_path / "b.png", tmp_path / "c.png"
    assert main(["render", str(ply), "-o", str(first), "--width", "96", "--height", "64",
                 "--save-camera", str(tmp_path / "cam.json")]) == 0
    err = capsys.readouterr().err
    printed = next(line for line in err.splitlines() if line.startswith("camera: "))[len("camera: "):]
    assert main(["-q", "render", str(ply), "-o", str(again), "--camera", str(tmp_path / "cam.json")]) == 0
    assert main(["-q", "render", str(ply), "-o", str(flags_png), *printed.split()]) == 0
    a, b, c = (np.asarray(Image.open(p)).astype(int) for p in (first, again, flags_png))
    assert a.shape == (64, 96, 3) and np.array_equal(a, b)
    assert np.abs(a - c).max() <= 1   # the printed flags reproduce the view (to 10 digits)


def test_cli_outputs_are_checked_before_loading_and_inputs_never_clobbered(tmp_path, capsys):
    missing = tmp_path / "never-read.ply"
    out = tmp_path / "out.png"
    out.write_bytes(b"precious")
    for flags, message in ((["-o", str(out), "--camera", str(out)], "refusing to overwrite the input"),
                           (["-o", str(tmp_path / "no" / "x.png")], "does not exist"),
                           (["-o", str(tmp_path / "x")], "unsupported image format"),
                           (["-o", str(tmp_path / "x.png"), "--depth", str(tmp_path / "d.tiff")], "--depth writes")):
        assert main(["-q", "render", str(missing), *flags]) == 2
        err = capsys.readouterr().err
        assert message in err and "never-read.ply" not in err and "Traceback" not in err
    assert out.read_bytes() == b"precious"
    assert main(["-q", "demo", "-o", str(out), "--width", "32", "--height", "32", "--force"]) == 0
    assert Image.open(out).size == (32, 32)
    assert not list(tmp_path.glob(".*.tmp"))   # no temporary file left behind


def test_camera_flags_are_parseable():
    cam = Camera(eye=(636001.25, 849002.5, 512.75), target=(636000, 849000, 400), up=(0, 0, 1), fov=35)
    flags = camera_flags(cam).split()
    assert flags[flags.index("--eye") + 1:flags.index("--eye") + 4] == ["636001.25", "849002.5", "512.75"]
    assert auto_camera(surfsplat.demo_scene("sphere"), 10, 10).width == 10


def test_huge_and_tiny_up_vectors_frame_like_their_direction():
    """An up vector of any magnitude (the long CLI fuzz found ``--up 1e308 -1 -1``) is a direction:
    no overflow warning, the same picture as its unit vector."""
    unit = np.array([1.0, -1.0, -1.0]) / np.sqrt(3.0)
    expected = surfsplat.render("demo:sphere", surfsplat.CameraSpec(up=tuple(unit)), width=24, height=16)
    for scale in (1e308, 1e-300):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            frame = surfsplat.render("demo:sphere", surfsplat.CameraSpec(up=tuple(unit * scale)), width=24, height=16)
        assert np.abs(frame.color - expected.color).max() < 1e-6
