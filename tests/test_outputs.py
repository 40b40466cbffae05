"""Outputs beside the image: depth as OpenEXR, normal maps (against an analytic sphere and plane),
coverage maps; from the API and the command line."""

from __future__ import annotations

import surfsplat
import importlib.util

import numpy as np
import pytest
from PIL import Image

from surfsplat import api
from surfsplat.camera import Camera
from surfsplat.cli import main
from surfsplat.errors import InputError
from surfsplat.io import save_ply
from surfsplat.io.exr import DEPTH_KEY, load_depth_exr, load_exr, save_depth_exr
from surfsplat.io.image_maps import (check_map_path, normals_from_depth, pixel_points, save_coverage, save_depth,
                                     save_normals)
from surfsplat.scenes import sphere

CAMERA = Camera(eye=(0.3, 0.2, 3.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=40.0, width=160, height=120)
RADIUS = 0.8


@pytest.fixture
def openexr():
    """The OpenEXR package (the exr extra): the tests writing or reading .exr files skip without it."""
    return pytest.importorskip("OpenEXR")


def analytic_sphere(camera: Camera, radius: float = RADIUS, center=(0.0, 0.0, 0.0)):
    """Depth (inf where the ray misses) and camera-space unit normals of a sphere, by ray casting."""
    view = camera.view_matrix
    c = view[:3, :3] @ np.asarray(center, dtype=np.float64) + view[:3, 3]
    ray = pixel_points(np.ones((camera.height, camera.width)), camera)   # the point at depth 1: z = -1
    b, a = ray @ c, np.sum(ray * ray, axis=-1)
    disc = b * b - a * (c @ c - radius * radius)
    depth = np.where(disc >= 0, (b - np.sqrt(np.maximum(disc, 0.0))) / a, np.inf)
    with np.errstate(invalid="ignore"):
        normals = (ray * depth[..., None] - c) / radius
    return depth, normals


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def interior(depth: np.ndarray) -> np.ndarray:
    """Pixels whose four neighbours are drawn too."""
    drawn = np.pad(np.isfinite(depth), 1)
    return drawn[1:-1, 1:-1] & drawn[:-2, 1:-1] & drawn[2:, 1:-1] & drawn[1:-1, :-2] & drawn[1:-1, 2:]


def test_depth_exr_round_trip_is_exact(tmp_path, openexr):
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.5, 7.0, size=(30, 41)).astype(np.float32)
    depth[:3, :5] = np.inf
    path = save_depth_exr(depth, tmp_path / "d.exr")
    back = load_depth_exr(path)
    assert back.dtype == np.float32 and back.shape == depth.shape
    assert np.array_equal(back, depth)   # float32 stored losslessly, inf kept
    channels, header = load_exr(path)
    assert list(channels) == ["Z"] and "inf = empty" in header[DEPTH_KEY]
    save_depth_exr(depth * 2.0, path)   # replaced
    assert np.array_equal(load_depth_exr(path), depth * 2.0)
    with pytest.raises(InputError, match="exists"):
        save_depth_exr(depth, path, overwrite=False)
    assert np.array_equal(load_depth_exr(path), depth * 2.0)


def test_normals_of_an_analytic_sphere():
    depth, truth = analytic_sphere(CAMERA)
    normals = normals_from_depth(depth, CAMERA)
    inside = interior(depth)
    assert inside.sum() > 5000
    points = pixel_points(np.where(np.isfinite(depth), depth, 1.0), CAMERA)
    facing = angle_deg(truth, -points / np.linalg.norm(points, axis=-1, keepdims=True))
    error = angle_deg(normals, truth)
    assert np.median(error[inside]) < 0.05
    assert error[inside & (facing < 70)].max() < 0.5
    assert error[inside].max() < 6.0   # grazing, one pixel inside the rim: one-sided differences
    assert np.isnan(normals[~np.isfinite(depth)]).all()
    # every normal drawn is unit length and faces the eye
    drawn = np.isfinite(normals).all(axis=-1)
    assert np.allclose(np.linalg.norm(normals[drawn], axis=-1), 1.0, atol=1e-5)
    assert (np.sum(normals * pixel_points(np.where(drawn, depth, 1.0), CAMERA), axis=-1)[drawn] < 0).all()
    world = normals_from_depth(depth, CAMERA, space="world")
    good = inside & (facing < 70)
    assert np.abs(world[good] - truth[good] @ CAMERA.view_matrix[:3, :3]).max() < 0.01


def test_normals_of_a_tilted_plane_are_exact_up_to_its_edges():
    # the plane n . p = d in camera space: depth along each pixel's ray p = depth * r (r_z = -1)
    n = np.array([0.3, -0.4, 0.866])
    n /= np.linalg.norm(n)
    ray = pixel_points(np.ones((CAMERA.height, CAMERA.width)), CAMERA)
    depth = -2.0 / (ray @ n)   # n . (t r) = -2: in front of the eye
    depth[:, :40] = np.inf   # an empty band: the edge pixels use one-sided differences
    normals = normals_from_depth(depth, CAMERA)
    drawn = np.isfinite(depth)
    assert np.abs(normals[drawn] - n).max() < 1e-4


