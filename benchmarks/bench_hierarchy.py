"""LOD hierarchy: build throughput (points/s) and per-view selection time (ms).

Build: :func:`surfsplat.hierarchy.build_hierarchy` on analytic models with
exact normals and covering splats (``surfsplat.scenes``: a torus grid of
elliptical splats at 100k, 1M and 2M points, a Fibonacci sphere of 2M
circular splats) and on the Stanford bunny preprocessed with
``surfsplat.preprocess`` (if ``../shared/data/bunny.ply`` is there). Each
build runs ``--repeats`` times; the table shows the fastest and the first
(cold: the process's first touch of ~1 GB of fresh memory) run, the node
count, the levels, the file size of ``Hierarchy.save`` and the save / load
times.

Selection: :func:`surfsplat.hierarchy.select` on the 2M-point torus at
1024x1024, tau in {0, 0.5, 1, 2, 4, 8} pixels, frustum culling on: the whole
model in view (also with back-face culling), the model seen from 4x farther,
and close-up views (the eye inside the torus' tube; just above the surface);
the fastest of ``--select-repeats`` runs and the median, the splats selected,
and the time of ``Hierarchy.splats`` (the gather of the selected splats into
one SplatCloud), fastest of 3.

    python benchmarks/bench_hierarchy.py [--repeats 3] [--select-repeats 20]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, markdown_table  # noqa: E402

from surfsplat import Camera, scenes  # noqa: E402
from surfsplat.camera import frame_bounds  # noqa: E402
from surfsplat.hierarchy import build_hierarchy, load_hierarchy, save_hierarchy, select  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def models():
    """(name, zero-argument factory) of the build inputs."""
    out = [
        ("torus grid 500x200", lambda: scenes.torus(500, 200)),
        ("torus grid 1600x625", lambda: scenes.torus(1600, 625)),
        ("torus grid 2000x1000", lambda: scenes.torus(2000, 1000)),
        ("sphere (Fibonacci)", lambda: scenes.sphere(2_000_000)),
    ]
    bunny = SHARED / "bunny.ply"
    if bunny.exists():
        def load_bunny():
            from surfsplat import load, preprocess

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return preprocess(load(bunny))

        out.append(("bunny (preprocessed)", load_bunny))
    return out


def timed(fn, repeats: int):
    """(list of seconds, last result)."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return times, result


def bench_build(repeats: int):
    rows, keep = [], None
    for name, make in models():
        cloud = make()
        n = len(cloud)
        times, h = timed(lambda: build_hierarchy(cloud), repeats)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "model.npz"
            save_s, _ = timed(lambda: save_hierarchy(h, path, overwrite=True), 1)
            size = path.stat().st_size
            load_s, _ = timed(lambda: load_hierarchy(path), 2)
        best = min(times)
        rows.append([name, n, round(best, 3), round(n / best), round(times[0], 3), len(h), h.levels,
                     round(size / 2**20, 1), round(save_s[0], 2), round(min(load_s), 2)])
        if name == "torus grid 2000x1000":
            keep = h
    return rows, keep


def cameras(h):
    lo, hi = h.bounds()
    full = frame_bounds(lo, hi, width=1024, height=1024)
    far = frame_bounds(lo, hi, width=1024, height=1024, fill=0.25)
    inside = Camera(eye=(1.0, 0.0, 0.0), target=(1.0, 1.0, 0.0), up=(0.0, 0.0, 1.0), width=1024, height=1024,
                    near=0.005, far=10.0)
    grazing = Camera(eye=(1.45, -0.35, 0.1), target=(0.6, 0.8, 0.0), up=(0.0, 0.0, 1.0), width=1024, height=1024,
                     near=0.005, far=10.0)
    return [("whole model in view", full, False), ("whole model, back-face culling", full, True),
            ("far: model 1/4 of the image", far, False), ("close-up: eye inside the tube", inside, False),
            ("close-up: eye 0.1 above the surface, grazing", grazing, False)]


def bench_select(h, repeats: int):
    rows = []
    for view, camera, backfaces in cameras(h):
        for lod_tolerance in (0.0, 0.5, 1.0, 2.0, 4.0, 8.0):
            select(h, camera, lod_tolerance, cull_backfaces=backfaces)  # warm-up
            times, sel = timed(lambda: select(h, camera, lod_tolerance, cull_backfaces=backfaces), repeats)
            gather, splats = timed(lambda: h.splats(sel), 3)
            assert len(splats) == len(sel)
            rows.append([view, lod_tolerance, round(min(times) * 1e3, 2), round(float(np.median(times)) * 1e3, 2),
                         len(sel), sel.node_count, sel.point_total, sel.visited, round(min(gather) * 1e3, 1)])
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="builds per model (default 3)")
    parser.add_argument("--select-repeats", type=int, default=20, help="selections per case (default 20)")
    args = parser.parse_args(argv)

    machine = machine_description()
    build_cols = ["model", "points", "build s (best)", "points/s", "build s (first run)", "nodes", "levels",
                  "file MiB", "save s", "load s"]
    build_rows, torus = bench_build(args.repeats)
    select_cols = ["view (2M-point torus, 1024x1024)", "tau px", "select ms (best)", "select ms (median)",
                   "splats", "node splats", "points", "nodes visited", "gather ms"]
    select_rows = bench_select(torus, args.select_repeats)

    lines = [f"Machine: {machine}", f"Date: {time.strftime('%Y-%m-%d')}", "",
             f"Build (leaf capacity 8, best of {args.repeats}; first run = cold memory):", ""]
    lines += markdown_table(build_cols, build_rows)
    lines += ["", f"Selection (frustum culling on; best and median of {args.select_repeats}; "
              "gather = Hierarchy.splats, best of 3):", ""]
    lines += markdown_table(select_cols, select_rows)
    text = "\n".join(lines)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "hierarchy.md").write_text(text + "\n")
    (RESULTS / "hierarchy.json").write_text(json.dumps(
        {"machine": machine, "date": time.strftime("%Y-%m-%d"),
         "build": {"columns": build_cols, "rows": build_rows},
         "select": {"columns": select_cols, "rows": select_rows}}, indent=1))


if __name__ == "__main__":
    main()
