"""``LodOptions(tolerance="auto")``: what it costs in quality and saves in time, per resolution.

Usage: python benchmarks/bench_lod_auto.py [--splats 1000000] [--sizes 256 512 1024] [--technique ewa]

The Stanford bunny (../shared/data) sampled to ``--splats`` splats (bench_render.bunny), the automatic
camera; per output size: the points per covered pixel (render/lod_auto.points_per_pixel) and what
"auto" decides for the cloud, then three ways to draw it: every splat; "auto" on the cloud (its points
merged per half pixel for the view where it is dense: render/lod_auto.merge_in_pixels, timed in the
frame); the hierarchy's cut at one pixel (the tolerance "auto" cuts a hierarchy at; the build is
once per model and not in the frame). Per way: splats drawn, the frame (merge or cut, upload, draw,
read-back: ``View.render`` of a prepared view), the PSNR against the mesh's ground truth (``surfsplat.render_mesh``, 4x4
supersampled) over the mesh's coverage. Saved as results/lod_auto.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_render import SHARED, bunny  # noqa: E402
from common import machine_description, write_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat.metrics import psnr  # noqa: E402
from surfsplat.pipeline import LodOptions, View, as_model, auto_camera, local_camera  # noqa: E402
from surfsplat.rendering.context import headless_context, renderer_name  # noqa: E402
from surfsplat.rendering.lod_auto import AUTO, AUTO_MIN_DENSITY, points_per_pixel  # noqa: E402


def timed(function, repeat: int):
    """(result of the last call, median seconds of ``repeat`` calls after a warm-up)."""
    import numpy as np

    result = function()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return result, float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    parser.add_argument("--technique", default="ewa")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()

    cloud = bunny(args.splats)
    start = time.perf_counter()
    tree = as_model(cloud).tree().data
    build = time.perf_counter() - start
    # prepared once, drawn for every size: every splat; "auto" on the cloud; the hierarchy cut at one pixel
    full_view, auto_view = View(cloud), View(cloud, lod=LodOptions(tolerance=AUTO))
    cut_view = View(tree, lod=LodOptions(tolerance=AUTO))
    rows = []
    for size in args.sizes:
        camera = auto_camera(cloud, size, size)
        truth = surfsplat.render_mesh(SHARED / "bunny.ply", camera)
        mask = truth.alpha > 0.5
        density = points_per_pixel(cloud.positions, local_camera(cloud, camera))
        full, full_s = timed(lambda: full_view.render(camera, technique=args.technique), args.repeat)
        auto, auto_s = timed(lambda: auto_view.render(camera, technique=args.technique), args.repeat)
        cut, cut_s = timed(lambda: cut_view.render(camera, technique=args.technique), args.repeat)
        db = [psnr(r.frame.color, truth.color, mask) for r in (full, auto, cut)]
        rows.append([f"{size}x{size}", len(cloud), round(density, 1),
                     "merge per half pixel" if density >= AUTO_MIN_DENSITY else "all splats",
                     round(full_s * 1000), round(db[0], 2),
                     auto.splats, round(auto_s * 1000), round(full_s / auto_s, 2), round(db[1], 2),
                     round(db[1] - db[0], 2),
                     cut.splats, round(cut_s * 1000), round(db[2], 2), round(db[2] - db[0], 2)])
        print(rows[-1], flush=True)
    columns = ["resolution", "splats", "points per covered pixel", "auto decides (cloud)", "all: frame ms",
               "all: PSNR dB", "auto: splats", "auto: frame ms", "auto: speed-up", "auto: PSNR dB", "auto - all dB",
               "1 px cut: splats", "1 px cut: frame ms", "1 px cut: PSNR dB", "cut - all dB"]
    write_table("lod_auto", columns, rows, machine_description(renderer_name(headless_context()))
                + f"; bunny, technique {args.technique}, PSNR against the mesh over its coverage; frame = View.render "
                  f"of a prepared view (merge or cut, upload, draw, read-back), median of {args.repeat}"
                + f"; hierarchy build (once, not in the 1 px cut's frame) {build:.2f} s")


if __name__ == "__main__":
    main()
