"""The viewer on a chunked hierarchy: how long the frame loop's turns take while cells are read in
the background, and when the still frame arrives.

Builds a chunked hierarchy of a generated torus (``--points`` points, far from zero) in a temporary
folder (never in the repository), opens it in the viewer (needs a display: run under
``xvfb-run -s '-screen 0 1600x900x24'``) and, for three still views (the first one, zoomed in,
orbited by 90 degrees), drives the loop turn by turn after the camera stops: the first turn (the
preview of the new view), the longest later turn that draws no full frame (while the cut is read
and computed in the background), and the time until the still frame is shown. Prints a Markdown
table and saves it to ``benchmarks/results/chunked_view.md``.

    xvfb-run -s '-screen 0 1600x900x24' python benchmarks/chunked_view.py --points 1000000
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "chunked_view.md"
sys.path.insert(0, str(HERE.parent / "tests"))

from test_chunked import torus_points, write_ply  # noqa: E402

from surfsplat.hierarchy.chunked import build_chunked  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402
from surfsplat.pipeline import CameraSpec, LodOptions, View  # noqa: E402
from surfsplat.rendering.options import RenderOptions  # noqa: E402
from surfsplat.viewer import app  # noqa: E402
from surfsplat.viewer import camera_control as cc  # noqa: E402


def settle(viewer) -> dict:
    """Drive the loop until the still view is shown; the turns' times (seconds)."""
    start, turns, first, longest = time.perf_counter(), 0, None, 0.0
    while (viewer.full_version != viewer.version or viewer.fade_from is not None or viewer.lod.pending
           or viewer.refine + 1 < len(viewer.budgets)):
        full_frames = viewer.full_frames
        t = time.perf_counter()
        viewer.step(wait=False)
        took = time.perf_counter() - t
        if first is None:
            first = took
        elif viewer.full_frames == full_frames:
            longest = max(longest, took)
        turns += 1
    return {"first": first, "longest": longest, "still": time.perf_counter() - start, "turns": turns,
            "splats": viewer.drawn, "cut_ms": viewer.lod.select_ms, "full_s": viewer.last_render_s["full"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--cell-points", type=int, default=60_000)
    parser.add_argument("--size", type=int, nargs=2, default=(1280, 720))
    parser.add_argument("--point-budget", type=int, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        source = write_ply(folder / "torus.ply", torus_points(args.points, seed=2))
        t = time.perf_counter()
        build_chunked(source, folder / "torus.ssh", cell_points=args.cell_points, scheduler="threads")
        build_s = time.perf_counter() - t
        plan = View(str(folder / "torus.ssh"), lod=LodOptions(tolerance=1.0, point_budget=args.point_budget),
                    interactive=True)   # as surfsplat.view prepares it
        model = plan.model.data
        glfw, window, ctx = app.open_window(*args.size, "chunked_view benchmark")
        viewer = app.Viewer(glfw, window, ctx, plan, CameraSpec(), technique="ewa", lights=Lights(),
                            options=RenderOptions(), background=(1, 1, 1), motion=app.MotionOptions("flat"),
                            hud=True)
        rows = [("first view", settle(viewer))]
        for name, move in (("zoomed in (4 wheel steps)", lambda c: cc.zoom(c, 4)),
                           ("orbited 90 deg", lambda c: cc.orbit(c, 90.0, 0.0, viewer.controller.up))):
            viewer.controller.camera = move(viewer.controller.camera)
            viewer._process_input(time.perf_counter())
            viewer.moved_at = -np.inf   # the camera has stopped
            rows.append((name, settle(viewer)))
        cells, preview, loads = len(model.cells), viewer.preview_splats.count, model.loads
        viewer.release()
        glfw.terminate()
    w, h = args.size
    lines = [f"# Viewer on a chunked hierarchy ({args.points:,}-point torus, {cells} cells, {w}x{h}, "
             f"budget {args.point_budget or 'none'})", "",
             f"Machine: llvmpipe, 2-core EPYC ({platform.machine()}), shared with other jobs; build {build_s:.1f} s; "
             f"preview {preview:,} splats; cell loads {loads} (a cell's coarse levels and all its levels count "
             f"one each).", "",
             "| view | first turn (preview) | longest later turn, cut pending | still frame after | turns | "
             "splats | cut (thread) | full render |",
             "|---|---|---|---|---|---|---|---|"]
    for name, r in rows:
        lines.append(f"| {name} | {1000 * r['first']:.0f} ms | {1000 * r['longest']:.0f} ms | {r['still']:.2f} s | "
                     f"{r['turns']} | {r['splats']:,} | {r['cut_ms']:.0f} ms | {r['full_s']:.2f} s |")
    table = "\n".join(lines) + "\n"
    print(table)
    RESULTS.write_text(table)


if __name__ == "__main__":
    main()
