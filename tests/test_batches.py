"""Draw batches (Renderer._batch_drawn): each handed to the driver by a glFlush, every FINISH_EVERY-th
waited for by a glFinish; where no glFlush is found, every batch is waited for. The frames are the same
whichever way the batches are synchronized."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import frame_bounds
from surfsplat.lighting import Lights
from surfsplat.rendering import context
from surfsplat.rendering import renderer as renderer_module
from surfsplat.rendering.options import RenderOptions
from surfsplat.rendering.renderer import Renderer

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): renderers of their own on the headless context


@pytest.fixture
def finishes(monkeypatch):
    """The glFinish calls made while drawing batches (a list with one entry per call)."""
    calls = []
    original = Renderer._batch_drawn

    def counted(self):
        before = self._unfinished
        original(self)
        if self._unfinished == 0:
            calls.append(before + 1)

    monkeypatch.setattr(Renderer, "_batch_drawn", counted)
    return calls


@pytest.mark.parametrize("technique", ["ewa", "flat"])
def test_finish_every_few_batches_same_frames(finishes, monkeypatch, technique):
    cloud = scenes.torus(200, 60)   # 12,000 splats
    camera = frame_bounds(*cloud.bounds(), width=64, height=48, direction=(0.3, -0.8, 0.6))
    renderer = Renderer(draw_batch=500)   # 24 batches per pass
    options = replace(RenderOptions(), compute=False)
    try:
        gpu = renderer.upload(cloud)
        monkeypatch.setattr(renderer_module, "FINISH_EVERY", 1)
        every = renderer.render(gpu, camera, technique, Lights(), options)
        assert finishes and set(finishes) == {1}
        finishes.clear()
        monkeypatch.setattr(renderer_module, "FINISH_EVERY", 4)
        fourth = renderer.render(gpu, camera, technique, Lights(), options)
        assert finishes and max(finishes) == 4 and len(finishes) < 0.4 * 24 * 2
        finishes.clear()
        monkeypatch.setattr(context, "_gl_flush", False)   # no OpenGL library with glFlush
        waited = renderer.render(gpu, camera, technique, Lights(), options)
        assert finishes and set(finishes) == {1}
        gpu.release()
    finally:
        renderer.release()
    assert every.alpha.sum() > 100
    for frame in (fourth, waited):
        assert np.array_equal(frame.color, every.color)
        assert np.array_equal(np.nan_to_num(frame.depth, nan=-1.0), np.nan_to_num(every.depth, nan=-1.0))


def test_gl_flush_is_found_here():
    """The test machine's GLVND libGL exports glFlush (the fallback is tested above)."""
    context._gl_flush = None
    assert context.gl_flush() is True
