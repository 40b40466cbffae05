"""The exported page in a real browser: Debian's Chromium, headless, WebGL2 on SwiftShader, driven over
the DevTools protocol (surfsplat/web/browser.py). Its canvas is held against the desktop renderer's
picture of the same camera; the tests skip where no Chromium is installed (.ci/run installs it)."""

from __future__ import annotations

import base64
import io
import json
import time
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from surfsplat.camera import Camera
from surfsplat.metrics import psnr
from surfsplat.pipeline import View
from surfsplat.rendering.options import EdlOptions, RenderOptions, VisibilityOptions
from surfsplat.scenes import torus
from surfsplat.web import export
from surfsplat.pipeline import SourceOptions
from surfsplat.web.browser import Browser, BrowserError, file_url, find_chromium
from surfsplat.web.export import as_drawn, exported_splats
from surfsplat.web.shaders import PROGRAMS, WEB_TECHNIQUES

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
        # programs are compiled on first use: the default ewa page's frames needed ewa's and the points preview's
        # alone; asked, every program of shaders.js compiles and links in the browser (a failure: an error)
        used = set(page.evaluate("surfsplat.programs"))
        assert {"ewa_visibility_points", "ewa_accumulation_points", "normalize_edges"} <= used
        assert not used & {"phong_accumulation", "flat", "blend_visibility_points"}
        assert sorted(page.evaluate("surfsplat.compileAll()")) == sorted(PROGRAMS)
        assert page.collect() == [] and page.evaluate("surfsplat.errors.length") == 0
        image = page.canvas()
        assert image.shape == (H, W, 3) and (image.min(axis=2) < 250).mean() > 0.1   # the torus is drawn
    finally:
        page.close()


# measured at 320 x 240 against the desktop's defaults (SwiftShader against llvmpipe; edge coverage and the fill
# pass): ewa 97.0 dB, perspective 97.0 dB, phong 98.7 dB, blend 98.7 dB, flat 43.6 dB (opaque disks at one
# depth rounded apart), points with EDL 87.0 dB
NEIGHBOUR = {"ewa": "perspective", "perspective": "ewa", "phong": "blend", "blend": "phong", "flat": "phong",
             "points": "flat"}


@pytest.mark.parametrize("technique,least", [("ewa", 80.0), ("perspective", 80.0), ("phong", 80.0), ("blend", 80.0),
                                             ("flat", 40.0), ("points", 75.0)])
