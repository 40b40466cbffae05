"""Chunked build of a large generated LiDAR-like cloud: build time, peak RSS, bytes on disk, render time.

Generates a LAS file in a temporary folder (never in the repository): terrain (hills and noise,
uniform in x, y) and box buildings (roofs and walls), written in chunks; builds it with
``surfsplat.hierarchy.chunked.build_chunked`` in a child process (its peak RSS, and its worker
processes', from ``getrusage``); renders an overview and a close-up from the lazily opened
directory; compares Dask with 1 and 2 workers on a smaller cloud. Prints a Markdown table and
saves it to ``benchmarks/results/chunked_build.md``; pictures go to the temporary folder.

    python benchmarks/chunked_build.py --points 10000000 --compare-points 2000000
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = ROOT / "benchmarks" / "results" / "chunked_build.md"
#: Georeferenced like real LiDAR: float32 alone would round these to 0.25 m.
OFFSET = np.array([512_000.0, 4_180_000.0, 300.0])
SIDE = 1000.0  # metres
BUILDINGS = 400


def generate_las(path: Path, n: int, seed: int = 0, chunk: int = 2_000_000, shift=(0.0, 0.0)) -> None:
    """``n`` points: 80 % terrain, 20 % on the roofs and walls of box buildings, written in chunks;
    the square ``SIDE`` wide from ``shift`` (metres, x and y)."""
    import laspy
    rng = np.random.default_rng(seed)
    centers = rng.uniform(50, SIDE - 50, (BUILDINGS, 2)) + shift
    sizes = rng.uniform(10, 40, (BUILDINGS, 2))
    heights = rng.uniform(5, 40, BUILDINGS)

    def ground(x, y):
        return 20 * np.sin(x / 130.0) * np.cos(y / 170.0) + 8 * np.sin(x / 37.0 + y / 53.0)

    header = laspy.LasHeader(point_format=3, version="1.2")
    header.offsets, header.scales = OFFSET, np.full(3, 0.001)
    with laspy.open(path, mode="w", header=header) as writer:
        for start in range(0, n, chunk):
            m = min(chunk, n - start)
            nb = m // 5
            x, y = rng.uniform(0, SIDE, m - nb) + shift[0], rng.uniform(0, SIDE, m - nb) + shift[1]
            z = ground(x, y) + rng.normal(0, 0.02, len(x))
            # buildings: a roof (area a b) or one of four walls (areas a h, b h), by area
            b = rng.integers(0, BUILDINGS, nb)
            (a_, b_), h = sizes[b].T, heights[b]
            areas = np.column_stack([a_ * b_, a_ * h, a_ * h, b_ * h, b_ * h])
            face = (rng.uniform(0, 1, nb)[:, None] > np.cumsum(areas, 1) / areas.sum(1, keepdims=True)).sum(1)
            s, t = rng.uniform(-0.5, 0.5, nb), rng.uniform(0, 1, nb)
            bx = np.where(face == 0, s * a_, np.where(face <= 2, s * a_, np.where(face == 3, -0.5, 0.5) * a_))
            by = np.where(face == 0, rng.uniform(-0.5, 0.5, nb) * b_,
                          np.where(face == 1, -0.5 * b_, np.where(face == 2, 0.5 * b_, s * b_)))
            base = ground(*centers[b].T)
            bz = base + np.where(face == 0, h, t * h)
            px = np.concatenate([x, centers[b, 0] + bx]) + OFFSET[0]
            py = np.concatenate([y, centers[b, 1] + by]) + OFFSET[1]
            pz = np.concatenate([z, bz]) + OFFSET[2]
            points = laspy.ScaleAwarePointRecord.zeros(m, header=header)
            points.x, points.y, points.z = px, py, pz
            grey = np.concatenate([np.full(len(x), 30000), np.full(nb, 52000)]).astype(np.uint16)
            points.red, points.green, points.blue = grey, (grey * 0.9).astype(np.uint16), (grey * 0.8).astype(np.uint16)
            writer.write_points(points)


class PeakRss:
    """Samples (every 0.1 s, in a thread) the RSS of this process and, separately, the sum over its
    child processes (Dask's process workers); ``own`` and ``children`` hold the peaks in MiB.
    (``getrusage``'s ru_maxrss would not do: Linux carries it over from the forking parent.)"""

    def __init__(self):
        import psutil
        self.process, self.own, self.children = psutil.Process(), 0.0, 0.0
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._watch, daemon=True)
        self.thread.start()

    def _watch(self):
        import psutil
        while not self.done.is_set():
            try:
                self.own = max(self.own, self.process.memory_info().rss / 2**20)
                kids = sum(c.memory_info().rss for c in self.process.children(recursive=True)) / 2**20
                self.children = max(self.children, kids)
            except psutil.Error:
                pass
            time.sleep(0.1)

    def stop(self):
        self.done.set()
        self.thread.join()
        return self.own, self.children


_CHILD = """
import json, sys, time
sys.path.insert(0, sys.argv[2])
from chunked_build import PeakRss
from surfsplat.hierarchy.chunked import build_chunked
args = json.loads(sys.argv[1])
rss = PeakRss()
t = time.perf_counter()
r = build_chunked(args["source"], args["output"], cell_points=args["cell_points"], scheduler=args["scheduler"],
                  workers=args["workers"], overwrite=True)
wall = time.perf_counter() - t
own, children = rss.stop()
print(json.dumps({"wall": wall, "rss_mb": own, "child_rss_mb": children, "points": r.points, "cells": r.cells,
                  "bytes": r.bytes, "seconds": r.seconds, "flipped": r.flipped, "nodes": r.nodes}))
"""


_IN_MEMORY = """
import json, sys, time
sys.path.insert(0, sys.argv[3])
from chunked_build import PeakRss
import surfsplat
from surfsplat.hierarchy import build_hierarchy, save_hierarchy
rss = PeakRss()
t = time.perf_counter()
cloud = surfsplat.preprocess(surfsplat.load(sys.argv[1]))
save_hierarchy(build_hierarchy(cloud), sys.argv[2], overwrite=True)
wall = time.perf_counter() - t
own, _ = rss.stop()
print(json.dumps({"wall": wall, "rss_mb": own, "child_rss_mb": 0, "points": len(cloud)}))
"""

_RENDER = """
import json, sys
sys.path.insert(0, sys.argv[3])
from chunked_build import PeakRss, render
from pathlib import Path
rss = PeakRss()
rows = render(Path(sys.argv[1]), Path(sys.argv[2]))
own, _ = rss.stop()
print(json.dumps({"rows": rows, "rss_mb": own}))
"""


def child(code: str, args: list[str], cores: int | None = None) -> dict:
    """Run ``code`` in a child Python (on ``cores`` CPUs with taskset when given); its JSON line."""
    pin = ["taskset", "-c", ",".join(str(c) for c in range(cores))] if cores else []
    out = subprocess.run(pin + [sys.executable, "-c", code, *args], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def build(source: Path, output: Path, cell_points: int, scheduler: str, workers: int, cores: int | None = None) -> dict:
    """One build in a child process: its report, wall time and peak RSS (MiB)."""
    arg = json.dumps({"source": str(source), "output": str(output), "cell_points": cell_points,
                      "scheduler": scheduler, "workers": workers})
    return child(_CHILD, [arg, str(HERE)], cores)


def render(output: Path, folder: Path) -> list[tuple[str, float, str]]:
    """Open lazily and draw an overview and a close-up at 1024x768; (what, seconds, detail) rows."""
    from surfsplat.hierarchy.chunked import open_chunked
    from surfsplat.pipeline import CameraSpec, LodOptions, View
    rows = []
    t = time.perf_counter()
    model = open_chunked(output)
    rows.append(("open (manifest, top hierarchy, preview)", time.perf_counter() - t, f"{len(model.cells)} cells"))
    framing = View(model)   # its cameras about the chunked model's own up axis
    camera = framing.camera(None, 1024, 768)
    center = model.origin + [0.0, 0.0, 0.0]
    close = framing.camera(CameraSpec(eye=tuple(center + [-60, -90, 70]), target=tuple(center + [0, 0, 10]),
                                      up=(0, 0, 1), fov=50), 1024, 768)
    far = framing.camera(CameraSpec(eye=tuple(model.origin + [-100_000, -150_000, 80_000]),
                                    target=tuple(model.origin), up=(0, 0, 1), fov=40), 1024, 768)
    for name, cam, budget, tolerance in (("overview", camera, None, 1.0), ("overview", camera, 1_000_000, 1.0),
                                         ("close-up", close, None, 1.0), ("close-up", close, 1_000_000, 1.0),
                                         ("far", far, None, 4.0)):
        view = View(model, lod=LodOptions(tolerance=tolerance, point_budget=budget))   # the model's cell cache shared
        for attempt in ("cold", "warm"):
            t = time.perf_counter()
            result = view.render(cam)
            seconds = time.perf_counter() - t
            s = result.selection
            rows.append((f"render {name}, tolerance {tolerance:g} px, budget {budget or 'none'} ({attempt} cache)",
                         seconds,
                         f"{result.splats:,} splats at {s.lod_tolerance:.2f} px, {s.cells_loaded} cells read, "
                         f"{s.cells_root_only} drawn as their root"))
        result.frame.save(folder / f"{name}_{budget or 'nobudget'}.png")
    return rows


def compare(chunked: Path, single: Path, folder: Path) -> list[str]:
    """Table rows: the chunked directory against the one-file hierarchy of the same cloud, one close-up."""
    from PIL import Image

    from surfsplat.hierarchy import load_hierarchy
    from surfsplat.hierarchy.chunked import open_chunked
    from surfsplat.metrics import psnr
    from surfsplat.pipeline import CameraSpec, LodOptions, View
    model, memory = open_chunked(chunked), load_hierarchy(single)
    c = model.origin
    close = View(model).camera(CameraSpec(eye=tuple(c + [-60, -90, 70]), target=tuple(c + [0, 0, 10]),
                                          up=(0, 0, 1), fov=50), 640, 480)
    rows = []
    for tolerance in (0.0, 1.0):
        lod = LodOptions(tolerance=tolerance)
        a = View(model, lod=lod).render(close)
        b = View(memory, lod=lod).render(close)
        d = np.abs(a.frame.color - b.frame.color)
        rows.append(f"| {tolerance:g} px | {a.splats:,} / {b.splats:,} | {psnr(a.frame.color, b.frame.color):.1f} | "
                    f"{100 * (d.max(axis=-1) > 0.05).mean():.2f} % |")
        picture = np.concatenate([a.frame.image(), b.frame.image(), (np.clip(d * 5, 0, 1) * 255).astype(np.uint8)], 1)
        Image.fromarray(picture).save(folder / f"compare_{tolerance:g}.png")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=10_000_000)
    parser.add_argument("--compare-points", type=int, default=2_000_000)
    parser.add_argument("--cell-points", type=int, default=1_000_000)
    parser.add_argument("--tiles", type=int, default=1, help="T: the cloud is T x T LAS tiles in a folder")
    parser.add_argument("--out", type=Path, default=RESULTS, help="the Markdown table (default %(default)s)")
    parser.add_argument("--tmp", type=Path, default=Path("/tmp/surfsplat_chunked_bench"))
    args = parser.parse_args()
    args.tmp.mkdir(parents=True, exist_ok=True)
    machine = f"llvmpipe (Mesa, no GPU), {platform.machine()} 2-core EPYC, Python {platform.python_version()}"
    what = (f"{args.tiles} x {args.tiles} LAS tiles in a folder, each" if args.tiles > 1 else "one LAS file:")
    lines = ["# Chunked build\n", f"Machine: {machine}. Generated LiDAR-like cloud, {what} terrain and "
             f"{BUILDINGS} box buildings over {SIDE:.0f} m x {SIDE:.0f} m, georeferenced at {OFFSET[:2].tolist()}; "
             f"`python benchmarks/chunked_build.py --points {args.points} --compare-points {args.compare_points} "
             f"--tiles {args.tiles}`.\n"]
    if args.tiles > 1:
        big = args.tmp / f"tiles_{args.points}"
        if not big.exists():
            t = time.perf_counter()
            big.mkdir()
            per = args.points // args.tiles**2
            for i in range(args.tiles):
                for j in range(args.tiles):
                    generate_las(big / f"tile_{i}_{j}.las", per, seed=10 * i + j, shift=(SIDE * i, SIDE * j))
            print(f"generated {big} in {time.perf_counter() - t:.1f} s", flush=True)
    else:
        big = args.tmp / f"cloud_{args.points}.las"
        if not big.exists():
            t = time.perf_counter()
            generate_las(big, args.points)
            print(f"generated {big} in {time.perf_counter() - t:.1f} s", flush=True)
    r = build(big, args.tmp / "big.ssh", args.cell_points, "threads", 2)
    s = r["seconds"]
    lines += ["## Build\n", "| points | cells | cell points | scheduler | build s | stream | preprocess | orient | "
              "octrees | peak RSS MiB | on disk MiB | B/splat | points/s |", "|" + "---|" * 13,
              f"| {r['points']:,} | {r['cells']} | {args.cell_points:,} | threads x2 | {r['wall']:.1f} | "
              f"{s['stream']:.1f} | {s['preprocess']:.1f} | {s['orient']:.1f} | {s['build']:.1f} | "
              f"{max(r['rss_mb'], r['child_rss_mb']):,.0f} | {r['bytes'] / 2**20:,.0f} | "
              f"{r['bytes'] / r['points']:.0f} | {r['points'] / r['wall']:,.0f} |", ""]
    print("\n".join(lines), flush=True)
    r = child(_RENDER, [str(args.tmp / "big.ssh"), str(args.tmp), str(HERE)])
    rows = r["rows"]
    lines += ["## Rendering the chunked directory at 1024x768 (ewa)\n",
              f"In one process (peak RSS {r['rss_mb']:,.0f} MiB, with the renderer and the gathered splats).\n",
              "| step | seconds | drawn |", "|---|---|---|"]
    lines += [f"| {a} | {b:.2f} | {c} |" for a, b, c in rows]
    lines.append(f"\nPictures: {args.tmp}/overview_*.png, {args.tmp}/close-up_*.png, {args.tmp}/far_*.png "
                 f"(and {args.tmp}/compare_*.png: chunked, in memory, 5x difference).\n")
    print("\n".join(lines[-len(rows) - 4:]), flush=True)
    if args.compare_points <= 0:
        args.out.write_text("\n".join(lines) + "\n")
        print(f"-> {args.out}")
        return
    small = args.tmp / f"cloud_{args.compare_points}.las"
    if not small.exists():
        generate_las(small, args.compare_points, seed=1)
    cell = max(args.compare_points // 8, 1000)
    lines += [f"## Dask workers ({args.compare_points:,} points, cells of at most {cell:,})\n",
              "Each task's NumPy kernels already use every core the process may use (threads), so on this "
              "2-core machine the scaling that matters is with cores: 1 worker pinned to 1 core "
              "(`taskset -c 0`) against 2 workers on 2 cores.\n",
              "| build | cores | build s | preprocess s | peak RSS MiB (driver / workers) | speed-up |",
              "|---|---|---|---|---|---|"]
    base = None
    for scheduler, workers, cores in (("threads", 1, 1), ("threads", 2, 2), ("processes", 2, 2)):
        r = build(small, args.tmp / "small.ssh", cell, scheduler, workers, cores)
        base = base or r["wall"]
        lines.append(f"| chunked, Dask {scheduler} x{workers} | {cores} | {r['wall']:.1f} | "
                     f"{r['seconds']['preprocess']:.1f} | {r['rss_mb']:,.0f} / {r['child_rss_mb']:,.0f} | "
                     f"{base / r['wall']:.2f} |")
        print(lines[-1], flush=True)
    r = child(_IN_MEMORY, [str(small), str(args.tmp / "small.npz"), str(HERE)], 2)
    lines.append(f"| in memory (preprocess + build_hierarchy + save .npz) | 2 | {r['wall']:.1f} | | "
                 f"{r['rss_mb']:,.0f} / 0 | {base / r['wall']:.2f} |")
    print(lines[-1], flush=True)
    lines += ["", "## Chunked against in-memory, the same 2 M points (close-up at 640x480, ewa)\n",
              "| LOD tolerance | splats chunked / in memory | PSNR dB | pixels differing > 0.05 |", "|---|---|---|---|"]
    lines += compare(args.tmp / "small.ssh", args.tmp / "small.npz", args.tmp)
    print("\n".join(lines[-3:]), flush=True)
    lines.append(f"\nLoad average (1 min) at the end: {os.getloadavg()[0]:.1f} on 2 cores (a machine shared with "
                 "other jobs: the worker comparison is noisy).")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    print(f"-> {args.out}")


if __name__ == "__main__":
    main()
