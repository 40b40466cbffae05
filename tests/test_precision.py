"""Precision independent of where the data sit.

The same torus (major radius 0.5, tube 0.2, splats about 8 mm apart) is rendered at the origin,
moved to offsets 1e6 and 1e7 (arrays, a LAS file with scale 0.001, a PLY with double
coordinates) and scaled by 1e-12..1e18, with the camera moved and scaled with it. Tolerance: PSNR
of the 8-bit image against the view at the origin >= 40 dB and covered pixels equal within 3
(the old float32 world positions gave 7-10 dB and tens of thousands of pixels missing at 1e6..1e7,
an empty frame at 1e-9; see benchmarks/results/precision.md).
"""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

import surfsplat
from surfsplat import Camera, SplatCloud
from surfsplat.pipeline import local_camera
from surfsplat.rendering.gpu_splats import gpu_scale
from surfsplat.cli import main
from surfsplat.geometry.preprocess import preprocess
from surfsplat.hierarchy import build_hierarchy, load_hierarchy
from surfsplat.hierarchy.storage import save_hierarchy
from surfsplat.io import load, save_ply
from surfsplat.scenes import torus

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): most tests render through the API and the command line

SIZE = 128
EYE = np.array([0.9, -1.3, 1.0])
DIRECTION = np.array([1.0, 0.8, 0.1])
MIN_PSNR = 40.0
MAX_COVERAGE_DIFF = 3


@pytest.fixture(scope="module")
def base() -> SplatCloud:
    return torus(400, 160, major=0.5, minor=0.2)


def moved(cloud: SplatCloud, offset, scale: float = 1.0) -> SplatCloud:
    """The cloud scaled about zero and moved, from float64 world arrays (as a user passes them)."""
    world = cloud.positions.astype(np.float64) * scale + np.asarray(offset, dtype=np.float64)
    return SplatCloud(world, cloud.normals, cloud.colors, cloud.u.astype(np.float64) * scale,
                      cloud.v.astype(np.float64) * scale)


def camera(offset, scale: float = 1.0) -> Camera:
    offset = np.asarray(offset, dtype=np.float64)
    return Camera(eye=tuple(offset + scale * EYE), target=tuple(offset), up=(0.0, 0.0, 1.0), width=SIZE, height=SIZE)


def psnr(frame, reference) -> float:
    a, b = frame.image().astype(np.float64), reference.image().astype(np.float64)
    mse = float(np.mean((a - b) ** 2))
    return np.inf if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def assert_same_picture(frame, reference) -> None:
    assert np.isfinite(frame.color).all()
    assert reference.mask.sum() > 0.2 * SIZE * SIZE   # the reference shows the torus
    assert abs(int(frame.mask.sum()) - int(reference.mask.sum())) <= MAX_COVERAGE_DIFF
    assert psnr(frame, reference) >= MIN_PSNR


@pytest.fixture(scope="module")
def references(base):
    return {t: surfsplat.render(base, camera(np.zeros(3)), technique=t) for t in ("ewa", "flat")}


@pytest.mark.parametrize("technique", ["ewa", "flat"])
@pytest.mark.parametrize("offset", [1e6, 1e7])
def test_offset_renders_the_same_picture(base, references, technique, offset):
    shift = offset * DIRECTION
    cloud = moved(base, shift)
    assert np.abs(cloud.origin - shift).max() < 1.0 and np.abs(cloud.positions).max() < 2.0
    frame = surfsplat.render(cloud, camera(shift), technique=technique)
    assert_same_picture(frame, references[technique])
    assert frame.camera.eye == camera(shift).eye   # the frame keeps the world camera
    # depth is a distance: the same wherever the model sits (float32 of depths near 2)
    both = np.isfinite(frame.depth) & np.isfinite(references[technique].depth)
    assert np.abs(frame.depth[both] - references[technique].depth[both]).max() < 1e-3


