"""Kernel sizes by measurement, with the screen-space hole filling on: coverage factor, Voronoi growth,
EWA cutoff and prefilter against frame time, overlap, PSNR (whole, contour, smooth) and holes.

Models, each at ``--size`` (512) with the automatic camera and the default headlight, against the mesh
4 x 4 supersampled (``render_mesh``; the contour and smooth masks of benchmarks/contour_quality.py):

- mesh samples (what a mesh file renders as: ``View.sample``, circular splats of radius 1.25 times the
  ``k``-th neighbour's distance): the bunny, the CAD part, the detailed generated surface, with the
  radius factor changed (the splats' axes scaled, clip lines kept in place);
- point clouds preprocessed (``surfsplat.preprocess``: Pajarola ellipses of 8 neighbours, grown to their
  Voronoi cells by default, or a fixed factor without growth): the bunny's vertices (truth: its mesh) and
  a faulty scan (``scenes_faulty.faulty_scan``: scan lines, strays, a tree, duplicates; truth: its square,
  so only its holes count);
- the EWA kernel on the bunny's mesh samples: cutoff c and the prefilter.

Columns: ``frame ms``: best of ``--repeat`` frames (drawing and read-back; the machine is shared, compare
rows of one model); ``overlap``: the splats' summed screen area over the covered pixels (the splats a
covered pixel lies under: what the accumulation pass pays for); ``psnr`` / ``contour`` / ``smooth`` (dB);
``holes``: pixels inside the truth's silhouette (eroded 2 px) that the splats leave uncovered; ``fill``:
pixels the hole filling filled (its rule on the frame without it).

    python benchmarks/kernel_sizing.py [--size 512] [--images /tmp/kernel_sizing]

Writes benchmarks/results/kernel_sizing.md and .json; PNGs go to ``--images`` (not the repo).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, markdown_table, save_results  # noqa: E402
from contour_quality import DATA, contour_mask, detailed_surface, score  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import FilterOptions, Lights, RenderOptions, SplatCloud, reference, scenes_faulty  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.io.mesh import Mesh  # noqa: E402
from surfsplat.rendering.passes import FILL_DEPTH_PX, FILL_GAP_PX, FILL_ITERATIONS  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

#: The mesh samples' radius factor today (``geometry.splats.CIRCLE_COVERAGE``).
SAMPLE_FACTOR = 1.25


def scaled(cloud: SplatCloud, factor: float) -> SplatCloud:
    """The cloud with every splat's axes times ``factor``; clip lines ``a s + b t + c >= 0`` kept in
    place (s, t are in units of the axes: a and b scale with them)."""
    lines = None
    if cloud.clip_lines is not None:
        lines = cloud.clip_lines.copy()
        lines[:, :, :2] *= np.float32(factor)
    return cloud.replace(u=cloud.u * np.float32(factor), v=cloud.v * np.float32(factor), clip_lines=lines)


def overlap(cloud: SplatCloud, camera, covered: int) -> float:
    """Summed screen area (px^2) of the splats in front of the eye over the ``covered`` pixels."""
    p = reference.to_camera(camera, cloud.positions.astype(np.float64) + np.asarray(cloud.origin))
    z = -p[:, 2]
    n = reference.to_camera_dir(camera, cloud.normals)
    ray = p / np.linalg.norm(p, axis=1, keepdims=True)
    cos = np.abs((n * ray).sum(axis=1))
    area = np.pi * np.linalg.norm(cloud.u, axis=1) * np.linalg.norm(cloud.v, axis=1)
    front = z > 1e-6
    screen = area[front] * cos[front] * (camera.focal_px / z[front]) ** 2
    return round(float(screen.sum() / max(covered, 1)), 2)


def inner_holes(frame, truth) -> int:
    """Pixels inside the truth's silhouette eroded by 2 px that the frame leaves uncovered."""
    inside = ndimage.binary_erosion(truth.alpha > 0.999, iterations=2)
    return int(np.count_nonzero(inside & ~(frame.alpha > 0)))


def measure(cloud, camera, truth, contour, options, repeat, images: Path, tag: str) -> dict:
    """Render ``cloud`` (best of ``repeat``) and score it; also the frame without the fill, for its count."""
    renderer = default_renderer()
    lights = Lights()
    renderer.render(cloud, camera, "ewa", lights, options)   # upload, programs
    times, frame = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        frame = renderer.render(cloud, camera, "ewa", lights, options)
        times.append(time.perf_counter() - start)
    bare = renderer.render(cloud, camera, "ewa", lights, replace(options, fill_holes=False))
    filled = int(reference.fill_holes(bare.color, bare.weight, bare.depth, bare.alpha, camera.focal_px, FILL_GAP_PX,
                                      FILL_DEPTH_PX, FILL_ITERATIONS)[4].sum()) if options.fill_holes else 0
    Image.fromarray((np.clip(frame.color, 0, 1) * 255 + 0.5).astype(np.uint8)).save(images / f"{tag}.png")
    s = score(frame, truth, contour)
    return {"ms": round(1000 * min(times)), "overlap": overlap(cloud, camera, int(np.count_nonzero(frame.alpha > 0))),
            "psnr": s["psnr"], "contour": s["contour"], "smooth": s["smooth"], "holes": inner_holes(frame, truth),
            "bare holes": inner_holes(bare, truth), "fill": filled}


