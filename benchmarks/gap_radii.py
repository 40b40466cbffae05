"""Splats grown to their Voronoi cells (``preprocess(coverage=None)``) against a global factor.

Three parts, each a table in ``results/gap_radii.md``:

* ``plane``: uniformly random (Poisson) points on a plane, k = 8, the bare Pajarola ellipses
  times 1.5 (the old default), times 1.0, and times 1.0 then grown by
  :func:`surfsplat.geometry.splats.cover_cells` (the new default). Holes: the share of a grid of
  query points (2 per mean spacing in each direction, 3 spacings in from the border) that no
  ellipse of its 24 nearest splats contains (each splat's own metric; ``cells`` also checked
  against the nearest splat alone: the Voronoi-cell property itself); overlap: the mean number
  of ellipses over 200,000 random interior points (64 nearest splats); area: the sum of
  ``pi |u| |v|`` relative to the 1.5 ellipses'; time: ``cover_cells`` alone (wall and CPU).
* ``border``: open squares (``scenes_faulty.stray_points()``: 20k random points and 1% strays; and
  100k random points without strays) preprocessed with ``coverage=1.5`` and the default, drawn
  ``flat`` top-down at 800 x 800 (far eye, narrow field of view): spill, the pixels drawn outside
  the true square, with how far out they reach (farthest and 99th percentile, px from the edge),
  and holes, background pixels inside the square eroded by 2 px.
* ``peers``: the peers' 1 M-point bunny and torus (``/tmp/peers-data``, normals and colours
  given), preprocessed with ``coverage=1.5`` (the old default) and the new default; preprocess
  time, then ``ewa`` and ``flat`` at 1024 x 1024 against the mesh ground truth (PSNR inside the
  mask; holes: mask pixels left black, and those more than 2 px inside the mask, i.e. not at the
  silhouette) and the median frame time (wall, and CPU ``time.process_time``) of 5 frames, the
  two versions' frames alternating. Pictures are saved under ``/tmp/gap_radii/``.

    python benchmarks/gap_radii.py [--part plane|border|peers|all] [--points 1000000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image
from scipy.ndimage import binary_erosion, distance_transform_edt
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, markdown_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import scenes_faulty  # noqa: E402
from surfsplat.camera import Camera  # noqa: E402
from surfsplat.geometry import knn, preprocess  # noqa: E402
from surfsplat.geometry.splats import GAP_BASE, cover_cells, elliptical_splats  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402
from surfsplat.pipeline import View, local_camera  # noqa: E402
from surfsplat.rendering.options import RenderOptions, VisibilityOptions  # noqa: E402
from surfsplat.rendering.renderer import Renderer  # noqa: E402

PEERS = Path("/tmp/peers-data")
PICTURES = Path("/tmp/gap_radii")
CAMERAS = {  # the peers' views (/work/notes/cuts.py)
    "bunny": dict(eye=(0.08, 0.16, 0.30), target=(-0.017, 0.11, 0.0), up=(0, 1, 0), fov=36, light=(0.5, 1.0, 0.8)),
    "torus": dict(eye=(0.0, -3.2, 2.4), target=(0.0, 0.0, 0.0), up=(0, 0, 1), fov=42, light=(0.3, -0.5, 1.0)),
}


def metric_to(queries: np.ndarray, centers: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(Q, C) squared ellipse metric of 2D ``queries`` (Q, 2) from the splats ``centers`` (Q, C, 2)
    with axes ``u``, ``v`` (Q, C, 2): <= 1 inside."""
    rel = queries[:, None, :] - centers
    s = np.einsum("qkc,qkc->qk", rel, u) / np.einsum("qkc,qkc->qk", u, u)
    t = np.einsum("qkc,qkc->qk", rel, v) / np.einsum("qkc,qkc->qk", v, v)
    return s * s + t * t


def coverage_counts(tree, p, u, v, queries, candidates, chunk=100_000):
    """(Q,) number of ellipses among the ``candidates`` nearest containing each query, and (Q,)
    bool: the nearest splat's own ellipse contains it."""
    count = np.empty(len(queries), dtype=np.int32)
    own = np.empty(len(queries), dtype=bool)
    for s in range(0, len(queries), chunk):
        q = queries[s:s + chunk]
        _, near = tree.query(q, candidates, workers=-1)
        m = metric_to(q, p[near, :2], u[near, :2], v[near, :2])
        count[s:s + chunk] = (m <= 1.0).sum(axis=1)
        own[s:s + chunk] = m[:, 0] <= 1.0
    return count, own


