"""Level of detail on the GPU (sequential point trees) against the CPU cut, along a camera path.

Usage: python benchmarks/bench_gpu_lod.py [--splats 1000000] [--frames 20] [--sizes 1024x1024 1280x720]
                                          [--technique ewa] [--tolerance 1] [--psnr-every 5]

The Stanford bunny (../shared/data) sampled to ``--splats`` splats (bench_render.bunny) and its
hierarchy; a path of ``--frames`` cameras orbiting 90 degrees while the eye moves from 0.7x to 2.5x
the automatic camera's distance. Per frame, as the viewer draws (``Renderer.draw`` into the
renderer's targets and a glFinish, no read-back):

- CPU cut: ``surfsplat.pipeline.lod_splats`` (select and gather) and ``Renderer.upload`` of the cut (both Python /
  NumPy work per frame), then the draw;
- GPU cut: the layout uploaded once (``render/sequential.py``); per frame the prefix search (Python,
  timed alone) and the draw, the vertex shader keeping the cut.

Frame = cut + upload + draw. PSNR: the two cuts rendered (``Renderer.render``) every ``--psnr-every``
frames, GPU against CPU, whole image. Saved as results/gpu_lod.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_render import bunny  # noqa: E402
from common import machine_description, write_table  # noqa: E402

from surfsplat.camera import Camera  # noqa: E402
from surfsplat.camera_path import orbit_cameras  # noqa: E402
from surfsplat.hierarchy.sequential import drawn_mask, sequential_layout  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402
from surfsplat.metrics import psnr  # noqa: E402
from surfsplat.pipeline import as_model, auto_camera, lod_splats  # noqa: E402
from surfsplat.rendering.context import headless_context, renderer_name  # noqa: E402
from surfsplat.rendering.options import RenderOptions  # noqa: E402
from surfsplat.rendering.renderer import _with_clip_planes, default_renderer, point_radius  # noqa: E402
from surfsplat.rendering.sequential import upload_sequential  # noqa: E402
from surfsplat.rendering.techniques import get_technique  # noqa: E402


def camera_path(cloud, width: int, height: int, frames: int) -> list:
    """``frames`` cameras: a 90 degree orbit while the distance goes from 0.7x to 2.5x the automatic one."""
    start = auto_camera(cloud, width, height)
    target = np.asarray(start.target)
    offset = np.asarray(start.eye) - target
    cams = orbit_cameras(start, frames, 90.0)
    out = []
    for i, cam in enumerate(cams):
        factor = 0.7 * (2.5 / 0.7) ** (i / max(frames - 1, 1))
        eye = target + factor * (np.asarray(cam.eye) - target) * np.linalg.norm(offset) / np.linalg.norm(
            np.asarray(cam.eye) - target)
        out.append(Camera(eye=tuple(eye), target=cam.target, up=cam.up, fov=cam.fov, width=width, height=height))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--sizes", nargs="+", default=["1024x1024", "1280x720"])
    parser.add_argument("--technique", default="ewa")
    parser.add_argument("--tolerance", type=float, default=1.0)
    parser.add_argument("--psnr-every", type=int, default=5)
    parser.add_argument("--name", default="gpu_lod")
    args = parser.parse_args()

    cloud = bunny(args.splats)
    start = time.perf_counter()
    tree = as_model(cloud).tree().data
    build_s = time.perf_counter() - start
    renderer = default_renderer()
    ctx = renderer.ctx
    start = time.perf_counter()
    layout = sequential_layout(tree)
    layout_s = time.perf_counter() - start
    start = time.perf_counter()
    gpu = upload_sequential(renderer, layout.splats, layout.lod, args.tolerance)
    upload_s = time.perf_counter() - start
    print(f"hierarchy {build_s:.2f} s, layout {layout_s:.2f} s ({len(layout):,} entries), upload {upload_s:.2f} s",
          flush=True)
    technique = get_technique(args.technique)
    lights, options = Lights(), RenderOptions()
    rows = []
    for size in args.sizes:
        width, height = (int(x) for x in size.split("x"))
        cams = camera_path(cloud, width, height, args.frames)
        cpu = {"frame": [], "python": [], "splats": []}
        gpu_t = {"frame": [], "python": [], "splats": [], "drawn": []}
        scores = []
        for i, cam in enumerate(cams):
            t0 = time.perf_counter()
            cut, _ = lod_splats(tree, cam, args.tolerance)
            splats = renderer.upload(cut)
            t1 = time.perf_counter()
            renderer.draw(splats, cam, technique, lights, options)
            ctx.finish()
            t2 = time.perf_counter()
            splats.release()
            cpu["frame"].append(t2 - t0)
            cpu["python"].append(t1 - t0)
            cpu["splats"].append(len(cut))

            t0 = time.perf_counter()
            renderer.draw(gpu, cam, technique, lights, options)
            ctx.finish()
            t1 = time.perf_counter()
            local = gpu.gpu_camera(_with_clip_planes(cam, gpu))
            t2 = time.perf_counter()
            gpu.draw_ranges(local, point_radius(local, gpu, technique, options, 1, renderer.point_px))
            t3 = time.perf_counter()
            gpu_t["frame"].append(t1 - t0)
            gpu_t["python"].append(t3 - t2)
            gpu_t["splats"].append(gpu.last_prefix)
            distance = np.linalg.norm(layout.splats.positions - np.asarray(cam.eye) + layout.splats.origin, axis=1)
            gpu_t["drawn"].append(int(drawn_mask(layout.lod, distance, local.focal_px / args.tolerance,
                                                 local.near / gpu.scale).sum()))
            if args.psnr_every and i % args.psnr_every == 0:
                a = renderer.render(gpu, cam, technique, lights, options).color
                b = renderer.render(cut, cam, technique, lights, options).color
                scores.append(psnr(a, b))
            print(size, i, f"cpu {1e3 * cpu['frame'][-1]:.0f} ms ({len(cut):,}), gpu {1e3 * gpu_t['frame'][-1]:.0f} ms "
                  f"({gpu.last_prefix:,} given, {gpu_t['drawn'][-1]:,} drawn)", flush=True)
        for mode, t in (("CPU cut (select, gather, upload)", cpu), ("GPU cut (sequential layout)", gpu_t)):
            rows.append([size, mode, round(1e3 * float(np.median(t["frame"]))), round(1e3 * float(np.mean(t["frame"]))),
                         round(1e3 * float(np.median(t["python"])), 2), round(float(np.mean(t["splats"]))),
                         round(float(np.mean(t["drawn"]))) if "drawn" in t else round(float(np.mean(t["splats"]))),
                         round(min(scores), 1) if mode.startswith("GPU") and scores else ""])
            print(rows[-1], flush=True)
    columns = ["resolution", "LOD", "frame ms (median)", "frame ms (mean)", "Python ms per frame (median)",
               "splats given to the GPU (mean)", "splats drawn (mean)", "PSNR GPU vs CPU cut, dB (min)"]
    write_table(args.name, columns, rows, machine_description(renderer_name(headless_context()))
                + f"; llvmpipe, 2-core EPYC; bunny {len(cloud):,} splats, {len(tree):,} nodes; technique "
                  f"{args.technique}, tolerance {args.tolerance:g} px; {args.frames} frames (orbit 90 deg, "
                  f"distance 0.7x -> 2.5x); frame = cut + upload + Renderer.draw + glFinish (no read-back); "
                  f"one-time: hierarchy {build_s:.1f} s, layout {layout_s:.2f} s, GPU upload {upload_s:.2f} s")


if __name__ == "__main__":
    main()
