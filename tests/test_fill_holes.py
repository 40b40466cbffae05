"""Screen-space hole filling (``RenderOptions.fill_holes``): the rule (:func:`surfsplat.reference.fill_holes`)
on analytic images, the fill pass (``fill.frag``) held against it, and rendered gaps, holes and silhouettes."""

from __future__ import annotations

import numpy as np
import pytest

from surfsplat import Camera, Lights, RenderOptions, SplatCloud, reference
from surfsplat.rendering.passes import FILL_DEPTH_PX, FILL_GAP_PX, FILL_ITERATIONS

UNLIT = Lights(enabled=False)
FILL = RenderOptions(fill_holes=True)
NO_FILL = RenderOptions(fill_holes=False)
F = 200.0   # focal length of the analytic images, pixels


def image(n: int = 32, depth: float = 2.0, color=(0.8, 0.2, 0.2)):
    """A covered n x n image of one surface at ``depth``: color, weight, depth, alpha."""
    return (np.broadcast_to(np.asarray(color, float), (n, n, 3)).copy(), np.ones((n, n)), np.full((n, n), depth),
            np.ones((n, n)))


def punch(img, mask, background=(1.0, 1.0, 1.0)):
    """The image with the pixels of ``mask`` uncovered (background color, no weight, depth inf, alpha 0)."""
    color, weight, depth, alpha = (a.copy() for a in img)
    color[mask], weight[mask], depth[mask], alpha[mask] = background, 0.0, np.inf, 0.0
    return color, weight, depth, alpha


def fill(img, iterations: int = FILL_ITERATIONS):
    return reference.fill_holes(*img, F, gap=FILL_GAP_PX, depth_px=FILL_DEPTH_PX, iterations=iterations)


@pytest.mark.parametrize("size", [1, 2, 3])
def test_a_gap_of_up_to_3_pixels_in_a_plane_is_filled_with_its_color_and_depth(size):
    plane = image()
    square, slit = np.zeros((32, 32), bool), np.zeros((32, 32), bool)
    square[10:10 + size, 12:12 + size] = True
    slit[12:21, 16:16 + size] = True   # a straight crack 9 px long: enclosed along 3 axes, and the 4th
    for mask in (square, slit):
        color, weight, depth, alpha, filled = fill(punch(plane, mask))
        assert (filled == mask).all()
        np.testing.assert_allclose(color, plane[0])
        np.testing.assert_allclose(depth, plane[2])
        assert (weight > 0).all() and (alpha == 1).all()


def test_a_slit_opening_into_the_background_stays_open():
    # two parts of one surface beside a slit 2 px wide that runs out to the background (a bay, the
    # jagged border of a scan): enclosed along 3 axes, open along the 4th
    mask = np.zeros((32, 32), bool)
    mask[:8, :] = True   # the background above the surface
    mask[8:20, 15:17] = True
    filled = fill(punch(image(), mask))[4]
    assert not filled.any()
    # the same slit closed off from the background by 4 rows of the surface is a crack (8 px long): filled
    closed = mask.copy()
    closed[8:12, 15:17] = False
    assert (fill(punch(image(), closed))[4] == (closed & (np.arange(32)[:, None] >= 8))).all()


def test_the_second_iteration_fills_what_the_first_one_encloses():
    mask = np.random.default_rng(1).random((32, 32)) < 0.3   # dense pinholes, some in clusters
    once, twice = (fill(punch(image(), mask), iterations=i)[4] for i in (1, 2))
    assert (once <= twice).all() and (twice <= mask).all() and twice.sum() > once.sum() + 5


def test_a_larger_hole_stays_a_hole():
    mask = np.zeros((32, 32), bool)
    mask[8:18, 8:18] = True   # 10 pixels
    color, weight, depth, alpha, filled = fill(punch(image(), mask))
    assert not filled.any() and (weight[mask] == 0).all()
    slit = np.zeros((32, 32), bool)
    slit[:, 14:18] = True   # 4 pixels wide
    assert not fill(punch(image(), slit))[4].any()


def test_a_silhouette_does_not_grow_but_its_inner_holes_close():
    n = 64
    y, x = np.mgrid[:n, :n] + 0.5
    r = np.hypot(x - 30.3, y - 33.1)
    rng = np.random.default_rng(0)
    outside = r > 20 + 1.5 * np.sin(7 * np.arctan2(y - 33.1, x - 30.3))   # a wavy rim
    holes = (r < 17) & (rng.random((n, n)) < 0.08)   # pinholes inside
    # a concave bay of the silhouette, 5 px wide and 8 deep, is not a gap (a crack 3 px wide or less
    # reaching the silhouette is, but for its last pixels)
    notch = (np.abs(x - 30.3) < 2.5) & (y > 45) & (y < 54)
    img = punch(image(n), outside | holes | notch)
    color, weight, depth, alpha, filled = fill(img)
    assert (weight[holes & ~notch] > 0).all()
    assert not filled[outside].any()
    assert (filled == (holes & ~outside & ~notch)).all()
    assert np.count_nonzero(weight > 0) == np.count_nonzero(~(outside | notch))


