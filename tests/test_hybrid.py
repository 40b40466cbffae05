"""Hybrid drawing for LiDAR: planar neighbourhoods as surface splats, non-planar ones as round points."""

from __future__ import annotations

import surfsplat
import numpy as np
import pytest

from surfsplat import api, pipeline
from surfsplat.camera import Camera
from surfsplat.errors import InputError
from surfsplat.geometry.preprocess import NONPLANAR, preprocess
from surfsplat.hierarchy import build_hierarchy
from surfsplat.rendering.hybrid import facing_points
from surfsplat.scenes_faulty import AERIAL_COLORS, BUILDING, GROUND, HIGH_VEGETATION, aerial, tree

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): most tests render


@pytest.fixture(scope="module")
def block():
    scene = aerial(n=12_000, houses=3, trees=4, seed=3)
    return scene, pipeline.as_splats(scene.cloud)


def _top_camera(cloud, size=200) -> Camera:
    lo, hi = cloud.bounds()
    c = 0.5 * (lo + hi)
    return Camera(eye=(c[0], c[1], hi[2] + 1.6 * (hi[0] - lo[0])), target=(c[0], c[1], 0.0), up=(0.0, 1.0, 0.0),
                  fov=35.0, width=size, height=size)


def test_preprocess_marks_nonplanar_points_only_when_asked():
    scene = tree(n=6000, crown=1500, seed=1)
    plain, report = preprocess(scene.cloud, return_report=True)
    marked = preprocess(scene.cloud, mark_nonplanar=True)
    assert plain.attributes is None or NONPLANAR not in plain.attributes
    for name in ("positions", "normals", "u", "v"):   # nothing else changes
        np.testing.assert_array_equal(getattr(marked, name), getattr(plain, name))
    flag = marked.attributes[NONPLANAR].astype(bool)
    assert int(flag.sum()) == report.volumetric
    surface = scene.surface[report.kept]
    assert flag[surface].mean() < 0.02        # the plane is planar
    assert flag[~surface].mean() > 0.6        # the crown and trunk are not


def test_aerial_scene_classes_and_attributes(block):
    scene, cloud = block
    cls = cloud.attributes["classification"]
    assert set(np.unique(cls)) == {GROUND, BUILDING, HIGH_VEGETATION}
    np.testing.assert_allclose(scene.cloud.colors[scene.cloud.attributes["classification"] == BUILDING][0],
                               AERIAL_COLORS[BUILDING])
    flag = cloud.attributes[NONPLANAR].astype(bool)
    assert flag[cls == GROUND].mean() < 0.02
    assert flag[cls == BUILDING].mean() < 0.15     # roof ridges and wall feet only
    assert flag[cls == HIGH_VEGETATION].mean() > 0.6
    with pytest.raises(InputError, match="houses"):
        aerial(houses=10, trees=10)


def test_facing_points_face_the_eye_and_keep_the_rest(block):
    scene, cloud = block
    camera = _top_camera(cloud)
    flag = cloud.attributes[NONPLANAR].astype(bool)
    out = facing_points(cloud, flag, camera)
    toward = np.asarray(camera.eye) - out.positions[flag]
    toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    u, v = out.u[flag].astype(np.float64), out.v[flag].astype(np.float64)
    r = np.maximum(np.linalg.norm(cloud.u[flag], axis=1), np.linalg.norm(cloud.v[flag], axis=1))
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), r, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), r, rtol=1e-5)
    assert np.abs(np.einsum("ij,ij->i", u, toward)).max() < 1e-5 * r.max()
    assert np.abs(np.einsum("ij,ij->i", v, toward)).max() < 1e-5 * r.max()
    for name in ("positions", "normals", "colors"):
        np.testing.assert_array_equal(getattr(out, name), getattr(cloud, name))
    np.testing.assert_array_equal(out.u[~flag], cloud.u[~flag])
    with pytest.raises(InputError, match="one entry per splat"):
        facing_points(cloud, flag[:-1], camera)


