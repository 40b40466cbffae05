"""Eye-dome lighting (Boucheny 2009; render/edl.py) against a per-pixel reference and on procedural scenes."""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat.camera import Camera
from surfsplat.cli import build_parser
from surfsplat.cli.options import render_options
from surfsplat.cloud import SplatCloud
from surfsplat.errors import InputError
from surfsplat.rendering.edl import eye_dome_shade, neighbour_offsets, obscurance
from surfsplat.rendering.options import EdlOptions, RenderOptions

EDL = RenderOptions(edl=EdlOptions())
CAMERA = Camera(eye=(0.0, 0.0, 4.0), target=(0, 0, 0), width=80, height=64, fov=30, near=1.0, far=10.0)
BACKGROUND = (1.0, 1.0, 1.0)


def plane(x0, x1, y0, y1, z, spacing=0.02) -> SplatCloud:
    """A grid of disks facing the camera (+z), overlapping (radius = spacing)."""
    xs, ys = np.meshgrid(np.arange(x0, x1 + 1e-9, spacing), np.arange(y0, y1 + 1e-9, spacing))
    pos = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)
    n = len(pos)
    return SplatCloud.from_arrays(pos, np.tile([0.0, 0.0, 1.0], (n, 1)), np.full((n, 3), 0.7),
                                  radius=np.full(n, spacing))


def step_scene() -> SplatCloud:
    """A near plane (z = 0.5) over the left half of a far one (z = 0): a vertical depth step."""
    near, far = plane(-1.0, 0.0, -0.6, 0.6, 0.5), plane(-0.3, 1.0, -0.6, 0.6, 0.0)
    return SplatCloud(*(np.concatenate([getattr(near, k), getattr(far, k)]) for k in
                        ("positions", "normals", "colors", "u", "v")))


def naive_obscurance(depth, radius):
    """Per pixel, the paper's sum over the 8 neighbours, background (inf) and outside the image as far."""
    h, w = depth.shape
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            if not np.isfinite(depth[y, x]):
                continue
            for dx, dy in neighbour_offsets(radius):
                yy, xx = y + dy, x + dx
                if 0 <= yy < h and 0 <= xx < w and np.isfinite(depth[yy, xx]):
                    out[y, x] += max(0.0, np.log2(float(depth[y, x])) - np.log2(float(depth[yy, xx])))
    return out


def test_neighbour_offsets():
    assert sorted(neighbour_offsets(1.4)) == sorted([(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1),
                                                     (1, -1)])
    assert (3, 0) in neighbour_offsets(3.0) and (2, 2) in neighbour_offsets(3.0)


@pytest.mark.parametrize("radius", [1.0, 1.4, 3.0])
def test_obscurance_matches_per_pixel_reference(radius):
    rng = np.random.default_rng(int(radius * 10))
    depth = rng.uniform(2.0, 5.0, (20, 23)).astype("f4")
    depth[rng.uniform(size=depth.shape) < 0.2] = np.inf
    np.testing.assert_allclose(obscurance(depth, radius), naive_obscurance(depth, radius), rtol=1e-10, atol=1e-12)


def test_synthetic_step_darkens_the_far_side_only():
    """A straight step: the far column next to the near edge gets exp(-s 3 log2(z_far / z_near)) (its 3
    left neighbours are near), every other pixel 1: the near side does not darken (max(0, .) = 0)."""
    z_near, z_far = 3.5, 4.0
    depth = np.full((10, 12), z_far, "f4")
    depth[:, :6] = z_near
    options = EdlOptions()
    shade = eye_dome_shade(depth, options)
    expected = np.ones_like(shade)
    expected[1:-1, 6] = np.exp(-options.strength * 3 * np.log2(z_far / z_near))
    expected[[0, -1], 6] = np.exp(-options.strength * 2 * np.log2(z_far / z_near))   # the image's edge
    np.testing.assert_allclose(shade, expected, rtol=1e-6)


