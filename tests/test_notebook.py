"""The Jupyter orbit widget (surfsplat.notebook) without a browser, and the example notebook run by nbclient."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import surfsplat
from surfsplat.api import orbit_cameras
from surfsplat.errors import InputError
from surfsplat.notebook import Orbit, orbit_camera
from surfsplat.scenes import sphere

#: Why the tests that open the widget skip without ipywidgets (the camera math and the committed
#: notebook's check run without it).
IPYWIDGETS_NEEDED = "the notebook widget needs ipywidgets (the notebook extra)"

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "quickstart.ipynb"
RED, BLUE = (0.9, 0.1, 0.1), (0.1, 0.1, 0.9)
#: Looking down -z at two spheres: red at x = +0.7, blue at x = -0.7.
START = surfsplat.Camera(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=40.0, width=96,
                         height=64)


@pytest.fixture(scope="module")
def two_spheres() -> surfsplat.SplatCloud:
    red, blue = sphere(3000, 0.3, (0.7, 0.0, 0.0), RED), sphere(3000, 0.3, (-0.7, 0.0, 0.0), BLUE)
    return surfsplat.SplatCloud(np.concatenate([red.positions, blue.positions]),
                                np.concatenate([red.normals, blue.normals]),
                                np.concatenate([red.colors, blue.colors]),
                                np.concatenate([red.u, blue.u]), np.concatenate([red.v, blue.v]))


@pytest.fixture(scope="module")
def view(two_spheres):
    pytest.importorskip("ipywidgets", reason=IPYWIDGETS_NEEDED)
    return Orbit(two_spheres, START, technique="flat", width=96, height=64)


def pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def masks(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels showing the red and the blue sphere (lit: the hue, not the exact color)."""
    r, b = image[..., 0], image[..., 2]
    return r > b + 60, b > r + 60


def center_x(mask: np.ndarray) -> float:
    return float(np.nonzero(mask)[1].mean())


def test_orbit_camera_matches_the_turntable_cameras():
    base = surfsplat.Camera(eye=(1.0, 0.5, 3.0), target=(0.1, 0.2, -0.3), up=(0.0, 1.0, 0.0), width=32, height=32)
    elevation = float(np.degrees(np.arcsin(0.3 / np.linalg.norm([0.9, 0.3, 3.3]))))
    for k, turned in enumerate(orbit_cameras(base, 8)):
        camera = orbit_camera(base, 45.0 * k, elevation, 1.0)
        np.testing.assert_allclose(camera.eye, turned.eye, atol=1e-12)
    zoomed = orbit_camera(base, 0.0, elevation, 4.0)
    np.testing.assert_allclose(np.subtract(zoomed.eye, base.target), np.subtract(base.eye, base.target) / 4.0,
                               atol=1e-12)
    high = orbit_camera(base, 0.0, 60.0, 1.0)
    offset = np.subtract(high.eye, high.target)
    assert offset[1] / np.linalg.norm(offset) == pytest.approx(np.sin(np.radians(60.0)))
    with pytest.raises(InputError, match="elevation within -89..89"):
        orbit_camera(base, 0.0, 90.0, 1.0)


@pytest.mark.gl
def test_starting_view_is_the_given_camera(view):
    assert view.azimuth.value == 0 and view.zoom.value == 1 and view.elevation.value == 0
    image = pixels(view.image.value)
    assert image.shape == (64, 96, 3)
    expected = surfsplat.render(view.view.sample().data, view.camera(), technique="flat").image()
    np.testing.assert_array_equal(image, expected)
    red, blue = masks(image)
    assert red.sum() > 100 and blue.sum() > 100
    assert center_x(red) > 48 > center_x(blue)   # red at +x on the right


@pytest.mark.gl
def test_sliders_stream_new_views(view):
    before = view.image.value
    view.azimuth.value = 180.0   # from behind: the spheres swap sides
    after = pixels(view.image.value)
    assert view.image.value != before
    red, blue = masks(after)
    assert center_x(red) < 48 < center_x(blue)
    np.testing.assert_array_equal(after, surfsplat.render(view.view.sample().data, view.camera(),
                                                          technique="flat").image())

    view.azimuth.value = 90.0    # from +x: the red sphere in front hides the blue one, both centered
    red, blue = masks(pixels(view.image.value))
    assert blue.sum() == 0 and abs(center_x(red) - 47.5) < 1.0
    area = red.sum()
    view.zoom.value = 2.0        # half the eye's distance to the target: 3.3 -> 1.3 to the sphere's center
    red, _ = masks(pixels(view.image.value))
    # a sphere of radius r at distance D on the axis images as a disk of radius f r / sqrt(D^2 - r^2)
    expected = np.sqrt(3.3 ** 2 - 0.3 ** 2) / np.sqrt(1.3 ** 2 - 0.3 ** 2)
    assert np.sqrt(red.sum() / area) == pytest.approx(expected, rel=0.08)

    view.technique.value = "ewa"
    assert view.status.value.startswith("ewa: 6,000 splats")
    np.testing.assert_array_equal(pixels(view.image.value),
                                  surfsplat.render(view.view.sample().data, view.camera(), technique="ewa").image())
    view.elevation.value = 80.0  # from above, the red sphere still in the middle
    red, blue = masks(pixels(view.image.value))
    assert abs(center_x(red) - 47.5) < 1.5
    bundle = view._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in bundle


def test_missing_ipywidgets_names_the_extra(two_spheres, monkeypatch):
    monkeypatch.setitem(sys.modules, "ipywidgets", None)
    with pytest.raises(InputError, match=r"needs ipywidgets.*\.\[notebook\]"):
        Orbit(two_spheres, START)


def test_example_notebook_is_committed_without_outputs():
    notebook = json.loads(EXAMPLE.read_text())
    code = [cell for cell in notebook["cells"] if cell["cell_type"] == "code"]
    assert code and all(cell["outputs"] == [] and cell["execution_count"] is None for cell in code)


@pytest.mark.gl
def test_example_notebook_runs(tmp_path):
    nbformat = pytest.importorskip("nbformat", reason="running the example notebook needs nbformat")
    nbclient = pytest.importorskip("nbclient", reason="running the example notebook needs nbclient")
    pytest.importorskip("ipykernel", reason="running the example notebook needs ipykernel")
    pytest.importorskip("ipywidgets", reason=IPYWIDGETS_NEEDED)
    notebook = nbformat.read(EXAMPLE, as_version=4)
    client = nbclient.NotebookClient(notebook, timeout=120, kernel_name="python3",
                                     resources={"metadata": {"path": str(EXAMPLE.parent)}})
    client.execute()
    outputs = [output for cell in notebook.cells if cell.cell_type == "code" for output in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 1                  # the demo Frame displayed inline
    assert any("application/vnd.jupyter.widget-view+json" in o.get("data", {}) for o in outputs)
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "orbit: azimuth 60" in text
