"""Robust splats from raw points: before/after table of preprocess on faulty and real clouds.

"Before" is the committed version (``git archive HEAD src`` into a temporary folder, run in a
subprocess with that folder first on ``PYTHONPATH``); "after" is the working tree. Both sets of
splats are drawn by this process (the working tree's renderer, same cameras).

Inputs: frag_115.ply's vertices as raw points (normals dropped, so PCA estimates them; and with
the file's normals kept), simple.las (airborne LiDAR), the Stanford bunny sampled from its mesh
(clean input: PSNR against ``render_mesh``), and the synthetic faulty scans of
:mod:`surfsplat.scenes_faulty`. Columns:

* ``largest / spacing``, ``p99 / spacing``, ``median / spacing``: splat radius (largest
  semi-axis) over the median nearest-neighbour spacing of the distinct input points (for the
  synthetic clouds: of the surface's samples);
* ``holes``: pixels inside the known footprint that no splat covers (synthetic: the square,
  eroded by 2 line gaps, top view; frag_115 and bunny: the mesh's silhouette eroded by 2 px;
  simple.las: the convex hull of the points, top view, eroded by 2 px);
* ``filled %``: share of the frame the splats cover;
* ``holes``: for the synthetic clouds counted in a rendering of the surface samples' splats
  alone (faults in front of the plane hide it, they cannot fill its holes);
* ``PSNR``: against the mesh rendered by ``render_mesh`` (frag_115, bunny; ``metrics.compare``)
  or, for the synthetic clouds, against the true plane (a dense grid of covering splats in the
  surface color) inside the footprint: what the faults, holes and wrong normals cost;
* ``px changed``: pixels of the after rendering that differ from the before one (any channel
  by more than 1/255, or coverage);
* ``s``: preprocess time (one run; the small inputs vary by ~30 % between runs).

A second table measures the ``outliers`` options; a third times 1 M points (torus, uniform; and
5:1 scan lines), before and after, interleaved, best of ``--repeats``.

    python benchmarks/robust_splats.py [--repeats 3] [--no-timing]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_preprocess import torus  # noqa: E402
from common import RESULTS, machine_description, markdown_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import SplatCloud, metrics, scenes  # noqa: E402
from surfsplat import scenes_faulty as sf  # noqa: E402
from surfsplat.pipeline import auto_camera  # noqa: E402
from surfsplat.camera import Camera  # noqa: E402
from surfsplat.geometry import knn, preprocess, sample_mesh  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
SIZE = 384

#: Where the renderings go (not into the repository).
PICTURES = Path(tempfile.gettempdir()) / "surfsplat_robust_splats"

#: Runs the committed preprocess on an .npz cloud (in a subprocess, HEAD's src first on the path).
BEFORE_SCRIPT = """
import sys, time, warnings, numpy as np
warnings.simplefilter("ignore")
from surfsplat import SplatCloud
from surfsplat.geometry import preprocess
data = np.load(sys.argv[1])
cloud = SplatCloud(data["positions"], normals=data["normals"] if "normals" in data else None,
                   colors=data["colors"] if "colors" in data else None)
best = None
for _ in range(int(sys.argv[3])):
    start = time.perf_counter()
    try:   # a version with a report: the input rows its splats come from (duplicates and outliers go)
        out, report = preprocess(cloud, return_report=True)
        kept = report.kept
    except TypeError:
        out, kept = preprocess(cloud), np.arange(len(cloud))
    elapsed = time.perf_counter() - start
    best = elapsed if best is None else min(best, elapsed)
np.savez(sys.argv[2], positions=out.positions, normals=out.normals, u=out.u, v=out.v, kept=kept,
         colors=out.colors if out.colors is not None else np.zeros((0, 3), np.float32), seconds=best)
