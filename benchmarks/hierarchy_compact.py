"""Compact hierarchy files (``surfsplat build --compact``): bytes per splat, load time and the cost of the
quantization in the picture.

For each model the hierarchy is built once (:func:`surfsplat.hierarchy.build_hierarchy`, leaf capacity 8)
and saved full and compact (:func:`surfsplat.hierarchy.save_hierarchy`); the table gives each file's bytes
per splat (file size over the points), the load time of :func:`~surfsplat.hierarchy.load_hierarchy`
(fastest of 3), and for ``ewa`` and ``flat`` at W x H at the default view the PSNR of the render of the
compact file against the render of the full one (``View(file).render``: the hierarchy's default cut), with
the covered pixels the compact render leaves empty (holes) and adds.

Models: the Stanford bunny and ``simple.las`` from ``shared/data`` (prepared as ``surfsplat build`` prepares
them: the bunny's surface sampled, the LiDAR points preprocessed, with their LAS attributes), and a
1,000,000-splat torus (``surfsplat.scenes.torus(1250, 800)``).

    python benchmarks/hierarchy_compact.py [--size 1024 768]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, markdown_table  # noqa: E402

from surfsplat.hierarchy import build_hierarchy, load_hierarchy, save_hierarchy  # noqa: E402
from surfsplat.metrics import psnr  # noqa: E402
from surfsplat.pipeline import View  # noqa: E402
from surfsplat.scenes import torus  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
SHARED = Path("/work/shared/data")


def covered(image: np.ndarray) -> np.ndarray:
    return image.min(axis=2) < 250   # the white background


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(1024, 768), metavar=("W", "H"))
    args = parser.parse_args()
    width, height = args.size
    data = DATA if DATA.is_dir() else SHARED
    models = [("torus 1M", torus(1250, 800))]
    for name in ("bunny.ply", "simple.las"):
        if (data / name).exists():
            models.append((name, View(data / name).sample().points()))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, cloud in models:
            h = build_hierarchy(cloud, 8)
            n = len(h.points)
            row = [name, n, len(h)]
            paths = {}
            for layout in ("full", "compact"):
                path = Path(tmp) / f"{layout}.npz"
                save_hierarchy(h, path, compact=layout == "compact")
                times = []
                for _ in range(3):
                    start = time.perf_counter()
                    load_hierarchy(path)
                    times.append(time.perf_counter() - start)
                row += [path.stat().st_size / n, min(times)]
                paths[layout] = path
            for technique in ("ewa", "flat"):
                view = View(paths["full"])
                camera = view.camera(None, width, height)
                a = view.render(camera, technique=technique).frame.image()
                b = View(paths["compact"]).render(camera, technique=technique).frame.image()
                holes = int((covered(a) & ~covered(b)).sum())
                added = int((covered(b) & ~covered(a)).sum())
                row += [round(psnr(a / 255.0, b / 255.0), 1), f"{holes} / {added}"]
            rows.append(row)
            print(row, flush=True)
    columns = ["model", "splats", "nodes", "full B/splat", "full load s", "compact B/splat", "compact load s",
               "ewa PSNR dB", "ewa holes / added px", "flat PSNR dB", "flat holes / added px"]
    machine = machine_description()
    command = "python benchmarks/hierarchy_compact.py" + ("" if (width, height) == (1024, 768)
                                                         else f" --size {width} {height}")
    lines = [f"Machine: {machine}", f"Date: {time.strftime('%Y-%m-%d')}", f"Command: `{command}`",
             f"Renders: {width} x {height}, default view, compact file against full file.", ""]
    text = "\n".join(lines + markdown_table(columns, rows))
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "hierarchy_compact.md").write_text(text + "\n")
    import json
    (RESULTS / "hierarchy_compact.json").write_text(json.dumps(
        {"machine": machine, "date": time.strftime("%Y-%m-%d"), "command": command, "size": [width, height],
         "columns": columns, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
