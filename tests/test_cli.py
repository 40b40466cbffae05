"""The command line end to end: every subcommand, and clear errors for bad input."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from surfsplat import SplatCloud
from surfsplat.cli import main
from surfsplat.io import load, save_ply

pytestmark = pytest.mark.gl   # tiers (tests/conftest.py): most commands render


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main(["-q", *map(str, argv)])
    out, err = capsys.readouterr()
    return status, out, err


def noisy_sphere(n: int = 3000, seed: int = 0) -> SplatCloud:
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return SplatCloud(p / np.linalg.norm(p, axis=1, keepdims=True))


@pytest.mark.parametrize("scene", ["torus", "sphere", "checkerboard"])
def test_demo_renders_a_picture(tmp_path, capsys, scene):
    out = tmp_path / f"{scene}.png"
    status, _, err = run(capsys, "demo", "--scene", scene, "-o", out, "--width", 160, "--height", 120)
    assert status == 0, err
    image = np.asarray(Image.open(out))
    assert image.shape == (120, 160, 3)
    covered = (image < 250).any(axis=2)
    assert 0.1 < covered.mean() < 0.95  # the model is framed: visible, not cropped to the edges


def test_render_raw_points_with_camera_flags_and_depth(tmp_path, capsys):
    ply = save_ply(noisy_sphere(), tmp_path / "points.ply")
    out, depth = tmp_path / "out.png", tmp_path / "depth.npy"
    status, _, err = run(capsys, "render", ply, "-o", out, "--width", 128, "--height", 96, "--eye", 0, 0, 4,
                         "--target", 0, 0, 0, "--fov", 40, "--light", 1, 1, 1, "--background", 0, 0, 0,
                         "--depth", depth)
    assert status == 0, err
    image = np.asarray(Image.open(out))
    d = np.load(depth)
    assert image.shape == (96, 128, 3) and d.shape == (96, 128)
    assert (image[0, 0] == 0).all()  # the black background
    # the eye is on the optical axis 4 units from a unit sphere: depth 3 at the center
    assert abs(d[48, 64] - 3.0) < 0.02
    # the exact sphere's silhouette radius in pixels, for the 40 degree field of view
    focal = 48 / np.tan(np.radians(20))
    radius_px = focal * np.tan(np.arcsin(1 / 4))
    covered = np.isfinite(d)
    # 3000 points: splats ~4 px wide, sized to cover random samples (coverage 1.5),
    # widen the silhouette by a fraction of a splat
    assert abs(np.sqrt(covered.sum() / np.pi) - radius_px) < 2.0


def test_preprocess_sample_info(tmp_path, capsys):
    import trimesh

    mesh_path = tmp_path / "ico.ply"
    trimesh.creation.icosphere(subdivisions=2).export(mesh_path)
    samples = tmp_path / "samples.ply"
    assert run(capsys, "sample", mesh_path, "-n", 2000, "-o", samples)[0] == 0
    cloud = load(samples)
    assert len(cloud) == 2000 and cloud.normals is not None

    splats = tmp_path / "splats.ply"
    assert run(capsys, "preprocess", samples, "-o", splats, "--k", 10)[0] == 0
    model = load(splats)
    assert model.has_splats and len(model) == 2000

    status, out, _ = run(capsys, "info", splats)
    assert status == 0
    assert "2,000" in out and "normals" in out and "spacing" in out

    # an existing output is replaced (a new file renamed over it); --force is accepted and changes nothing
    inode = splats.stat().st_ino
    assert run(capsys, "preprocess", samples, "-o", splats, "--shape", "circle")[0] == 0
    replaced = load(splats)
    assert splats.stat().st_ino != inode and len(replaced) == 2000
    assert np.allclose(np.linalg.norm(replaced.u, axis=1), np.linalg.norm(replaced.v, axis=1))   # circles now
    assert run(capsys, "preprocess", samples, "-o", splats, "--force")[0] == 0


@pytest.mark.parametrize("content, problem", [
    (b"", ""),
    (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n2\n", ""),
    (b"not a ply file at all", ""),
])
def test_bad_files_give_a_clear_error(tmp_path, capsys, content, problem):
    bad = tmp_path / "bad.ply"
    bad.write_bytes(content)
    status, out, err = run(capsys, "render", bad, "-o", tmp_path / "x.png")
    assert status == 2
    assert "bad.ply" in err and "Traceback" not in err
    assert not (tmp_path / "x.png").exists()


def test_missing_file_and_unknown_scene(tmp_path, capsys):
    status, _, err = run(capsys, "render", tmp_path / "nope.ply", "-o", tmp_path / "x.png")
    assert status == 2 and "nope.ply" in err
    assert main(["demo", "--scene", "nope"]) == 2
    assert "invalid choice: 'nope'" in capsys.readouterr().err


def test_render_refuses_to_overwrite_its_input(tmp_path, capsys):
    ply = save_ply(noisy_sphere(500), tmp_path / "points.ply")
    before = ply.read_bytes()
    status, _, err = run(capsys, "preprocess", ply, "-o", ply, "--force")
    assert status == 2 and "input" in err
    assert ply.read_bytes() == before


def test_bad_numbers_are_rejected(tmp_path, capsys):
    ply = save_ply(noisy_sphere(500), tmp_path / "points.ply")
    out = tmp_path / "x.png"
    assert run(capsys, "render", ply, "-o", out, "--background", 2, 0, 0)[0] == 2
    assert run(capsys, "render", ply, "-o", out, "--fov", 0, "--eye", 0, 0, 3)[0] == 2
    assert run(capsys, "render", ply, "-o", out, "--width", 0)[0] == 2
    assert run(capsys, "render", ply, "-o", out, "--light", 0, 0, 0)[0] == 2
    assert not out.exists()


@pytest.mark.parametrize("flags", [["--technique", "phong"], ["--technique", "blend", "--kernel", "gaussian",
                                                              "--kernel-sigma", 0.4],
                                   ["--technique", "blend", "--kernel-a", 4, "--kernel-n", 5],
                                   ["--technique", "ewa", "--deferred"]])
def test_demo_with_object_space_techniques_and_deferred_shading(tmp_path, capsys, flags):
    out = tmp_path / "demo.png"
    status, _, err = run(capsys, "demo", "--scene", "sphere", "-o", out, "--width", 96, "--height", 96, *flags)
    assert status == 0, err
    covered = (np.asarray(Image.open(out)) < 250).any(axis=2)
    assert 0.3 < covered.mean() < 0.95


def test_bad_kernel_option_is_a_clear_error(tmp_path, capsys):
    status, _, err = run(capsys, "demo", "-o", tmp_path / "x.png", "--technique", "blend", "--kernel-n", -1)
    assert status == 2 and "--kernel-n: must be a number > 0, got '-1'" in err
    assert not (tmp_path / "x.png").exists()


def test_api_rejects_unknown_render_options():
    import surfsplat
    from surfsplat.errors import InputError

    with pytest.raises(TypeError, match="kernal"):
        surfsplat.render(noisy_sphere(200), kernal="gaussian")
    with pytest.raises(InputError, match="kernel n must be a positive number"):
        surfsplat.KernelOptions(n=-1.0)


def test_render_mesh_ground_truth_matches_its_splats(tmp_path, capsys):
    """render --mesh and render of the mesh's own samples frame the model identically."""
    import trimesh

    mesh_path = tmp_path / "ico.ply"
    trimesh.creation.icosphere(subdivisions=4).export(mesh_path)
    truth, splats = tmp_path / "truth.png", tmp_path / "splats.png"
    view = ["--width", 128, "--height", 128, "--eye", 0, 0, 4, "--target", 0, 0, 0]
    assert run(capsys, "render", mesh_path, "--mesh", "-o", truth, *view)[0] == 0
    assert run(capsys, "render", mesh_path, "-o", splats, *view)[0] == 0
    a = (np.asarray(Image.open(truth)) < 250).any(axis=2)
    b = (np.asarray(Image.open(splats)) < 250).any(axis=2)
    # splats of the 2,562 vertices stick out of the silhouette a little; the framing is the same
    assert a.sum() > 2000 and (a ^ b).sum() < 0.1 * a.sum()
    centroid = [np.argwhere(m).mean(axis=0) for m in (a, b)]
    assert np.abs(centroid[0] - centroid[1]).max() < 0.5
    status, _, err = run(capsys, "render", mesh_path, "--mesh", "-o", mesh_path)
    assert status == 2 and "refusing to overwrite" in err