"""


class Before:
    """The committed version of the package, exported to a temporary folder."""

    def __init__(self):
        self.dir = tempfile.TemporaryDirectory(prefix="surfsplat_head_")
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", "HEAD", "src"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", self.dir.name], input=archive, check=True)
        self.src = Path(self.dir.name) / "src"
        self.commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], check=True,
                                     capture_output=True, text=True).stdout.strip()

    def preprocess(self, cloud: SplatCloud, repeats: int = 1) -> tuple[SplatCloud, float, np.ndarray]:
        """HEAD's ``preprocess(cloud)``, its best time of ``repeats`` runs (seconds) and the input rows
        its splats come from."""
        with tempfile.TemporaryDirectory() as tmp:
            arrays = {"positions": cloud.positions}
            if cloud.normals is not None:
                arrays["normals"] = cloud.normals
            if cloud.colors is not None:
                arrays["colors"] = cloud.colors
            np.savez(Path(tmp) / "in.npz", **arrays)
            env = dict(os.environ, PYTHONPATH=str(self.src))
            subprocess.run([sys.executable, "-c", BEFORE_SCRIPT, str(Path(tmp) / "in.npz"), str(Path(tmp) / "out.npz"),
                            str(repeats)], check=True, env=env)
            data = np.load(Path(tmp) / "out.npz")
            colors = data["colors"] if len(data["colors"]) else None
            return (SplatCloud(data["positions"], data["normals"], colors, data["u"], data["v"]),
                    float(data["seconds"]), data["kept"])


def after(cloud: SplatCloud, repeats: int = 1, **options):
    """The working tree's ``preprocess`` with a report, and its best time (seconds)."""
    best = None
    for _ in range(repeats):
        start = time.perf_counter()
        out, report = preprocess(cloud, return_report=True, **options)
        elapsed = time.perf_counter() - start
        best = elapsed if best is None else min(best, elapsed)
    return out, report, best


def nn_spacing(points: np.ndarray) -> float:
    """Median distance to the nearest other distinct point, model units."""
    distinct = np.unique(np.asarray(points, dtype=np.float32), axis=0)
    return float(np.median(knn(distinct, 1)[0]))


def top_camera(lo, hi, size: int = SIZE) -> Camera:
    """Looking down -z at the box ``lo``..``hi`` (x, y filling ~90 % of the frame)."""
    center = 0.5 * (np.asarray(lo, float) + np.asarray(hi, float))
    half = 0.5 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    distance = 1.12 * half / np.tan(np.radians(20.0))
    return Camera(eye=tuple(center + [0, 0, distance + hi[2] - center[2]]), target=tuple(center), up=(0, 1, 0),
                  fov=40.0, width=size, height=size)


def project(camera: Camera, points: np.ndarray) -> np.ndarray:
    """(N, 2) pixel coordinates (column, row from the top) of world points (pinhole, look-at)."""
    c = np.c_[np.asarray(points, float), np.ones(len(points))] @ camera.view_matrix.T
    depth = -c[:, 2]
    cx, cy = camera.principal_point
    x = cx + camera.focal_px * c[:, 0] / depth
    y = cy + camera.focal_px * c[:, 1] / depth  # window coordinates, y up
    return np.c_[x, camera.height - y]