def plane(n: int, seed: int = 1) -> list[list]:
    """Rows of the plane table (see the module docstring)."""
    rng = np.random.default_rng(seed)
    side = float(np.sqrt(n))  # mean spacing 1
    p = np.zeros((n, 3), dtype=np.float32)
    p[:, :2] = rng.random((n, 2)) * side
    normals = np.tile(np.float32([0, 0, 1]), (n, 1))
    dist, idx, knn_tree = knn(p, 8, return_tree=True)
    variants = {"coverage 1.5 (old default)": elliptical_splats(p, normals, idx, dist, coverage=1.5),
                "coverage 1.0": elliptical_splats(p, normals, idx, dist, coverage=1.0)}
    u, v = elliptical_splats(p, normals, idx, dist, coverage=GAP_BASE)
    wall, cpu = time.perf_counter(), time.process_time()
    ug, vg, factors = cover_cells(p, idx, u, v, tree=knn_tree)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    variants[f"cells: {GAP_BASE} + cover_cells (new default)"] = (ug, vg)
    tree = cKDTree(p[:, :2])
    g = np.arange(3.0, side - 3.0, 0.5)
    gx, gy = np.meshgrid(g, g)
    grid = np.stack([gx.ravel(), gy.ravel()], axis=1)
    sample = rng.random((200_000, 2)) * (side - 6.0) + 3.0
    area0 = None
    rows = []
    for name, (uu, vv) in variants.items():
        area = float((np.linalg.norm(uu, axis=1) * np.linalg.norm(vv, axis=1)).sum())
        area0 = area if area0 is None else area0
        count, own = coverage_counts(tree, p, uu, vv, grid, 24)
        overlap, _ = coverage_counts(tree, p, uu, vv, sample, 64)
        grown = int((factors[:, 1] > 1).sum()) if name.startswith("cells") else 0
        rows.append([name, n, len(grid), int((count == 0).sum()), float((count == 0).mean()),
                     int((~own).sum()), float(overlap.mean()), area / area0, grown,
                     f"{wall:.2f} / {cpu:.2f}" if grown else ""])
        print(rows[-1], flush=True)
    return rows


def psnr_holes(png: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> tuple[float, float, int]:
    """PSNR (dB) inside the mask, the share of mask pixels left black (holes) and the number of
    those more than 2 px inside the mask (not silhouette pixels)."""
    se = ((gt.astype(np.float64) - png) ** 2)[mask].mean()
    black = np.all(png == 0, axis=2)
    holes = (black & mask).sum() / mask.sum()
    inner = int((black & binary_erosion(mask, iterations=2)).sum())
    return float(10 * np.log10(255 ** 2 / se)), float(holes), inner


def peers(frames: int = 5) -> list[list]:
    """Rows of the peers table (see the module docstring). The two versions' frames alternate
    (``frames`` timed each, after one untimed), so drifting load on the machine hits both alike."""
    PICTURES.mkdir(exist_ok=True)
    renderer = Renderer()
    rows = []
    versions = (("coverage 1.5 (old default)", 1.5, "old"), ("cells (new default)", None, "cells"))
    for scene, view in CAMERAS.items():
        source = surfsplat.load(PEERS / f"{scene}_1000000.ply")
        gt = np.asarray(Image.open(PEERS / f"gt_{scene}_1024x1024.png").convert("RGB"))
        mask = np.asarray(Image.open(PEERS / f"gt_{scene}_1024x1024_mask.png").convert("L")) > 127
        light = np.asarray(view["light"], float) / np.linalg.norm(view["light"])
        lights = Lights(directions=[tuple(light)], ambient=0.2, diffuse=0.8, specular=0.3, shininess=32)
        drawn = {}
        for _name, coverage, tag in versions:
            wall, cpu = time.perf_counter(), time.process_time()
            cloud = preprocess(source, coverage=coverage)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            area = float((cloud.radii * np.linalg.norm(cloud.v, axis=1)).sum())  # |u| |v|, u the major axis
            lo, hi = cloud.bounds()
            camera = Camera(eye=view["eye"], target=view["target"], up=view["up"], fov=view["fov"],
                            width=1024, height=1024)
            camera = camera.with_clip_from_bounds(lo, hi, margin=float(cloud.radii.max()))
            plan = View(cloud)   # back faces culled where a closed cloud is seen from outside, normals outward
            cull = plan.culls(camera)
            model = plan.sample(camera).data
            options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=cull))
            drawn[tag] = (renderer.upload(model), local_camera(model, camera), options, f"{wall:.2f} / {cpu:.2f}",
                          area)
        for technique in ("ewa", "flat"):
            images, times = {}, {tag: [] for tag in drawn}
            for rep in range(frames + 1):
                for tag, (gpu, local, options, _, _) in drawn.items():
                    t, c = time.perf_counter(), time.process_time()
                    frame = renderer.render(gpu, local, technique, lights, options, background=(0, 0, 0))
                    if rep:
                        times[tag].append((time.perf_counter() - t, time.process_time() - c))
                    images[tag] = frame
            for name, _, tag in versions:
                png = np.round(np.clip(images[tag].color, 0, 1) * 255).astype(np.uint8)
                Image.fromarray(png).save(PICTURES / f"{scene}_{tag}_{technique}.png")
                psnr, holes, inner = psnr_holes(png, gt, mask)
                wall_ms, cpu_ms = (1000 * float(np.median([x[i] for x in times[tag]])) for i in (0, 1))
                rows.append([scene, name, technique, drawn[tag][3], drawn[tag][4] / drawn["old"][4], wall_ms,
                             cpu_ms, psnr, holes, inner])
                print(rows[-1], flush=True)
        for gpu, *_ in drawn.values():
            gpu.release()
    return rows