def test_the_canvas_is_the_desktop_render_of_the_same_camera(browser, site, model, technique, least):
    view = View(as_drawn(model))
    camera = Camera(eye=(2.2, -1.1, 2.6), target=(0.1, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=35.0, width=W, height=H)
    camera = view.camera(camera)
    # the desktop's defaults (ewa with edge coverage; a cloud is drawn two-sided)
    options = RenderOptions(edl=EdlOptions() if technique == "points" else None)
    reference = view.render(camera, technique=technique, options=options).frame.image()
    page = opened(browser, file_url(site / "index.html", "?ui=0" + camera_hash(camera, technique)))
    try:
        canvas = page.canvas()
    finally:
        page.close()
    assert psnr(canvas / 255.0, reference / 255.0) >= least
    # the technique asked for, not its neighbour (the same passes with another footprint or kernel)
    other = view.render(camera, technique=NEIGHBOUR[technique], options=options).frame.image()
    assert psnr(canvas / 255.0, other / 255.0) < psnr(canvas / 255.0, reference / 255.0) - 10
    # no hole: pixels the desktop covers that the page leaves as background
    background = (canvas == 255).all(axis=2)
    covered = ~(reference == 255).all(axis=2)
    assert (background & covered).sum() <= 0.001 * covered.sum()


# measured at 320 x 240: the preview is the desktop's points of the same subset pixel for pixel (SwiftShader against
# llvmpipe), no hole; the full frame after it against the desktop's ewa 97.0 dB, as without a preview
def test_a_large_page_s_first_frame_is_a_decimated_preview_then_the_full_frame(browser, site, model):
    # ?preview=N: the first frame from about N splats (a page of over 131,072 splats does this by default)
    view = View(as_drawn(model))
    camera = view.camera(Camera(eye=(2.2, -1.1, 2.6), target=(0.1, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=35.0,
                                width=W, height=H))
    page = opened(browser, file_url(site / "index.html", "?ui=0&profile=1&preview=2048" + camera_hash(camera, "ewa")))
    try:
        step, splats = page.evaluate("surfsplat.previewStep"), page.evaluate("surfsplat.firstDrawn")
        first = page.evaluate("surfsplat.firstImage")
        canvas = page.canvas()
        hud = page.evaluate("document.getElementById('hud').textContent")
    finally:
        page.close()
    assert step == -(-len(model) // 2048) == 5 and splats == len(range(0, len(model), step))
    preview = np.asarray(Image.open(io.BytesIO(base64.b64decode(first.split(",", 1)[1]))).convert("RGB"))
    # the preview: every 5th splat of the page's order as points, their axes grown by sqrt(5) (the same area)
    drawn = as_drawn(model)
    grow = np.float32(np.sqrt(step))
    rows = np.arange(0, len(drawn), step)
    subset = drawn.subset(rows).replace(u=drawn.u[rows] * grow, v=drawn.v[rows] * grow)
    points = View(subset).render(camera, technique="points", options=RenderOptions()).frame.image()
    assert psnr(preview / 255.0, points / 255.0) >= 80.0
    # it covers the surface: the full frame's covered pixels it leaves as background are few
    covered = ~(canvas == 255).all(axis=2)
    assert ((preview == 255).all(axis=2) & covered).sum() <= 0.002 * covered.sum()
    # then the full frame of every splat, unchanged
    options = RenderOptions()
    reference = view.render(camera, technique="ewa", options=options).frame.image()
    assert psnr(canvas / 255.0, reference / 255.0) >= 80.0
    assert f"{len(model):,} splats drawn" in hud and "preview" not in hud


# measured at 320 x 240 against `surfsplat render --supersample K` of the same splats: ewa 101.8 dB (K = 2), points
# with EDL 85.7 dB (K = 2), 86.3 (K = 3); against the render at K = 1 they score 41.3 and 21.5 dB
@pytest.mark.parametrize("technique,k,least", [("ewa", 2, 80.0), ("points", 3, 75.0)])
def test_a_supersampled_page_is_the_supersampled_render(browser, site, model, technique, k, least):
    view = View(as_drawn(model))
    camera = View(model).camera(None, W, H)   # the page's default view
    options = RenderOptions(edl=EdlOptions() if technique == "points" else None)
    reference = view.render(camera, technique=technique, options=options, supersample=k).frame.image()
    single = view.render(camera, technique=technique, options=options).frame.image()
    page = opened(browser, file_url(site / "index.html", f"?ui=0&supersample={k}&technique={technique}"))
    try:
        canvas = page.canvas()
    finally:
        page.close()
    near = psnr(canvas / 255.0, reference / 255.0)
    assert near >= least and psnr(canvas / 255.0, single / 255.0) < near - 20


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
        following = WEB_TECHNIQUES[WEB_TECHNIQUES.index("ewa") + 1]   # the menu's order
        assert page.wait_for(f"surfsplat.technique === '{following}' && "
                             f"document.getElementById('technique').value === '{following}'", timeout=10)
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


# (file, source options, technique, least PSNR): a mesh, a scan mesh (sampled), aerial LiDAR; measured at 320 x 240
# against the desktop's defaults (edge coverage, the fill pass, back faces culled where the view plan culls them):
# the bunny's pictures are equal, frag 78.6 to 84.4 dB (on the pixels but the depth ties below; the 4 or 2 pixels
# its fill pass fills are the desktop's), the LAS sample 87.6 dB (the same splats in the same order: the same
# pictures but for rounding)
DATA = [("bunny.ply", SourceOptions(samples=30_000), "ewa", 80.0),
        ("frag_115.ply", SourceOptions(samples=30_000), "flat", 75.0),
        ("simple.las", None, "points", 75.0)]
#: The share of the pixels where two opaque disks meet the pixel's ray at one depth to float precision (at
#: most 1e-7 apart at a depth of 2.5), so the browser's and the desktop's GL round them apart and draw another
#: disk: the sampled scan mesh's coplanar samples show one such pixel at 320 x 240, or none.
DEPTH_TIES = 1e-4


@pytest.mark.parametrize("name,options,technique,least", DATA, ids=[d[0] for d in DATA])
def test_real_data_pages_match_the_desktop(browser, shared_data, tmp_path, name, options, technique, least):
    source = shared_data / name
    out = tmp_path / "site"
    export(source, out, technique=technique, source_options=options)
    plan = View(source, source_options=options)
    drawn = View(as_drawn(exported_splats(plan, plan.camera(None, 1024, 1024), None)))
    camera = plan.camera(None, W, H)
    # the desktop's defaults, back faces culled where the view plan culls them (the mesh's samples with ewa)
    culls = VisibilityOptions(cull_backfaces=plan.culls(camera, technique=technique))
    options = RenderOptions(visibility=culls, edl=EdlOptions() if technique == "points" else None)
    reference = drawn.render(camera, technique=technique, options=options).frame.image()
    unfilled = drawn.render(camera, technique=technique, options=replace(options, fill_holes=False)).frame.image()
    page = opened(browser, file_url(out / "index.html", "?ui=0"))
    try:
        canvas = page.canvas()
        shown = json.loads(page.evaluate("JSON.stringify(surfsplat.camera)"))
    finally:
        page.close()
    assert np.allclose(shown["eye"], camera.eye, rtol=1e-9, atol=1e-9)   # the render's default view
    apart = np.abs(canvas.astype(int) - reference.astype(int)).max(axis=2) > 8
    # every pixel the desktop's fill pass fills, the page fills with the same color
    filled = (unfilled != reference).any(axis=2)
    assert not (apart & filled).any()
    # elsewhere the same picture but for disks at one depth to float precision
    assert apart.sum() <= DEPTH_TIES * apart.size
    assert psnr(canvas / 255.0, reference / 255.0, mask=~apart) >= least


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
    result = view.render(view.camera(None, W, H), technique="ewa", options=RenderOptions())
    # the first frame: the cut within the preview's budget (?preview=N; 131,072 unless told), then the page's
    page = opened(browser, file_url(out / "index.html", "?ui=0&preview=1000"))
    try:
        drawn, canvas = page.evaluate("surfsplat.drawn"), page.canvas()
        assert page.evaluate("surfsplat.firstDrawn") <= 1000 < drawn
        # more budget on the page: more drawn, up to the tolerance cut
        page.evaluate("var e = document.getElementById('budget'); e.value = 100000; "
                      "e.dispatchEvent(new Event('change'))")
        page.wait_for(f"surfsplat.drawn > {drawn}", timeout=20)
        assert page.collect() == []
    finally:
        page.close()
    assert drawn <= budget and drawn == result.splats   # Potree's priority, the same cut as hierarchy.lod.select
    assert psnr(canvas / 255.0, result.frame.image() / 255.0) >= 50.0   # measured 56.0 and 54.5 dB


# measured at 320 x 240: 53.8 dB (points + EDL; ewa 39.2 dB: the desktop draws LiDAR's non-planar splats as
# round points, the page as splats)
def test_colour_by_classification_on_the_page_is_the_render_coloured_by_it(browser, shared_data, tmp_path):
    from surfsplat.colors import ColorOptions
    source = shared_data / "simple.las"
    out = tmp_path / "site"
    export(source, out, technique="points", size=(W, H))
    view = View(source, source_options=SourceOptions(color=ColorOptions("classification")))
    camera = view.camera(None, W, H)
    reference = view.render(camera, technique="points", options=RenderOptions(edl=EdlOptions())).frame.image()
    own = View(source).render(camera, technique="points", options=RenderOptions(edl=EdlOptions())).frame.image()
    page = opened(browser, file_url(out / "index.html", "?ui=0#color=classification"))
    try:
        canvas = page.canvas()
        modes = page.evaluate("Array.from(document.getElementById('color').options).map(o => o.value)")
        assert page.evaluate("surfsplat.colorBy") == "classification"
        page.evaluate("document.getElementById('view').focus()")
        page.key("c", code="KeyC", key_code=67)   # C: the next colouring, as in the desktop viewer
        following = modes[modes.index("classification") + 1]
        page.wait_for(f"surfsplat.colorBy === {json.dumps(following)} && location.hash.indexOf('color=') >= 0",
                      timeout=10)
        assert page.collect() == []
    finally:
        page.close()
    assert modes[:2] == ["own colours", "elevation"] and modes[2:] == sorted(modes[2:]) and "nonplanar" not in modes
    assert psnr(canvas / 255.0, reference / 255.0) >= 48.0   # measured 53.8 dB
    assert psnr(canvas / 255.0, own / 255.0) < psnr(canvas / 255.0, reference / 255.0) - 10   # recoloured


# measured at 200 x 150: 63.1 dB against the desktop's defaults (512 x 384: 60.7 dB): the page's splats are the
# render's (the mesh sampled for the same size), drawn with edge coverage and back faces culled as the view plan
# culls them
@pytest.mark.slow
def test_a_mesh_page_exported_for_its_size_is_surfsplat_render_of_the_mesh(browser, shared_data, tmp_path):
    source, width, height = shared_data / "bunny.ply", 200, 150   # small: the test samples the mesh twice
    out = tmp_path / "site"
    result = export(source, out, size=(width, height))
    view = View(source)
    camera = view.camera(None, width, height)
    reference = view.render(camera, technique="ewa", options=RenderOptions()).frame.image()
    page = opened(browser, file_url(out / "index.html", "?ui=0"), width, height)
    try:
        canvas = page.canvas()
    finally:
        page.close()
    assert result.splats == len(view.sample(camera).points())
    assert psnr(canvas / 255.0, reference / 255.0) >= 55.0
    # from inside the model's bounds the view plan culls nothing, and the page draws both sides as well
    # (measured 66.2 dB; 17.2 dB against the desktop culling back faces there)
    lo, hi = view.sample(camera).bounds()
    center = (lo + hi) / 2
    inside = view.camera(Camera(eye=tuple(center), target=tuple(center + [0.0, 0.0, 1.0]), up=(0.0, 1.0, 0.0),
                                fov=60.0, width=width, height=height))
    assert not view.culls(inside)
    page = opened(browser, file_url(out / "index.html", "?ui=0" + camera_hash(inside, "ewa")), width, height)
    try:
        canvas = page.canvas()
    finally:
        page.close()
    reference = view.render(inside, technique="ewa").frame.image()
    assert psnr(canvas / 255.0, reference / 255.0) >= 55.0


def test_on_a_small_page_the_controls_fold_behind_one_button(browser, site):
    area = ("(function () { var p = document.getElementById('panel').getBoundingClientRect(); "
            "return p.width * p.height / (innerWidth * innerHeight); })()")
    visible = "getComputedStyle(document.getElementById('technique')).display !== 'none' && " \
              "document.getElementById('technique').getBoundingClientRect().width > 0"
    page = opened(browser, file_url(site / "index.html"), 360, 240)
    try:
        folded = page.evaluate(area)
        assert page.evaluate("surfsplat.compact") and not page.evaluate(visible)
        page.evaluate("document.getElementById('menu').click()")
        assert page.evaluate(visible)
        assert page.evaluate("document.getElementById('menu').getAttribute('aria-expanded')") == "true"
        assert page.collect() == []
    finally:
        page.close()
    wide = opened(browser, file_url(site / "index.html"), 1024, 600)
    try:
        assert not wide.evaluate("surfsplat.compact") and wide.evaluate(visible)
        assert wide.evaluate("getComputedStyle(document.getElementById('menu')).display") == "none"
        spread = wide.evaluate(area)
    finally:
        wide.close()
    assert folded < 0.04 and spread < 0.12   # the folded bar: a corner of the picture (was a third of it)


# -- a chunked hierarchy streamed from a static server (surfsplat.web.stream) -------------------------------

STREAM_BUDGET = 8_000


@pytest.fixture(scope="module")
def streamed(tmp_path_factory):
    """A small chunked hierarchy (a 15 k-splat torus in some 40 cells), exported with browser LOD."""
    from surfsplat.hierarchy.chunked import build_chunked
    from surfsplat.io import save_ply
    folder = tmp_path_factory.mktemp("streamed")
    save_ply(torus(240, 64), folder / "torus.ply")
    build_chunked(folder / "torus.ply", folder / "torus.ssh", cell_points=1_000, scheduler="synchronous")
    export(folder / "torus.ssh", folder / "site", browser_lod=True, point_budget=STREAM_BUDGET)
    return folder / "torus.ssh", folder / "site"


@pytest.fixture(scope="module")
def server(streamed):
    """A static web server (python's http.server) of the exported folder, in a thread; its log of paths."""
    import functools
    import http.server
    import threading
    paths: list[str] = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format, *args):   # noqa: A002
            paths.append(self.path)

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Handler, directory=streamed[1]))
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/", paths
    httpd.shutdown()


