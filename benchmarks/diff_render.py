"""The differentiable renderer (surfsplat.diff) against the OpenGL ``ewa`` technique, and its speed.

Scenes of 100,000 splats: the sphere of ``surfsplat.scenes.sphere`` (latitude bands) and the Stanford
bunny's surface (``geometry.sampling.surface_splats`` of shared data's bunny.ply, 100,000 samples, no
clip lines: the differentiable renderer does not draw them; coloured by height so that the picture has
detail). Camera: the view plan's automatic framing (``surfsplat.prepare(cloud).camera()``), default
lights. For 256 x 256 and 512 x 512 pixels:

- PSNR of the differentiable forward image (float32, default ``DiffOptions``: edge coverage on, as the
  OpenGL default) against the OpenGL frame (``surfsplat.render(cloud, camera, technique="ewa")``), over
  the whole image, over the silhouette's ring (pixels within 1 px of OpenGL's silhouette, alpha 0.5, on
  either side) and inside OpenGL's silhouette eroded by 2 px; the same with hard rims and hard depth
  tests (``edge_softness = 0``, ``depth_softness = 0``); the whole image and the ring without the
  differentiable renderer's edge coverage (``DiffOptions(edge_coverage=False)``: all-or-nothing rims)
  against the same OpenGL frame; holes: pixels inside OpenGL's silhouette eroded by 1 px that the
  differentiable image leaves below alpha 0.5; rim pixels: pixels covered (alpha >= 0.5) in one image
  and not in the other;
- time of one forward pass without gradients, and of a forward + backward pass with gradients to
  positions, axes, colours, opacity and focal length (median of 3 after a warm-up), with 1 and 2 CPU
  threads (``torch.set_num_threads``); wall-clock, and for the forward + backward pass also the CPU time
  of the process (all its threads: on a machine other jobs share, the wall-clock time grows with their
  load, the CPU time much less).

    python benchmarks/diff_render.py [--images /tmp/diff_render] [--bunny PATH] [--threads 1 2]

Writes benchmarks/results/diff_render.md and .json; PNGs (OpenGL | diff | 10x difference) to ``--images``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import label, machine_description, write_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import metrics, scenes  # noqa: E402
from surfsplat.diff import DiffCamera, DiffOptions, Splats, render_frame  # noqa: E402
from surfsplat.geometry.sampling import surface_splats  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402

#: PyTorch CPU threads the times are taken with (on a machine other processes share, one thread can be the
#: faster: OpenMP's barriers wait for descheduled threads).
THREADS = (1, 2)
DEFAULT_BUNNY = Path(__file__).resolve().parents[2] / "shared" / "data" / "bunny.ply"


def bunny(path: Path, n: int) -> surfsplat.SplatCloud:
    """``n`` surface splats of the bunny, coloured by height (a ramp) so that the image has detail."""
    cloud = surface_splats(load_mesh(path), n, sharp_angle=None, boundaries=False)
    y = np.asarray(cloud.positions[:, 1], np.float64)
    t = (y - y.min()) / max(np.ptp(y), 1e-30)
    cloud.colors = np.stack([0.9 - 0.6 * t, 0.4 + 0.4 * np.sin(12 * t) ** 2, 0.3 + 0.6 * t], 1).astype(np.float32)
    return cloud


def timed(fn, repeats: int = 3) -> tuple[float, float]:
    """Median wall-clock and CPU seconds (this process, all threads) of ``repeats`` calls after a warm-up call."""
    fn()
    times, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return statistics.median(times), statistics.median(cpu)


def run_case(name: str, cloud, size: int, images: Path, threads: tuple[int, ...]) -> list:
    view = surfsplat.prepare(cloud)
    camera = view.camera(None, size, size)
    gl = view.render(camera, technique="ewa").frame
    splats = Splats.from_cloud(cloud)
    cam = DiffCamera.from_camera(gl.camera)
    with torch.no_grad():
        soft = render_frame(splats, cam)
        hard = render_frame(splats, cam, options=DiffOptions(edge_softness=0.0, depth_softness=0.0))
        papers = render_frame(splats, cam, options=DiffOptions(edge_coverage=False)).color.numpy()
    image = soft.color.numpy()
    covered = gl.alpha > 0.5
    inner = metrics.erode(covered, 2)
    ring = metrics.dilate(covered, 1) & ~metrics.erode(covered, 1)
    holes = int((metrics.erode(covered, 1) & (soft.alpha.numpy() < 0.5)).sum())
    rim = int((covered & (soft.alpha.numpy() < 0.5)).sum() + (~covered & (soft.alpha.numpy() >= 0.5)).sum())
    strip = np.concatenate([gl.color, image, np.clip(np.abs(gl.color - image) * 10, 0, 1)], axis=1)
    picture = label((strip * 255).round().astype(np.uint8), f"{name} {size}: OpenGL | diff | 10x difference")
    Image.fromarray(picture).save(images / f"{name}_{size}.png")

    def forward():
        with torch.no_grad():
            render_frame(splats, cam)

    params = Splats(*(t.clone().requires_grad_(True) for t in (splats.positions, splats.u, splats.v, splats.colors)),
                    opacity=torch.ones(len(splats), requires_grad=True), normals=splats.normals)
    grad_cam = DiffCamera(cam.rotation, cam.translation, cam.focal.clone().requires_grad_(True), cam.width,
                          cam.height, cam.near, cam.far)

    def forward_backward():
        render_frame(params, grad_cam).color.sum().backward()

    times = []
    for count in threads:
        torch.set_num_threads(count)
        (f_wall, _), (fb_wall, fb_cpu) = timed(forward), timed(forward_backward)
        times += [round(f_wall, 3), round(fb_wall, 3), round(fb_cpu, 3)]
    return [name, f"{size}x{size}", len(cloud), round(metrics.psnr(image, gl.color), 2),
            round(metrics.psnr(image, gl.color, mask=ring), 2), round(metrics.psnr(image, gl.color, mask=inner), 2),
            round(metrics.psnr(hard.color.numpy(), gl.color), 2), round(metrics.psnr(papers, gl.color), 2),
            round(metrics.psnr(papers, gl.color, mask=ring), 2), holes, rim, *times]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=Path, default=Path("/tmp/diff_render"))
    parser.add_argument("--bunny", type=Path, default=DEFAULT_BUNNY)
    parser.add_argument("--splats", type=int, default=100_000)
    parser.add_argument("--threads", type=int, nargs="+", default=list(THREADS),
                        help="PyTorch CPU thread counts to time with (default 1 2)")
    args = parser.parse_args()
    threads = tuple(args.threads)
    args.images.mkdir(parents=True, exist_ok=True)
    cases = [("sphere", scenes.sphere(args.splats, color="bands"))]
    if args.bunny.exists():
        cases.append(("bunny", bunny(args.bunny, args.splats)))
    rows = [run_case(name, cloud, size, args.images, threads) for name, cloud in cases for size in (256, 512)]
    columns = ["scene", "pixels", "splats", "PSNR dB", "PSNR ring dB", "PSNR inside dB", "PSNR hard dB",
               "PSNR no edge coverage dB", "PSNR ring no edge coverage dB", "holes", "rim pixels"]
    for count in threads:
        columns += [f"forward s ({count} thr.)", f"forward+backward s ({count} thr.)",
                    f"forward+backward CPU s ({count} thr.)"]
    machine = machine_description() + f", torch {torch.__version__}"
    write_table("diff_render", columns, rows, machine)
    print("command: python benchmarks/diff_render.py " + " ".join(sys.argv[1:]))


if __name__ == "__main__":
    main()
