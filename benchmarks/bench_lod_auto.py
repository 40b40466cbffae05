"""``lod_tolerance="auto"``: what the cut at one pixel costs in quality and saves in time, per resolution.

Usage: python benchmarks/bench_lod_auto.py [--splats 1000000] [--sizes 256 512 1024] [--technique ewa]

The Stanford bunny (../shared/data) sampled to ``--splats`` splats (bench_render.bunny), the automatic
camera; per output size: the points per covered pixel (render/lod_auto.points_per_pixel) and what
"auto" decides, then every splat drawn against the hierarchy's cut at one pixel (the tolerance "auto"
cuts at): splats drawn, the one-time hierarchy build, the frame (cut, upload, draw, read-back:
``api.render_model``), and the PSNR of each against the mesh's ground truth (``api.render_mesh``,
4x4 supersampled) over the mesh's coverage. Saved as results/lod_auto.md.
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

from surfsplat import api  # noqa: E402
from surfsplat.metrics import psnr  # noqa: E402
from surfsplat.render.context import headless_context, renderer_name  # noqa: E402
from surfsplat.render.lod_auto import AUTO, auto_lod_tolerance, points_per_pixel  # noqa: E402


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
    tree = api.as_hierarchy(cloud)
    build = time.perf_counter() - start
    rows = []
    for size in args.sizes:
        camera = api.auto_camera(cloud, size, size)
        truth = api.render_mesh(SHARED / "bunny.ply", camera)
        mask = truth.alpha > 0.5
        density = points_per_pixel(cloud.positions, api.local_camera(cloud, camera))
        decided = auto_lod_tolerance(cloud.positions, api.local_camera(cloud, camera))
        full, full_s = timed(lambda: api.render_model(cloud, camera, technique=args.technique), args.repeat)
        cut, cut_s = timed(lambda: api.render_model(tree, camera, technique=args.technique, lod_tolerance=AUTO),
                           args.repeat)
        db_full = psnr(full.frame.color, truth.color, mask)
        db_cut = psnr(cut.frame.color, truth.color, mask)
        rows.append([f"{size}x{size}", len(cloud), round(density, 1), "cut at 1 px" if decided else "all splats",
                     cut.splats, round(len(cloud) / cut.splats, 2), round(full_s * 1000), round(cut_s * 1000),
                     round(build, 2), round(db_full, 2), round(db_cut, 2), round(db_cut - db_full, 2)])
        print(rows[-1], flush=True)
    columns = ["resolution", "splats", "points per covered pixel", "auto decides", "splats in the 1 px cut", "fewer",
               "all splats frame ms", "1 px cut frame ms", "hierarchy build s (once)", "all splats PSNR dB",
               "1 px cut PSNR dB", "cut - all dB"]
    write_table("lod_auto", columns, rows, machine_description(renderer_name(headless_context()))
                + f"; bunny, technique {args.technique}, PSNR against the mesh over its coverage; frame = "
                  "api.render_model (cut, upload, draw, read-back), median of " + str(args.repeat))


if __name__ == "__main__":
    main()
