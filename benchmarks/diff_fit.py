"""Fitting splats to mesh views (surfsplat.diff.fit): the bunny and a CAD part from a few thousand noisy points.

Ground truth: shared data's bunny.ply and featuretype.ply (a machined block with sharp edges, a step, a hole
and a chamfer) with vertex colours (a smooth procedural pattern: the files have none, and unlit views of a
uniform surface would show silhouettes only), rendered by ``surfsplat.render_mesh`` unlit and transparent
(what ``surfsplat render --mesh --no-lighting --transparent`` writes) from ``--views`` cameras on a
Fibonacci sphere around the model (training) and 8 others between them (held out), at ``--size`` pixels.
Initial cloud: ``--points`` points sampled uniformly on the surface, moved by Gaussian noise of ``--noise``
times the bounding-box diagonal, made into splats by the view plan (grey). Fit: ``surfsplat.diff.fit.fit``
with ``--iterations`` steps and its default options, once per seed of ``--seeds`` (view order, background
colours, split directions).

Measured: held-out PSNR of the fitted splats (differentiable renderer, default options, unlit, over white)
against the mesh views; the centres' distance to the mesh (mean, as a fraction of the bounding-box
diagonal; distance to the nearest of 2,000,000 surface samples) and the angle between each splat's normal
and the surface's normal there (median, degrees, unsigned); wall-clock and CPU time of the fit
(the machine's load average after the fits is in the table's header).

    python benchmarks/diff_fit.py [--models bunny featuretype] [--views 32] [--size 256] [--points 5000]
                                  [--iterations 600] [--seeds 0 1] [--threads 1]
                                  [--jobs 1]

Writes benchmarks/results/diff_fit.md and .json, and docs/images/diff_fit_MODEL.png (two held-out views:
mesh | fitted splats).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import label, machine_description, write_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import metrics  # noqa: E402
from surfsplat.cloud import SplatCloud  # noqa: E402
from surfsplat.camera import Camera  # noqa: E402
from surfsplat.diff import DiffCamera, DiffOptions, Splats, render  # noqa: E402
from surfsplat.diff.fit import FitOptions, FitView, fit, initial_cloud  # noqa: E402
from surfsplat.geometry.sampling import sample_mesh  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data"
MODELS = {"bunny": DATA / "bunny.ply", "featuretype": DATA / "featuretype.ply"}
UNLIT = Lights(enabled=False)


def fibonacci(n: int, offset: float = 0.5) -> np.ndarray:
    i = np.arange(n) + offset
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=1)


def cameras(center: np.ndarray, diagonal: float, directions: np.ndarray, size: int) -> list[Camera]:
    distance = 0.45 * diagonal / np.tan(np.radians(20.0))
    return [Camera(eye=tuple(center + distance * d), target=tuple(center), up=(0.0, 1.0, 0.0) if abs(d[1]) < 0.99
                   else (0.0, 0.0, 1.0), fov=40.0, width=size, height=size) for d in directions]


def colored_mesh(path: Path):
    """The mesh of ``path`` with a smooth procedural vertex colouring; its bounding-box centre and diagonal."""
    mesh = load_mesh(path)
    v = np.asarray(mesh.vertices, np.float64)
    lo, hi = v.min(0), v.max(0)
    t = (v - lo) / (hi - lo)
    mesh.vertex_colors = np.stack([0.55 + 0.4 * np.sin(9 * t[:, 0] + 3 * t[:, 1]),
                                   0.5 + 0.4 * np.sin(7 * t[:, 1] - 2 * t[:, 2]),
                                   0.5 + 0.4 * np.cos(8 * t[:, 2] + 4 * t[:, 0])], 1).astype(np.float32)
    return mesh, (lo + hi) / 2, float(np.linalg.norm(hi - lo))


@dataclass
class Model:
    """One model's training and held-out views, initial splats and ground-truth samples."""

    name: str
    diagonal: float
    train: list
    test: list
    init: SplatCloud
    tree: cKDTree
    normals: np.ndarray


def prepare(name: str, path: Path, args) -> Model:
    """A model's mesh views (training, held out), its noisy initial splats and dense surface samples."""
    mesh, center, diagonal = colored_mesh(path)

    def views(cams):
        out = []
        for camera in cams:
            frame = surfsplat.render_mesh(mesh, camera, lights=UNLIT)
            rgba = frame.rgba().astype(np.float64)
            out.append(FitView(frame.camera, rgba[..., :3], rgba[..., 3]))
        return out

    train = views(cameras(center, diagonal, fibonacci(args.views), args.size))
    test = views(cameras(center, diagonal, fibonacci(8, 0.25) @ np.diag([1.0, 0.9, -1.0]), args.size))
    rng = np.random.default_rng(0)
    samples = sample_mesh(mesh, args.points, seed=1)
    points = np.asarray(samples.positions, np.float64) + np.asarray(samples.origin, np.float64)
    points += rng.normal(size=points.shape) * args.noise * diagonal
    dense = sample_mesh(mesh, 2_000_000, seed=2)
    tree = cKDTree(np.asarray(dense.positions, np.float64) + np.asarray(dense.origin, np.float64))
    return Model(name, diagonal, train, test, initial_cloud(points), tree, np.asarray(dense.normals, np.float64))