def test_hybrid_frame_no_holes_in_the_ground_trees_on_top(block, gl_renderer):
    scene, cloud = block
    camera = _top_camera(cloud)
    frame = surfsplat.prepare(cloud, source_options=surfsplat.SourceOptions(hybrid=True)).render(
        camera, lights=None).frame
    image = frame.image().astype(np.float64) / 255
    # project every point; the ground away from houses and trees must be covered without holes
    view = camera.view_matrix
    p = cloud.positions.astype(np.float64) @ view[:3, :3].T + view[:3, 3]
    px = p[:, :2] / -p[:, 2:3] * camera.focal_px + (camera.width / 2, camera.height / 2)
    col, row = np.floor(px[:, 0]).astype(int), camera.height - 1 - np.floor(px[:, 1]).astype(int)
    cls = cloud.attributes["classification"]
    inside = (col >= 2) & (col < camera.width - 2) & (row >= 2) & (row < camera.height - 2)
    others = np.zeros((camera.height, camera.width), dtype=bool)
    others[row[inside & (cls != GROUND)], col[inside & (cls != GROUND)]] = True
    from surfsplat.metrics import dilate, erode
    ground = np.zeros_like(others)
    ground[row[inside & (cls == GROUND)], col[inside & (cls == GROUND)]] = True
    open_ground = erode(dilate(ground, 2), 4) & ~dilate(others, 4)
    assert open_ground.sum() > 0.3 * camera.width * camera.height
    assert frame.alpha[open_ground].min() > 0.99
    # seen from above the crowns hide the ground: the pixels over a crown's center are green
    tree_pixels = inside & (cls == HIGH_VEGETATION) & (cloud.positions[:, 2] > np.quantile(cloud.positions[:, 2], 0.99))
    rgb = image[row[tree_pixels], col[tree_pixels]]
    green = rgb[:, 1] > rgb[:, 0] + 0.05
    assert green.mean() > 0.9


def test_hybrid_on_a_hierarchy_votes_per_node(block, gl_renderer):
    scene, cloud = block
    h = build_hierarchy(cloud)
    camera = _top_camera(cloud)
    tree = pipeline.as_model(h)
    drawn, selection = tree.cut(camera, 4.0)
    out = pipeline.hybrid_splats(tree, drawn, selection, camera)
    changed = np.any(out.u != drawn.u, axis=1)
    nodes = selection.node_indices()
    flags = cloud.attributes[NONPLANAR].astype(bool)[h.order]
    share = np.array([flags[s:s + c].mean() for s, c in zip(h.node_point_start[nodes], h.node_point_count[nodes])])
    # a node is drawn as a point iff most of its points are non-planar (u may be unchanged by chance: never here)
    np.testing.assert_array_equal(changed[:len(nodes)], share > 0.5)
    np.testing.assert_array_equal(changed[len(nodes):], flags[selection.point_indices()])


def test_hybrid_is_the_default_for_las_only(tmp_path):
    laspy = pytest.importorskip("laspy")
    assert pipeline.is_lidar("scan.LAZ") and pipeline.is_lidar(tmp_path / "a.las") and not pipeline.is_lidar("a.ply")
    assert not pipeline.is_lidar(np.zeros((3, 3)))
    scene = aerial(n=3000, houses=1, trees=2, seed=5)
    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales = [0.001] * 3
    las = laspy.LasData(header)
    pts = scene.cloud.positions
    las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
    las.classification = scene.cloud.attributes["classification"]
    path = tmp_path / "block.las"
    las.write(str(path))
    camera = pipeline.CameraSpec(fov=30.0)
    auto = api.render(str(path), camera, width=96, height=96)
    on = api.render(str(path), camera, width=96, height=96, source_options=surfsplat.SourceOptions(hybrid=True))
    off = api.render(str(path), camera, width=96, height=96, source_options=surfsplat.SourceOptions(hybrid=False))
    np.testing.assert_array_equal(auto.color, on.color)
    assert np.abs(on.color - off.color).max() > 0.05
    # the command line: hybrid by default for LAS, --no-hybrid turns it off
    from PIL import Image
    from surfsplat.cli import main

    for flags, name in (([], "auto.png"), (["--no-hybrid"], "off.png")):
        assert main(["-q", "render", str(path), "-o", str(tmp_path / name), "--width", "96", "--height", "96",
                     "--fov", "30"] + flags) in (0, None)
    cli_auto, cli_off = (np.asarray(Image.open(tmp_path / n)).astype(int) for n in ("auto.png", "off.png"))
    np.testing.assert_array_equal(cli_auto, on.image())
    np.testing.assert_array_equal(cli_off, off.image())
