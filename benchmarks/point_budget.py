"""Point budget: frame time and quality against the full cloud, Stanford bunny, 1 M surface samples.

The bunny's mesh (``shared/data/bunny.ply``) is sampled with 1 M splats
(:func:`surfsplat.geometry.sampling.surface_splats`), its point-octree built once; the automatic
view with the eye moved to 0.7 of its distance (the bunny fills the frame) is drawn with ``ewa``:

* ``full``: every splat, no LOD (the reference image);
* ``LOD 1 px``: the tolerance cut at 1 pixel (the default);
* ``budget N``: the 1 px cut refined largest node on screen first until N splats
  (:func:`surfsplat.hierarchy.select` with ``point_budget``, Potree's priority).

Columns: splats drawn; selection time (cut + gather, ms, best of ``--repeats``); frame time (the
whole ``View.render`` of a prepared view: selection, upload, drawing, read-back; ms, best of ``--repeats``);
PSNR (dB) and SSIM against the full cloud over the pixels either image covers.

    python benchmarks/point_budget.py [--size 1024 768] [--samples 1000000] [--repeats 2]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, write_table  # noqa: E402

from surfsplat import metrics  # noqa: E402
from surfsplat.camera import Camera  # noqa: E402
from surfsplat.geometry.sampling import surface_splats  # noqa: E402
from surfsplat.hierarchy import build_hierarchy, select  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.pipeline import LodOptions, View, auto_camera  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

BUNNY = Path(__file__).resolve().parents[2] / "shared" / "data" / "bunny.ply"
BUDGETS = (30_000, 100_000, 300_000, 600_000)


def best_of(repeats: int, fn):
    """(best wall time in seconds, last result) of ``repeats`` calls of ``fn``."""
    best, result = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(1024, 768))
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    width, height = args.size

    mesh = load_mesh(BUNNY)
    cloud = surface_splats(mesh, args.samples, sharp_angle=None, seed=0)
    start = time.perf_counter()
    h = build_hierarchy(cloud)
    print(f"{len(cloud):,} samples, hierarchy of {len(h):,} nodes in {time.perf_counter() - start:.1f} s")
    home = auto_camera(cloud, width, height)
    eye, target = np.asarray(home.eye), np.asarray(home.target)
    camera = Camera(eye=tuple(target + 0.7 * (eye - target)), target=home.target, up=home.up, fov=home.fov,
                    width=width, height=height)

    def prepared(**lod) -> View:
        """The view of every splat of the cloud (no LOD options), else of the hierarchy cut as ``lod`` says."""
        return View(h, lod=LodOptions(**lod)) if lod else View(cloud)

    prepared(tolerance=1.0, point_budget=1000).render(camera)   # warm-up: shaders compiled, renderer created
    full = prepared()
    ref_s, ref = best_of(args.repeats, lambda: full.render(camera))
    reference = ref.frame
    rows = [["full (every splat)", len(cloud), "-", round(1000 * ref_s), "ref", "ref"]]
    cases = [("LOD 1 px", None)] + [(f"budget {n:,}", n) for n in BUDGETS]
    for label, budget in cases:
        sel_s, selection = best_of(args.repeats, lambda: h.splats(select(h, camera, 1.0, point_budget=budget)))
        view = prepared(tolerance=1.0, point_budget=budget)
        t, result = best_of(args.repeats, lambda: view.render(camera))
        mask = result.frame.mask | reference.mask
        rows.append([label, result.splats, round(1000 * sel_s), round(1000 * t),
                     round(metrics.psnr(result.frame.color, reference.color, mask), 2),
                     round(metrics.ssim(result.frame.color, reference.color, mask), 4)])
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    load = os.getloadavg()[0]   # the cores are shared: times grow with the other jobs' load
    write_table("point_budget", ["drawn", "splats", "select ms", "frame ms", "PSNR dB", "SSIM"], rows,
                f"{machine}; load average {load:.1f} at the end; bunny, {len(cloud):,} samples, ewa at "
                f"{width}x{height}, best of {args.repeats}")


if __name__ == "__main__":
    main()