def polygon_mask(camera: Camera, corners: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixel centers inside the convex hull of the projected ``corners``."""
    xy = project(camera, corners)
    hull = ConvexHull(xy)
    cols, rows = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
    q = np.stack([cols.ravel(), rows.ravel()], axis=1)
    inside = (q @ hull.equations[:, :2].T + hull.equations[:, 2] <= 0).all(axis=1)
    return inside.reshape(camera.height, camera.width)


def radii_stats(cloud: SplatCloud, spacing: float) -> list[float]:
    r = cloud.radii / spacing
    return [round(float(r.max()), 1), round(float(np.quantile(r, 0.99)), 1), round(float(np.median(r)), 2)]


def render(cloud: SplatCloud, camera: Camera):
    return surfsplat.render(cloud, camera, width=camera.width, height=camera.height)


def true_plane(side: float) -> SplatCloud:
    """The square [0, side]^2 of z = 0 as a dense grid of covering splats in the surface color."""
    grid = scenes.checkerboard(400, size=side)
    return grid.replace(positions=grid.positions + np.float32([side / 2, side / 2, 0]),
                        colors=np.broadcast_to(np.float32(sf.SURFACE_COLOR), grid.positions.shape))


def case_rows(name, raw: SplatCloud, spacing: float, camera: Camera, footprint: np.ndarray, before: Before,
              reference=None, surface: np.ndarray | None = None):
    """Table rows (before, after) of one input. ``reference``: a Frame to compare with (PSNR:
    ``metrics.compare`` against a mesh rendering, or over ``footprint`` for the synthetic
    planes); ``surface``: (N,) bool, the input's surface samples: holes are then counted in a
    rendering of their splats alone (the faults may hide the surface, they cannot fill its holes)."""
    rows = []
    inner = metrics.erode(footprint, 2)
    previous = None
    for version in ("before", "after"):
        if version == "before":
            out, seconds, kept = before.preprocess(raw)
            counts = ""
        else:
            out, report, seconds = after(raw)
            kept = report.kept
            counts = (f"dup {report.duplicates}, outliers {report.outliers} ({report.outlier_clusters} clusters, "
                      f"{report.strays} strays), lines {report.linear}, non-planar {report.volumetric}, "
                      f"capped {report.capped}")
        frame = render(out, camera)
        covered = frame.mask if surface is None else render(out.subset(surface[kept]), camera).mask
        holes = int((inner & ~covered).sum())
        psnr = ""
        if reference is not None:
            if surface is None:
                psnr = f"{metrics.compare(frame, reference)['psnr']:.2f}"
            else:
                psnr = f"{metrics.psnr(frame.color, reference.color, inner):.2f}"
        changed = ""
        if previous is not None:
            changed = int(((np.abs(frame.color - previous.color).max(axis=2) > 1 / 255)
                           | (frame.mask != previous.mask)).sum())
        previous = frame
        rows.append([name, version, f"{len(raw):,} → {len(out):,}", *radii_stats(out, spacing), holes,
                     round(100 * float(frame.mask.mean()), 1), psnr, changed, f"{seconds:.3f}", counts])
        frame.save(PICTURES / f"{name.replace(' ', '_').replace(':', '-')}_{version}.png")
    return rows


def synthetic_cases():
    return [sf.stray_points(), sf.stray_clusters(), sf.scan_lines(), sf.tree(), sf.duplicates(), sf.faulty_scan()]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats of the 1 M point runs (default 3)")
    parser.add_argument("--no-timing", action="store_true", help="skip the 1 M point timings")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    PICTURES.mkdir(parents=True, exist_ok=True)
    before = Before()
    columns = ["input", "version", "points", "largest / spacing", "p99 / spacing", "median / spacing", "holes px",
               "filled %", "PSNR dB", "px changed", "s", "report (after)"]
    rows = []

    # real data
    frag = SHARED / "frag_115.ply"
    if frag.exists():
        mesh = load_mesh(frag)
        cloud = surfsplat.load(frag)
        camera = auto_camera(SplatCloud(mesh.vertices), SIZE, SIZE)
        reference = surfsplat.render_mesh(mesh, camera, width=SIZE, height=SIZE)
        spacing = nn_spacing(cloud.positions)
        for label, raw in (("frag_115 vertices, raw", cloud.replace(normals=None)),
                           ("frag_115 vertices + normals", cloud)):
            rows += case_rows(label, raw, spacing, camera, reference.mask, before, reference=reference)
    las = SHARED / "simple.las"
    if las.exists():
        cloud = surfsplat.load(las)
        lo, hi = cloud.bounds()
        camera = top_camera(lo, hi)
        rows += case_rows("simple.las", cloud, nn_spacing(cloud.positions), camera,
                          polygon_mask(camera, cloud.positions), before)
    bunny = SHARED / "bunny.ply"
    if bunny.exists():
        mesh = load_mesh(bunny)
        samples = sample_mesh(mesh, 200_000, seed=0)
        camera = auto_camera(SplatCloud(mesh.vertices), SIZE, SIZE)
        reference = surfsplat.render_mesh(mesh, camera, width=SIZE, height=SIZE)
        spacing = nn_spacing(samples.positions)
        for label, raw in (("bunny, 200k mesh samples, raw", samples.replace(normals=None)),
                           ("bunny, 200k mesh samples + normals", samples)):
            rows += case_rows(label, raw, spacing, camera, reference.mask, before, reference=reference)

    # synthetic faulty scans: the plane z = 0, [0, 1]^2
    for fc in synthetic_cases():
        camera = top_camera((0, 0, 0), (fc.side, fc.side, 0))
        gap = fc.spacing * (5 if "scan" in fc.name else 1)
        m = 2 * gap
        footprint = polygon_mask(camera, np.array([[m, m, 0], [fc.side - m, m, 0], [m, fc.side - m, 0],
                                                   [fc.side - m, fc.side - m, 0]]))
        reference = render(true_plane(fc.side), camera)
        rows += case_rows(fc.name, fc.cloud, nn_spacing(fc.cloud.positions[fc.surface]), camera, footprint, before,
                          reference=reference, surface=fc.surface)

    # the outliers options on the faults (PSNR against the surface's own samples alone, after)
    option_rows = []
    for fc in synthetic_cases():
        if not (~fc.surface).any():
            continue
        camera = top_camera((0, 0, 0), (fc.side, fc.side, 0))
        reference = render(preprocess(fc.cloud.subset(fc.surface)), camera)
        row = [fc.name]
        for option in ("drop", "cap", "keep"):
            frame = render(preprocess(fc.cloud, outliers=option), camera)
            wrong = int((np.abs(frame.color - reference.color).max(axis=2) > 0.1).sum())
            row += [round(metrics.psnr(frame.color, reference.color), 2), wrong]
        option_rows.append(row)
    option_columns = ["input", "drop: PSNR dB", "drop: wrong px", "cap: PSNR dB", "cap: wrong px",
                      "keep: PSNR dB", "keep: wrong px"]

    timing_rows = []
    if not args.no_timing:
        pts, _ = torus(1_000_000)
        scan = sf.scan_lines(lines=450)
        for label, cloud in (("torus, uniform, 1 M", SplatCloud(pts)),
                             (f"scan lines 5:1, {len(scan.cloud) / 1e6:.2f} M", scan.cloud.replace(colors=None))):
            old = [before.preprocess(cloud, repeats=1)[1] for _ in range(args.repeats)]
            new = [after(cloud)[2] for _ in range(args.repeats)]
            timing_rows.append([label, round(min(old), 2), round(min(new), 2)])

    machine = f"{machine_description()}; {platform.platform()}; os.cpu_count() = {os.cpu_count()}"
    date = time.strftime("%Y-%m-%d")
    text = [f"Machine: {machine}", f"Date: {date}", f"Before: HEAD {before.commit}; after: working tree", "",
            "## Before / after", ""] + markdown_table(columns, rows)
    text += ["", "## outliers= options (after; PSNR against the surface's samples alone, same camera; wrong px: "
             "any channel off by > 0.1)", ""] + markdown_table(option_columns, option_rows)
    if timing_rows:
        text += ["", f"## preprocess time, 1 M points (best of {args.repeats}, before and after interleaved)", ""]
        text += markdown_table(["input", "before s", "after s"], timing_rows)
    print("\n".join(text))
    (RESULTS / "robust_splats.md").write_text("\n".join(text) + "\n")
    (RESULTS / "robust_splats.json").write_text(json.dumps(
        {"machine": machine, "date": date, "before": before.commit,
         "tables": {"before_after": {"columns": columns, "rows": rows},
                    "outliers": {"columns": option_columns, "rows": option_rows},
                    "timing": {"columns": ["input", "before s", "after s"], "rows": timing_rows}}}, indent=1))


if __name__ == "__main__":
    main()