def test_build_info_and_render_a_hierarchy(tmp_path, capsys):
    ply = save_ply(noisy_sphere(4000), tmp_path / "points.ply")
    model = tmp_path / "model.npz"
    status, _, err = run(capsys, "build", ply, "-o", model)
    assert status == 0, err
    status, out, _ = run(capsys, "info", model)
    assert status == 0 and "points:     4,000" in out and "LOD hierarchy" in out and "capacity 8" in out
    assert run(capsys, "build", ply, "-o", tmp_path / "small.npz", "--leaf-capacity", 2)[0] == 0
    assert "capacity 2" in run(capsys, "info", tmp_path / "small.npz")[1]
    assert run(capsys, "build", ply, "-o", tmp_path / "small.npz")[0] == 0   # replaced
    assert "capacity 8" in run(capsys, "info", tmp_path / "small.npz")[1]
    assert run(capsys, "build", ply, "-o", tmp_path / "model.ply")[0] == 2   # wrong suffix
    images = {}
    for tau in (0, 1, 64):
        out_png = tmp_path / f"tau{tau}.png"
        status, _, err = run(capsys, "render", model, "-o", out_png, "--lod-tolerance", tau, "--width", 128,
                             "--height", 128)
        assert status == 0, err
        images[tau] = (np.asarray(Image.open(out_png)) < 250).any(axis=2)
    assert images[0].mean() > 0.2
    # coarser cuts still cover the same silhouette (conservative ellipses: no holes, a little wider)
    for tau in (1, 64):
        assert (images[0] & ~images[tau]).sum() < 0.01 * images[0].sum()
    # a point file rendered with a tolerance builds its hierarchy on the fly: same picture as the saved one
    status, _, err = run(capsys, "render", ply, "-o", tmp_path / "direct.png", "--lod-tolerance", 64,
                         "--width", 128, "--height", 128)
    assert status == 0, err
    assert np.array_equal(np.asarray(Image.open(tmp_path / "direct.png")),
                          np.asarray(Image.open(tmp_path / "tau64.png")))
    status, _, err = run(capsys, "render", tmp_path / "missing.npz", "-o", tmp_path / "x.png")
    assert status == 2 and "missing.npz" in err