def geometry(model: Model, cloud) -> tuple[float, float]:
    """Mean centre distance to the surface / diagonal and median unsigned normal error (degrees)."""
    p = np.asarray(cloud.positions, np.float64) + np.asarray(cloud.origin, np.float64)
    distance, index = model.tree.query(p)
    n = np.asarray(cloud.normals, np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cos = np.abs(np.sum(n * model.normals[index], axis=1))
    return float(distance.mean() / model.diagonal), float(np.degrees(np.median(np.arccos(np.clip(cos, 0, 1)))))


#: The renderer with the papers' rims (no edge coverage): ``surfsplat render --no-edge-coverage``.
PAPERS_RIMS = DiffOptions(edge_coverage=False)


def held_out(model: Model, cloud, options: DiffOptions | None = None) -> tuple[float, list]:
    """Mean PSNR (dB) of the held-out views over white, and each view's mesh | splats picture (``options``:
    the renderer's, None: its defaults, which match ``surfsplat render``'s ``ewa``)."""
    splats = Splats.from_cloud(cloud)
    if cloud.attributes and "opacity" in cloud.attributes:
        splats.opacity = torch.as_tensor(cloud.attributes["opacity"])
    values, pictures = [], []
    for view in model.test:
        with torch.no_grad():
            image = render(splats, DiffCamera.from_camera(view.camera), lights=UNLIT, options=options).numpy()
        target = view.image * view.alpha[..., None] + (1.0 - view.alpha[..., None])
        values.append(metrics.psnr(image, target))
        pictures.append(np.concatenate([target, image], axis=1))
    return float(np.mean(values)), pictures


#: The rims a fit trains with (``--training-rims``), before and while sharpening: edge coverage (the renderer's
#: default) or the papers' (soft, all-or-nothing coverage).
TRAINING_RIMS = {"coverage": (True, True), "papers": (False, False), "switch": (False, True)}


def fit_job(name: str, train: list, init: SplatCloud, iterations: int, seed: int, threads: int, rims: str):
    """One fit (in a worker process): the fitted splats, wall-clock and CPU seconds, the load after it."""
    torch.set_num_threads(threads)
    start, cpu = time.perf_counter(), time.process_time()

    def log(step: int, loss: float, splats: int) -> None:
        if step % 100 == 0 or step == iterations - 1:
            print(f"{name} seed {seed} step {step}: loss {loss:.4f}, {splats:,} splats, "
                  f"{time.perf_counter() - start:.0f} s", flush=True)

    first, last = TRAINING_RIMS[rims]
    options = FitOptions(iterations=iterations, max_splats=200_000, seed=seed,
                         render=DiffOptions(edge_softness=0.5, depth_softness=0.3, edge_coverage=first),
                         sharpen_to=DiffOptions(edge_coverage=last))
    result = fit(train, init, options=options, on_step=log)
    return result.cloud, time.perf_counter() - start, time.process_time() - cpu, os.getloadavg()[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--views", type=int, default=32)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--points", type=int, default=5000)
    parser.add_argument("--noise", type=float, default=0.002)
    parser.add_argument("--iterations", type=int, default=600)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="the fit's seeds (one run each)")
    parser.add_argument("--threads", type=int, default=1, help="PyTorch threads per fit")
    parser.add_argument("--jobs", type=int, default=1, help="fits run at once (worker processes)")
    parser.add_argument("--pictures", type=Path, default=ROOT / "docs" / "images")
    parser.add_argument("--training-rims", nargs="+", default=["switch"], choices=list(TRAINING_RIMS),
                        help="the rims the fits train with: the papers' then edge coverage while sharpening "
                             "(switch: FitOptions' default), edge coverage throughout, or the papers' throughout")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    models = [prepare(name, MODELS[name], args) for name in args.models]
    jobs = [(m, seed, rims) for m in models for rims in args.training_rims for seed in args.seeds]
    # fits in worker processes (spawned: no OpenGL or thread pool inherited), --jobs at a time
    with ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(fit_job, m.name, m.train, m.init, args.iterations, seed, args.threads, rims)
                   for m, seed, rims in jobs]
        fitted = [f.result() for f in futures]
    rows, loads = [], []
    for m in models:
        psnr0, _ = held_out(m, m.init)
        papers0, _ = held_out(m, m.init, PAPERS_RIMS)
        d0, a0 = geometry(m, m.init)
        rows.append([m.name, "initial (noisy points)", len(m.init), round(psnr0, 2), round(papers0, 2),
                     round(100 * d0, 3), round(a0, 2), 0.0, 0.0])
        picture = None
        for (model, seed, rims), (cloud, seconds, cpu, load) in zip(jobs, fitted):
            if model is not m:
                continue
            psnr1, pictures = held_out(m, cloud)
            papers1, _ = held_out(m, cloud, PAPERS_RIMS)
            d1, a1 = geometry(m, cloud)
            loads.append(load)
            rows.append([m.name, f"fitted ({args.iterations} steps, {args.views} views {args.size}x{args.size}, "
                         f"{rims} rims, seed {seed})", len(cloud), round(psnr1, 2), round(papers1, 2),
                         round(100 * d1, 3), round(a1, 2), round(seconds, 1), round(cpu, 1)])
            print(rows[-1], flush=True)
            if picture is None:
                strip = np.concatenate(pictures[:2], axis=0)
                picture = label((np.clip(strip, 0, 1) * 255).round().astype(np.uint8),
                                f"{m.name}: mesh | fitted splats")
        args.pictures.mkdir(parents=True, exist_ok=True)
        assert picture is not None
        Image.fromarray(picture).save(args.pictures / f"diff_fit_{m.name}.png", optimize=True)
    columns = ["model", "stage", "splats", "held-out PSNR dB (edge coverage)", "held-out PSNR dB (papers' rims)",
               "centre distance / diagonal %",
               "normal error median deg", "wall s", "CPU s"]
    machine = (machine_description() + f", torch {torch.__version__}, {args.threads} thread(s) per fit, {args.jobs} "
               f"fit(s) at once, load average after the fits {min(loads):.1f} to {max(loads):.1f}")
    write_table("diff_fit", columns, rows, machine)
    print("command: python benchmarks/diff_fit.py " + " ".join(sys.argv[1:]))


if __name__ == "__main__":
    main()