def test_a_gap_in_front_of_a_far_surface_takes_the_front_surface():
    front = image(depth=2.0, color=(0.9, 0.9, 0.1))
    far = image(depth=4.0, color=(0.1, 0.1, 0.9))
    mask = np.zeros((32, 32), bool)
    mask[12:14, 8:16] = True   # a 2 px crack of the front surface showing the far one
    img = tuple(np.where(mask[..., None] if a.ndim == 3 else mask, b, a) for a, b in zip(front, far))
    color, weight, depth, alpha, filled = fill(img)
    assert (filled == mask).all()
    np.testing.assert_allclose(color[mask], 0.9 * np.ones((mask.sum(), 1)) * [1, 1, 0] + [0, 0, 0.1])
    np.testing.assert_allclose(depth[mask], 2.0)
    # the far surface seen through a real hole (10 px) stays
    hole = np.zeros((32, 32), bool)
    hole[10:20, 10:20] = True
    img = tuple(np.where(hole[..., None] if a.ndim == 3 else hole, b, a) for a, b in zip(front, far))
    assert not fill(img)[4].any()


def test_a_valley_of_one_surface_and_a_step_are_left_alone():
    # a V-shaped groove, walls at 60 degrees to the image plane: its bottom is behind its walls, by less
    # than the tolerance
    n = 32
    x = np.arange(n) + 0.5
    z = 2.0 + np.tan(np.radians(60)) * (2.0 / F) * (6 - np.abs(x - 16)).clip(0)
    img = image(n)
    img = (img[0], img[1], np.broadcast_to(z, (n, n)).copy(), img[3])
    assert not fill(img)[4].any()
    # a step: a near surface beside a far one is never spread over it
    step = image(n)
    step[2][:, 16:] = 4.0
    assert not fill(step)[4].any()


# -- the fill pass on the GPU ---------------------------------------------------------------------------

CAMERA = Camera(eye=(0.0, 0.0, 3.0), target=(0, 0, 0), width=96, height=96, fov=20, near=0.5, far=10.0)
PIXEL = 2 * 3.0 * np.tan(np.radians(10)) / 96   # world size of a pixel on the plane z = 0


def slit_plane(gap: float, z: float = 0.0, color=0.8, spacing: float = 0.012,
               length: float = 8 * PIXEL) -> SplatCloud:
    """Splats on a grid of the plane at ``z`` (radius 0.75 spacing: no holes) cut by clip lines (Zwicker
    2004, sec. 5) at |x| = gap / 2 where |y| <= length / 2: a straight slit ``gap`` wide and about
    ``length`` long (less the unclipped splats' radius at its ends)."""
    g = np.arange(-0.5, 0.5, spacing)
    x, y = np.meshgrid(g, g)
    p = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
    rad = 0.75 * spacing
    cut = np.abs(p[:, 1]) <= length / 2
    keep = ~cut | (np.abs(p[:, 0]) >= gap / 2 - 0.999 * rad)
    p, cut = p[keep], cut[keep]
    k = len(p)
    sign = np.where(p[:, 0] >= 0, 1.0, -1.0)
    # kept where a s + b t + c >= 0 for q = p + s u + t v: sign (x_p + s rad) - gap / 2 >= 0
    line = np.column_stack([sign * rad, np.zeros(k), sign * p[:, 0] - gap / 2])
    line[~cut] = (0.0, 0.0, 1.0)
    lines = np.stack([line, np.tile([0.0, 0.0, 1.0], (k, 1))], axis=1)
    u, v = np.tile([rad, 0.0, 0.0], (k, 1)), np.tile([0.0, rad, 0.0], (k, 1))
    return SplatCloud(p, np.tile([0.0, 0.0, 1.0], (k, 1)), np.full((k, 3), color), u, v, clip_lines=lines)


def slit_region(frame):
    """The central part of the image (away from the plane's borders) and its pixels not covered whole
    (edge coverage draws a slit's rims partly covered)."""
    mid = np.s_[20:-20, 20:-20]
    return (frame.weight[mid] <= 0) | (frame.alpha[mid] < 1.0)