@pytest.mark.parametrize("technique", ["ewa", "flat"])
@pytest.mark.parametrize("scale", [1e-12, 1e-9, 1e-6, 1e6, 1e9, 1e12, 1e18])
def test_scale_renders_the_same_picture(base, references, technique, scale):
    frame = surfsplat.render(moved(base, np.zeros(3), scale), camera(np.zeros(3), scale), technique=technique)
    assert_same_picture(frame, references[technique])
    both = np.isfinite(frame.depth) & np.isfinite(references[technique].depth)
    assert np.allclose(frame.depth[both] / scale, references[technique].depth[both], rtol=1e-3)


def test_offset_and_small_scale_together(base, references):
    shift = 1e7 * DIRECTION
    frame = surfsplat.render(moved(base, shift, 1e-3), camera(shift, 1e-3), technique="ewa")
    assert_same_picture(frame, references["ewa"])


def test_automatic_camera_follows_the_data(base):
    shift = 1e7 * DIRECTION
    near = surfsplat.auto_camera(base, SIZE, SIZE)
    far = surfsplat.auto_camera(moved(base, shift), SIZE, SIZE)
    assert np.allclose(np.subtract(far.eye, shift), near.eye, atol=1e-6)
    assert np.allclose(np.subtract(far.target, shift), near.target, atol=1e-6)
    assert far.near == pytest.approx(near.near, rel=1e-5) and far.far == pytest.approx(near.far, rel=1e-5)


def test_las_with_large_offset(tmp_path):
    laspy = pytest.importorskip("laspy")
    small = torus(200, 80, major=0.5, minor=0.2)
    local = np.round(small.positions.astype(np.float64), 3)
    far = np.round(1e7 * DIRECTION, 3)
    frames = {}
    for name, offset in (("origin", np.zeros(3)), ("far", far)):
        header = laspy.LasHeader(point_format=0, version="1.2")
        header.scales, header.offsets = np.array([0.001] * 3), offset
        las = laspy.LasData(header)
        world = local + offset
        las.x, las.y, las.z = world[:, 0], world[:, 1], world[:, 2]
        las.write(str(tmp_path / f"{name}.las"))
        cloud = load(tmp_path / f"{name}.las")
        # world coordinates kept to the file's millimetre: origin + float32 local positions
        assert np.abs(cloud.world_positions() - world).max() < 1e-4
        frames[name] = surfsplat.render(str(tmp_path / f"{name}.las"), camera(offset), technique="ewa")
    assert_same_picture(frames["far"], frames["origin"])


def test_ply_with_double_coordinates(tmp_path, base):
    shift = 1e7 * DIRECTION
    cloud = moved(base, shift)
    save_ply(cloud, tmp_path / "far.ply")          # a cloud with an origin is written in doubles
    back = load(tmp_path / "far.ply")
    assert np.abs(back.world_positions() - cloud.world_positions()).max() < 1e-6
    reference = surfsplat.render(base, camera(np.zeros(3)), technique="flat")
    assert_same_picture(surfsplat.render(str(tmp_path / "far.ply"), camera(shift), technique="flat"), reference)


def test_hierarchy_keeps_the_origin(tmp_path, base):
    shift = 1e7 * DIRECTION
    hierarchy = build_hierarchy(moved(base, shift))
    save_hierarchy(hierarchy, tmp_path / "far.npz")
    loaded = load_hierarchy(tmp_path / "far.npz")
    np.testing.assert_array_equal(loaded.points.origin, hierarchy.points.origin)
    lo, hi = loaded.bounds()
    assert np.allclose(lo, shift - [0.7, 0.7, 0.2], atol=1e-3) and np.allclose(hi, shift + [0.7, 0.7, 0.2], atol=1e-3)
    reference = surfsplat.render(build_hierarchy(base), camera(np.zeros(3)), technique="ewa")
    frame = surfsplat.render(loaded, camera(shift), technique="ewa")
    assert abs(int(frame.mask.sum()) - int(reference.mask.sum())) <= MAX_COVERAGE_DIFF
    assert psnr(frame, reference) >= MIN_PSNR
    # a file written before the origin was stored loads with its points at zero
    old = tmp_path / "old.npz"
    with zipfile.ZipFile(tmp_path / "far.npz") as src, zipfile.ZipFile(old, "w") as dst:
        for item in src.namelist():
            if item != "point_origin.npy":
                dst.writestr(item, src.read(item))
    assert not load_hierarchy(old).points.origin.any()


