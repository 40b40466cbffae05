"""The camera a newcomer gets without flags: the up axis travels with the model (stored, implied by
the file kind, or guessed by a stated rule), the automatic view is chosen by what it shows (viewpoint
entropy), and a turntable keeps the whole model in every frame."""

from __future__ import annotations

import numpy as np
import pytest

import surfsplat
from surfsplat import reference
from surfsplat.pipeline.framing import DEFAULT_DIRECTION, auto_camera, default_direction
from surfsplat.pipeline.sources import natural_up
from surfsplat.camera import Camera
from surfsplat.camera_path import orbit_cameras, orbit_distance
from surfsplat.cli import main
from surfsplat.cloud import SplatCloud, concatenate
from surfsplat.colors import colorize
from surfsplat.errors import InputError
from surfsplat.geometry.phong import phong_splats
from surfsplat.hierarchy import build_hierarchy, load_hierarchy
from surfsplat.hierarchy.storage import hierarchy_up, save_hierarchy
from surfsplat.io import load, save_ply
from surfsplat.io.ply import ply_up
from surfsplat.orientation import FLAT_RATIO, Y_UP, Z_UP, guess_up, model_up
from surfsplat.viewpoint import FACE_ON_SHARE, candidate_directions, choose_direction, viewpoint_entropy

Z_HINT = "--up 0 1 0 to change"
Y_HINT = "--up 0 0 1 to change"


def terrain(n=4000, seed=0) -> np.ndarray:
    """A z-up scan of gently rolling ground, 200 x 150 across, a few metres high, far from zero."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform((0, 0), (200, 150), (n, 2))
    z = 4.0 * np.sin(xy[:, 0] / 30.0) + 2.0 * np.cos(xy[:, 1] / 20.0)
    return np.column_stack([xy + (5.0e5, 4.2e6), z + 300.0])


def blob(n=4000, seed=1) -> np.ndarray:
    """A y-up, bunny-like lump: an ellipsoid 1.0 wide, 1.0 high, 0.8 deep with a bump (like the Stanford bunny's
    extents 0.155 x 0.154 x 0.121)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = 1.0 + 0.15 * np.exp(-8 * np.sum((d - (0.3, 0.8, 0.2)) ** 2, axis=1))
    return d * r[:, None] * (0.5, 0.5, 0.4)


def splats(points, up=None) -> SplatCloud:
    return surfsplat.preprocess(SplatCloud(points, up=up), k=8)


def angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arccos(np.clip(abs(a @ b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


# -- the up rule -------------------------------------------------------------------


def test_guess_up_terrain_is_z_up_and_a_lump_is_y_up():
    up, reason = guess_up(terrain())
    assert up == Z_UP and "flat in z" in reason and reason.endswith(Z_HINT)
    up, reason = guess_up(blob())
    assert up == Y_UP and reason.endswith(Y_HINT)
    # flat in y (a y-up floor) stays +y, for its own reason; too few points: +y
    floor = terrain()[:, [0, 2, 1]]
    assert guess_up(floor)[0] == Y_UP and "flat in y" in guess_up(floor)[1]
    assert guess_up(np.zeros((2, 3)))[0] == Y_UP


def test_guess_up_threshold_is_the_stated_ratio():
    base = np.random.default_rng(3).uniform(0, 1, (20000, 3))
    below = base * (10.0, 12.0, 10.0 * FLAT_RATIO * 0.9)   # z extent 0.9 x the ratio of the smaller across
    above = base * (10.0, 12.0, 10.0 * FLAT_RATIO * 1.1)
    assert guess_up(below)[0] == Z_UP and guess_up(above)[0] == Y_UP
    # one far outlier does not change the answer (robust 2nd-98th percentile extents)
    spiky = np.vstack([below, [[5.0, 5.0, 1e4]]])
    assert guess_up(spiky)[0] == Z_UP


def test_model_up_prefers_stored_then_file_kind_then_guess():
    flat = SplatCloud(terrain().astype(np.float32))
    assert model_up(flat)[0] == Z_UP                                   # guessed
    assert model_up(flat.replace(up=(0, 1, 0)))[0] == Y_UP              # stored beats the guess
    assert "stored" in model_up(flat.replace(up=(0, 1, 0)))[1]
    assert model_up(SplatCloud(blob()), "scan.laz")[0] == Z_UP         # the file kind beats the guess
    assert model_up(None, "x.E57")[0] == Z_UP and model_up(None, "x.ply")[0] == Y_UP
    assert model_up(flat, "demo:checkerboard")[0] == Y_UP              # built-in scenes are y-up
    assert natural_up(surfsplat.demo_scene("checkerboard")) == Y_UP   # though flat in z: it says so
    # natural_up: stored or kind; the guess only for an explicit model (it must not tilt a placed camera)
    assert natural_up(flat) == Y_UP and natural_up(flat.replace(up=Z_UP)) == Z_UP
    assert natural_up(flat, flat) == Z_UP and natural_up(SplatCloud(blob()), SplatCloud(blob())) == Y_UP


def test_up_is_validated_and_normalized():
    cloud = SplatCloud(blob(), up=(0, 0, 2))
    assert cloud.up == (0.0, 0.0, 1.0)
    for bad in ((0, 0, 0), (1, 2), (np.nan, 0, 1), "up"):
        with pytest.raises(InputError, match="up must be 3 finite numbers"):
            SplatCloud(blob(), up=bad)


def test_up_survives_subsets_replace_concatenation_and_phong():
    cloud = splats(blob(), up=Z_UP)
    assert cloud.up == Z_UP                                              # through preprocess
    assert cloud.subset(np.arange(10)).up == Z_UP
    assert cloud.replace(colors=np.zeros((len(cloud), 3))).up == Z_UP
    assert cloud.with_arrays(cloud.positions[:5], normals=cloud.normals[:5]).up == Z_UP
    assert cloud.validated().up == Z_UP
    joined = concatenate([cloud, cloud.subset(np.arange(7))])
    assert joined.up == Z_UP and len(joined) == len(cloud) + 7
    assert concatenate([cloud, cloud.replace(up=Y_UP)]).up is None      # disagreeing: unknown
    assert concatenate([cloud, cloud.replace(up=None)]).up == Z_UP      # one unknown: the other's
    assert phong_splats(cloud, count=200).up == Z_UP
    assert colorize(cloud, "elevation", up=Z_UP).up == Z_UP


# -- the up stored with the model -----------------------------------------------------


@pytest.mark.parametrize("binary", [True, False])
def test_ply_stores_up_in_its_header(tmp_path, binary):
    cloud = splats(blob(), up=(0.0, 0.0, 1.0))
    path = save_ply(cloud, tmp_path / "up.ply", binary=binary)
    assert b"comment surfsplat up 0.0 0.0 1.0" in path.read_bytes()[:2000]
    back = load(path)
    assert back.up == Z_UP and ply_up(path) == Z_UP and natural_up(path) == Z_UP
    plain = save_ply(cloud.replace(up=None), tmp_path / "plain.ply", binary=binary)
    assert load(plain).up is None and ply_up(plain) is None and natural_up(plain) == Y_UP


def test_a_malformed_up_comment_names_the_file(tmp_path):
    path = save_ply(SplatCloud(blob()), tmp_path / "bad.ply", binary=False)
    text = path.read_text().replace("comment written by surfsplat", "comment surfsplat up 0 0")
    path.write_text(text)
    with pytest.raises(InputError, match=r"bad.ply: malformed up comment"):
        load(path)


def test_a_plain_z_up_ply_scan_is_guessed_z_up(tmp_path):
    path = save_ply(SplatCloud(terrain()), tmp_path / "scan.ply")   # no up in the file: many published scans
    cloud = load(path)
    assert cloud.up is None
    up, reason = model_up(cloud, path)
    assert up == Z_UP and "flat in z" in reason and reason.endswith(Z_HINT)
    assert natural_up(path, cloud) == Z_UP


def test_hierarchy_files_store_up(tmp_path):
    cloud = splats(terrain(2000), up=Z_UP)
    hierarchy = build_hierarchy(cloud)
    assert hierarchy.points.up == Z_UP
    assert hierarchy.node_splats().up == Z_UP
    path = save_hierarchy(hierarchy, tmp_path / "h.npz")
    assert hierarchy_up(path) == Z_UP and natural_up(path) == Z_UP
    assert load_hierarchy(path).points.up == Z_UP
    unknown = save_hierarchy(build_hierarchy(cloud.replace(up=None)), tmp_path / "u.npz")
    assert hierarchy_up(unknown) is None and load_hierarchy(unknown).points.up is None


def test_las_up_travels_through_preprocess_and_build(tmp_path):
    laspy = pytest.importorskip("laspy")
    xyz = terrain(3000)
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = (0.01, 0.01, 0.01)
    header.offsets = xyz.min(axis=0)
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    scan = tmp_path / "scan.las"
    las.write(scan)
    assert load(scan).up == Z_UP
    main(["-q", "preprocess", str(scan), "-o", str(tmp_path / "scan.ply")])
    main(["-q", "build", str(scan), "-o", str(tmp_path / "scan.npz")])
    assert ply_up(tmp_path / "scan.ply") == Z_UP and load(tmp_path / "scan.ply").up == Z_UP
    assert hierarchy_up(tmp_path / "scan.npz") == Z_UP
    for path in (tmp_path / "scan.ply", tmp_path / "scan.npz"):
        frame = surfsplat.render(path, width=96, height=72)
        assert frame.camera.up == Z_UP   # drawn upright without --up


# -- the automatic view ----------------------------------------------------------------


def plate(normal, n=60000, seed=4) -> SplatCloud:
    """A CAD-like plate 4 x 3 x 0.3 whose big faces point along ``normal``, with two bosses on top."""
    rng = np.random.default_rng(seed)
    size = np.array([4.0, 3.0, 0.3])
    faces = []
    for axis in range(3):   # the six faces of the box, sampled by area
        for sign in (-1.0, 1.0):
            others = [k for k in range(3) if k != axis]
            count = int(n * size[others[0]] * size[others[1]] / 30.0)
            p = rng.uniform(-0.5, 0.5, (count, 3)) * size
            p[:, axis] = sign * 0.5 * size[axis]
            nrm = np.zeros((count, 3))
            nrm[:, axis] = sign
            faces.append((p, nrm))
    for cx in (-1.0, 1.0):   # two round bosses 0.4 high on the top face
        t = rng.uniform(0, 2 * np.pi, 3000)
        h = rng.uniform(0, 0.4, 3000)
        side = np.column_stack([cx + 0.5 * np.cos(t), 0.5 * np.sin(t), 0.15 + h])
        faces.append((side, np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])))
    p = np.vstack([f[0] for f in faces])
    nrm = np.vstack([f[1] for f in faces])
    # turn +z (the plate's normal) onto ``normal``
    z = np.array([0.0, 0.0, 1.0])
    w = np.asarray(normal, float) / np.linalg.norm(normal)
    axis = np.cross(z, w)
    s, c = np.linalg.norm(axis), z @ w
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + k + k @ k * ((1 - c) / s**2 if s > 1e-12 else 0.0)
    return SplatCloud.from_arrays((p @ rot.T).astype(np.float32), (nrm @ rot.T).astype(np.float32),
                                  radius=np.full(len(p), 0.03))


def test_a_plate_seen_head_on_by_default_gets_an_oblique_view():
    default = np.array(DEFAULT_DIRECTION) / np.linalg.norm(DEFAULT_DIRECTION)
    model = plate(default)   # the default direction looks straight onto the big face
    choice = choose_direction(model, Y_UP, default)
    assert choice.default_face_share > FACE_ON_SHARE and not choice.kept_default
    assert angle(choice.direction, default) > 20.0               # not face-on any more
    assert choice.score > choice.default_score + 0.07
    assert "one face covers" in choice.reason
    # the api's automatic camera takes it
    chosen = default_direction(model, Y_UP)
    assert angle(chosen, default) > 20.0
    cam = auto_camera(model, 64, 64)
    view = np.asarray(cam.eye) - cam.target
    assert angle(view, default) > 20.0


@pytest.mark.parametrize("scene", ["sphere", "torus", "cube", "csg"])
def test_models_that_look_right_keep_the_default_view(scene):
    cloud = surfsplat.demo_scene(scene)
    default = np.array(DEFAULT_DIRECTION) / np.linalg.norm(DEFAULT_DIRECTION)
    choice = choose_direction(cloud, Y_UP, default)
    assert choice.kept_default
    np.testing.assert_allclose(default_direction(cloud, Y_UP), default, atol=1e-12)


def test_a_lump_keeps_the_default_view():
    cloud = splats(blob(20000))
    np.testing.assert_allclose(default_direction(cloud, Y_UP),
                               np.array(DEFAULT_DIRECTION) / np.linalg.norm(DEFAULT_DIRECTION), atol=1e-12)


def test_viewpoint_entropy_of_a_square_seen_head_on_matches_the_formula():
    # a flat square filling a known share of the image, one orientation class: H = -(a log a + b log b)
    g = np.linspace(-1, 1, 300)
    x, y = np.meshgrid(g, g)
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    h = viewpoint_entropy(pts, nrm, [[0.0, 0.0, 1.0]], Y_UP, resolution=64)[0]
    a = 2.0 / (2.0 * np.sqrt(2.0))   # the square's side over the bounding sphere's diameter, squared below
    share = a * a
    expected = -(share * np.log2(share) + (1 - share) * np.log2(1 - share))
    assert abs(h - expected) < 0.03
    # seen obliquely, a second class (none here) cannot appear: the entropy only drops with the covered share
    assert viewpoint_entropy(pts, nrm, [[0.0, 0.8, 0.6]], Y_UP, resolution=64)[0] < h


def test_candidates_cover_the_upper_hemisphere_evenly():
    d = candidate_directions((0.0, 0.0, 1.0), 40)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert (d[:, 2] > 0).all() and np.degrees(np.arcsin(d[:, 2].max())) < 80.0
    azimuth = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360
    assert np.histogram(azimuth, bins=4, range=(0, 360))[0].min() >= 8   # every quadrant


# -- the turntable ------------------------------------------------------------------


def test_every_orbit_camera_shows_every_point_of_an_elongated_offset_model():
    rng = np.random.default_rng(5)
    points = rng.uniform(-0.5, 0.5, (5000, 3)) * (4.0, 1.0, 1.0) + (30.0, -7.0, 12.0)   # 4:1:1, off the origin
    cloud = SplatCloud(points.astype(np.float32))
    start = auto_camera(cloud, 320, 240)
    old = orbit_cameras(start, 24)
    inside = lambda cam: ((0 <= (xy := reference.project(cam, reference.to_camera(cam, points)))) &   # noqa: E731
                          (xy <= (cam.width, cam.height))).all(axis=1).all()
    assert not all(inside(c) for c in old)   # the fitted first view's distance lets the model out
    ring = orbit_cameras(start, 24, points=points, margin=0.05)
    assert len(ring) == 24
    for cam in ring:
        assert inside(cam)
        depth = -reference.to_camera(cam, points)[:, 2]
        assert (depth > cam.near).all() and (depth < cam.far).all()
    distances = [np.linalg.norm(np.subtract(c.eye, c.target)) for c in ring]
    np.testing.assert_allclose(distances, distances[0])   # one distance for the whole orbit
    # tight: some frame reaches 90% of the image's half-extent minus the margin
    reach = max(np.abs(reference.project(c, reference.to_camera(c, points)) - (160, 120)).max(axis=0)[0] / 160
                for c in ring)
    assert 0.8 < reach <= 0.9 + 1e-9


def test_orbit_distance_is_the_closed_form_for_one_point():
    # a point at lateral offset 1 along the screen's right axis, at the target's depth: D = 1 / t_x
    d = orbit_distance([[1.0, 0.0, 0.0]], (0, 0, 0), [[0.0, 0.0, 1.0]], (0, 1, 0), fov=60.0, aspect=1.0, fill=1.0)
    assert np.isclose(d, 1.0 / np.tan(np.radians(30.0)))
    with pytest.raises(InputError, match="points must have shape"):
        orbit_distance(np.zeros((0, 3)), (0, 0, 0), [[0, 0, 1]], (0, 1, 0), fov=40.0)


def test_orbit_without_points_is_unchanged():
    cam = Camera(eye=(0, 1, 5), target=(0, 0, 0), near=1.0, far=9.0)
    ring = orbit_cameras(cam, 4)
    np.testing.assert_allclose(ring[1].eye, (5, 1, 0), atol=1e-12)
    assert ring[2].target == cam.target and ring[3].near == 1.0


def test_framing_points_of_a_large_cloud_hold_every_point():
    from surfsplat.camera_path import framing_points
    rng = np.random.default_rng(6)
    points = rng.normal(size=(300_000, 3)) * (5.0, 1.0, 2.0) + 100.0
    corners = framing_points(points, limit=1000, cells=16)
    assert len(corners) < 16**3 * 2
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    assert (points >= lo - 1e-9).all() and (points <= hi + 1e-9).all()
    # for any direction the support of the points is at most the corners' (the hull holds the points)
    dirs = rng.normal(size=(50, 3))
    assert ((points @ dirs.T).max(axis=0) <= (corners @ dirs.T).max(axis=0) + 1e-9).all()
    cam = orbit_cameras(auto_camera(SplatCloud(points[::100]), 128, 128), 6, points=points)
    for c in cam:
        xy = reference.project(c, reference.to_camera(c, points))
        assert ((xy >= 0) & (xy <= 128)).all()


def test_chunked_builds_record_the_input_up(tmp_path):
    from surfsplat.hierarchy.chunked import build_chunked, chunked_up, open_chunked
    stored = save_ply(SplatCloud(terrain(3000), up=Z_UP), tmp_path / "stored.ply")
    plain = save_ply(SplatCloud(terrain(3000)), tmp_path / "plain.ply")
    build_chunked(stored, tmp_path / "stored.ssh", cell_points=2_000, scheduler="synchronous")
    build_chunked(plain, tmp_path / "plain.ssh", cell_points=2_000, scheduler="synchronous")
    assert chunked_up(tmp_path / "stored.ssh") == Z_UP and natural_up(tmp_path / "stored.ssh") == Z_UP
    model = open_chunked(tmp_path / "stored.ssh")
    assert model.up == Z_UP and model.points.up == Z_UP
    assert chunked_up(tmp_path / "plain.ssh") is None
    unknown = open_chunked(tmp_path / "plain.ssh")
    assert unknown.up is None and model_up(unknown)[0] == Z_UP   # guessed from the preview: flat in z


# -- the front doors use it --------------------------------------------------------------------------------

def test_the_view_plan_guesses_a_plain_ply_scans_up_and_says_how_to_change_it(tmp_path, capsys):
    from surfsplat import progress
    path = save_ply(SplatCloud(terrain()), tmp_path / "scan.ply")
    with progress.enabled(True):
        view = surfsplat.prepare(str(path))
        camera = view.camera(None, 64, 48)
        view.camera(None, 64, 48)   # said once
    assert view.up == Z_UP and tuple(camera.up) == Z_UP
    err = capsys.readouterr().err
    assert err.count("flat in z") == 1 and Z_HINT in err
    with progress.enabled(True):
        surfsplat.prepare(str(path)).camera(surfsplat.CameraSpec(up=(0.0, 1.0, 0.0)), 64, 48)
    assert "flat in z" not in capsys.readouterr().err   # an up given: nothing guessed is used


def test_a_camera_placed_along_the_guessed_up_is_still_valid(tmp_path):
    path = save_ply(SplatCloud(terrain()), tmp_path / "scan.ply")
    view = surfsplat.prepare(str(path))
    lo, hi = view.model.bounds()
    center = 0.5 * (lo + hi)
    camera = view.camera(surfsplat.CameraSpec(eye=tuple(center + (0.0, 0.0, 500.0))), 64, 64)   # straight down
    assert abs(np.dot(camera.up, (0.0, 0.0, 1.0))) < 1e-9


@pytest.mark.gl
def test_the_turntable_command_keeps_the_whole_scan_in_every_frame(tmp_path):
    rng = np.random.default_rng(5)
    points = rng.uniform(-0.5, 0.5, (3000, 3)) * (4.0, 1.0, 1.0) + (30.0, -7.0, 12.0)   # long, off the origin
    view = surfsplat.prepare(SplatCloud(points.astype(np.float32)))
    ring = view.orbit(None, 12, width=96, height=72)
    splats = view.sample().points()
    world = splats.positions.astype(np.float64) + splats.origin
    for cam in ring:
        xy = reference.project(cam, reference.to_camera(cam, world))
        assert ((xy >= 0) & (xy <= (cam.width, cam.height))).all()
    spec = surfsplat.CameraSpec(eye=(40.0, -7.0, 12.0))
    placed, start = view.orbit(spec, 4, width=96, height=72), view.camera(spec, 96, 72)
    distance = np.linalg.norm(np.subtract(start.eye, start.target))   # a placed eye keeps its distance
    assert all(np.isclose(np.linalg.norm(np.subtract(c.eye, c.target)), distance, rtol=1e-6) for c in placed)
    ply = save_ply(SplatCloud(points.astype(np.float32)), tmp_path / "long.ply")
    out = tmp_path / "spin.gif"
    assert main(["turntable", str(ply), "-o", str(out), "--frames", "6", "--width", "64", "--height", "48"]) == 0
    from PIL import Image, ImageSequence
    with Image.open(out) as gif:
        for frame in ImageSequence.Iterator(gif):
            image = np.asarray(frame.convert("RGB")).astype(int)
            background = image[0, 0]
            drawn = np.abs(image - background).sum(axis=2) > 24
            assert drawn.any() and not drawn[:, 0].any() and not drawn[:, -1].any()   # never cut at a side