def stream_state(page) -> dict:
    return json.loads(page.evaluate("JSON.stringify(Object.assign({drawn: surfsplat.drawn}, surfsplat.stream))"))


# measured at 320 x 240: close to one side 17 of 42 cells requested, 1,784 splats drawn (the desktop's cut 1,768),
# 62.8 dB; the default view: every cell, 7,998 splats as the desktop's cut (the budget binds), 61.2 dB
def test_a_chunked_model_streams_its_cells_on_demand_from_a_static_server(browser, streamed, server):
    from surfsplat.pipeline import LodOptions
    from surfsplat.hierarchy.chunked import open_chunked
    path, site = streamed
    url, paths = server
    cells = len(open_chunked(path).cells)
    view = View(path, lod=LodOptions(tolerance=1.0, point_budget=STREAM_BUDGET, shading="flat"))
    home = view.camera(None, W, H)
    target, eye = np.asarray(home.target), np.asarray(home.eye)
    right = np.cross(target - eye, home.up)
    right *= 0.25 * np.linalg.norm(target - eye) / np.linalg.norm(right)
    close = Camera(eye=tuple(eye + right + 0.7 * (target - eye)), target=tuple(target + right), up=home.up,
                   fov=home.fov, width=W, height=H)
    for camera, hash_ in ((close, camera_hash(close, "ewa")), (home, "")):
        del paths[:]
        page = opened(browser, url + "index.html?ui=0" + hash_)
        try:
            page.wait_for("surfsplat.stream.idle", timeout=30)
            state, canvas = stream_state(page), page.canvas()
            assert page.collect() == []
        finally:
            page.close()
        requested = [p for p in paths if p.startswith("/cells/")]
        assert state["requests"] == state["loads"] == len(requested) == len(set(requested)) <= cells
        assert state["drawn"] <= STREAM_BUDGET and state["bytes"] <= state["memoryBudget"]
        result = view.render(view.camera(camera), technique="ewa", options=RenderOptions())
        reference = result.frame.image()
        # the cut of ChunkedHierarchy.view_splats: the same at the home view, where the budget binds
        assert abs(state["drawn"] - result.splats) <= (0 if camera is home else 0.02 * result.splats)
        assert psnr(canvas / 255.0, reference / 255.0) >= 50.0   # measured 61.9 and 61.0 dB
        if camera is close:   # on demand: only the cells in view, close enough to refine
            assert 0 < len(requested) < cells / 2
        else:
            assert len(requested) > cells / 2


