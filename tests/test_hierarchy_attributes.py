"""Per-point attributes through the LOD hierarchy: node values, files, colour by attribute."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest
from PIL import Image

from surfsplat import SplatCloud
from surfsplat.api import load_model
from surfsplat.colors import ColorOptions
from surfsplat.pipeline import SourceOptions
from surfsplat.cli import main
from surfsplat.colors import ASPRS_CLASSES, asprs_palette
from surfsplat.errors import InputError
from surfsplat.hierarchy import build_hierarchy, load_hierarchy, save_hierarchy, uniform_cut


def attributed_cloud(n: int = 3000, seed: int = 0) -> SplatCloud:
    """Random splats on a bumpy sheet with float (with NaNs), small-integer and boolean attributes."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 10, size=(n, 2))
    pos = np.column_stack([xy, 0.1 * np.sin(xy[:, 0])])
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    reflectance = rng.normal(size=n).astype(np.float32)
    reflectance[rng.choice(n, 50, replace=False)] = np.nan
    return SplatCloud.from_arrays(pos, normals, radius=np.full(n, 0.2)).replace(attributes={
        "reflectance": reflectance,
        "gps_time": rng.uniform(1e9, 1e9 + 1e5, size=n),                # far from 0: digits kept
        "classification": rng.integers(0, 4, size=n).astype(np.uint8),   # small range: many ties
        "scan_angle": rng.integers(-3, 3, size=n).astype(np.int8),
        "nonplanar": rng.random(n) < 0.3,
        "user_id": rng.integers(-10**6, 10**6, size=n),             # wide int64: ties of 1 to the smallest
        "source_id": rng.integers(70_000, 70_003, size=n).astype(np.int32),   # few values far from 0
    })


@pytest.fixture(scope="module")
def hierarchy():
    return build_hierarchy(attributed_cloud(), leaf_capacity=8)


def node_points(h, node):
    s, c = int(h.node_point_start[node]), int(h.node_point_count[node])
    return slice(s, s + c)


def test_points_keep_their_attributes_in_hierarchy_order(hierarchy):
    cloud = attributed_cloud()
    for name, values in cloud.attributes.items():
        np.testing.assert_array_equal(hierarchy.points.attributes[name], values[hierarchy.order])
        assert hierarchy.node_attributes[name].dtype == hierarchy.points.attributes[name].dtype
        assert hierarchy.node_attributes[name].shape == (len(hierarchy),)


def test_float_node_values_are_nan_ignoring_means(hierarchy):
    pts = hierarchy.points.attributes
    for name in ("reflectance", "gps_time"):
        want = np.array([np.nanmean(pts[name][node_points(hierarchy, k)].astype(np.float64))
                         if np.isfinite(pts[name][node_points(hierarchy, k)]).any() else np.nan
                         for k in range(len(hierarchy))])
        got = hierarchy.node_attributes[name].astype(np.float64)
        rtol = 1e-6 if pts[name].dtype == np.float32 else 1e-14
        np.testing.assert_allclose(got, want, rtol=rtol, atol=0)
    # a leaf of one point holds that point's value; the root the mean of all
    assert np.isclose(hierarchy.node_attributes["gps_time"][0], pts["gps_time"].mean(), rtol=1e-12)


def brute_majority(values):
    distinct, counts = np.unique(values, return_counts=True)
    return distinct[np.argmax(counts)]      # argmax: the first (smallest value) of the most frequent


def test_integer_node_values_are_majority_votes_ties_to_smallest(hierarchy):
    pts = hierarchy.points.attributes
    ties = 0
    for name in ("classification", "scan_angle", "nonplanar", "user_id", "source_id"):
        got = hierarchy.node_attributes[name]
        for k in range(len(hierarchy)):
            values = pts[name][node_points(hierarchy, k)]
            assert got[k] == brute_majority(values), (name, k)
            counts = np.unique(values, return_counts=True)[1]
            ties += int((counts == counts.max()).sum() > 1)
    assert ties > 100          # the ties rule was exercised


def test_save_load_round_trip_keeps_attributes(tmp_path, hierarchy):
    path = save_hierarchy(hierarchy, tmp_path / "h.npz")
    back = load_hierarchy(path)
    assert set(back.points.attributes) == set(hierarchy.points.attributes)
    for name, values in hierarchy.points.attributes.items():
        np.testing.assert_array_equal(back.points.attributes[name], values)
        np.testing.assert_array_equal(back.node_attributes[name], hierarchy.node_attributes[name])
        assert back.points.attributes[name].dtype == values.dtype
    assert back.describe()["attributes"]["classification"] == "uint8"


def rewrite_without(path, out, drop):
    with np.load(path) as data:
        members = {k: data[k] for k in data.files if not drop(k)}
    np.savez(out, **members)


