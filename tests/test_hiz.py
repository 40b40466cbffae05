"""The accumulation pass's occlusion test of whole splats (``passes.HizPass``, ``hiz.frag``, ``hiz.glsl``):
the blocks' farthest visible depths against NumPy, and frames drawn with the test equal to those drawn
without it, bit for bit (a splat it drops is one each of whose fragments the per-fragment depth test
discards)."""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import Camera
from surfsplat.lighting import Lights
from surfsplat.rendering import passes
from surfsplat.rendering.options import RenderOptions, VisibilityOptions
from surfsplat.rendering.shaders import FILL_FAR
from surfsplat.rendering.techniques import TECHNIQUES

HIZ_TECHNIQUES = sorted(name for name, technique in TECHNIQUES.items() if technique.hiz_cull)
#: Opaque techniques whose second compute pass skips splats behind the first one's depths (ComputeOpaquePass)
OPAQUE_HIZ = sorted(name for name, technique in TECHNIQUES.items() if technique.compute_opaque)


def splats_tested(plan) -> bool:
    """Whether a frame's plan tests whole splats against blocks' farthest depths."""
    opaque = plan.get("compute_opaque")
    return plan.get("hiz") is not None or (opaque is not None and opaque.hiz_block > 0)
SIDE_NONE, SIDE_CRACK = 0.5, 0.375   # visibility.glsl


@pytest.fixture(scope="module")
def torus():
    return scenes.torus(400, 100)   # 40,000 splats: the far side of the ring lies behind the near one


def oblique(cloud, width=160, height=120):
    """From above the ring, tilted: the near side of the tube hides part of its far side and of the
    ring behind it; the back faces are drawn (not culled) and hidden."""
    camera = Camera(eye=(0.3, -2.6, 1.5), target=(0.0, 0.0, 0.0), up=(0, 0, 1), fov=40, width=width, height=height)
    return camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))


OPTIONS = RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))


def frames_equal(a, b) -> None:
    for name in ("color", "depth", "weight", "alpha"):
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(np.nan_to_num(x, nan=-7.0), np.nan_to_num(y, nan=-7.0)), name


def test_blocks_hold_the_farthest_visible_depth(gl_renderer, torus):
    """The hiz target after a frame: per 8 x 8 block of the record, the largest offset depth of its
    covered pixels, FILL_FAR where a pixel has no disk (or is a crack); partial blocks at the borders."""
    camera = oblique(torus, 150, 100)   # 150 x 100: the last blocks are 6 and 4 pixels
    gl_renderer.render(torus, camera, "ewa", Lights(), OPTIONS)
    targets = gl_renderer._targets
    record = np.empty(targets["cracks"].size[::-1] + (2,), "f4")
    targets["cracks"].read_into(record)
    hiz = np.empty(targets["hiz"].size[::-1], "f4")
    targets["hiz"].read_into(hiz)
    block = passes.HIZ_BLOCK
    height, width = record.shape[:2]
    covered = np.abs(record[..., 0] - SIDE_NONE) > 0.25
    depth = np.where(covered, record[..., 1], np.float32(FILL_FAR))
    padded = np.zeros((hiz.shape[0] * block, hiz.shape[1] * block), "f4")   # the rows and columns past the edge: 0
    padded[:height, :width] = depth
    expected = padded.reshape(hiz.shape[0], block, hiz.shape[1], block).max(axis=(1, 3))
    assert hiz.shape == (-(-height // block), -(-width // block))
    np.testing.assert_array_equal(hiz, expected)
    inner = expected < FILL_FAR
    assert inner.sum() > 20 and (~inner).sum() > 20   # blocks inside the surface and at its border


@pytest.mark.parametrize("technique", HIZ_TECHNIQUES + OPAQUE_HIZ)
def test_frames_equal_those_without_the_test(gl_renderer, torus, monkeypatch, technique):
    """Every technique that declares the test (and "flat", whose second compute pass tests its splats
    against the first one's depths), with edge coverage where it has it, supersampled in tiles (each tile's
    blocks start at its own corner) and not: the same frame bit for bit as with no hiz pass."""
    camera = oblique(torus)
    edges = TECHNIQUES[technique].edge_coverage
    cases = [(OPTIONS, 1, 4096),
             (RenderOptions(visibility=VisibilityOptions(cull_backfaces=False, edge_coverage=edges)), 2, 136)]
    gpu = gl_renderer.upload(torus)
    try:
        for options, k, max_tile in cases:
            with_test = gl_renderer.render(gpu, camera, technique, Lights(), options, supersample=k, max_tile=max_tile)
            assert splats_tested(gl_renderer.plan(gpu, camera, technique, options))
            monkeypatch.setattr(passes, "HIZ_BLOCK", 0)
            assert not splats_tested(gl_renderer.plan(gpu, camera, technique, options))
            without = gl_renderer.render(gpu, camera, technique, Lights(), options, supersample=k, max_tile=max_tile)
            monkeypatch.undo()
            assert with_test.alpha.mean() > 0.2
            frames_equal(with_test, without)
    finally:
        gpu.release()