def border_view(side: float, size: int) -> tuple[Camera, np.ndarray]:
    """A top-down camera on the square [0, side]^2 at z = 0 (far eye, narrow field of view: the plane
    is parallel to the image, so it maps linearly) and the (size, size) bool mask of the pixels
    whose centres lie on the square."""
    half = 0.6 * side  # the square fills 1 / 1.2 of the frame
    distance = 50.0 * side
    fov = float(np.degrees(2.0 * np.arctan(half / distance)))
    camera = Camera(eye=(side / 2, side / 2, distance), target=(side / 2, side / 2, 0.0), up=(0, 1, 0), fov=fov,
                    width=size, height=size)
    centre = (np.arange(size) + 0.5 - size / 2) / (size / 2) * half + side / 2  # pixel centres, model units
    inside = (centre >= 0) & (centre <= side)
    return camera, inside[:, None] & inside[None, :]


def border(size: int = 800) -> list[list]:
    """Rows of the border table: spill (pixels drawn outside the true square) and holes (background
    pixels inside the square eroded by 2 px) of ``flat`` top-down renders of open squares, the old
    factor 1.5 against the default. Pictures are saved under ``/tmp/gap_radii/``."""
    PICTURES.mkdir(exist_ok=True)
    scenes = {"stray_points (20k + 1% strays)": scenes_faulty.stray_points(),
              "random square (100k)": scenes_faulty.stray_points(100_000, fraction=0.0)}
    rows = []
    for scene, faulty in scenes.items():
        camera, square = border_view(faulty.side, size)
        inner = binary_erosion(square, iterations=2)
        for name, coverage, tag in (("coverage 1.5 (old default)", 1.5, "old"), ("cells (default)", None, "cells")):
            cloud = preprocess(faulty.cloud, coverage=coverage)
            frame = surfsplat.render(cloud, camera, technique="flat", width=size, height=size, background=(0, 0, 0))
            drawn = np.any(frame.color > 0, axis=2)
            png = np.round(np.clip(frame.color, 0, 1) * 255).astype(np.uint8)
            Image.fromarray(png).save(PICTURES / f"border_{scene.split()[0]}_{tag}_{size}.png")
            spill = drawn & ~square
            reach = distance_transform_edt(~square)[spill]  # px from the square's edge
            rows.append([scene, name, f"{size} x {size}", faulty.spacing * size / (1.2 * faulty.side),
                         int(spill.sum()), float(reach.max(initial=0)), float(np.percentile(reach, 99)),
                         int((~drawn & inner).sum())])
            print(rows[-1], flush=True)
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("plane", "border", "peers", "all"), default="all")
    parser.add_argument("--points", type=int, default=1_000_000, help="points of the plane (default 1 M)")
    args = parser.parse_args(argv)
    machine = machine_description("llvmpipe")
    out = RESULTS / "gap_radii.md"
    sections = {}
    if out.exists():  # keep the other part's table when running one part
        for chunk in out.read_text().split("\n## ")[1:]:
            sections[chunk.split("\n", 1)[0]] = "## " + chunk.rstrip("\n")
    if args.part in ("plane", "all"):
        rows = plane(args.points)
        sections["Uniformly random points on a plane"] = "\n".join(
            ["## Uniformly random points on a plane", ""] + markdown_table(
                ["ellipses", "points", "grid points", "holes", "holes share", "outside own ellipse",
                 "mean overlap", "area / 1.5", "grown", "cover_cells s (wall / CPU)"], rows))
    if args.part in ("border", "all"):
        rows = border()
        sections["Open borders, top-down flat"] = "\n".join(
            ["## Open borders, top-down flat", ""] + markdown_table(
                ["scene", "splats", "pixels", "mean spacing (px)", "spill (px outside the square)",
                 "farthest spill (px)", "99th percentile spill (px)", "holes (px, square eroded 2 px)"], rows))
    if args.part in ("peers", "all"):
        rows = peers()
        sections["Peers' 1 M-point bunny and torus, 1024 x 1024"] = "\n".join(
            ["## Peers' 1 M-point bunny and torus, 1024 x 1024", ""] + markdown_table(
                ["scene", "splats", "technique", "preprocess s (wall / CPU)", "area / old", "frame ms (wall)",
                 "frame ms (CPU)", "PSNR in mask (dB)", "holes (share of mask)", "holes > 2 px inside"], rows))
    note = ("Command: `python benchmarks/gap_radii.py` (see its docstring for the columns). The machine is shared: "
            "absolute times vary by up to 2x between runs; the old and new frames alternate, so their ratio holds.")
    text = "\n".join([f"Machine: {machine} (2-core EPYC, llvmpipe)", f"Date: {time.strftime('%Y-%m-%d')}", "", note, ""]
                     + [sections[k] + "\n" for k in sections])
    RESULTS.mkdir(exist_ok=True)
    out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
