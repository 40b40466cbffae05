"""The LiDAR pictures of the documentation (``docs/images/lidar_*.png``): colour by attribute, EDL, hybrid.

Inputs: ``shared/data/simple.las`` (1,065 airborne points) and a generated aerial block
(:func:`surfsplat.scenes_faulty.aerial`: ground, gable roofs with walls, trees; 400 k ground
samples 0.25 m apart over 160 m, written as a LAS file so it takes the LAS path: z up, hybrid by
default, ``classification`` and ``intensity`` dimensions). Every picture is drawn through
``surfsplat.render`` as a user would; pairs are put side by side (left | right), 640 px wide.

    python benchmarks/lidar_pictures.py [--out docs/images] [--ground 400000]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import laspy
import numpy as np
from PIL import Image

import surfsplat
from surfsplat.pipeline import CameraSpec, SourceOptions
from surfsplat.colors import ColorOptions
from surfsplat.rendering.options import EdlOptions, RenderOptions
from surfsplat.scenes_faulty import aerial

SIMPLE = Path(__file__).resolve().parents[2] / "shared" / "data" / "simple.las"
WIDTH = 640


def write_las(cloud, path: Path) -> None:
    """The aerial block as a LAS 1.2 file (point format 3: intensity, classification, RGB)."""
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = [0.001] * 3
    las = laspy.LasData(header)
    p = cloud.positions.astype(np.float64)
    las.x, las.y, las.z = p[:, 0], p[:, 1], p[:, 2]
    las.intensity = cloud.attributes["intensity"]
    las.classification = cloud.attributes["classification"]
    rgb = np.round(cloud.colors * 65535).astype(np.uint16)
    las.red, las.green, las.blue = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    las.write(str(path))


def draw(source, width, height, camera=None, color=None, hybrid=None, **kw) -> np.ndarray:
    start = time.perf_counter()
    options = SourceOptions(color=ColorOptions(color) if color else None, hybrid=hybrid)   # hybrid None: on for LAS
    frame = surfsplat.render(str(source), camera, width=width, height=height, source_options=options, **kw)
    kw = kw if hybrid is None else kw | {"hybrid": hybrid}
    print(f"  {Path(source).name} {color or 'own colours'} {kw}: {time.perf_counter() - start:.1f} s")
    return frame.image()


def save(image: np.ndarray, out: Path) -> None:
    # 256 colours (median cut, no dithering): a few tens of KB a picture, no visible banding here
    Image.fromarray(image).quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
        out, optimize=True)
    print(f"-> {out} ({out.stat().st_size // 1024} KB)")


def pair(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    gap = np.full((left.shape[0], 4, 3), 255, np.uint8)
    return np.concatenate([left, gap, right], axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "images")
    parser.add_argument("--ground", type=int, default=400_000)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    half = (WIDTH - 4) // 2
    edl = RenderOptions(edl=EdlOptions())

    # simple.las: three colourings, and EDL off | on
    for by in ("elevation", "classification", "intensity"):
        save(draw(SIMPLE, WIDTH, 400, color=by), args.out / f"lidar_simple_{by}.png")
    save(pair(draw(SIMPLE, half, 260, color="elevation"), draw(SIMPLE, half, 260, color="elevation", options=edl)),
         args.out / "lidar_simple_edl.png")

    with tempfile.TemporaryDirectory() as tmp:
        block = Path(tmp) / "aerial_block.las"
        scene = aerial(n=args.ground, houses=7, trees=9, side=160.0, seed=2)
        write_las(scene.cloud, block)
        print(f"aerial block: {len(scene.cloud):,} points")
        oblique = CameraSpec(eye=(-40.0, -60.0, 95.0), target=(80.0, 80.0, 0.0), up=(0.0, 0.0, 1.0), fov=45.0)
        for by in ("elevation", "classification", "intensity"):
            save(draw(block, WIDTH, 420, oblique, color=by), args.out / f"lidar_aerial_{by}.png")
        # EDL off | on, own colours (a block without shading cues)
        # seen steeply from above, as aerial data usually is (at grazing angles EDL darkens the ground too:
        # along a receding plane the nearer neighbours above each pixel count as occluders)
        close = CameraSpec(eye=(60.0, 35.0, 110.0), target=(80.0, 80.0, 0.0), up=(0.0, 0.0, 1.0), fov=40.0)
        save(pair(draw(block, half, 300, close, color="elevation", lights=surfsplat.Lights(enabled=False)),
                  draw(block, half, 300, close, color="elevation", lights=surfsplat.Lights(enabled=False),
                       options=edl)), args.out / "lidar_aerial_edl.png")
        # all splats | hybrid, near a tree
        trees = scene.cloud.positions[scene.cloud.attributes["classification"] == 5]
        c = trees[np.argmin(np.linalg.norm(trees[:, :2] - trees[:, :2].mean(axis=0), axis=1))].astype(float)
        near = CameraSpec(eye=(c[0] - 14.0, c[1] - 14.0, c[2] + 4.0), target=(c[0], c[1], c[2] - 3.0),
                          up=(0.0, 0.0, 1.0), fov=50.0)
        save(pair(draw(block, half, 300, near, hybrid=False), draw(block, half, 300, near, hybrid=True)),
             args.out / "lidar_aerial_hybrid.png")


if __name__ == "__main__":
    main()