def test_a_streamed_page_keeps_its_memory_budget_and_lets_go_of_unseen_cells_from_a_file_url(browser, streamed):
    path, site = streamed
    budget = 300_000   # bytes: a fifth of the cells
    page = opened(browser, file_url(site / "index.html", f"?ui=0&memory={budget}"))
    try:
        page.wait_for("surfsplat.stream.idle", timeout=30)
        states = [stream_state(page)]
        camera = json.loads(page.evaluate("JSON.stringify(surfsplat.camera)"))
        target, eye = np.asarray(camera["target"]), np.asarray(camera["eye"])
        right = np.cross(target - eye, camera["up"])
        right *= 0.25 * np.linalg.norm(target - eye) / np.linalg.norm(right)
        for side in (-1, 1):   # close to one side of the torus, then to the other
            moved = {**camera, "eye": (eye + side * right + 0.7 * (target - eye)).tolist(),
                     "target": (target + side * right).tolist()}
            page.evaluate(f"surfsplat.setCamera({json.dumps(moved)})")
            page.wait_for(f"surfsplat.stream.requests > {states[-1]['requests']} && surfsplat.stream.idle", timeout=30)
            states.append(stream_state(page))
        assert page.collect() == []
    finally:
        page.close()
    assert states[0]["blocked"] and 0 < states[0]["loads"]   # the budget stops the loads at the home view
    assert all(s["peakBytes"] <= budget and s["bytes"] <= budget for s in states)
    assert states[-1]["evictions"] > 0   # the cells of the first side let go for those of the other
    # Potree's order within the memory budget: no cell left out is worth more to the view than one kept
    assert all(s["wantedTop"] <= s["loadedLeast"] for s in states if s["blocked"])