def test_preprocessing_at_an_offset_matches_the_origin(base):
    raw = base.positions[::4].astype(np.float64)
    near = preprocess(SplatCloud(raw))
    far = preprocess(SplatCloud(raw + 1e7 * DIRECTION))
    assert len(near) == len(far)
    assert np.abs(far.world_positions() - 1e7 * DIRECTION - near.positions).max() < 1e-6
    assert np.einsum("ij,ij->i", near.normals, far.normals).min() > 0.999
    # float32 rounding of the local positions may flip a tie between equidistant neighbours
    assert np.mean(np.isclose(far.radii, near.radii, rtol=1e-3)) >= 0.999


@pytest.mark.parametrize("magnitude", [1e20, 1e25, 1e30])
def test_info_bounds_of_huge_coordinates(tmp_path, capsys, magnitude):
    rng = np.random.default_rng(0)
    world = magnitude * (1.0 + rng.random((50, 3)))   # spread over the magnitude itself
    save_ply(SplatCloud(world), tmp_path / "huge.ply")
    assert main(["-q", "info", str(tmp_path / "huge.ply")]) == 0
    out = capsys.readouterr().out
    line = next(s for s in out.splitlines() if s.startswith("bounds:"))
    numbers = np.array([float(x) for x in line.replace("[", " ").replace("]", " ").split()[2:] if x not in ("max",)])
    assert np.isfinite(numbers).all()
    np.testing.assert_allclose(numbers, np.concatenate([world.min(axis=0), world.max(axis=0)]), rtol=1e-4)
    diagonal = float(out.split("diagonal ")[1].split(")")[0])
    assert diagonal == pytest.approx(np.linalg.norm(world.max(axis=0) - world.min(axis=0)), rel=1e-3)


def test_origin_is_chosen_only_where_float32_would_lose_precision():
    near = SplatCloud(np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]))
    assert not near.origin.any()
    f32 = SplatCloud(np.array([[1e7, 0.0, 0.0], [1e7 + 1, 0.0, 0.0]], dtype=np.float32))
    assert not f32.origin.any()                       # float32 given: taken as it is
    far = SplatCloud(np.array([[1e7 + 0.001, 5.0, 0.0], [1e7 + 0.003, 5.0, 0.0]]))
    assert far.origin[0] == pytest.approx(1e7, abs=0.01)
    np.testing.assert_allclose(far.world_positions()[:, 0], [1e7 + 0.001, 1e7 + 0.003], rtol=0, atol=1e-9)
    assert far.subset([1]).origin is far.origin or np.array_equal(far.subset([1]).origin, far.origin)
    with pytest.raises(surfsplat.InputError, match="origin"):
        SplatCloud(np.zeros((2, 3), np.float32), origin=(0.0, np.nan, 0.0))


def test_local_camera_and_gpu_scale(base):
    cloud = moved(base, 1e7 * DIRECTION, 1e-3)
    world = camera(1e7 * DIRECTION, 1e-3)
    local = local_camera(cloud, world)
    # the view of a point is the same through the world camera and, minus the origin, the local one
    p = cloud.world_positions()[:5]
    v_world = (world.view_matrix @ np.c_[p, np.ones(5)].T)[:3]
    v_local = (local.view_matrix @ np.c_[p - cloud.origin, np.ones(5)].T)[:3]
    assert np.allclose(v_world, v_local, rtol=0, atol=1e-8)
    assert local.near == pytest.approx(world.with_clip_from_bounds(*cloud.bounds(), float(cloud.radii.max())).near)
    k = gpu_scale(moved(base, np.zeros(3), 1e-9))
    assert k == 2.0 ** round(np.log2(k)) and 0.5 <= k * 1e-9 * float(np.ptp(base.positions, axis=0).max()) <= 2.0
    assert gpu_scale(base) == 1.0
    scaled = world.scaled(2.0)
    assert scaled.near is None and np.allclose(scaled.eye, np.multiply(world.eye, 2.0))