def test_old_file_without_attributes_loads(tmp_path, hierarchy):
    path = save_hierarchy(hierarchy, tmp_path / "h.npz")
    rewrite_without(path, tmp_path / "old.npz", lambda k: "attribute:" in k)
    with zipfile.ZipFile(tmp_path / "old.npz") as z:
        assert not any("attribute" in name for name in z.namelist())
    old = load_hierarchy(tmp_path / "old.npz")
    assert old.points.attributes is None and old.node_attributes is None
    np.testing.assert_array_equal(old.node_positions, hierarchy.node_positions)
    with pytest.raises(InputError, match="no attribute 'classification'.*available: elevation$"):
        load_model(tmp_path / "old.npz", SourceOptions(color=ColorOptions("classification")))


def test_attribute_for_points_only_is_refused(tmp_path, hierarchy):
    path = save_hierarchy(hierarchy, tmp_path / "h.npz")
    rewrite_without(path, tmp_path / "bad.npz", lambda k: k == "node_attribute:gps_time")
    with pytest.raises(InputError, match=r"bad\.npz.*gps_time.*points or the nodes only"):
        load_hierarchy(tmp_path / "bad.npz")


def test_colorized_nodes_majority_class_or_mean_colour(hierarchy):
    palette = asprs_palette()
    by_class = hierarchy.colorized("classification")
    np.testing.assert_array_equal(by_class.node_colors, palette[hierarchy.node_attributes["classification"]])
    np.testing.assert_array_equal(by_class.points.colors, palette[hierarchy.points.attributes["classification"]])
    assert hierarchy.points.colors is None      # the original is untouched
    smooth = hierarchy.colorized("gps_time", "viridis")
    for k in (0, 7, len(hierarchy) - 1):
        np.testing.assert_allclose(smooth.node_colors[k], smooth.points.colors[node_points(hierarchy, k)].mean(axis=0),
                                   atol=1e-5)
    with pytest.raises(InputError, match="no attribute 'nope'.*available: elevation, reflectance"):
        hierarchy.colorized("nope")


# -- CLI: build a LAS file, render the hierarchy coloured by class ---------------------------


def write_blocks_las(path, n=48, block=3):
    """A flat n x n grid (z up) whose classes (ground 2, building 6, water 9) change every
    ``block`` points: coarse nodes hold several classes."""
    laspy = pytest.importorskip("laspy")
    x, y = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64), indexing="ij")
    classes = np.array([2, 6, 9], dtype=np.uint8)[((x // block) + 2 * (y // block)).astype(int).ravel() % 3]
    las = laspy.create(point_format=3, file_version="1.4")
    las.header.scales = np.array([0.001, 0.001, 0.001])
    las.header.offsets = np.zeros(3)
    las.x, las.y, las.z = x.ravel(), y.ravel(), 0.01 * np.sin(x.ravel())
    las.classification = classes
    las.write(str(path))
    return classes


def palette_fraction(png, classes) -> float:
    """Fraction of the non-background pixels within 2/255 of a class's palette colour."""
    image = np.asarray(Image.open(png).convert("RGB")).reshape(-1, 3).astype(np.int64)
    image = image[(image != 255).any(axis=1)]
    assert len(image) > 2000
    colors = np.array([ASPRS_CLASSES[int(c)][1] for c in np.unique(classes)])
    distance = np.abs(image[:, None, :] - colors[None]).max(axis=2).min(axis=1)
    return float((distance <= 2).mean())


@pytest.mark.gl
def test_cli_build_then_render_colored_by_classification(tmp_path, capsys):
    classes = write_blocks_las(tmp_path / "scan.las")
    model = tmp_path / "model.npz"
    assert main(["build", str(tmp_path / "scan.las"), "-o", str(model), "-q"]) == 0
    assert main(["info", str(model)]) == 0
    text = capsys.readouterr().out
    assert "attribute:  classification (uint8): 2 .. 9; nodes: majority vote" in text
    common = ["--color-by", "classification", "--technique", "flat", "--no-lighting", "--width", "160",
              "--height", "160", "-q"]
    fine, coarse = tmp_path / "fine.png", tmp_path / "coarse.png"
    assert main(["render", str(model), "-o", str(fine), "--lod-tolerance", "0"] + common) == 0
    assert main(["render", str(model), "-o", str(coarse), "--lod-tolerance", "40"] + common) == 0
    assert palette_fraction(fine, classes) > 0.99
    assert palette_fraction(coarse, classes) > 0.99
    # the coarse picture draws mixed nodes (their mean colour would be a blend), and differs
    h = load_hierarchy(model)
    cut = uniform_cut(h, 40)
    mixed = [k for k in cut if len(np.unique(h.points.attributes["classification"][node_points(h, k)])) > 1]
    assert len(mixed) > len(cut) // 2
    a = np.asarray(Image.open(fine).convert("RGB"), dtype=np.float64)
    b = np.asarray(Image.open(coarse).convert("RGB"), dtype=np.float64)
    assert np.abs(a - b).max(axis=2).mean() > 5