def test_phong_command_writes_splats_with_normal_fields(tmp_path, capsys):
    ply = save_ply(noisy_sphere(6000), tmp_path / "samples.ply")
    out = tmp_path / "phong.ply"
    status, _, err = run(capsys, "phong", ply, "-o", out, "--count", 300)
    assert status == 0, err
    splats = load(out)
    assert splats.normal_field is not None and 250 <= len(splats) <= 350
    # a unit sphere: the fields tilt the normals outward (alpha, beta > 0 for outward normals)
    outward = np.sum(splats.normals * splats.positions, axis=1) > 0
    field = np.where(outward[:, None], splats.normal_field, -splats.normal_field)
    assert np.median(field) > 0.05
    image = tmp_path / "phong.png"
    assert run(capsys, "render", out, "-o", image, "--technique", "phong", "--width", 96, "--height", 96)[0] == 0
    assert run(capsys, "phong", ply, "-o", out, "--count", 200)[0] == 0            # replaced
    assert 190 <= len(load(out)) <= 210
    status, _, err = run(capsys, "phong", ply, "-o", tmp_path / "x.ply")
    assert status == 2 and "exactly one of --error" in err


def test_quiet_anywhere_version_and_defaults_written_once(tmp_path, capsys):
    import surfsplat
    from surfsplat.cli import build_parser

    out = tmp_path / "d.png"
    assert main(["demo", "-o", str(out), "--width", "32", "--height", "32", "-q"]) == 0
    assert capsys.readouterr().err == ""  # -q after the subcommand silences progress too
    assert main(["--version"]) == 0
    assert surfsplat.__version__ in capsys.readouterr().out
    # the flags' defaults are the dataclasses' defaults, shown in --help
    args = build_parser().parse_args(["demo"])
    kernel, visibility = surfsplat.KernelOptions(), surfsplat.VisibilityOptions()
    assert (args.kernel, args.kernel_a, args.kernel_sigma) == (kernel.name, kernel.a, kernel.sigma)
    assert args.depth_epsilon == visibility.depth_epsilon and args.cutoff == surfsplat.FilterOptions().cutoff
    assert main(["demo", "--help"]) == 0
    assert f"(default {kernel.a})" in capsys.readouterr().out