@pytest.mark.parametrize("technique", ["ewa", "perspective", "phong", "blend", "flat", "points"])
def test_rendered_slits_of_1_and_2_pixels_close_and_10_pixels_stay(gl_renderer, technique):
    for gap_px, closes in ((1, True), (2, True), (10, False)):
        cloud = slit_plane(gap_px * PIXEL)
        off = gl_renderer.render(cloud, CAMERA, technique, UNLIT, NO_FILL)
        on = gl_renderer.render(cloud, CAMERA, technique, UNLIT, FILL)
        if gap_px == 2 and technique != "points":   # points have no clip lines: their squares reach in
            assert slit_region(off).sum() >= 2 * 4   # the slit is there without the fill
        holes = slit_region(on).sum()
        assert holes == 0 if closes else holes == slit_region(off).sum() >= 8 * 4, (gap_px, holes)
        # the fill pass is the reference rule, pixel for pixel
        color, weight, depth, alpha, _ = reference.fill_holes(off.color, off.weight, off.depth, off.alpha,
                                                              CAMERA.focal_px, FILL_GAP_PX, FILL_DEPTH_PX,
                                                              FILL_ITERATIONS)
        np.testing.assert_allclose(on.color, color, atol=1e-5)
        np.testing.assert_allclose(on.weight, weight, rtol=1e-5)
        np.testing.assert_allclose(on.alpha, alpha, atol=1e-6)
        covered = weight > 0
        np.testing.assert_allclose(on.depth[covered], depth[covered], rtol=1e-5)


@pytest.mark.parametrize("technique", ["ewa", "flat"])
def test_a_rendered_crack_over_a_far_surface_takes_the_front_color_and_depth(gl_renderer, technique):
    front = slit_plane(2 * PIXEL, z=0.0, color=0.9)
    far = slit_plane(0.0, z=-1.5, color=0.1, length=0.0)
    both = SplatCloud(np.concatenate([front.positions, far.positions]),
                      np.concatenate([front.normals, far.normals]), np.concatenate([front.colors, far.colors]),
                      np.concatenate([front.u, far.u]), np.concatenate([front.v, far.v]),
                      clip_lines=np.concatenate([front.clip_lines, far.clip_lines]))
    off = gl_renderer.render(both, CAMERA, technique, UNLIT, NO_FILL)
    on = gl_renderer.render(both, CAMERA, technique, UNLIT, FILL)
    mid = np.s_[20:-20, 20:-20]
    through = off.color[mid][..., 0] < 0.5   # the far surface seen through the crack
    assert through.sum() >= 2 * 4
    np.testing.assert_allclose(on.color[mid][..., 0], 0.9, atol=1e-5)
    np.testing.assert_allclose(on.depth[mid], 3.0, rtol=1e-4)


@pytest.mark.parametrize("technique", ["ewa", "phong", "flat"])
@pytest.mark.parametrize("supersample", [1, 2])
def test_a_sphere_silhouette_does_not_grow(gl_renderer, technique, supersample):
    from surfsplat import scenes

    cloud = scenes.sphere(4000)
    cam = Camera(eye=(0.0, 0.0, 4.0), target=(0, 0, 0), width=80, height=80, fov=40)
    off = gl_renderer.render(cloud, cam, technique, UNLIT, NO_FILL, supersample=supersample)
    on = gl_renderer.render(cloud, cam, technique, UNLIT, FILL, supersample=supersample)
    assert np.count_nonzero(on.alpha > 0) <= np.count_nonzero(off.alpha > 0)
    assert ((off.alpha > 0) | ~(on.alpha > 0)).all()   # nothing covered that was not
    # where the fill touched nothing the picture is unchanged
    same = np.abs(on.color - off.color).max(axis=-1) == 0
    assert same.mean() > 0.99


def test_tiles_meet_without_seams_with_the_fill(gl_renderer):
    cloud = slit_plane(2 * PIXEL)
    whole = gl_renderer.render(cloud, CAMERA, "ewa", UNLIT, FILL, supersample=2)
    tiled = gl_renderer.render(cloud, CAMERA, "ewa", UNLIT, FILL, supersample=2, max_tile=40)
    np.testing.assert_allclose(tiled.color, whole.color, atol=1e-6)
    assert slit_region(whole).sum() == 0


def test_the_command_line_turns_the_fill_off():
    from surfsplat.cli import build_parser
    from surfsplat.cli.options import render_options

    args = build_parser().parse_args(["render", "in.ply", "-o", "out.png", "--no-fill-holes"])
    assert render_options(args).fill_holes is False
    assert render_options(build_parser().parse_args(["render", "in.ply", "-o", "out.png"])).fill_holes is True