def test_map_files(tmp_path, openexr):
    depth, truth = analytic_sphere(CAMERA)
    normals = normals_from_depth(depth, CAMERA)
    png = np.asarray(Image.open(save_normals(normals, tmp_path / "n.png")), dtype=np.float64)
    drawn = np.isfinite(depth)
    assert np.abs((png[drawn] / 255.0 - 0.5) * 2.0 - normals[drawn]).max() <= 1.0 / 255 + 1e-6
    assert (png[~drawn] == 0).all()
    assert np.array_equal(np.load(save_normals(normals, tmp_path / "n.npy")), normals, equal_nan=True)
    channels, _ = load_exr(save_normals(normals, tmp_path / "n.exr"))
    assert np.array_equal(channels["RGB"], normals, equal_nan=True)   # stored as channels R, G, B
    alpha = np.linspace(0.0, 1.0, 7 * 9, dtype=np.float32).reshape(7, 9)
    for bits, top in ((8, 255), (16, 65535)):
        values = np.asarray(Image.open(save_coverage(alpha, tmp_path / f"c{bits}.png", bit_depth=bits)))
        assert values.max() == top and np.abs(values / top - alpha).max() <= 0.5 / top + 1e-7
    assert np.array_equal(np.load(save_coverage(alpha, tmp_path / "c.npy")), alpha)
    with pytest.raises(InputError, match="--normals writes"):
        check_map_path("normals", tmp_path / "n.jpg")
    with pytest.raises(InputError, match="--depth writes"):
        check_map_path("depth", tmp_path / "d.tiff")


def test_exr_without_the_extra_names_it(tmp_path, monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "OpenEXR" else real(name, *a))
    with pytest.raises(InputError, match=r"surfsplat\[exr\]") as info:
        save_depth(np.ones((2, 2)), tmp_path / "d.exr", 1.0, 2.0)
    assert "d.exr" in str(info.value) and not (tmp_path / "d.exr").exists()


@pytest.fixture(scope="module")
def sphere_file(tmp_path_factory):
    return save_ply(sphere(20_000, radius=RADIUS), tmp_path_factory.mktemp("outputs") / "sphere.ply")


@pytest.mark.gl
def test_rendered_sphere_maps_match_the_frame_and_the_analytic_sphere(tmp_path, sphere_file, openexr):
    model = api.load_model(sphere_file)
    result = surfsplat.prepare(model).render(CAMERA, supersample=2)
    frame = result.frame
    save_depth(frame.depth, tmp_path / "d.exr", 1.0, 2.0)
    assert np.array_equal(load_depth_exr(tmp_path / "d.exr"), frame.depth)   # exactly Frame.depth
    depth, truth = analytic_sphere(CAMERA)
    both = interior(frame.depth) & interior(depth)
    assert both.sum() > 0.9 * interior(depth).sum()
    error = angle_deg(result.normals()[both], truth[both])
    assert np.median(error) < 2.0 and np.percentile(error, 95) < 6.0
    assert result.coverage is frame.alpha
    # the antialiased coverage: full inside, fractional on the rim, none outside
    assert (frame.alpha[both] == 1).all() and (frame.alpha[~np.isfinite(frame.depth)] == 0).all()
    assert ((frame.alpha > 0) & (frame.alpha < 1)).sum() > 50


@pytest.mark.gl
def test_cli_writes_the_maps_it_prints(tmp_path, sphere_file, capsys, openexr):
    d, n, c = tmp_path / "d.exr", tmp_path / "n.png", tmp_path / "c.npy"
    status = main(["render", str(sphere_file), "-o", str(tmp_path / "out.png"), "--width", "80", "--height", "60",
                   "--eye", "0.3", "0.2", "3", "--target", "0", "0", "0", "--fov", "40",
                   "--depth", str(d), "--normals", str(n), "--coverage", str(c)])
    err = capsys.readouterr().err
    assert status == 0, err
    for path in (d, n, c):
        assert f"-> {path}\n" in err and path.is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.npy", "d.exr", "n.png", "out.png"]
    depth = load_depth_exr(d)
    coverage = np.load(c)
    assert depth.shape == coverage.shape == (60, 80)
    assert np.array_equal(np.isfinite(depth), coverage > 0)
    assert abs(depth[30, 40] - (np.linalg.norm([0.3, 0.2, 3.0]) - RADIUS)) < 0.02   # the sphere's front
    rgb = np.asarray(Image.open(n), dtype=np.float64) / 255.0 * 2.0 - 1.0
    assert rgb[30, 40, 2] > 0.95   # facing the camera at the center
    status = main(["-q", "render", str(sphere_file), "-o", str(tmp_path / "x.png"),
                   "--normals", str(tmp_path / "n.bmp")])
    assert status == 2 and "--normals writes" in capsys.readouterr().err