@pytest.mark.parametrize("flags, message", [
    (["--width", "0"], "--width: must be an integer >= 1"),
    (["--fov", "200"], "--fov: must be a number >= 0.001 and < 180"),
    (["--lod-tolerance", "-1"], "--lod-tolerance: must be a number >= 0"),
    (["--k", "1"], "--k: must be an integer >= 3"),
    (["--background", "0", "0", "nan"], "--background: must be a number >= 0 and <= 1"),
])
def test_bad_values_are_refused_before_loading(tmp_path, capsys, flags, message):
    out = tmp_path / "x.png"
    status, _, err = run(capsys, "render", tmp_path / "not-read.ply", "-o", out, *flags)
    assert status == 2 and message in err and "Traceback" not in err
    assert "not-read.ply" not in err  # refused while parsing, before the (missing) input is looked at
    assert not out.exists()


def test_the_main_function_leaves_the_process_settings_alone(tmp_path, capsys):
    import warnings

    from surfsplat import progress

    before = warnings.showwarning
    main(["demo", "-o", str(tmp_path / "d.png"), "--width", "16", "--height", "16"])
    assert warnings.showwarning is before and not progress.is_enabled()


def test_a_mesh_renders_its_surface_by_default(tmp_path, capsys, shared_data):
    """`render featuretype.ply` draws the sampled surface (welded, crease
    normals, clip lines), close to `render --mesh` of the same file; `--vertices` the old cloud."""
    import trimesh

    from surfsplat import metrics
    from scipy import ndimage

    path = shared_data / "featuretype.ply"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    soup = tmp_path / "soup.stl"   # a triangle soup: every triangle its own three vertices
    trimesh.load(path, process=False).export(soup)
    size = ["--width", 200, "--height", 200]
    images = {}
    for name, args in (("truth", [path, "--mesh"]), ("surface", [path]), ("soup", [soup]),
                       ("vertices", [path, "--vertices"])):
        out = tmp_path / f"{name}.png"
        status, _, err = run(capsys, "render", *args, "-o", out, *size)
        assert status == 0, err
        images[name] = np.asarray(Image.open(out)).astype(np.float64) / 255
    silhouette = (images["truth"] < 0.98).any(axis=2)
    inner = ndimage.binary_erosion(silhouette, iterations=2)
    scores = {name: metrics.psnr(images[name][inner], images["truth"][inner])
              for name in ("surface", "soup", "vertices")}
    assert scores["surface"] > 28 and scores["soup"] > 28, scores   # measured 31-32 dB
    assert scores["vertices"] < scores["surface"] - 10, scores       # the vertices as splats: about 12 dB
    holes = inner & ~(images["surface"] < 0.98).any(axis=2)
    assert holes.sum() == 0