# measured at 320 x 240: 67.5 dB (every cell streamed and coloured as it arrives)
def test_a_streamed_lidar_page_colours_its_cells_by_classification_as_the_desktop(browser, shared_data, tmp_path):
    from surfsplat.colors import ColorOptions
    from surfsplat.hierarchy.chunked import build_chunked
    from surfsplat.pipeline import LodOptions
    model = tmp_path / "las.ssh"
    build_chunked(shared_data / "simple.las", model, cell_points=150, scheduler="synchronous")
    export(model, tmp_path / "site", browser_lod=True, technique="points", point_budget=100_000)
    view = View(model, source_options=SourceOptions(color=ColorOptions("classification")),
                lod=LodOptions(tolerance=1.0, point_budget=100_000, shading="flat"))
    reference = view.render(view.camera(None, W, H), technique="points",
                            options=RenderOptions(edl=EdlOptions())).frame.image()
    page = opened(browser, file_url(tmp_path / "site" / "index.html", "?ui=0#color=classification"))
    try:
        page.wait_for("surfsplat.stream.idle", timeout=30)
        loads, canvas = page.evaluate("surfsplat.stream.loads"), page.canvas()
        assert page.collect() == []
    finally:
        page.close()
    assert loads > 1
    assert psnr(canvas / 255.0, reference / 255.0) >= 55.0   # measured 67.5 dB


