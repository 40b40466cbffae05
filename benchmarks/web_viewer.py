"""The browser viewer (``surfsplat export``): export time, size, quantization cost, canvas against desktop,
frame times in headless Chromium.

* export: a 1 M-splat model (the torus scene at 1250 x 800) written as a folder, and 1 M raw points
  (the same torus's centres in a PLY without normals: read, preprocessed, written), wall-clock seconds;
* size: bytes per splat of the web format, and of the whole folder;
* quality, on the Stanford bunny (``shared/data/bunny.ply``, sampled for the default view at 1024 px as
  ``surfsplat render`` samples it), at 1024 x 768, for every technique of the page (``points`` with EDL):
  the quantization cost (PSNR of the desktop render of the decoded splats against the desktop render of
  the original ones; for ewa and flat also the drop of the PSNR against the mesh's ground truth); the
  canvas of the exported page in headless Chromium (SwiftShader) against the desktop render of the same
  camera: of the file (``surfsplat render``, which samples the mesh for its own camera), of the exported
  splats, and of the decoded ones (what the page draws); and the desktop's covered pixels the canvas
  leaves empty (holes);
* frame times in headless Chromium at 1024 x 768 for the 1 M-splat torus opened from ``file://``: the
  first frame (the first picture of the model the page draws: a large page's decimated ``points``
  preview, 1 splat in 8 here, before the other splats are decoded), its parts (the page's scripts loaded
  and parsed, the preview's splats decoded and uploaded, its frame) and the first full-quality frame, ms
  after navigation start, and a full-quality frame drawn again (median of 3); ewa's first frame also in a
  fresh browser (nothing compiled yet, as a user opening the page sees it);
* the same torus with ``--browser-lod`` and a budget of 300,000: export time (the hierarchy built),
  splats the page's cut draws at the default view, and its frame times (the first frame: the cut within
  the preview's 131,072 splats);
* with ``--chunked N``: a chunked hierarchy of N raw points (a torus, built with ``surfsplat build --chunked``
  in cells of ``--cell-points``) exported with ``--browser-lod`` and served by python's ``http.server``: build
  and export times, bytes, the first frame, and the time, full-quality frames and cell requests until the
  still default view is fully refined (``surfsplat.stream.idle``).

The bunny is exported for the page size (``export(..., size=(W, H))``), so it is sampled as ``surfsplat
render --width W --height H`` samples it.

    python benchmarks/web_viewer.py [--size 1024 768] [--skip-raw] [--chunked 10000000 --cell-points 500000]
    python benchmarks/web_viewer.py --quality-only     # the bunny rows alone, saved as results/web_quality.md
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, write_table  # noqa: E402

from surfsplat import metrics  # noqa: E402
from surfsplat.api import render_mesh  # noqa: E402
from surfsplat.cloud import SplatCloud  # noqa: E402
from surfsplat.io import save_ply  # noqa: E402
from surfsplat.pipeline import View  # noqa: E402
from surfsplat.rendering.options import EdlOptions, RenderOptions, VisibilityOptions  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402
from surfsplat.scenes import torus  # noqa: E402
from surfsplat.web import export  # noqa: E402
from surfsplat.web.browser import Browser, file_url  # noqa: E402
from surfsplat.web.export import as_drawn, exported_splats  # noqa: E402
from surfsplat.web.shaders import WEB_TECHNIQUES  # noqa: E402

BUNNY = Path(__file__).resolve().parents[2] / "shared" / "data" / "bunny.ply"
if not BUNNY.exists():
    BUNNY = Path("/work/shared/data/bunny.ply")
TECHNIQUES = WEB_TECHNIQUES
#: The point budget of the browser-LOD page.
LOD_BUDGET = 300_000


def folder_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.iterdir())


def camera_hash(camera, technique: str) -> str:
    vec = lambda v: ",".join(repr(float(x)) for x in v)   # noqa: E731
    return (f"#eye={vec(camera.eye)}&target={vec(camera.target)}&up={vec(camera.up)}&fov={camera.fov}"
            f"&technique={technique}")


def opened(browser, url, width, height, timeout=300.0):
    page = browser.page(url, width, height)
    page.wait_for("document.body && document.body.getAttribute('data-ready') === '1'", timeout=timeout, poll=0.1)
    errors = page.collect()
    if errors:
        raise RuntimeError("; ".join(errors))
    return page


def options_for(technique: str, culls: bool | None = None) -> RenderOptions:
    """The desktop's defaults as the page draws ``technique``: EDL with points, back faces culled where the
    view plan culls them for the exported view (``View.culls``: a closed mesh's samples with ewa, perspective;
    None: as the view plan decides)."""
    return RenderOptions(edl=EdlOptions() if technique == "points" else None,
                         visibility=VisibilityOptions(cull_backfaces=culls))


def chunked_rows(browser, work: Path, count: int, cell_points: int, width: int, height: int) -> list:
    """The streaming rows: a chunked hierarchy of ``count`` raw points served over HTTP."""
    import functools
    import http.server
    import threading

    from surfsplat.hierarchy.chunked import build_chunked

    rows: list = []
    side = int(np.sqrt(count / 1.6))
    cloud = torus(int(1.6 * side), side)
    raw = work / "big.ply"
    save_ply(SplatCloud(cloud.positions, colors=cloud.colors, origin=cloud.origin, up=cloud.up), raw)
    n = len(cloud)
    del cloud
    start = time.perf_counter()
    build_chunked(raw, work / "big.ssh", cell_points=cell_points)
    rows.append([f"chunked: build {n:,} raw points (cells of {cell_points:,})", "s",
                 round(time.perf_counter() - start, 1)])
    start = time.perf_counter()
    result = export(work / "big.ssh", work / "big", browser_lod=True)
    rows.append(["chunked: export with browser LOD (every cell encoded)", "s", round(time.perf_counter() - start, 1)])
    cells = list((work / "big" / "cells").iterdir())
    rows.append(["chunked: page files (data.js and the rest)", "MB", round(folder_bytes(work / "big") / 1e6, 1)])
    rows.append([f"chunked: cell files ({len(cells)})", "MB", round(sum(p.stat().st_size for p in cells) / 1e6, 1)])
    rows.append(["chunked: entries (nodes and points)", "splats", result.splats])
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format, *args):   # noqa: A002
            pass

    handler = functools.partial(Quiet, directory=str(work / "big"))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        page = opened(browser, f"http://127.0.0.1:{httpd.server_address[1]}/index.html?technique=ewa", width, height)
        first = page.evaluate("surfsplat.firstFrameMs")
        page.wait_for("surfsplat.stream.idle", timeout=1800, poll=0.5)
        done = page.evaluate("performance.now()")
        state = json.loads(page.evaluate("JSON.stringify(Object.assign({drawn: surfsplat.drawn, "
                                         "frames: surfsplat.fullFrames}, surfsplat.stream))"))
        page.close()
    finally:
        httpd.shutdown()
    rows.append(["chunked over HTTP: first frame (the top hierarchy)", "ms after navigation", round(float(first))])
    rows.append(["chunked: default view fully refined", "ms after navigation", round(float(done))])
    rows.append(["chunked: full-quality frames until then", "frames", state["frames"]])
    rows.append(["chunked: cells requested / in the model", "cells", f"{state['requests']} / {len(cells)}"])
    rows.append(["chunked: splats drawn (budget 1,000,000)", "splats", state["drawn"]])
    rows.append(["chunked: loaded cells' GPU arrays (budget 512 MiB)", "MB", round(state["bytes"] / 1e6, 1)])
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, nargs=2, default=(1024, 768))
    parser.add_argument("--skip-raw", action="store_true", help="skip the export of 1 M raw points")
    parser.add_argument("--images", type=Path, help="also save the canvases and desktop renders here")
    parser.add_argument("--chunked", type=int, default=0, metavar="N",
                        help="also stream a chunked hierarchy of N raw points (0: skip)")
    parser.add_argument("--cell-points", type=int, default=500_000, help="points per cell of that hierarchy")
    parser.add_argument("--export-only", action="store_true",
                        help="only the export rows, saved as results/web_export.md (the browser rows are kept)")
    parser.add_argument("--quality-only", action="store_true",
                        help="only the bunny's quality rows, saved as results/web_quality.md")
    args = parser.parse_args()
    width, height = args.size
    work = Path(tempfile.mkdtemp(prefix="surfsplat-web-bench-"))
    rows = []
    try:
        if not args.quality_only:
            # -- export time and size ------------------------------------------------------------------
            big = torus(1250, 800)
            start = time.perf_counter()
            result = export(big, work / "torus")
            rows.append(["export 1 M splats (torus scene)", "s", round(time.perf_counter() - start, 2)])
            rows.append(["web format", "bytes / splat", result.bytes / result.splats])
            rows.append(["exported folder, 1 M splats", "bytes / splat",
                         round(folder_bytes(work / "torus") / len(big), 1)])
            if not args.skip_raw:
                raw = work / "raw.ply"
                save_ply(SplatCloud(big.positions, colors=big.colors, origin=big.origin, up=big.up), raw)
                start = time.perf_counter()
                export(raw, work / "raw")
                rows.append(["export 1 M raw points (read, preprocess, write)", "s",
                             round(time.perf_counter() - start, 2)])
            if args.export_only:
                command = " ".join(["python benchmarks/web_viewer.py", *sys.argv[1:]])
                write_table("web_export", ["measure", "unit", "value"], rows,
                            f"{machine_description()}; load average {os.getloadavg()[0]:.1f} at the end; `{command}`")
                return

        # -- quality on the bunny --------------------------------------------------------------------
        plan = View(BUNNY)
        camera = plan.camera(None, width, height)
        splats = exported_splats(plan, camera, None)   # sampled as export samples for this page size
        quantized = View(as_drawn(splats))
        original = View(splats)
        rendered = View(BUNNY)   # `surfsplat render bunny.ply` at this size: sampled for its own camera
        mesh = render_mesh(BUNNY, camera)
        start = time.perf_counter()
        bunny = export(BUNNY, work / "bunny", size=(width, height))
        rows.append([f"export of the bunny mesh for a {width} x {height} page", "s",
                     round(time.perf_counter() - start, 2)])
        rows.append([f"bunny for a {width} x {height} page: splats (as `surfsplat render` samples it)", "splats",
                     bunny.splats])
        rows.append(["bunny: data.js", "MB", round((work / "bunny" / "data.js").stat().st_size / 1e6, 1)])
        with Browser() as browser:
            for technique in TECHNIQUES:
                culled = options_for(technique, plan.culls(camera, technique=technique))
                desk = original.render(camera, technique=technique, options=culled).frame
                desk_q = quantized.render(camera, technique=technique, options=culled).frame
                url = file_url(work / "bunny" / "index.html", "?ui=0" + camera_hash(camera, technique))
                page = opened(browser, url, width, height)
                canvas = page.canvas() / 255.0
                page.close()
                a, q = desk.image() / 255.0, desk_q.image() / 255.0
                name = technique + (" + EDL" if technique == "points" else "")
                rows.append([f"quantization, {name} (bunny, {len(splats):,} splats)", "dB vs unquantized",
                             round(metrics.psnr(q, a), 2)])
                if technique != "points":
                    drop = metrics.psnr(a, mesh.color) - metrics.psnr(q, mesh.color)
                    rows.append([f"quantization, {name}", "dB lost against the mesh", round(drop, 3)])
                own = rendered.render(camera, technique=technique, options=options_for(technique)).frame.image()
                rows.append([f"canvas vs `surfsplat render` of the file, {name}", "dB",
                             round(metrics.psnr(canvas, own / 255.0), 2)])
                rows.append([f"canvas vs desktop, {name}", "dB", round(metrics.psnr(canvas, a), 2)])
                rows.append([f"canvas vs desktop of the decoded splats, {name}", "dB",
                             round(metrics.psnr(canvas, q), 2)])
                # a hole: background on the canvas where the desktop shows the surface (not a rim pixel the
                # desktop's edge coverage leaves within a level of the background, as the canvas does)
                shown = (np.abs(a - 1.0) > 1.5 / 255.0).any(axis=2) & desk.mask
                holes = int(((canvas == 1.0).all(axis=2) & shown).sum())
                rows.append([f"holes: desktop pixels the canvas leaves empty, {name}", "pixels", holes])
                if args.images:
                    args.images.mkdir(parents=True, exist_ok=True)
                    Image.fromarray((canvas * 255).astype(np.uint8)).save(args.images / f"canvas_{technique}.png")
                    Image.fromarray(desk.image()).save(args.images / f"desktop_{technique}.png")

            if not args.quality_only:
                # -- frame times, 1 M splats -----------------------------------------------------------------
                # the first frame in a fresh browser (SwiftShader's compiled routines and the shader cache empty),
                # as a user opening the page sees it; the rows below reuse the browser that drew the bunny
                with Browser() as fresh:
                    page = fresh.page(file_url(work / "torus" / "index.html", "?technique=ewa"), width, height)
                    page.wait_for("document.body && document.body.getAttribute('data-first-frame') === '1'",
                                  timeout=300, poll=0.1)
                    first = page.evaluate("surfsplat.firstFrameMs")
                    page.close()
                rows.append(["first frame, 1 M splats, ewa, in a fresh browser", "ms after navigation",
                             round(float(first))])
                for technique in TECHNIQUES:
                    page = opened(browser, file_url(work / "torus" / "index.html", f"?technique={technique}"), width,
                                  height)
                    first, ready, step, parts = json.loads(page.evaluate(
                        "JSON.stringify([surfsplat.firstFrameMs, surfsplat.readyMs, surfsplat.previewStep, "
                        "surfsplat.timings])"))
                    again = [page.evaluate("surfsplat.redraw()") for _ in range(3)]
                    page.close()
                    name = technique + (" + EDL" if technique == "points" else "")
                    rows.append([f"first frame, 1 M splats, {name} (a points preview of 1 splat in {step})",
                                 "ms after navigation", round(float(first))])
                    rows.append([f"first frame's parts, {name}: scripts loaded / preview decoded and uploaded / "
                                 "preview frame", "ms", " / ".join(str(round(float(parts.get(k, 0))))
                                                                    for k in ("start", "previewLoad", "preview"))])
                    rows.append([f"after it, {name}: every splat decoded / uploaded; programs compiled until ready",
                                 "ms", " / ".join(str(round(float(parts.get(k, 0))))
                                                  for k in ("decode", "upload", "compile"))])
                    rows.append([f"first full-quality frame, 1 M splats, {name}", "ms after navigation",
                                 round(float(ready))])
                    rows.append([f"full-quality frame, 1 M splats, {name}", "ms (median of 3)",
                                 round(statistics.median(again))])
                # -- level of detail in the browser: the 1 M-splat torus's hierarchy, cut per view -----------------
                start = time.perf_counter()
                export(big, work / "lod", browser_lod=True, point_budget=LOD_BUDGET)
                rows.append(["export with browser LOD (hierarchy built), 1 M splats", "s",
                             round(time.perf_counter() - start, 2)])
                page = opened(browser, file_url(work / "lod" / "index.html", "?technique=ewa"), width, height)
                first, ready = json.loads(page.evaluate("JSON.stringify([surfsplat.firstFrameMs, surfsplat.readyMs])"))
                drawn = page.evaluate("surfsplat.drawn")
                again = [page.evaluate("surfsplat.redraw()") for _ in range(3)]
                page.close()
                rows.append([f"browser LOD, budget {LOD_BUDGET:,}: splats drawn at the default view", "splats", drawn])
                rows.append(["browser LOD: first frame, ewa (the cut within the preview's 131,072 splats)",
                             "ms after navigation", round(float(first))])
                rows.append(["browser LOD: first full-quality frame, ewa", "ms after navigation",
                             round(float(ready))])
                rows.append(["browser LOD: full-quality frame, ewa", "ms (median of 3)",
                             round(statistics.median(again))])
                if args.chunked:
                    rows.extend(chunked_rows(browser, work, args.chunked, args.cell_points, width, height))
            version = browser.version
    finally:
        shutil.rmtree(work, ignore_errors=True)
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    command = " ".join(["python benchmarks/web_viewer.py", *sys.argv[1:]])
    write_table("web_quality" if args.quality_only else "web_viewer", ["measure", "unit", "value"], rows,
                f"{machine}; headless {version} (WebGL2 on SwiftShader); load average {os.getloadavg()[0]:.1f} "
                f"at the end; {width}x{height}; `{command}`")
    print(json.dumps({"results": str(RESULTS / ("web_quality.md" if args.quality_only else "web_viewer.md"))}))


if __name__ == "__main__":
    main()