def test_preprocess_and_build_sample_a_mesh(tmp_path, capsys):
    import trimesh

    mesh_path = tmp_path / "box.off"
    trimesh.creation.box(extents=(2, 1, 0.5)).export(mesh_path)
    splats = tmp_path / "box.ply"
    status, _, err = run(capsys, "preprocess", mesh_path, "-o", splats, "--samples", 5000)
    assert status == 0, err
    cloud = load(splats)
    assert len(cloud) == 5000 and cloud.has_splats and cloud.clip_lines is not None   # a box has sharp edges
    assert run(capsys, "build", mesh_path, "-o", tmp_path / "box.npz", "--samples", 3000)[0] == 0
    status, out, _ = run(capsys, "info", tmp_path / "box.npz")
    assert "points:     3,000" in out


def test_turntable_gif_and_mp4(tmp_path, capsys):
    from PIL import Image as PILImage

    gif = tmp_path / "spin.gif"
    status, _, err = run(capsys, "turntable", "demo:sphere", "-o", gif, "--frames", 6, "--width", 48,
                         "--height", 40, "--elevation", 20)
    assert status == 0, err
    with PILImage.open(gif) as image:
        assert image.n_frames == 6 and image.size == (48, 40)
        frames = []
        for i in range(image.n_frames):
            image.seek(i)
            frames.append(np.asarray(image.convert("RGB")).astype(int))
    assert all(((f < 250).any(axis=2).mean() > 0.2) for f in frames)   # the model in every frame
    assert run(capsys, "turntable", "demo:sphere", "-o", gif, "--frames", 3, "--width", 16, "--height", 16)[0] == 0
    with PILImage.open(gif) as image:   # replaced
        assert image.n_frames == 3 and image.size == (16, 16)
    pytest.importorskip("imageio_ffmpeg")
    mp4 = tmp_path / "spin.mp4"
    assert run(capsys, "turntable", "demo:sphere", "-o", mp4, "--frames", 8, "--width", 64, "--height", 48)[0] == 0
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(mp4))
    meta = next(reader)
    video = [np.frombuffer(f, np.uint8).reshape(48, 64, 3).astype(int) for f in reader]
    assert tuple(meta["size"]) == (64, 48) and len(video) == 8
    assert all(((f < 250).any(axis=2).mean() > 0.2) for f in video)   # the model in every frame, not blank


def test_orbit_cameras_keep_distance_and_loop():
    from surfsplat.api import orbit_cameras
    from surfsplat.camera import Camera

    cam = Camera(eye=(0, 1, 3), target=(0, 0, 0), up=(0, 1, 0), width=10, height=10)
    ring = orbit_cameras(cam, 8)
    distances = [np.linalg.norm(np.subtract(c.eye, c.target)) for c in ring]
    assert np.allclose(distances, distances[0]) and ring[0].eye == cam.eye
    assert np.allclose(ring[4].eye, (0, 1, -3), atol=1e-12)    # half a turn about +y
    high = orbit_cameras(cam, 1, elevation=45)[0]
    assert np.isclose(np.degrees(np.arcsin(high.eye[1] / np.linalg.norm(high.eye))), 45)


def test_batch_render_with_a_pattern(tmp_path, capsys):
    a = save_ply(noisy_sphere(800, seed=1), tmp_path / "a.ply")
    b = save_ply(noisy_sphere(800, seed=2), tmp_path / "b.ply")
    status, _, err = run(capsys, "render", a, b, "-o", tmp_path / "out_{stem}.png", "--width", 32, "--height", 32)
    assert status == 0, err
    assert (tmp_path / "out_a.png").exists() and (tmp_path / "out_b.png").exists()
    status, _, err = run(capsys, "render", a, b, "-o", tmp_path / "same.png")
    assert status == 2 and "{stem}" in err and not (tmp_path / "same.png").exists()