# measured at 320 x 240: ewa 68.3 dB, flat 54.5 dB against `surfsplat render` (35.0 and 34.3 dB against the
# render drawing every splat as a surface splat; 39.2 dB for ewa before the page drew them as points)
@pytest.mark.parametrize("technique,least", [("ewa", 60.0), ("flat", 48.0)])
def test_a_lidar_page_draws_its_non_planar_splats_as_round_points_as_the_desktop(browser, shared_data, tmp_path,
                                                                                 technique, least):
    source = shared_data / "simple.las"
    out = tmp_path / "site"
    export(source, out, technique=technique, size=(W, H))
    view = View(source)
    assert view.hybrid
    camera = view.camera(None, W, H)
    page_options = RenderOptions()
    reference = view.render(camera, technique=technique, options=page_options).frame.image()
    flat_page = View(source, source_options=SourceOptions(hybrid=False)).render(camera, technique=technique,
                                                                                options=page_options)
    page = opened(browser, file_url(out / "index.html", "?ui=0"))
    try:
        canvas = page.canvas()
    finally:
        page.close()
    assert psnr(canvas / 255.0, reference / 255.0) >= least
    # the splats drawn as points: nearer the hybrid render than the all-splats one
    assert psnr(canvas / 255.0, reference / 255.0) > psnr(canvas / 255.0, flat_page.frame.image() / 255.0) + 3


# measured at 320 x 240: 68.9 dB (35.0 dB against the cut drawn without hybrid points)
def test_a_browser_lod_lidar_page_draws_the_non_planar_splats_of_its_cut_as_round_points(browser, shared_data,
                                                                                        tmp_path):
    from surfsplat.pipeline import LodOptions
    source = shared_data / "simple.las"
    out = tmp_path / "site"
    export(source, out, browser_lod=True, size=(W, H))
    lod = LodOptions(tolerance=1.0, point_budget=1_000_000, shading="flat")   # the page's first cut
    hybrid = View(source, lod=lod)
    camera = hybrid.camera(None, W, H)
    page_options = RenderOptions()
    reference = hybrid.render(camera, technique="ewa", options=page_options)
    splats = View(source, lod=lod, source_options=SourceOptions(hybrid=False)).render(camera, technique="ewa",
                                                                                      options=page_options)
    page = opened(browser, file_url(out / "index.html", "?ui=0"))
    try:
        drawn, canvas = page.evaluate("surfsplat.drawn"), page.canvas()
    finally:
        page.close()
    near = psnr(canvas / 255.0, reference.frame.image() / 255.0)
    assert drawn == reference.splats
    assert near >= 60.0 and near > psnr(canvas / 255.0, splats.frame.image() / 255.0) + 3


