"""Per-point attributes (LAS dimensions, extra PLY properties) and colour by attribute."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from surfsplat import SplatCloud
from surfsplat.api import load_model
from surfsplat.colors import ColorOptions
from surfsplat.pipeline import SourceOptions
from surfsplat.cli import main
from surfsplat.colors import ASPRS_CLASSES, colorize
from surfsplat.errors import InputError
from surfsplat.geometry.preprocess import preprocess
from surfsplat.io import load, save_ply


def grid(n: int = 12) -> np.ndarray:
    """A gently sloped (N, 3) grid in the x-y plane, rising along x (z up)."""
    x, y = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64), indexing="ij")
    return np.column_stack([x.ravel(), y.ravel(), 0.2 * x.ravel()])


def write_las(path, xyz, *, point_format=3, laz=False):
    laspy = pytest.importorskip("laspy")
    las = laspy.create(point_format=point_format, file_version="1.4")
    las.add_extra_dim(laspy.ExtraBytesParams(name="reflectance", type=np.float32))
    las.header.scales = np.array([0.001, 0.001, 0.001])
    las.header.offsets = np.zeros(3)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    n = len(xyz)
    las.intensity = (np.arange(n) * 100 % 65536).astype(np.uint16)
    las.classification = np.where(np.arange(n) % 2 == 0, 2, 6).astype(np.uint8)
    las.return_number = (np.arange(n) % 3 + 1).astype(np.uint8)
    las.number_of_returns = np.full(n, 3, dtype=np.uint8)
    las.gps_time = np.linspace(1000.0, 2000.0, n)
    las.reflectance = np.linspace(-5.0, 5.0, n).astype(np.float32)
    las.write(str(path))
    return las


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_las_dimensions_become_attributes(tmp_path, suffix):
    if suffix == ".laz":
        pytest.importorskip("lazrs")
    xyz = grid(5)
    write_las(tmp_path / f"a{suffix}", xyz)
    cloud = load(tmp_path / f"a{suffix}")
    attrs = cloud.attributes
    assert {"intensity", "classification", "return_number", "number_of_returns", "gps_time",
            "reflectance"} <= set(attrs)
    assert not {"X", "x", "red", "green", "blue"} & set(attrs)
    n = len(xyz)
    np.testing.assert_array_equal(attrs["intensity"], np.arange(n) * 100)
    assert attrs["intensity"].dtype == np.uint16
    np.testing.assert_array_equal(attrs["classification"], np.where(np.arange(n) % 2 == 0, 2, 6))
    np.testing.assert_array_equal(attrs["return_number"], np.arange(n) % 3 + 1)
    np.testing.assert_allclose(attrs["gps_time"], np.linspace(1000.0, 2000.0, n))
    np.testing.assert_allclose(attrs["reflectance"], np.linspace(-5, 5, n), rtol=1e-6)


def test_ply_extra_properties_round_trip(tmp_path):
    from plyfile import PlyData, PlyElement
    n = 10
    data = np.zeros(n, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("confidence", "f4"), ("intensity", "u2"),
                              ("label", "i4")])
    data["x"] = np.arange(n)
    data["confidence"] = np.linspace(0, 1, n)
    data["intensity"] = np.arange(n) * 7
    data["label"] = -np.arange(n)
    PlyData([PlyElement.describe(data, "vertex")]).write(str(tmp_path / "a.ply"))
    cloud = load(tmp_path / "a.ply")
    assert set(cloud.attributes) == {"confidence", "intensity", "label"}
    assert cloud.attributes["intensity"].dtype == np.uint16
    for binary in (True, False):
        out = save_ply(cloud, tmp_path / f"b{binary}.ply", binary=binary)
        back = load(out)
        for name in ("confidence", "intensity", "label"):
            np.testing.assert_array_equal(back.attributes[name], cloud.attributes[name])
            assert back.attributes[name].dtype == cloud.attributes[name].dtype


def test_attributes_are_validated_and_follow_subset():
    cloud = SplatCloud(np.zeros((4, 3)), attributes={"a": np.arange(4), "flag": np.array([True, False] * 2)})
    assert cloud.attributes["flag"].dtype == np.uint8
    np.testing.assert_array_equal(cloud.subset(np.array([3, 1])).attributes["a"], [3, 1])
    np.testing.assert_array_equal(cloud.subset(np.array([True, False, True, False])).attributes["a"], [0, 2])
    assert cloud.replace(colors=np.zeros((4, 3))).attributes["a"] is not None
    with pytest.raises(InputError, match="attribute 'b'"):
        SplatCloud(np.zeros((4, 3)), attributes={"b": np.arange(3)})
    with pytest.raises(InputError, match="numeric"):
        SplatCloud(np.zeros((2, 3)), attributes={"s": np.array(["a", "b"])})
    positions = np.zeros((3, 3))
    positions[1, 0] = np.nan
    with pytest.warns(UserWarning):
        valid = SplatCloud(positions, attributes={"a": np.array([5, 6, 7])}).validated()
    np.testing.assert_array_equal(valid.attributes["a"], [5, 7])


def test_attributes_survive_preprocess_with_outlier_and_duplicate():
    pts = grid(12)
    n = len(pts)
    outlier = np.array([[100.0, 100.0, 100.0]])
    duplicate = pts[5:6]          # the same position as row 5: merged into it
    positions = np.vstack([pts, outlier, duplicate])
    ident = np.arange(len(positions))
    cloud = SplatCloud(positions, attributes={"id": ident, "score": ident.astype(np.float32) * 0.5})
    out, report = preprocess(cloud, k=8, return_report=True)
    assert report.duplicates == 1
    assert len(out) == n
    np.testing.assert_array_equal(out.attributes["id"], report.kept)
    np.testing.assert_array_equal(out.attributes["id"], np.arange(n))   # the first of the pair kept, outlier gone
    np.testing.assert_allclose(out.attributes["score"], np.arange(n) * 0.5)


def test_colorize_elevation_is_monotone_on_a_ramp():
    pytest.importorskip("matplotlib")
    z = np.linspace(0.0, 10.0, 50)
    cloud = SplatCloud(np.column_stack([np.zeros(50), np.zeros(50), z]))
    colored = colorize(cloud, "elevation", "viridis", (0.0, 10.0), up=(0, 0, 1))
    # viridis goes from dark to bright: luminance rises monotonically along the ramp
    lum = colored.colors @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    assert np.all(np.diff(lum) > 0)
    # the robust default range: the ends clamp to the first and last colours
    auto = colorize(cloud, "elevation", "viridis", up=(0, 0, 1))
    np.testing.assert_allclose(auto.colors[0], auto.colors[1])
    np.testing.assert_allclose(auto.colors[-1], auto.colors[-2])
    # up +y: elevation of this ramp is constant
    flat = colorize(cloud, "elevation", "viridis", (0.0, 1.0), up=(0, 1, 0))
    assert np.ptp(flat.colors, axis=0).max() == 0


def test_classification_uses_the_asprs_palette():
    codes = np.array([2, 5, 6, 9, 200], dtype=np.uint8)
    cloud = SplatCloud(np.zeros((5, 3)), attributes={"classification": codes})
    colored = colorize(cloud, "classification")
    for row, code in enumerate(codes[:4]):
        np.testing.assert_allclose(colored.colors[row], np.array(ASPRS_CLASSES[int(code)][1]) / 255, atol=1e-6)
    np.testing.assert_allclose(colored.colors[4], np.array([128, 128, 128]) / 255, atol=1e-6)
    assert cloud.colors is None   # a pure function


def test_unknown_attribute_lists_the_available_ones():
    cloud = SplatCloud(np.zeros((2, 3)), attributes={"intensity": np.array([1, 2])})
    with pytest.raises(InputError, match=r"no attribute 'height'.*elevation, intensity"):
        colorize(cloud, "height")
    assert colorize(cloud, "INTENSITY", "asprs").colors.shape == (2, 3)   # names ignore case


def test_missing_matplotlib_names_the_extra(monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    cloud = SplatCloud(np.zeros((2, 3)), attributes={"intensity": np.array([1, 2])})
    with pytest.raises(InputError, match=r"matplotlib.*\[color\]"):
        colorize(cloud, "intensity")


def test_bad_color_range_and_api_threading(tmp_path):
    with pytest.raises(InputError, match="LO < HI"):
        ColorOptions("intensity", value_range=(5, 1))
    write_las(tmp_path / "c.las", grid(10))
    model = load_model(tmp_path / "c.las", SourceOptions(color=ColorOptions("classification")))
    ground = model.attributes["classification"] == 2
    np.testing.assert_allclose(model.colors[ground][0], np.array(ASPRS_CLASSES[2][1]) / 255, atol=1e-6)


@pytest.mark.gl
def test_cli_render_las_colored_by_intensity(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    write_las(tmp_path / "scan.las", grid(16))
    out = tmp_path / "scan.png"
    status = main(["render", str(tmp_path / "scan.las"), "-o", str(out), "--width", "96", "--height", "72",
                   "--color-by", "intensity", "--colormap", "turbo"])
    assert status == 0, capsys.readouterr().err
    image = np.asarray(Image.open(out).convert("RGB"), dtype=np.float64)
    assert image.std(axis=(0, 1)).max() > 5       # not one flat colour
    assert main(["info", str(tmp_path / "scan.las")]) == 0
    text = capsys.readouterr().out
    assert "attribute:  intensity (uint16): 0 .. 25500" in text
    assert main(["render", str(tmp_path / "scan.las"), "-o", str(out), "--force", "--color-by", "nope"]) != 0
    assert "available: elevation, intensity" in capsys.readouterr().err
