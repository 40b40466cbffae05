"""The exported page in a real browser: Debian's Chromium, headless, WebGL2 on SwiftShader, driven over
the DevTools protocol (surfsplat/web/browser.py). Its canvas is held against the desktop renderer's
picture of the same camera; the tests skip where no Chromium is installed (.ci/run installs it)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from surfsplat.camera import Camera
from surfsplat.metrics import psnr
from surfsplat.pipeline import View
from surfsplat.rendering.options import EdlOptions, RenderOptions, VisibilityOptions
from surfsplat.scenes import torus
from surfsplat.web import export
from surfsplat.pipeline import SourceOptions
from surfsplat.web.browser import Browser, BrowserError, file_url, find_chromium
from surfsplat.web.export import as_drawn, exported_splats
from surfsplat.web.shaders import PROGRAMS

pytestmark = [pytest.mark.browser, pytest.mark.gl,
              pytest.mark.skipif(find_chromium() is None,
                                 reason="no Chromium: install Debian's chromium package (.ci/run does)")]

W, H = 320, 240
READY = "document.body && document.body.getAttribute('data-ready') === '1'"


@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


@pytest.fixture(scope="module")
def model():
    return torus(160, 64)


@pytest.fixture(scope="module")
def site(model, tmp_path_factory):
    out = tmp_path_factory.mktemp("web") / "site"
    export(model, out)
    return out


def camera_hash(camera: Camera, technique: str, edl: bool | None = None) -> str:
    vec = lambda v: ",".join(repr(float(x)) for x in v)   # noqa: E731
    extra = "" if edl is None else f"&edl={int(edl)}"
    return (f"#eye={vec(camera.eye)}&target={vec(camera.target)}&up={vec(camera.up)}&fov={camera.fov}"
            f"&technique={technique}{extra}")


def opened(browser, url, width=W, height=H):
    page = browser.page(url, width, height)
    page.wait_for(READY, timeout=60)
    assert page.collect() == []
    return page


def test_the_driver_reports_a_page_s_errors(browser, tmp_path):
    # what "no error" in the other tests rests on: an exception, console.error and a failed load are caught
    page_file = tmp_path / "bad.html"
    page_file.write_text("<html><body><script>console.error('first'); setTimeout(function () { "
                         "throw new Error('second'); }, 0);</script><script src='missing.js'></script>"
                         "<div id='done'></div></body></html>")
    page = browser.page(file_url(page_file), 200, 100)
    try:
        with pytest.raises(BrowserError, match="reported errors"):
            page.wait_for("false", timeout=10)
        end = time.monotonic() + 10
        while not all(word in " | ".join(page.collect()) for word in ("first", "second", "missing.js")):
            assert time.monotonic() < end, page.errors
            time.sleep(0.05)
    finally:
        page.close()


def test_the_page_opens_from_a_file_url_at_the_render_default_view(browser, site, model):
    page = opened(browser, file_url(site / "index.html"))
    try:
        state = page.evaluate("JSON.stringify({camera: surfsplat.camera, errors: surfsplat.errors, "
                              "w: document.getElementById('view').width, h: document.getElementById('view').height, "
                              "hud: document.getElementById('hud').textContent})")
        state = json.loads(state)
        assert state["errors"] == [] and (state["w"], state["h"]) == (W, H)
        expected = View(model).camera(None, W, H)
        assert np.allclose(state["camera"]["eye"], expected.eye, rtol=0, atol=1e-9)
        assert np.allclose(state["camera"]["target"], expected.target, rtol=0, atol=1e-9)
        assert f"{len(model):,} splats drawn" in state["hud"] and "ms/frame" in state["hud"]
        # every program of shaders.js compiled and linked in the browser (a failure is an error above)
        assert sorted(page.evaluate("surfsplat.programs")) == sorted(PROGRAMS)
        image = page.canvas()
        assert image.shape == (H, W, 3) and (image.min(axis=2) < 250).mean() > 0.1   # the torus is drawn
    finally:
        page.close()


#: What the page draws of the desktop's visibility options: no edge coverage, back faces drawn (the web guide).
PAGE_VISIBILITY = VisibilityOptions(edge_coverage=False, cull_backfaces=False)


# measured at 320 x 240 (SwiftShader against llvmpipe): ewa identical, flat 43.6 dB (opaque disks at one depth
# rounded apart), points with EDL 87.0 dB
@pytest.mark.parametrize("technique,least", [("ewa", 60.0), ("flat", 40.0), ("points", 60.0)])
def test_the_canvas_is_the_desktop_render_of_the_same_camera(browser, site, model, technique, least):
    view = View(as_drawn(model))
    camera = Camera(eye=(2.2, -1.1, 2.6), target=(0.1, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=35.0, width=W, height=H)
    camera = view.camera(camera)
    # the page has no edge coverage and draws back faces (the web guide): the desktop's picture without them
    options = RenderOptions(visibility=PAGE_VISIBILITY, edl=EdlOptions() if technique == "points" else None)
    reference = view.render(camera, technique=technique, options=options).frame.image()
    page = opened(browser, file_url(site / "index.html", "?ui=0" + camera_hash(camera, technique)))
    try:
        canvas = page.canvas()
    finally:
        page.close()
    assert psnr(canvas / 255.0, reference / 255.0) >= least
    # no hole: pixels the desktop covers that the page leaves as background
    background = (canvas == 255).all(axis=2)
    covered = ~(reference == 255).all(axis=2)
    assert (background & covered).sum() <= 0.001 * covered.sum()


def test_a_drag_orbits_the_view_and_the_address_keeps_it(browser, site):
    page = opened(browser, file_url(site / "index.html"))
    try:
        before_camera, before = page.evaluate("JSON.stringify(surfsplat.camera)"), page.canvas()
        page.drag((W / 2, H / 2), (W / 2 + 60, H / 2 + 10))
        page.wait_for("location.hash.indexOf('eye=') >= 0", timeout=10)
        after_camera = page.evaluate("JSON.stringify(surfsplat.camera)")
        frames = page.evaluate("surfsplat.frames")
        page.wait_for(f"surfsplat.frames >= {frames}", timeout=10)
        after = page.canvas()
        url = page.evaluate("location.href")
        assert page.collect() == []
    finally:
        page.close()
    assert after_camera != before_camera
    assert np.abs(after.astype(int) - before.astype(int)).max() > 100
    again = opened(browser, url)   # the shared address opens the same view
    try:
        shared = json.loads(again.evaluate("JSON.stringify(surfsplat.camera)"))
    finally:
        again.close()
    moved = json.loads(after_camera)
    assert np.allclose(shared["eye"], moved["eye"], rtol=1e-8) and np.allclose(shared["target"], moved["target"],
                                                                                  rtol=1e-8, atol=1e-9)


def test_the_wheel_zooms_toward_the_target(browser, site):
    page = opened(browser, file_url(site / "index.html"))
    try:
        distance = "(function (c) { return Math.hypot(c.eye[0] - c.target[0], c.eye[1] - c.target[1], " \
                   "c.eye[2] - c.target[2]); })(surfsplat.camera)"
        before = page.evaluate(distance)
        page.call("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": W / 2, "y": H / 2, "deltaX": 0,
                                               "deltaY": -200})
        page.wait_for(f"{distance} < {before}", timeout=10)
        after = page.evaluate(distance)
        assert after == pytest.approx(before * np.exp(-200 * 0.0015), rel=1e-6)   # viewer.js: exp(0.0015 dy)
        assert page.collect() == []
    finally:
        page.close()


def test_a_pinch_zooms_and_one_finger_orbits(browser, site):
    page = opened(browser, file_url(site / "index.html"))
    try:
        page.call("Emulation.setTouchEmulationEnabled", {"enabled": True, "maxTouchPoints": 2})
        distance = "(function (c) { return Math.hypot(c.eye[0] - c.target[0], c.eye[1] - c.target[1], " \
                   "c.eye[2] - c.target[2]); })(surfsplat.camera)"
        before = page.evaluate(distance)

        def touch(kind, points):
            page.call("Input.dispatchTouchEvent", {"type": kind, "touchPoints": [
                {"x": x, "y": y, "id": i} for i, (x, y) in enumerate(points)]})

        touch("touchStart", [(W / 2 - 20, H / 2), (W / 2 + 20, H / 2)])
        for step in range(1, 5):   # the fingers move apart: zoom in
            touch("touchMove", [(W / 2 - 20 - 10 * step, H / 2), (W / 2 + 20 + 10 * step, H / 2)])
        touch("touchEnd", [])
        page.wait_for(f"{distance} < {0.9 * before}", timeout=10)
        target = page.evaluate("JSON.stringify(surfsplat.camera.target)")
        eye = page.evaluate("JSON.stringify(surfsplat.camera.eye)")
        touch("touchStart", [(W / 2, H / 2)])
        touch("touchMove", [(W / 2 + 40, H / 2)])
        touch("touchEnd", [])
        page.wait_for(f"JSON.stringify(surfsplat.camera.eye) !== {json.dumps(eye)}", timeout=10)
        assert page.evaluate("JSON.stringify(surfsplat.camera.target)") == target   # an orbit keeps the target
        assert page.collect() == []
    finally:
        page.close()


def test_keys_orbit_and_switch_the_technique(browser, site):
    page = opened(browser, file_url(site / "index.html"))
    try:
        page.evaluate("document.getElementById('view').focus()")
        start = page.evaluate("JSON.stringify(surfsplat.camera)")
        page.key("ArrowLeft", key_code=37)
        page.wait_for(f"JSON.stringify(surfsplat.camera) !== {json.dumps(start)}", timeout=10)
        page.key("t", code="KeyT", key_code=84)
        assert page.wait_for("surfsplat.technique === 'flat' && document.getElementById('technique').value === 'flat'",
                             timeout=10)
        assert page.collect() == []
    finally:
        page.close()


def test_one_self_contained_file_with_ui_0_shows_no_overlay(browser, model, tmp_path):
    single = tmp_path / "model.html"
    export(model, single, technique="points")
    page = opened(browser, file_url(single, "?ui=0"))
    try:
        shown = page.evaluate("Array.from(document.querySelectorAll('.overlay')).filter("
                              "e => getComputedStyle(e).display !== 'none').length")
        assert shown == 0
        assert page.evaluate("surfsplat.technique === 'points' && surfsplat.edl")
        assert (page.canvas().min(axis=2) < 250).mean() > 0.1
    finally:
        page.close()


# (file, source options, technique, least PSNR): a mesh, a CAD part (sampled small), aerial LiDAR; measured
# at 320 x 240: 97.0, 65.5 and 87.6 dB (the same splats in the same order: the same pictures but for rounding)
DATA = [("bunny.ply", SourceOptions(samples=30_000), "ewa", 60.0),
        ("frag_115.ply", SourceOptions(samples=30_000), "flat", 50.0),
        ("simple.las", None, "points", 60.0)]


@pytest.mark.parametrize("name,options,technique,least", DATA, ids=[d[0] for d in DATA])
def test_real_data_pages_match_the_desktop(browser, shared_data, tmp_path, name, options, technique, least):
    source = shared_data / name
    out = tmp_path / "site"
    export(source, out, technique=technique, source_options=options)
    plan = View(source, source_options=options)
    drawn = View(as_drawn(exported_splats(plan, plan.camera(None, 1024, 1024), None)))
    camera = plan.camera(None, W, H)
    page_options = RenderOptions(visibility=PAGE_VISIBILITY, edl=EdlOptions() if technique == "points" else None)
    reference = drawn.render(camera, technique=technique, options=page_options).frame.image()
    page = opened(browser, file_url(out / "index.html", "?ui=0"))
    try:
        canvas = page.canvas()
        shown = json.loads(page.evaluate("JSON.stringify(surfsplat.camera)"))
    finally:
        page.close()
    assert np.allclose(shown["eye"], camera.eye, rtol=1e-9, atol=1e-9)   # the render's default view
    assert psnr(canvas / 255.0, reference / 255.0) >= least


@pytest.fixture(scope="module")
def hierarchy_file(tmp_path_factory):
    from surfsplat.hierarchy import build_hierarchy, save_hierarchy
    path = tmp_path_factory.mktemp("lod") / "torus.npz"
    save_hierarchy(build_hierarchy(torus(200, 80)), path)
    return path


# measured at 320 x 240: 2,000 -> 55.8 dB, 6,000 (5,997 drawn) -> 47.2 dB: the same cut as the desktop's, drawn
# in another order (the page draws every entry of a cut as a GL_POINTS point)
@pytest.mark.parametrize("budget", [2_000, 6_000])
def test_the_page_cuts_a_hierarchy_within_the_budget_as_the_desktop_does(browser, hierarchy_file, tmp_path, budget):
    from surfsplat.pipeline import LodOptions
    out = tmp_path / "site"
    export(hierarchy_file, out, browser_lod=True, point_budget=budget)
    view = View(hierarchy_file, lod=LodOptions(tolerance=1.0, point_budget=budget, shading="flat"))
    result = view.render(view.camera(None, W, H), technique="ewa", options=RenderOptions(visibility=PAGE_VISIBILITY))
    page = opened(browser, file_url(out / "index.html", "?ui=0"))
    try:
        drawn, canvas = page.evaluate("surfsplat.drawn"), page.canvas()
        # more budget on the page: more drawn, up to the tolerance cut
        page.evaluate("var e = document.getElementById('budget'); e.value = 100000; "
                      "e.dispatchEvent(new Event('change'))")
        page.wait_for(f"surfsplat.drawn > {drawn}", timeout=20)
        assert page.collect() == []
    finally:
        page.close()
    assert drawn <= budget and drawn == result.splats   # Potree's priority, the same cut as hierarchy.lod.select
    assert psnr(canvas / 255.0, result.frame.image() / 255.0) >= 40.0
