"""``surfsplat.render`` called again and again on one SplatCloud: prepared once, uploaded once, and a
cloud changed in place between two calls is drawn as it is now."""

from __future__ import annotations

import numpy as np
import pytest

import surfsplat
from surfsplat import api, scenes
from surfsplat.camera import Camera
from surfsplat.pipeline import SourceOptions
from surfsplat.rendering import renderer as renderer_module

pytestmark = pytest.mark.gl


def test_a_cloud_rendered_again_is_prepared_and_uploaded_once(monkeypatch):
    cloud = scenes.torus(160, 40)
    camera = Camera(eye=(0.0, -3.2, 2.4), target=(0.0, 0.0, 0.0), up=(0, 0, 1), fov=42, width=96, height=96)
    first = surfsplat.render(cloud, camera)
    view = api._last_view[3]
    uploads = []
    upload = renderer_module.Renderer.upload
    monkeypatch.setattr(renderer_module.Renderer, "upload", lambda self, c: uploads.append(1) or upload(self, c))
    again = surfsplat.render(cloud, camera)
    assert api._last_view[3] is view and uploads == []
    np.testing.assert_array_equal(first.color, again.color)
    # the same cloud with other source options: another view
    surfsplat.render(cloud, camera, source_options=SourceOptions(hybrid=True))
    assert api._last_view[3] is not view
    # changed in place: prepared and uploaded anew, drawn as it is now
    surfsplat.render(cloud, camera)
    view = api._last_view[3]
    uploads.clear()
    cloud.positions[:, 0] += np.float32(0.5)
    moved = surfsplat.render(cloud, camera)
    assert api._last_view[3] is not view and len(uploads) == 1
    fresh = surfsplat.render(scenes.torus(160, 40).subset(np.arange(len(cloud))), camera)   # another object
    assert not np.array_equal(moved.color, first.color)
    assert not np.array_equal(fresh.color, moved.color)
    shifted = scenes.torus(160, 40)
    shifted.positions[:, 0] += np.float32(0.5)
    np.testing.assert_array_equal(surfsplat.render(shifted, camera).color, moved.color)