def square_mesh(color) -> Mesh:
    """The faulty scan's true surface: the unit square of z = 0."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    return Mesh(v, np.array([[0, 1, 2], [0, 2, 3]], np.int64), vertex_colors=np.tile(np.float32(color), (4, 1)))


def rows_for(name: str, truth_mesh: Mesh, variants: list[tuple[str, SplatCloud, RenderOptions]], camera, repeat,
             images: Path) -> list[list]:
    truth = surfsplat.render_mesh(truth_mesh, camera, supersample=4)
    contour = contour_mask(truth)
    rows = []
    for label, cloud, options in variants:
        tag = f"{name}_{label}".replace(" ", "_").replace("/", "-").replace(",", "")
        m = measure(cloud, camera, truth, contour, options, repeat, images, tag)
        rows.append([name, label, f"{len(cloud):,}", m["ms"], m["overlap"], m["psnr"], m["contour"], m["smooth"],
                     m["holes"], m["bare holes"], m["fill"]])
        print(rows[-1], flush=True)
    return rows


def mesh_sample_rows(size: int, factors: list[float], repeat: int, images: Path) -> list[list]:
    rows = []
    meshes = [(name, load_mesh(DATA / file)) for name, file in (("bunny", "bunny.ply"), ("CAD part", "featuretype.ply"))
              if (DATA / file).exists()]
    meshes.append(("detailed surface", detailed_surface()))
    for name, mesh in meshes:
        view = surfsplat.prepare(mesh)
        camera = view.camera(None, size, size)
        cloud = view.sample(camera).points()
        variants = [(f"samples x {f / SAMPLE_FACTOR:.2f} (radius {f:g} h_k)" + (", no fill" if fill is False else ""),
                     scaled(cloud, f / SAMPLE_FACTOR), RenderOptions(fill_holes=fill))
                    for f in factors for fill in ((True, False) if f == SAMPLE_FACTOR else (True,))]
        if name == "bunny":
            base = scaled(cloud, 1.0)
            variants += [(f"cutoff c = {c:g}", base, RenderOptions(filter=FilterOptions(cutoff=c))) for c in (0.5, 2.0)]
            variants += [("no prefilter", base, RenderOptions(filter=FilterOptions(prefilter=False)))]
        rows += rows_for(f"{name} (mesh samples)", mesh, variants, camera, repeat, images)
    return rows


def point_cloud_rows(size: int, coverages: list[float], repeat: int, images: Path) -> list[list]:
    rows = []
    sources = []
    if (DATA / "bunny.ply").exists():
        mesh = load_mesh(DATA / "bunny.ply")
        origin = np.asarray(mesh.origin) if mesh.origin is not None else 0.0
        sources.append(("bunny (points)", mesh, np.asarray(mesh.vertices, np.float64) + origin))
    faulty = scenes_faulty.faulty_scan()
    sources.append(("faulty scan", square_mesh(scenes_faulty.SURFACE_COLOR), faulty.cloud))
    for name, truth_mesh, points in sources:
        variants = []
        default = surfsplat.preprocess(points)
        camera = surfsplat.prepare(default).camera(None, size, size)
        variants.append(("Voronoi growth (default)", default, RenderOptions()))
        variants.append(("Voronoi growth, no fill", default, RenderOptions(fill_holes=False)))
        for c in coverages:
            variants.append((f"factor {c:g}, no growth", surfsplat.preprocess(points, coverage=c), RenderOptions()))
        rows += rows_for(name, truth_mesh, variants, camera, repeat, images)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--factors", type=float, nargs="+", default=[1.0, 1.1, 1.25],
                        help="mesh samples' radius factors (times h_k)")
    parser.add_argument("--coverages", type=float, nargs="+", default=[1.0, 1.2, 1.5],
                        help="point clouds' fixed ellipse factors")
    parser.add_argument("--images", type=Path, default=Path("/tmp/kernel_sizing"))
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    rows = mesh_sample_rows(args.size, args.factors, args.repeat, args.images)
    rows += point_cloud_rows(args.size, args.coverages, args.repeat, args.images)
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    date = time.strftime("%Y-%m-%d")
    command = "python benchmarks/kernel_sizing.py " + shlex.join(sys.argv[1:])
    columns = ["model", "splats", "count", "frame ms", "overlap", "psnr", "contour", "smooth", "holes",
               "holes without fill", "fill"]
    text = "\n".join([f"Machine: {machine}", f"Date: {date}", f"Command: `{command.strip()}`", "",
                      f"{args.size} x {args.size}, ewa, headlight, against the 4 x 4 mesh (the faulty scan: its "
                      "square; only its holes count).", ""] + markdown_table(columns, rows))
    save_results("kernel_sizing", text + "\n", {"machine": machine, "date": date, "command": command.strip(),
                                                   "columns": columns, "rows": rows})


if __name__ == "__main__":
    main()
