"""Point attributes through a chunked build: a generated aerial LiDAR block coloured by
classification and intensity, chunked against in memory.

Writes the block (``surfsplat.scenes_faulty.aerial``: ground, houses, trees; ASPRS classes and
intensity) as a LAS file in a temporary folder, builds a chunked hierarchy of it in cells of
``--cell-points``, and renders both the chunked model and the LAS file (in memory, its hierarchy
built on loading) with ``--color-by classification`` and ``intensity`` at the same LOD tolerance,
oblique, 640x420 ``ewa``. Reports the build, the fraction of drawn pixels in an ASPRS palette colour
(no lighting), and the PSNR between the two pictures; prints and saves the Markdown table to
``benchmarks/results/chunked_attributes.md`` and the pictures (chunked | in memory) to ``--pictures``
(never the repository).

    python benchmarks/chunked_attributes.py --ground 400000 --pictures /tmp
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_description  # noqa: E402
from lidar_pictures import pair, write_las  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat.pipeline import CameraSpec, LodOptions, SourceOptions  # noqa: E402
from surfsplat.colors import ColorOptions, asprs_palette  # noqa: E402
from surfsplat.hierarchy.chunked import build_chunked, open_chunked  # noqa: E402
from surfsplat.metrics import psnr  # noqa: E402
from surfsplat.scenes_faulty import aerial  # noqa: E402

RESULTS = HERE / "results" / "chunked_attributes.md"

#: What keeping the attributes costs a build (measured once, by hand).
BUILD_COST = """
Build cost of the attributes, one 4 M-point tile of the 64 M-point benchmark cloud (LAS point format
3, 13 attribute columns), `/usr/bin/time -v surfsplat build tile_0_0.las -o T.ssh --chunked`, the
code before attributes were kept against the code that keeps them, one after the other: 53.5 s ->
65.6 s, peak RSS 1,446 -> 1,544 MiB, on disk 586 -> 711 MB (146 -> 178 bytes a splat).
"""
WIDTH, HEIGHT = 640, 420
CAMERA = CameraSpec(eye=(-40.0, -60.0, 95.0), target=(80.0, 80.0, 0.0), up=(0.0, 0.0, 1.0), fov=45.0)


def draw(source, by: str, lights: bool) -> tuple[np.ndarray, float]:
    start = time.perf_counter()
    frame = surfsplat.render(source, CAMERA, width=WIDTH, height=HEIGHT, lod=LodOptions(tolerance=1.0),
                             lights=surfsplat.Lights(enabled=lights),
                             source_options=SourceOptions(color=ColorOptions(by)))
    return frame.image(), time.perf_counter() - start


def palette_share(image: np.ndarray) -> float:
    """Fraction of the non-background pixels within 2/255 of an ASPRS palette colour."""
    palette = np.unique(np.round(asprs_palette().astype(np.float64) * 255), axis=0)
    drawn = np.any(image != 255, axis=2)
    pixels = image[drawn].astype(np.float64)
    near = np.zeros(len(pixels), dtype=bool)
    for colour in palette:
        near |= np.abs(pixels - colour).max(axis=1) <= 2
    return float(near.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ground", type=int, default=400_000, help="ground samples of the aerial block")
    parser.add_argument("--cell-points", type=int, default=60_000)
    parser.add_argument("--pictures", type=Path, default=Path("/tmp"))
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        block = Path(tmp) / "aerial_block.las"
        scene = aerial(n=args.ground, houses=7, trees=9, side=160.0, seed=2)
        write_las(scene.cloud, block)
        start = time.perf_counter()
        report = build_chunked(block, Path(tmp) / "block.ssh", cell_points=args.cell_points, scheduler="threads")
        build_s = time.perf_counter() - start
        model = open_chunked(report.path)
        attribute_bytes = 0   # their share of the files: per-point files and node members
        for cell in model.cells:
            attribute_bytes += sum(size for name, size in cell["files"].items() if name.startswith("attribute_"))
            with np.load(report.path / "cells" / cell["key"] / "nodes.npz") as nodes:
                attribute_bytes += sum(nodes[name].nbytes for name in nodes.files if name.startswith("node_attribute_"))
        for by, lights in (("classification", False), ("intensity", True)):
            chunked, chunked_s = draw(report.path, by, lights)
            memory, memory_s = draw(str(block), by, lights)
            out = args.pictures / f"chunked_attributes_{by}.png"
            Image.fromarray(pair(chunked, memory)).save(out)
            rows.append({"by": by, "chunked_s": chunked_s, "memory_s": memory_s,
                         "psnr": psnr(chunked.astype(np.float32) / 255, memory.astype(np.float32) / 255),
                         "palette": (palette_share(chunked), palette_share(memory)) if not lights else None,
                         "picture": out})
            print(rows[-1], flush=True)
    text = (f"# Attributes through a chunked build: the aerial block by classification and intensity\n\n"
            f"Machine: llvmpipe, 2-core EPYC ({machine_description()}), shared with other jobs. "
            f"`python benchmarks/chunked_attributes.py --ground {args.ground} --cell-points {args.cell_points}`: "
            f"{len(scene.cloud):,} points (ground, 7 houses, 9 trees; LAS point format 3), chunked build "
            f"{build_s:.1f} s into {report.cells} cells, {report.bytes / 2**20:.1f} MiB "
            f"({report.bytes / report.points:.0f} B a splat, of which {attribute_bytes / report.points:.0f} B the "
            f"attributes' points and nodes); {len(model.attributes)} attributes kept: "
            f"{', '.join(model.attributes)}.\n\n"
            f"Oblique view, {WIDTH}x{HEIGHT} `ewa`, LOD tolerance 1 px; in memory = the LAS file, its hierarchy "
            f"built on loading (render time includes preprocessing and building).\n\n"
            "| colour by | chunked render s | in memory s | PSNR chunked vs in memory "
            "| pixels in palette colours (chunked / in memory) |\n"
            "|---|---|---|---|---|\n")
    for r in rows:
        share = "-" if r["palette"] is None else f"{r['palette'][0]:.3f} / {r['palette'][1]:.3f}"
        text += f"| {r['by']} | {r['chunked_s']:.1f} | {r['memory_s']:.1f} | {r['psnr']:.1f} dB | {share} |\n"
    text += BUILD_COST
    RESULTS.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
