"""Back-facing blocks (GpuSplats.facing_blocks): where a frame culls back faces, the blocks of 4,096
consecutive splats whose every splat the shaders would cull are not drawn at all.

Each block's cone of normals and its centers' box decide (block_cones: Pajarola 2003's normal cones, per
block of the upload's order: radius classes, each in Morton order). Checked against NumPy (every splat of
a dropped block faces away by the shaders' own test, splat_vertex.glsl) and against the frames drawn
without the test (identical, bit for bit).
"""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import scenes
from surfsplat.camera import Camera
from surfsplat.lighting import Lights
from surfsplat.rendering.gpu_splats import BLOCK
from surfsplat.rendering.options import RenderOptions, VisibilityOptions
from surfsplat.rendering.renderer import Renderer
from surfsplat.rendering.techniques import get_technique

CULL = RenderOptions(visibility=VisibilityOptions(cull_backfaces=True))


@pytest.fixture(scope="module")
def sphere():
    return scenes.sphere(200_000)   # 49 blocks, outward normals


def views(cloud):
    """A distant view and a close one, both from outside."""
    cams = [Camera(eye=(0.3, -4.0, 2.5), target=(0, 0, 0), up=(0, 0, 1), fov=40, width=96, height=80),
            Camera(eye=(1.6, 0.4, -0.9), target=(0, 0, 0), up=(0, 0, 1), fov=70, width=96, height=80)]
    return [c.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max())) for c in cams]


def test_dropped_blocks_hold_only_back_facing_splats(gl_renderer, sphere):
    """NumPy: every splat of a block facing_blocks drops has its plane normal and its shading normal
    facing away from the eye (what the shaders cull); some of a smooth sphere's blocks go from outside."""
    gpu = gl_renderer.upload(sphere)
    try:
        position, normal, u, v = (np.frombuffer(gpu.buffers[k].read(), "f4").reshape(-1, 3).astype(np.float64)
                                  for k in ("position", "normal", "u", "v"))
        for camera in views(sphere):
            camera = gpu.gpu_camera(camera)
            facing = gpu.facing_blocks(camera)
            assert 0.1 < np.mean(~facing) < 0.5   # a smooth surface: blocks span a few cells of normals
            dropped = np.concatenate([np.arange(b * BLOCK, min((b + 1) * BLOCK, gpu.count))
                                      for b in np.flatnonzero(~facing)])
            to_eye = np.asarray(camera.eye) - position[dropped]
            plane = np.cross(u[dropped], v[dropped])
            plane *= np.sign(np.einsum("ij,ij->i", plane, normal[dropped]))[:, None]
            assert (np.einsum("ij,ij->i", plane, to_eye) < 0).all()
            assert (np.einsum("ij,ij->i", normal[dropped], to_eye) < 0).all()
    finally:
        gpu.release()


@pytest.mark.parametrize("technique", ("ewa", "perspective", "blend", "flat", "points"))
def test_frames_with_back_blocks_dropped_equal_the_full_draw(gl_renderer, sphere, technique):
    """The same frame bit for bit with the back-facing blocks dropped and without the test (no cones)."""
    gpu = gl_renderer.upload(sphere)
    try:
        for camera in views(sphere):
            culled = gl_renderer.render(gpu, camera, technique, Lights(), CULL)
            cones, gpu.cones = gpu.cones, None
            full = gl_renderer.render(gpu, camera, technique, Lights(), CULL)
            gpu.cones = cones
            assert full.alpha.sum() > 0.1 * full.alpha.size
            for name in ("color", "depth", "weight", "alpha"):
                a, b = getattr(full, name), getattr(culled, name)
                assert np.array_equal(np.nan_to_num(a, nan=-7.0), np.nan_to_num(b, nan=-7.0)), name
    finally:
        gpu.release()


def test_no_block_is_dropped_without_culling_or_with_a_normal_field(gl_renderer, sphere):
    """Frames that keep back faces draw every block; splats with a linear normal field (Phong splats,
    which the shaders keep by more than their normals) get no cones."""
    gpu = gl_renderer.upload(sphere)
    try:
        camera = gpu.gpu_camera(views(sphere)[0])
        keep = RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))
        quads, points = Renderer._drawn_ranges(gl_renderer, gpu, camera, get_technique("ewa"), keep, 1)
        assert sum(n for _, n in quads + points) == len(sphere)
    finally:
        gpu.release()
    field = sphere.replace(normal_field=np.zeros((len(sphere), 2), np.float32))
    gpu = gl_renderer.upload(field)
    try:
        assert gpu.cones is None and gpu.facing_blocks(gpu.gpu_camera(views(sphere)[0])) is None
    finally:
        gpu.release()
