"""Point attributes in chunked hierarchies: LAS dimensions such as classification and
intensity kept per cell (points in octree order, nodes by majority vote or mean, as the in-memory
hierarchy), carried by views, and ``--color-by`` on a chunked model.

The reference is the input: each kept splat's row in it (``ids``) names its values.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from PIL import Image
from test_chunked import OFFSET, torus_points

from surfsplat import pipeline
from surfsplat.cli import main
from surfsplat.colors import class_colors
from surfsplat.errors import InputError
from surfsplat.hierarchy.chunked import build_chunked, open_chunked


@pytest.fixture(scope="module")
def lidar(tmp_path_factory):
    """Two LAS tiles of a torus: classification 2 (ground) on the half x < 0 (relative to the
    center), 6 (building) on the other; intensity 115..3885 from the angle around the axis.
    Writing them needs laspy: the tests using them skip without it."""
    laspy = pytest.importorskip("laspy")
    folder = tmp_path_factory.mktemp("attributes")
    points = torus_points(12_000, seed=31)
    rel = points - OFFSET
    classification = np.where(rel[:, 0] < 0, 2, 6).astype(np.uint8)
    intensity = (2000 + 600 * np.arctan2(rel[:, 1], rel[:, 0])).astype(np.uint16)
    (folder / "tiles").mkdir()
    for name, part in (("a.las", slice(0, 7_000)), ("b.las", slice(7_000, None))):
        header = laspy.LasHeader(point_format=1, version="1.2")
        header.offsets, header.scales = OFFSET, np.full(3, 1e-4)
        las = laspy.LasData(header)
        las.x, las.y, las.z = points[part].T
        las.classification = classification[part]
        las.intensity = intensity[part]
        las.write(folder / "tiles" / name)
    build_chunked(folder / "tiles", folder / "t.ssh", cell_points=3_000, chunk_points=2_500, scheduler="synchronous")
    return folder / "t.ssh", classification, intensity


def test_cells_keep_the_points_attributes_and_node_majorities(lidar):
    path, classification, intensity = lidar
    model = open_chunked(path)
    assert model.attributes["classification"] == np.uint8 and model.attributes["intensity"] == np.uint16
    assert len(model.cells) >= 4
    for i in range(len(model.cells)):
        h = model.cell(i)
        _, ids, values = model._points(i)
        assert np.array_equal(values["classification"], classification[ids])
        assert np.array_equal(values["intensity"], intensity[ids])
        # node values: majority class (ties to the smallest) and mean intensity over each node's points
        start, end = h.node_point_start, h.node_point_start + h.node_point_count
        buildings = np.concatenate([[0], np.cumsum(values["classification"] == 6)])
        majority = np.where(2 * (buildings[end] - buildings[start]) > end - start, 6, 2)
        assert np.array_equal(h.node_attributes["classification"], majority)
        # an integer column is voted too: the most frequent value, ties to the smallest (a sample of nodes)
        for node in np.linspace(0, len(h) - 1, 50).astype(int):
            found, counts = np.unique(values["intensity"][start[node]:end[node]], return_counts=True)
            assert h.node_attributes["intensity"][node] == found[np.argmax(counts)]


def test_views_carry_attributes_and_colour_by_classification(lidar):
    path, _, intensity = lidar
    model = open_chunked(path)
    camera = pipeline.resolve_camera(model, None, 96, 96)
    cloud, selection = model.view_splats(camera, 2.0, point_budget=1_500)
    assert len(cloud) <= 1_500 and selection.node_count > 0
    assert set(np.unique(cloud.attributes["classification"])) <= {2, 6}
    coloured = model.colorized("classification")
    cloud, _ = coloured.view_splats(camera, 2.0, point_budget=1_500)
    # coarse splats too draw palette colours (majority class), never a blend of ground and building
    assert np.array_equal(cloud.colors, class_colors(cloud.attributes["classification"]))
    # a continuous attribute spans one range for every view: its 2nd-98th percentiles over the points
    # (sampled at build time; a cell this small gives all its points)
    by_intensity = model.colorized("intensity")
    low, high = by_intensity.coloring[2]
    assert np.allclose((low, high), np.percentile(intensity, [2, 98]), atol=0.01 * (high - low))
    with pytest.raises(InputError, match="classification"):
        model.colorized("no_such_attribute")


@pytest.mark.gl
def test_cli_renders_a_chunked_model_by_classification(lidar, tmp_path):
    path, _, _ = lidar
    png = tmp_path / "c.png"
    assert main(["render", str(path), "-o", str(png), "--width", "96", "--height", "96", "--color-by",
                 "classification", "--no-lighting", "--point-budget", "3000", "--quiet"]) == 0
    image = np.asarray(Image.open(png).convert("RGB"), dtype=np.int64)
    ground, building = (class_colors(np.array([c])) [0] * 255 for c in (2, 6))
    drawn = np.any(image != 255, axis=2)
    near = [np.abs(image - np.round(colour)).max(axis=2) <= 3 for colour in (ground, building)]
    # both classes appear, and (edges blending with the background aside) in their palette colours
    assert near[0].sum() > 200 and near[1].sum() > 200
    assert (near[0] | near[1])[drawn].mean() > 0.8


def test_version_1_directories_without_attributes_still_open(lidar, tmp_path):
    path, _, _ = lidar
    old = tmp_path / "old.ssh"
    shutil.copytree(path, old)
    manifest = json.loads((old / "manifest.json").read_text())
    assert manifest["format_version"] == 2
    manifest["format_version"] = 1   # what format version 1 wrote: no attribute table, no attribute files read
    del manifest["attributes"]
    (old / "manifest.json").write_text(json.dumps(manifest))
    model = open_chunked(old)
    cloud, _ = model.view_splats(pipeline.resolve_camera(model, None, 64, 64), 2.0)
    assert model.attributes == {} and cloud.attributes is None and len(cloud) > 0
    with pytest.raises(InputError, match="classification"):
        model.colorized("classification")
    manifest["format_version"] = 3
    (old / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(InputError, match="version 3 is not supported"):
        open_chunked(old)