def test_mesh_far_from_zero_samples_and_rasterizes_the_same(base):
    import trimesh

    shift = 1e7 * DIRECTION
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    near = surfsplat.io.Mesh(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    far = surfsplat.io.objects.from_object(trimesh.Trimesh(np.asarray(sphere.vertices) + shift, sphere.faces))
    assert np.abs(far.origin - shift).max() < 1.0
    assert np.abs(far.vertices.astype(np.float64) + far.origin - shift - near.vertices).max() < 1e-6
    for draw in (surfsplat.render_mesh, surfsplat.render):
        reference = draw(near, camera(np.zeros(3)))
        frame = draw(far, camera(shift))
        assert abs(int(frame.mask.sum()) - int(reference.mask.sum())) <= MAX_COVERAGE_DIFF
        assert psnr(frame, reference) >= MIN_PSNR


def test_elevation_colours_use_world_heights(base):
    from surfsplat.colors import ColorOptions
    from surfsplat.pipeline import as_model

    shift = np.array([0.0, 0.0, 1e7])
    far = as_model(moved(base, shift)).colored(ColorOptions("elevation", "viridis", (1e7 - 0.2, 1e7 + 0.2)),
                                              (0.0, 0.0, 1.0)).data
    near = as_model(base).colored(ColorOptions("elevation", "viridis", (-0.2, 0.2)), (0.0, 0.0, 1.0)).data
    assert np.abs(far.colors - near.colors).max() < 0.01
    assert np.ptp(near.colors[:, 0]) > 0.3   # the range spans the colormap


def test_text_points_and_conversions_keep_world_coordinates(tmp_path):
    from surfsplat.io.objects import from_object, to_trimesh

    rng = np.random.default_rng(1)
    world = np.round(rng.random((200, 3)) * 10.0 + [6.5e5, 5.2e6, 300.0], 3)   # UTM-like, millimetres
    np.savetxt(tmp_path / "far.xyz", world, fmt="%.3f")
    cloud = load(tmp_path / "far.xyz")
    assert cloud.origin.any() and np.abs(cloud.positions).max() < 10.0
    assert np.abs(cloud.world_positions() - world).max() < 1e-5
    again = SplatCloud.from_dict(cloud.to_dict(columns=True))
    assert np.abs(again.world_positions() - world).max() < 1e-5
    assert np.abs(np.asarray(to_trimesh(cloud).vertices) - world).max() < 1e-5
    assert np.abs(from_object(world).world_positions() - world).max() < 1e-5


def test_coordinates_beyond_float32_around_their_origin_are_refused_clearly(tmp_path, capsys):
    from plyfile import PlyData, PlyElement

    data = np.zeros(5, dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    data["x"] = 1e300 + np.arange(5) * 1e290        # a spread float32 cannot hold even about the centre
    PlyData([PlyElement.describe(data, "vertex")]).write(str(tmp_path / "vast.ply"))
    assert main(["-q", "info", str(tmp_path / "vast.ply")]) == 2
    err = capsys.readouterr().err
    assert "vast.ply: no valid points left" in err and "float32" in err and "Traceback" not in err
    assert "overflow" not in err
    far = SplatCloud(np.array([[1e40, 0.0, 0.0], [1e40 + 1e30, 1.0, 2.0]]))   # beyond float32, its spread within
    lo, hi = far.bounds()
    assert np.isfinite(far.positions).all() and hi[0] - lo[0] == pytest.approx(1e30, rel=1e-6)


def test_phong_splats_keep_the_origin():
    from surfsplat.geometry.phong.splatting import phong_splats
    from surfsplat.scenes import sphere

    s = sphere(3000)
    shift = 1e7 * DIRECTION
    near = phong_splats(SplatCloud(s.positions.astype(np.float64), s.normals), count=300)
    far = phong_splats(SplatCloud(s.positions.astype(np.float64) + shift, s.normals), count=300)
    assert len(far) == len(near)
    assert np.abs(far.world_positions() - shift - near.positions).max() < 1e-5
    assert np.allclose(far.radii, near.radii, rtol=1e-3)
