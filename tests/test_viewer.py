"""The interactive viewer: camera-control math without a window, then the window itself on a
virtual X server (Xvfb, started here) in the scripted mode.

The window tests run the viewer in subprocesses: a glfw (GLX) context and the test
session's headless EGL context are never current in the same process.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import shutil
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from PIL import Image

import surfsplat
from surfsplat import Camera, auto_camera
from surfsplat.errors import InputError, RenderError
from surfsplat.viewer import camera_control as cc
from surfsplat.viewer.app import preview_cloud
from surfsplat.viewer.screenshots import save_image, unique_screenshot_path

# -- camera control (no window) -----------------------------------------------------------------


@pytest.fixture
def camera() -> Camera:
    return Camera(eye=(0.5, 0.8, 3.0), target=(0.1, -0.2, 0.3), up=(0, 1, 0), fov=40, width=320, height=240)


def dist(c: Camera) -> float:
    return float(np.linalg.norm(np.subtract(c.eye, c.target)))


def project(c: Camera, point) -> np.ndarray:
    """Window pixel (x right, y down) of a world point."""
    p = c.view_matrix @ np.append(point, 1.0)
    x = c.width / 2 + c.focal_px * p[0] / -p[2]
    y = c.height / 2 - c.focal_px * p[1] / -p[2]
    return np.array([x, y])


def test_orbit_keeps_the_distance_and_turns_about_up(camera):
    for yaw, pitch in [(30, 0), (-75, 20), (200, -35), (0, 80)]:
        moved = cc.orbit(camera, yaw, pitch)
        assert dist(moved) == pytest.approx(dist(camera), rel=1e-12)
        assert moved.target == camera.target
    # a pure yaw turns about the up axis through the target: the height stays, a full turn returns
    turned = cc.orbit(camera, 50)
    assert turned.eye[1] == pytest.approx(camera.eye[1], abs=1e-12)
    assert np.allclose(cc.orbit(turned, 310).eye, camera.eye, atol=1e-12)
    # pitch is clamped short of the pole (no flip, up stays valid)
    top = cc.orbit(camera, 0, 500)
    offset = np.subtract(top.eye, top.target) / dist(top)
    assert np.degrees(np.arcsin(offset[1])) == pytest.approx(cc.MAX_ELEVATION_DEG)
    # near/far are left to the renderer (set from the model's bounds per view)
    assert turned.near is None and turned.far is None


def test_pan_moves_eye_and_target_together_under_the_cursor(camera):
    moved = cc.pan(camera, 25.0, -10.0)
    shift = np.subtract(moved.eye, camera.eye)
    assert np.allclose(np.subtract(moved.target, camera.target), shift, atol=1e-12)
    assert np.linalg.norm(shift) > 0 and dist(moved) == pytest.approx(dist(camera))
    # "grab": the point at the old target follows the cursor by exactly (dx, dy) pixels
    assert np.allclose(project(moved, camera.target) - project(camera, camera.target), [25.0, -10.0], atol=1e-6)


def test_zoom_changes_the_distance_toward_the_target(camera):
    closer = cc.zoom(camera, 2, factor=0.8)
    assert dist(closer) == pytest.approx(dist(camera) * 0.64)
    assert closer.target == camera.target
    direction = lambda c: np.subtract(c.eye, c.target) / dist(c)  # noqa: E731
    assert np.allclose(direction(closer), direction(camera))
    assert dist(cc.zoom(camera, -1, factor=0.8)) == pytest.approx(dist(camera) / 0.8)
    assert dist(cc.zoom(camera, 1000, min_distance=1e-3)) == pytest.approx(1e-3)  # never reaches the target


def test_fly_and_look(camera):
    forward = np.subtract(camera.target, camera.eye) / dist(camera)
    moved = cc.fly(camera, forward=0.5, right=0.0, upward=0.25)
    assert np.allclose(np.subtract(moved.eye, camera.eye), 0.5 * forward + [0, 0.25, 0])
    assert np.allclose(np.subtract(moved.target, moved.eye), np.subtract(camera.target, camera.eye))
    looked = cc.look(camera, 30, 10)
    assert looked.eye == camera.eye and dist(looked) == pytest.approx(dist(camera))


def test_controller_reset_equals_auto_camera_and_input_signs():
    cloud = surfsplat.scenes.torus(60, 24)
    home = lambda w, h: auto_camera(cloud, w, h, 40.0, up=(0, 0, 1))  # noqa: E731
    control = cc.CameraController(home(320, 240), home, scale=1.4, up=np.array([0.0, 0.0, 1.0]))
    control.drag("left", 40, 15)
    control.drag("right", 10, 5)
    control.scroll(3)
    control.toggle_mode()
    assert control.keys((1, 1, 1), (1, 0), 0.1)
    assert not control.keys((0, 0, 0), (0, 0), 0.1)
    control.toggle_mode()
    control.resize(400, 300)
    control.reset()
    assert control.camera == auto_camera(cloud, 400, 300, 40.0, up=(0, 0, 1))
    # wheel forward moves closer; orbit keeps the up axis
    before = dist(control.camera)
    control.scroll(1)
    assert dist(control.camera) < before
    height = control.camera.eye[2]
    control.drag("left", 100, 0)
    assert control.camera.eye[2] == pytest.approx(height)


def test_preview_is_a_coarse_hole_free_cut_of_the_hierarchy(gl_renderer):
    from surfsplat.hierarchy import build_hierarchy

    torus = surfsplat.demo_scene("torus")
    h = build_hierarchy(torus)
    small = preview_cloud(h, 5000)
    assert 5000 / 8 <= len(small) <= 5000 and small.normal_field is None
    assert preview_cloud(h, len(torus)) is None and preview_cloud(h, 0) is None
    # drawn flat, the preview covers what the whole model covers
    camera = surfsplat.auto_camera(torus, 200, 160)
    full = gl_renderer.render(torus, camera, "flat").mask
    coarse = gl_renderer.render(small, camera, "flat").mask
    assert (full & ~coarse).sum() <= 0.002 * full.sum()


def test_screenshots_never_overwrite(tmp_path):
    image = np.zeros((4, 5, 3), np.uint8)
    first = unique_screenshot_path(tmp_path, now=0.0)
    assert first.name.startswith("surfsplat-") and first.suffix == ".png"
    paths = [save_image(image, first, exclusive=True) for _ in range(3)]
    assert len(set(paths)) == 3 and all(p.exists() for p in paths)
    assert unique_screenshot_path(tmp_path, now=0.0) not in paths


def test_hud_text_panel_is_premultiplied_rgba():
    from surfsplat.viewer.hud import render_text

    panel = render_text("ewa\t1,000 splats\nP\tprefilter", size_px=14)
    assert panel.ndim == 3 and panel.shape[2] == 4 and panel.dtype == np.uint8
    assert (panel[..., :3] <= panel[..., 3:]).all()  # premultiplied: color <= alpha
    assert panel[..., 3].min() > 0 and (panel[..., 0] > 200).any()  # translucent panel, white text


def test_view_command_options():
    from surfsplat.cli.view import add_view_command

    parser = argparse.ArgumentParser()
    add_view_command(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["view", "demo:torus", "--frames", "3", "--orbit", "5", "--screenshot", "x.png"])
    assert args.size == [1280, 720] or tuple(args.size) == (1280, 720)
    assert args.width is None and args.frames == 3 and args.orbit == 5.0 and args.technique == "ewa"
    assert args.motion_budget == surfsplat.MotionOptions().budget  # the default written once
    with pytest.raises(InputError, match="orbit"):
        surfsplat.viewer.view("demo:torus", orbit=5.0)  # --orbit without --frames: refused before any window
    with pytest.raises(InputError, match="demo scene"):
        surfsplat.viewer.view("demo:nope", frames=1)  # checked before the window opens


# -- the window, on a virtual X server -------------------------------------------------------------


@pytest.fixture(scope="session")
def xvfb_display():
    """A private Xvfb server for the session; yields its DISPLAY value (":N")."""
    pytest.importorskip("glfw", reason="the viewer needs the glfw package (pip install 'surfsplat[viewer]')")
    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.skip("Xvfb is not installed (Debian/Ubuntu: apt-get install xvfb): window tests skipped")
    # -displayfd: the server picks a free display number and writes it to our pipe when ready;
    # -noreset: an X server resets when its last client leaves and refuses connections meanwhile,
    # which would fail the next test's window at random
    read_end, write_end = os.pipe()
    server = subprocess.Popen([exe, "-displayfd", str(write_end), "-screen", "0", "1280x1024x24",
                               "-nolisten", "tcp", "-noreset"], pass_fds=(write_end,),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    # read up to the newline, and keep our end open while the server runs: it may write the
    # number and the newline separately and dies of SIGPIPE if the pipe is closed in between
    received, deadline = b"", time.monotonic() + 15.0
    while not received.endswith(b"\n") and time.monotonic() < deadline:
        ready, _, _ = select.select([read_end], [], [], max(0.0, deadline - time.monotonic()))
        chunk = os.read(read_end, 64) if ready else b""
        if not chunk:
            break
        received += chunk
    number = received.decode().strip()
    if not number.isdigit():
        server.kill()
        server.wait()
        os.close(read_end)
        pytest.skip("Xvfb did not start (no display number within 15 s): window tests skipped")
    try:
        yield f":{number}"
    finally:
        server.terminate()
        try:
            server.wait(timeout=5)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        os.close(read_end)


def run_python(code: str, display: str | None, timeout: float = 120, cwd=None) -> subprocess.CompletedProcess:
    env = {key: value for key, value in os.environ.items() if key not in ("DISPLAY", "WAYLAND_DISPLAY")}
    if display is not None:
        env["DISPLAY"] = display
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, capture_output=True,
                          text=True, timeout=timeout, cwd=cwd)


def run_view(args: list, display: str | None, timeout: float = 120) -> subprocess.CompletedProcess:
    code = f"import sys; from surfsplat.cli import main; sys.exit(main({[str(a) for a in args]!r}))"
    return run_python(code, display, timeout)


def test_scripted_screenshot_matches_render(xvfb_display, tmp_path):
    out = tmp_path / "view.png"
    result = run_view(["-q", "view", "demo:torus", "--frames", 1, "--orbit", 0, "--size", 400, 300,
                       "--lod-tolerance", 4, "--screenshot", out], xvfb_display)
    assert result.returncode == 0, result.stderr
    shot = np.asarray(Image.open(out)).astype(int)
    assert shot.shape == (300, 400, 3)
    # the same view rendered headless (automatic framing at the same size, the same LOD cut)
    torus = surfsplat.demo_scene("torus")
    expected = surfsplat.render(torus, width=400, height=300, lod=surfsplat.LodOptions(tolerance=4)).image().astype(int)
    assert (expected != surfsplat.render(torus, width=400, height=300).image()).any(), "LOD changed nothing"
    diff = np.abs(shot - expected).max(axis=2)
    # same renderer, same camera: only the float -> 8-bit conversion may differ by one level
    assert diff.mean() < 1.0 and (diff <= 2).mean() >= 0.999


def test_every_technique_runs_in_the_window(xvfb_display, tmp_path):
    result = run_python(f"""
        import json
        from surfsplat.rendering.techniques import TECHNIQUES
        from surfsplat.viewer import MotionOptions, view
        stats = {{}}
        for name in sorted(TECHNIQUES):
            s = view("demo:torus", technique=name, size=(256, 192), frames=3, orbit=10.0,
                     motion=MotionOptions("flat", budget=20_000), screenshot=r"{tmp_path}/" + name + ".png")
            stats[name] = [s.frames, s.preview_frames, s.full_frames, s.preview_splats]
        print(json.dumps(stats))
        """, xvfb_display)
    assert result.returncode == 0, result.stderr
    stats = json.loads(result.stdout.strip().splitlines()[-1])
    assert stats, "no technique registered"
    for name, (frames, previews, fulls, preview_splats) in stats.items():
        assert frames == 3 and previews == 3 and fulls == 0  # moving: previews only (the screenshot is extra)
        assert preview_splats <= 20_000
        image = np.asarray(Image.open(tmp_path / f"{name}.png"))
        assert image.shape == (192, 256, 3)
        covered = (image < 250).any(axis=2).mean()
        assert 0.05 < covered < 0.95, f"{name}: the screenshot is empty or all model"


def test_window_shows_the_image_and_the_hud(xvfb_display):
    # drive the Viewer frame by frame: the window holds the full image plus the HUD in the top left
    result = run_python("""
        import numpy as np
        from surfsplat.lighting import Lights
        from surfsplat.pipeline import LodOptions, SourceOptions, View
        from surfsplat.rendering.options import RenderOptions
        from surfsplat.viewer import app
        glfw, window, ctx = app.open_window(320, 240, "test")
        viewer = app.Viewer(glfw, window, ctx, View("demo:torus", interactive=True), None, technique="flat",
                            lights=Lights(), options=RenderOptions(), background=(1, 1, 1),
                            motion=app.MotionOptions("flat", budget=0, scale=1.0), hud=True)
        image = viewer.full_image()
        viewer.present(1.0)
        screen = viewer.screen_image()
        hud_h, hud_w = viewer.hud.status.size[1], viewer.hud.status.size[0]
        uploads = viewer.hud.status.uploads
        for _ in range(5):
            viewer.present(1.0)  # same text: no new upload
        assert viewer.hud.status.uploads == uploads
        outside = np.ones(image.shape[:2], bool)
        outside[: hud_h + 10, : hud_w + 10] = False
        assert (screen[outside] == image[outside]).all()
        assert (screen[~outside] != image[~outside]).any()
        viewer.release()
        glfw.terminate()
        print("ok")
        """, xvfb_display)
    assert result.returncode == 0 and result.stdout.strip().endswith("ok"), result.stderr


def test_input_drives_the_view(xvfb_display, tmp_path):
    # synthetic input through the viewer's own glfw callbacks, one loop turn at a time
    result = run_python("""
        import time
        from surfsplat.lighting import Lights
        from surfsplat.pipeline import LodOptions, SourceOptions, View
        from surfsplat.rendering.options import RenderOptions
        from surfsplat.viewer import app
        glfw, window, ctx = app.open_window(320, 240, "test")
        v = app.Viewer(glfw, window, ctx, View("demo:torus", interactive=True), None, technique="ewa",
                       lights=Lights(), options=RenderOptions(), background=(1, 1, 1),
                       motion=app.MotionOptions("flat", budget=20000, scale=0.5), hud=True)
        G = glfw
        v.step(wait=False)
        assert (v.full_frames, v.preview_frames) == (1, 0)
        home = v.controller.camera
        # left drag: previews while moving, then one full frame cross-faded in once still
        v._on_button(window, G.MOUSE_BUTTON_LEFT, G.PRESS, 0)
        for _ in range(3):
            x, y = v._cursor
            v._on_cursor(window, x + 20, y + 5)
            v.step(wait=False)
        v._on_button(window, G.MOUSE_BUTTON_LEFT, G.RELEASE, 0)
        assert v.preview_frames == 3 and v.full_frames == 1 and v.showing_preview
        deadline = time.perf_counter() + 20
        while (v.showing_preview or v.fade_from is not None) and time.perf_counter() < deadline:
            v.step()
        assert v.full_frames == 2 and not v.showing_preview
        frames = v.full_frames + v.preview_frames
        for _ in range(3):
            v.step(wait=False)  # still: the full frame is shown again, not re-rendered
        assert v.full_frames + v.preview_frames == frames
        assert v.controller.camera != home
        # keys: technique, prefilter, lighting, culling, help, tolerance, screenshots, reset
        for key in (G.KEY_T, G.KEY_P, G.KEY_L, G.KEY_B, G.KEY_H):
            v._on_key(window, key, 0, G.PRESS, 0)
        v._on_char(window, ord("+"))
        v._on_key(window, G.KEY_S, 0, G.PRESS, 0)
        v._on_key(window, G.KEY_S, 0, G.PRESS, 0)
        v._on_key(window, G.KEY_R, 0, G.PRESS, 0)
        v.step(wait=False)
        assert v.technique == v.techniques[(v.techniques.index("ewa") + 1) % len(v.techniques)]
        # B: automatic culling drew the closed torus two-sided (it never culls); the key turns culling on
        assert not v.options.filter.prefilter and not v.lights.enabled and v.options.visibility.cull_backfaces is True
        assert v.hud.show_help and abs(v.lod_tolerance - 2 ** 0.5) < 1e-9
        assert v.controller.camera == v.controller.home(*v.size)
        v._on_key(window, G.KEY_2, 0, G.PRESS, 0)
        v.step(wait=False)
        assert v.technique == v.techniques[1]
        # resize: the camera and the targets follow the framebuffer
        glfw.set_window_size(window, 400, 260)
        for _ in range(50):
            v.step(wait=False)
            if v.size == (400, 260):
                break
            time.sleep(0.02)
        assert v.size == (400, 260) and v.controller.camera.width == 400
        assert v.full_image().shape == (260, 400, 3)
        # fly mode: Q moves instead of quitting; Esc quits
        v._on_key(window, G.KEY_F, 0, G.PRESS, 0)
        v._on_key(window, G.KEY_Q, 0, G.PRESS, 0)
        assert v.step(wait=False) and v.controller.mode == "fly"
        v._on_key(window, G.KEY_ESCAPE, 0, G.PRESS, 0)
        assert v.step(wait=False) is False
        v.release()
        glfw.terminate()
        print("ok")
        """, xvfb_display, cwd=tmp_path)
    assert result.returncode == 0 and result.stdout.strip().endswith("ok"), result.stderr
    shots = sorted(tmp_path.glob("surfsplat-*.png"))
    assert len(shots) == 2  # the second S did not overwrite the first
    assert np.asarray(Image.open(shots[0])).shape == (240, 320, 3)


def test_no_display_is_a_clear_error(monkeypatch):
    glfw = pytest.importorskip("glfw", reason="the viewer needs the glfw package")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    glfw.set_error_callback(lambda code, text: None)
    try:
        if glfw.init():
            glfw.terminate()
            pytest.skip("glfw found a display platform even without DISPLAY")
    finally:
        glfw.set_error_callback(None)
    with pytest.raises(RenderError, match="surfsplat render") as error:
        surfsplat.viewer.view("demo:torus", frames=1)
    assert "xvfb-run" in str(error.value)
    # the command: exit status 2 and the same advice
    result = run_view(["view", "demo:torus", "--frames", 1], display=None)
    assert result.returncode == 2
    assert "surfsplat render" in result.stderr and "xvfb-run" in result.stderr


# -- point budget, refinement, colour by, EDL, recording ------------------------------------------

def test_refinement_budgets_grow_to_the_budget():
    from surfsplat.viewer.detail import REFINE_MIN, refinement_budgets

    assert refinement_budgets(None) == [None]
    steps = refinement_budgets(1_000_000)
    assert steps == sorted(steps) and steps[-1] == 1_000_000 and len(steps) == 3 and steps[0] >= REFINE_MIN
    assert refinement_budgets(5_000) == [5_000]      # below the smallest step: drawn at once
    assert refinement_budgets(100_000)[0] == REFINE_MIN


def test_recolor_averages_point_colors_per_node():
    from surfsplat.hierarchy import build_hierarchy
    from surfsplat.viewer.detail import recolor

    h = build_hierarchy(surfsplat.demo_scene("torus"))
    rng = np.random.default_rng(0)
    colors = rng.uniform(size=(len(h.points), 3)).astype(np.float32)
    recolor(h, colors)
    for node in (0, 5, len(h) - 1):
        s, c = h.node_point_start[node], h.node_point_count[node]
        np.testing.assert_allclose(h.node_colors[node], colors[s:s + c].mean(axis=0), atol=1e-5)
    np.testing.assert_array_equal(h.points.colors, colors)
    recolor(h, None)
    assert h.node_colors is None and h.points.colors is None


def test_recorder_writes_one_video_frame_per_scripted_frame(tmp_path):
    from surfsplat.viewer.recorder import Recorder

    rec = Recorder(tmp_path / "r.gif", realtime=False)
    for i in range(5):
        rec.add(lambda i=i: np.full((20, 30, 3), 40 * i, np.uint8))
    assert rec.close() == tmp_path / "r.gif"
    with Image.open(tmp_path / "r.gif") as gif:
        assert gif.n_frames == 5 and gif.size == (30, 20)
        gif.seek(3)
        assert np.asarray(gif.convert("RGB"))[0, 0, 0] == 120
    with pytest.raises(InputError, match="unsupported"):
        Recorder(tmp_path / "r.avi")


def test_view_command_takes_budget_record_and_hybrid():
    from surfsplat.cli.view import add_view_command

    parser = argparse.ArgumentParser()
    add_view_command(parser.add_subparsers())
    args = parser.parse_args(["view", "scan.las", "--point-budget", "5000", "--record", "a.mp4"])
    assert args.point_budget == 5000 and args.record == "a.mp4" and args.hybrid is None
    assert parser.parse_args(["view", "a.ply", "--no-hybrid"]).hybrid is False
    with pytest.raises(SystemExit):
        parser.parse_args(["view", "a.ply", "--point-budget", "0"])


def test_budget_refines_progressively_with_edl_and_colors(xvfb_display, tmp_path):
    result = run_python(f"""
        import time
        import numpy as np
        from surfsplat import api
        from surfsplat import pipeline
        from surfsplat.pipeline import LodOptions, SourceOptions, View
        from surfsplat.lighting import Lights
        from surfsplat.rendering.options import RenderOptions
        from surfsplat.scenes_faulty import aerial
        from surfsplat.viewer import app, detail
        detail.REFINE_MIN = 500
        model = pipeline.as_splats(aerial(n=8000, houses=3, trees=3).cloud)
        glfw, window, ctx = app.open_window(240, 180, "test")
        plan = View(model, lod=LodOptions(point_budget=4000), source_options=SourceOptions(hybrid=True),
                    interactive=True)
        v = app.Viewer(glfw, window, ctx, plan, pipeline.CameraSpec(up=(0, 0, 1)), technique="ewa", lights=Lights(),
                       options=RenderOptions(), background=(1, 1, 1),
                       motion=app.MotionOptions("off"), hud=False, record=r"{tmp_path}/rec.gif")
        assert v.budgets == [500, 1000, 4000]
        drawn, images = [], []
        v.step(wait=False)
        drawn.append(v.drawn); images.append(v.full_image())
        while v.refine + 1 < len(v.budgets) or v.fade_from is not None:
            before = v.refine
            v.step(wait=False)
            if v.refine != before:
                # the new step is faded in from the previous one: halfway, the screen is their mean
                v.present(0.5)
                mid = v.screen_image().astype(int)
                prev = np.frombuffer(v._targets["previous"].read(), np.uint8).reshape(180, 240, 4)[::-1, :, :3]
                full = v.full_image().astype(int)
                assert np.abs(mid - (prev.astype(int) + full) / 2).max() <= 2
                drawn.append(v.drawn); images.append(full)
        assert drawn == sorted(drawn) and drawn[-1] <= 4000 and drawn[0] <= 500 and len(drawn) == 3
        assert np.abs(images[0].astype(int) - images[-1]).mean() > 0.5   # the refinement changed the image
        # O: eye-dome lighting darkens depth edges of the still view
        plain = v.full_image().astype(int)
        v._on_key(window, glfw.KEY_O, 0, glfw.PRESS, 0)
        v.step(wait=False)
        assert v.options.edl is not None and v.refine == 0   # a change starts the refinement again
        while v.refine + 1 < len(v.budgets) or v.fade_from is not None:
            v.step(wait=False)
        shaded = v.full_image().astype(int)
        assert (shaded <= plain + 1).all() and (shaded < plain - 20).any()
        # C: colour by elevation, then classification (ASPRS palette)
        assert v.color_modes[:2] == ["own colours", "elevation"] and "classification" in v.color_modes
        v._on_key(window, glfw.KEY_C, 0, glfw.PRESS, 0)
        v.step(wait=False)
        while v.refine + 1 < len(v.budgets) or v.fade_from is not None or v.full_version != v.version:
            v.step(wait=False)
        by_height = v.full_image().astype(int)
        assert np.abs(by_height - shaded).mean() > 5
        v.release()
        glfw.terminate()
        print("ok", v.recorder.frames)
        """, xvfb_display)
    assert result.returncode == 0 and result.stdout.strip().splitlines()[-1].startswith("ok"), result.stderr
    frames = int(result.stdout.strip().split()[-1])
    with Image.open(tmp_path / "rec.gif") as gif:
        assert 1 <= gif.n_frames <= frames   # Pillow merges repeated frames into longer ones
        total = 0
        for i in range(gif.n_frames):
            gif.seek(i)
            total += gif.info["duration"]
        assert abs(total - frames * 1000 / 24) <= 2 * frames   # the real-time clock: 24 frames/s


# -- a chunked hierarchy: cells streamed in the background ----------------------------------------


@pytest.fixture(scope="module")
def chunked_model(tmp_path_factory):
    """A small chunked hierarchy (a 12 k-point torus far from zero, in several cells) and its path."""
    from surfsplat.hierarchy.chunked import build_chunked
    from test_chunked import torus_points, write_ply

    folder = tmp_path_factory.mktemp("chunked_view")
    source = write_ply(folder / "torus.ply", torus_points(12_000, seed=5))
    build_chunked(source, folder / "torus.ssh", cell_points=3_000, chunk_points=8_000, scheduler="synchronous")
    return folder / "torus.ssh"


def test_streamer_reads_cells_in_the_background_once(chunked_model):
    import threading

    from surfsplat.hierarchy.chunked import open_chunked
    from surfsplat.viewer.streaming import CellStreamer

    model = open_chunked(chunked_model)
    camera = surfsplat.pipeline.resolve_camera(model, None, 240, 180)
    reference = open_chunked(chunked_model).view_splats(camera, 1.0)[0]
    gate, threads, runs = threading.Event(), [], []

    def cut(tag):
        def run():
            threads.append(threading.current_thread())
            runs.append(tag)
            assert gate.wait(10)
            return model.view_splats(camera, 1.0)
        return run

    streamer = CellStreamer()
    try:
        start = time.perf_counter()
        assert streamer.poll("a", cut("a")) is None and streamer.pending   # the read is held at the gate
        assert streamer.poll("a", cut("a")) is None   # asking again does not start a second read
        assert time.perf_counter() - start < 0.5 and model.loads == 0
        assert streamer.poll("b", cut("b")) is None   # queued behind "a" ...
        assert streamer.poll("c", cut("c")) is None   # ... and dropped for the newer view, never run
        gate.set()
        cloud, selection = streamer.result("c", cut("c"))
        assert runs == ["a", "c"] and streamer.submitted == 3
        assert all(t is not threading.main_thread() for t in threads)
        np.testing.assert_array_equal(cloud.positions, reference.positions)
        assert np.allclose(cloud.origin, reference.origin) and selection.cells_loaded >= 2
        # each needed cell was read once: "c" found in the cache every cell "a" had read
        assert model.loads == len(model.cached) == selection.cells_loaded
        assert streamer.poll("c", cut("c"))[0] is cloud and not streamer.pending and model.loads == len(model.cached)
    finally:
        gate.set()
        streamer.close()
    # the motion preview is what opening read (the preview splats, drawn whole), no cell
    fresh = open_chunked(chunked_model)
    assert preview_cloud(fresh, 1000) is None and 1000 < len(fresh.points) < fresh.point_count
    assert fresh.loads == 0


def test_view_of_a_chunked_model_matches_render(xvfb_display, chunked_model, tmp_path):
    out = tmp_path / "view.png"
    result = run_view(["-q", "view", chunked_model, "--frames", 2, "--size", 240, 180, "--point-budget", 4000,
                       "--screenshot", out], xvfb_display)
    assert result.returncode == 0, result.stderr
    shot = np.asarray(Image.open(out)).astype(float)
    expected = surfsplat.render(chunked_model, width=240, height=180,
                                lod=surfsplat.LodOptions(point_budget=4000)).image().astype(float)
    covered = (expected < 250).any(axis=2).mean()
    assert 0.1 < covered < 0.9   # the model is framed, not empty
    mse = ((shot - expected) ** 2).mean()
    assert mse == 0 or 10 * np.log10(255.0 ** 2 / mse) > 35.0


def test_window_keeps_drawing_while_cells_stream(xvfb_display, chunked_model):
    # the cut is slowed down: the loop does not wait for it, shows the preview, then the full frame
    result = run_python(f"""
        import time
        import numpy as np
        from surfsplat.pipeline import LodOptions, SourceOptions, View
        from surfsplat.pipeline import CameraSpec
        from surfsplat.lighting import Lights
        from surfsplat.rendering.options import RenderOptions
        from surfsplat.viewer import app
        from surfsplat.hierarchy.chunked import ChunkedHierarchy
        from surfsplat.hierarchy.chunked import open_chunked
        model = open_chunked(r"{chunked_model}")
        cut = ChunkedHierarchy.view_splats
        def slow(self, *args, **kw):   # on the class: recoloured copies are slow too
            time.sleep(1.0)
            return cut(self, *args, **kw)
        ChunkedHierarchy.view_splats = slow
        glfw, window, ctx = app.open_window(240, 180, "test")
        v = app.Viewer(glfw, window, ctx, View(model, interactive=True), CameraSpec(), technique="ewa", lights=Lights(),
                       options=RenderOptions(), background=(1, 1, 1),
                       motion=app.MotionOptions("flat", budget=1000), hud=True)
        start = time.perf_counter()
        v.step(wait=False)
        assert time.perf_counter() - start < 0.8, "the loop waited for the cells"
        assert v.lod.pending and v.showing_preview and v.full_frames == 0 and v.preview_frames == 1
        assert v.preview_splats.count == len(model.points) and model.loads == 0   # the stored preview
        assert "reading cells" in v.status_text()
        preview = v.screen_image()
        assert (preview[90:] < 200).any(axis=2).mean() > 0.05   # the preview shows the model (below the HUD)
        turns = 1
        while v.full_version != v.version or v.fade_from is not None:
            v.step(wait=False)
            turns += 1
        assert turns > 3 and v.full_frames == 1 and model.loads > 0
        full = v.full_image()
        assert (full < 200).any(axis=2).mean() > 0.05
        # C: colour by elevation; the preview at once, the still view read again and coloured
        assert v.color_modes[:2] == ["own colours", "elevation"]
        v._on_key(window, glfw.KEY_C, 0, glfw.PRESS, 0)
        v.step(wait=False)
        assert v.color_index == 1 and "colour by elevation" in v.status_text()
        assert np.ptp(v.lod.hierarchy.points.colors, axis=0).max() > 0.3   # the preview coloured
        deadline = time.perf_counter() + 30
        while (v.full_version != v.version or v.fade_from is not None) and time.perf_counter() < deadline:
            v.step(wait=False)
        colored = v.full_image().astype(int)
        assert v.full_frames == 2, v.full_frames
        saturation = colored.max(axis=2) - colored.min(axis=2)
        grey = full.astype(int).max(axis=2) - full.astype(int).min(axis=2)
        assert (saturation > 40).mean() > 0.02 and (grey > 40).mean() < 0.01, ((saturation > 40).mean(),
                                                                             (grey > 40).mean())
        v.release()
        glfw.terminate()
        print("ok", turns)
        """, xvfb_display)
    assert result.returncode == 0 and result.stdout.strip().splitlines()[-1].startswith("ok"), result.stderr


def test_preview_levels_are_nested_coarse_to_fine_cuts_within_the_budget():
    # the motion preview's ladder: each level a hole-free uniform cut, about 4x fewer splats per step
    from surfsplat.hierarchy import build_hierarchy
    from surfsplat.viewer.detail import PREVIEW_MIN, preview_levels
    torus = surfsplat.scenes.torus(n_major=800, n_minor=320)
    h = build_hierarchy(torus)
    levels = preview_levels(h, 100_000)
    counts = [len(level) for level in levels]
    assert len(levels) >= 2 and counts == sorted(set(counts)), counts
    assert counts[-1] <= 100_000 and counts[0] >= PREVIEW_MIN
    for coarse, fine in zip(counts, counts[1:]):
        assert coarse <= fine // 4   # a step at least 4x: octree levels
    # every level covers the model: same bounds within the coarse splats' size
    lo, hi = torus.bounds()
    for level in levels:
        llo, lhi = level.bounds()
        assert np.all(np.abs(llo - lo) < 0.1 * np.linalg.norm(hi - lo))
    assert preview_levels(h, len(torus) + 1)[-1] is None   # the whole model is the finest level
    assert preview_levels(h, 0) == [None]


def test_preview_level_follows_the_frame_time():
    from surfsplat.viewer.detail import PREVIEW_HEADROOM, PREVIEW_SHARE, next_preview_level
    counts = [5_000, 20_000, 80_000]
    target = 1.0 / 25.0
    assert next_preview_level(2, counts, 0.01, 25.0, frame_s=2.0 * target) == 1   # too slow: coarser
    assert next_preview_level(0, counts, 0.01, 25.0, frame_s=2.0 * target) == 0   # nothing coarser
    # the finer level: the frame plus 3x more render time (4x the splats) must fit under the headroom
    assert next_preview_level(1, counts, 0.002, 25.0, frame_s=0.01) == 2
    render = 0.004
    just_over = PREVIEW_HEADROOM * target - 3 * render + 1e-4
    assert next_preview_level(1, counts, render, 25.0, frame_s=just_over) == 1
    assert next_preview_level(1, counts, render, 25.0, frame_s=just_over - 2e-4) == 2
    assert next_preview_level(2, counts, 0.001, 25.0, frame_s=0.002) == 2         # nothing finer
    assert next_preview_level(0, counts, 10.0, 0.0) == 2                          # fps 0: always the finest
    # without the frame's time, the render is taken as PREVIEW_SHARE of it
    assert next_preview_level(2, counts, 1.01 * PREVIEW_SHARE * target, 25.0) == 1
    assert next_preview_level(2, counts, 0.99 * PREVIEW_SHARE * target, 25.0) == 2
    # no flip-flop: after stepping down because level 2's frame was too slow, the prediction from
    # level 1 (its frame plus 3x its render) is not under the headroom
    fixed, per_splat = 0.02, 0.5e-6
    frame2 = fixed + per_splat * counts[2]
    frame1 = fixed + per_splat * counts[1]
    assert frame2 > target and next_preview_level(2, counts, frame2 - 0.015, 25.0, frame2) == 1
    assert next_preview_level(1, counts, frame1 - 0.015, 25.0, frame1) == 1


def test_viewer_draws_two_sided_by_default_and_b_culls(xvfb_display):
    # as render does: automatic culling never culls (it can open holes), a closed surface neither; B culls
    result = run_python("""
        from surfsplat import scenes
        from surfsplat.lighting import Lights
        from surfsplat.pipeline import LodOptions, SourceOptions, View
        from surfsplat.rendering.options import RenderOptions
        from surfsplat.viewer import app
        from surfsplat.viewer import camera_control as cc
        glfw, window, ctx = app.open_window(160, 120, "test")
        kw = dict(technique="ewa", lights=Lights(), options=RenderOptions(), background=(1, 1, 1),
                  motion=app.MotionOptions("off"), hud=False)
        torus = app.Viewer(glfw, window, ctx, View("demo:torus", interactive=True), None, **kw)
        assert torus.options.visibility.cull_backfaces is None and not torus.culling
        assert torus.drawn_options().visibility.cull_backfaces is False
        torus._actions.append(("cull",))
        torus._process_input(0.0)
        assert torus.options.visibility.cull_backfaces is True and torus.culling
        assert torus.drawn_options().visibility.cull_backfaces is True
        torus.release()
        sheet = app.Viewer(glfw, window, ctx, View(scenes.checkerboard(n_side=100), interactive=True), None, **kw)
        assert not sheet.culling
        print("ok")
        """, xvfb_display)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("ok")


@pytest.mark.parametrize("options", [dict(fps="x"), dict(fps=None), dict(fps=float("nan")), dict(fps=-1.0),
                                     dict(fps=1e9), dict(scale="a"), dict(budget=1.5), dict(budget="3"),
                                     dict(budget=float("inf")), dict(budget=True)])
def test_motion_options_refuse_bad_values_clearly(options):
    with pytest.raises(InputError, match="motion"):
        surfsplat.MotionOptions(**options)