@pytest.fixture(scope="module")
def cad_part(shared_data, tmp_path_factory):
    """The CAD part's page for 320 x 240, its view plan and default camera, and the export's result."""
    source = shared_data / "featuretype.ply"
    out = tmp_path_factory.mktemp("cad") / "site"
    result = export(source, out, size=(W, H))
    view = View(source)
    return out, view, view.camera(None, W, H), result


# measured at 320 x 240: ewa 63.5 dB, perspective 63.6 dB, flat 54.8 dB against `surfsplat render` of the part (the
# 19-byte codes of positions and axes are what is left; float16 lines alone cost ewa 75.8 dB, flat nothing);
# without its clip lines the page scores 23.4 and 21.4 dB (ragged sharp edges), with lines not flipped with the
# decoded axes 41.8 and 37.1 dB
@pytest.mark.parametrize("technique,least", [("ewa", 58.0), ("perspective", 58.0), ("flat", 50.0)])
def test_a_cad_part_page_cuts_its_splats_at_the_sharp_edges_as_the_desktop(browser, cad_part, technique, least):
    out, view, camera, result = cad_part
    cloud = view.sample(camera).points()
    cutting = int((np.abs(cloud.clip_lines[:, :, :2]).sum(axis=(1, 2)) > 0).sum())
    assert 0 < cutting < len(cloud)
    assert result.bytes == 19 * len(cloud) + 16 * cutting   # the lines of the splats that cut, alone
    reference = view.render(camera, technique=technique, options=RenderOptions()).frame.image()
    page = opened(browser, file_url(out / "index.html", f"?ui=0&technique={technique}"))
    try:
        canvas = page.canvas()
    finally:
        page.close()
    assert psnr(canvas / 255.0, reference / 255.0) >= least


# measured at 320 x 240: phong 98.7 dB, blend 94.8 dB against the desktop drawing the same splats, 40.1 and 39.6 dB
# against it drawing them without their normal fields (shaded per splat)
@pytest.mark.parametrize("technique", ["phong", "blend"])
def test_phong_splats_are_shaded_by_their_normal_fields_on_the_page_as_on_the_desktop(browser, phong_sphere, tmp_path,
                                                                                    technique):
    out = tmp_path / "site"
    export(phong_sphere, out, technique=technique, size=(W, H))
    drawn = as_drawn(phong_sphere)
    view = View(drawn)
    camera = View(phong_sphere).camera(None, W, H)   # the page's default view
    reference = view.render(camera, technique=technique).frame.image()
    faceted = View(drawn.replace(normal_field=None)).render(camera, technique=technique).frame.image()
    page = opened(browser, file_url(out / "index.html", "?ui=0"))
    try:
        canvas = page.canvas()
    finally:
        page.close()
    near, far = psnr(canvas / 255.0, reference / 255.0), psnr(canvas / 255.0, faceted / 255.0)
    assert near >= 80.0 and far < near - 20.0


# measured at 320 x 240: flat 54.8 dB, ewa 64.2 dB against the desktop's cut at 1 px (24.7 and 30.1 dB when the page
# drew the nodes over the sharp edges, which carry no clip lines, instead of refining them as the desktop does)
def test_a_browser_lod_cad_page_keeps_its_sharp_edges_as_the_desktop_s_cut(browser, shared_data, tmp_path):
    from surfsplat.pipeline import LodOptions
    source = shared_data / "featuretype.ply"
    out = tmp_path / "site"
    export(source, out, browser_lod=True, size=(W, H))
    view = View(source, lod=LodOptions(tolerance=1.0, point_budget=1_000_000, shading="flat"))   # the page's cut
    camera = view.camera(None, W, H)
    for technique, least in (("flat", 50.0), ("ewa", 58.0)):
        reference = view.render(camera, technique=technique, options=RenderOptions())
        page = opened(browser, file_url(out / "index.html", f"?ui=0&technique={technique}"))
        try:
            drawn, canvas = page.evaluate("surfsplat.drawn"), page.canvas()
        finally:
            page.close()
        if technique == "flat":   # nothing culled: the desktop's very cut (ewa's drops back-facing nodes)
            assert drawn == reference.splats
        assert psnr(canvas / 255.0, reference.frame.image() / 255.0) >= least