@pytest.mark.parametrize("technique", ["flat", "ewa", "points"])
def test_rendered_step_edge(renderer, technique):
    """On a rendered step the EDL factor is the formula's on the Frame's depth; the darkened pixels are
    the far plane's, within the radius of the near plane's edge; the near side and background keep theirs."""
    cloud = step_scene()
    off = renderer.render(cloud, CAMERA, technique)
    on = renderer.render(cloud, CAMERA, technique, options=EDL)
    shade = np.exp(-EdlOptions().strength * naive_obscurance(off.depth, EdlOptions().radius_px))
    # the surface is shaded, not the background a rim pixel shows in part (edge coverage: alpha < 1)
    behind = np.asarray(BACKGROUND) * (1.0 - off.alpha[..., None])
    np.testing.assert_allclose(on.color, behind + (off.color - behind) * shade[..., None], atol=2e-6)
    dark = shade < 0.99
    assert dark.sum() >= CAMERA.height // 2
    assert np.all(off.depth[dark] > 3.9)                      # far side only (z = 4 against 3.5)
    near = off.depth < 3.6
    assert np.abs(on.color[near] - off.color[near]).max() < 1e-3   # ewa: weighted-depth noise only
    # the darkest far pixels have at least one near neighbour across the whole step
    assert shade.min() <= 1.01 * np.exp(-EdlOptions().strength * np.log2(4.0 / 3.5))


def test_flat_plane_does_not_darken_and_background_stays(renderer):
    cloud = plane(-0.5, 0.5, -0.4, 0.4, 0.0)
    off = renderer.render(cloud, CAMERA, "ewa", background=BACKGROUND)
    on = renderer.render(cloud, CAMERA, "ewa", options=EDL, background=BACKGROUND)
    covered = off.alpha > 0
    assert covered.any() and (~covered).any()
    np.testing.assert_allclose(on.color[covered], off.color[covered], rtol=0.01)
    np.testing.assert_array_equal(on.color[~covered], off.color[~covered])
    np.testing.assert_array_equal(on.color[~covered], np.broadcast_to(BACKGROUND, on.color[~covered].shape))


def test_edl_off_leaves_pixels_identical(renderer):
    cloud = step_scene()
    default = renderer.render(cloud, CAMERA, "ewa")
    off = renderer.render(cloud, CAMERA, "ewa", options=RenderOptions(edl=None))
    for name in ("color", "depth", "weight", "alpha"):
        np.testing.assert_array_equal(getattr(off, name), getattr(default, name))


def test_edl_tiled_equals_untiled_and_supersampled(renderer):
    cloud = step_scene()
    whole = renderer.render(cloud, CAMERA, "flat", options=EDL, supersample=2)
    tiled = renderer.render(cloud, CAMERA, "flat", options=EDL, supersample=2, max_tile=32)
    np.testing.assert_array_equal(tiled.color, whole.color)
    # at the output resolution: the factor is the formula's on the output depth, background kept
    off = renderer.render(cloud, CAMERA, "flat", supersample=2)
    shade = eye_dome_shade(off.depth, EdlOptions())[..., None]
    behind = np.asarray(BACKGROUND) * (1 - off.alpha[..., None])
    np.testing.assert_allclose(whole.color, behind + (off.color - behind) * shade, atol=2e-6)


def test_edl_options_and_cli():
    with pytest.raises(InputError):
        EdlOptions(strength=0.0)
    with pytest.raises(InputError):
        EdlOptions(radius_px=0.5)
    with pytest.raises(InputError):
        RenderOptions(edl=1.0)
    parser = build_parser()
    args = parser.parse_args(["render", "in.ply", "-o", "out.png"])
    assert render_options(args).edl is None
    args = parser.parse_args(["render", "in.ply", "-o", "out.png", "--edl"])
    assert render_options(args).edl == EdlOptions()
    args = parser.parse_args(["render", "in.ply", "-o", "out.png", "--edl", "--edl-strength", "10",
                              "--edl-radius", "2"])
    assert render_options(args).edl == EdlOptions(strength=10.0, radius_px=2.0)
    with pytest.raises(SystemExit):
        parser.parse_args(["render", "in.ply", "-o", "out.png", "--edl-radius", "0.5"])
