"""The experiments of Zwicker et al. 2004 (figures 3, 6 and 7): documentation pictures and numbers.

Usage: python benchmarks/zwicker_figures.py [--out docs/images]

Renders the views of tests/test_zwicker_experiments.py (whose helpers build the scenes and
the analytic ground truth) at 512 px width:

- ``zwicker_grazing_ewa.png``, ``zwicker_grazing_perspective.png`` (figures 3 and 7): the
  grazing plane of exactly covering splats (PLY with a ``radius`` property, loaded back),
  prefilter on; pixels inside the square's exact image (eroded by 2 px) that the technique
  left empty are painted red.
- ``zwicker_checker_prefilter.png``, ``zwicker_checker_noprefilter.png`` (figure 6): the
  checkerboard with ``perspective``, with and without the EWA prefilter;
  ``zwicker_checker_truth.png``: the texture ray-cast at 4x4 samples per pixel;
  ``zwicker_checker_low_prefilter.png``, ``zwicker_checker_low_noprefilter.png``: the same
  from a low eye looking to the far edge (recognizable squares in the foreground).

and prints (and saves as benchmarks/results/zwicker_experiments.md/.json) the hole counts of
the grazing plane and the checkerboard's errors against the supersampled texture, at the
tests' resolution (320x160) and the pictures' (512x256), plus a low eye looking to the far
edge (squares up to ~15 px wide in the foreground), where the prefilter's blur weighs more.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import numpy as np  # noqa: E402
from common import machine_description, write_table  # noqa: E402
from PIL import Image  # noqa: E402
from test_zwicker_experiments import (  # noqa: E402
    CHECKER_CAMERA, GRAZING_CAMERA, UNLIT, checker_cloud, checker_truth, grazing_measure, grazing_truth,
    image_errors, write_grazing_ply)

import surfsplat  # noqa: E402
from surfsplat.camera import Camera  # noqa: E402
from surfsplat.rendering.context import renderer_name  # noqa: E402
from surfsplat.rendering.renderer import Renderer  # noqa: E402
from surfsplat.rendering.options import FilterOptions, RenderOptions  # noqa: E402

ROOT = HERE.parent
#: Color of the hole pixels in the grazing pictures.
HOLE_RED = (230, 30, 30)
#: The checkerboard pictures: the tests' view at 512 px width (the same field of view).
PICTURE_CAMERA = CHECKER_CAMERA.resized(512, 256)
#: A low eye (10 squares above the plane, 10 behind its near edge) looking at the far edge,
#: as in figure 6: squares ~15 px wide at the bottom, shrinking to the moire toward the far edge.
LOW_CAMERA = Camera(eye=(0.0, -186.5, 10.0), target=(0.0, 176.5, 0.0), up=(0.0, 0.0, 1.0), fov=20.25,
                    width=512, height=256, near=1.0, far=1500.0)


def save_png(image: np.ndarray, path: Path) -> Path:
    """Write an (H, W, 3) uint8 image as an optimized PNG."""
    Image.fromarray(image).save(path, optimize=True)
    return path


def grazing_experiment(renderer: Renderer, out: Path) -> list[list]:
    """Figures 3 and 7: holes and leaks of ewa and perspective on the grazing plane; two pictures."""
    with tempfile.TemporaryDirectory() as folder:
        cloud = surfsplat.load(write_grazing_ply(Path(folder) / "grazing_plane.ply"))
    truth = grazing_truth(GRAZING_CAMERA)
    region = int(truth["inner"].sum())
    cam = GRAZING_CAMERA
    rows = []
    for technique in ("ewa", "perspective"):
        result = {pf: grazing_measure(renderer, cloud, technique, pf, truth) for pf in (True, False)}
        picture = result[True]["frame"].image().copy()
        picture[result[True]["hole_mask"]] = HOLE_RED
        print("wrote", save_png(picture, out / f"zwicker_grazing_{technique}.png"))
        view = f"{cam.width}x{cam.height}, {len(cloud)} splats"
        rows.append(["grazing plane (fig. 3, 7)", technique, view, f"hole pixels (of {region:,})",
                     result[True]["holes"], result[False]["holes"], "-"])
        rows.append(["grazing plane (fig. 3, 7)", technique, view, "pixels drawn outside the disks",
                     result[True]["leaks"], result[False]["leaks"], "-"])
    return rows


def checker_errors(renderer: Renderer, gpu, camera: Camera, techniques=("perspective", "ewa")) -> dict:
    """{technique: {prefilter: (errors, frame)}} and the truth against the supersampled texture."""
    truth, full = checker_truth(camera)
    results = {}
    for technique in techniques:
        results[technique] = {}
        for prefilter in (True, False):
            options = RenderOptions(filter=FilterOptions(prefilter=prefilter))
            frame = renderer.render(gpu, camera, technique, UNLIT, options)
            results[technique][prefilter] = (image_errors(frame.color, truth, full), frame)
    return {"truth": truth, "full": full, "results": results}


def checker_rows(label: str, camera: Camera, measured: dict, splats: int, metrics=("rmse",)) -> list[list]:
    """Table rows of one checkerboard view: error with and without the prefilter, and the factor."""
    rows = []
    covered = int(measured["full"].sum())
    for technique, by_prefilter in measured["results"].items():
        for metric in metrics:
            on, off = by_prefilter[True][0][metric], by_prefilter[False][0][metric]
            rows.append([label, technique, f"{camera.width}x{camera.height}, {splats:,} splats",
                         f"{metric.upper()} over {covered:,} covered px", round(on, 4), round(off, 4),
                         f"{off / on:.2f}x"])
    return rows


def checker_experiment(renderer: Renderer, out: Path) -> list[list]:
    """Figure 6: errors with and without the prefilter at three views; five pictures."""
    cloud = checker_cloud()
    gpu = renderer.upload(cloud)
    try:
        test_view = checker_errors(renderer, gpu, CHECKER_CAMERA)
        picture_view = checker_errors(renderer, gpu, PICTURE_CAMERA)
        low_view = checker_errors(renderer, gpu, LOW_CAMERA, techniques=("perspective",))
    finally:
        gpu.release()
    frames = picture_view["results"]["perspective"]
    print("wrote", save_png(frames[True][1].image(), out / "zwicker_checker_prefilter.png"))
    print("wrote", save_png(frames[False][1].image(), out / "zwicker_checker_noprefilter.png"))
    truth = np.round(np.clip(picture_view["truth"], 0.0, 1.0) * 255.0).astype(np.uint8)
    print("wrote", save_png(truth, out / "zwicker_checker_truth.png"))
    frames = low_view["results"]["perspective"]
    print("wrote", save_png(frames[True][1].image(), out / "zwicker_checker_low_prefilter.png"))
    print("wrote", save_png(frames[False][1].image(), out / "zwicker_checker_low_noprefilter.png"))
    rows = checker_rows("checkerboard (fig. 6), test view", CHECKER_CAMERA, test_view, len(cloud), ("rmse", "mae"))
    rows += checker_rows("checkerboard (fig. 6), pictures", PICTURE_CAMERA, picture_view, len(cloud))
    rows += checker_rows("checkerboard, low eye to the far edge", LOW_CAMERA, low_view, len(cloud))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images", help="folder of the PNGs")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    renderer = Renderer()
    rows = grazing_experiment(renderer, args.out) + checker_experiment(renderer, args.out)
    columns = ["experiment", "technique", "image", "measure", "prefilter on", "prefilter off", "off / on"]
    write_table("zwicker_experiments", columns, rows, machine_description(renderer_name(renderer.ctx)))
    print(f"({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
