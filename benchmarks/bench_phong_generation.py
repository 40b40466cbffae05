"""Phong splat generation throughput (surfsplat.geometry.phong, Botsch et al. 2004 sec. 3).

Inputs: Fibonacci spheres and (theta, phi) torus grids with exact normals at 100 k
and 1 M samples, the Stanford bunny's vertices (mesh normals) and 1 M samples of its
mesh (face normals), a count-mode run, and the CAD part sampled with sharp edges.
Each case runs once in this process (after a small warm-up run); the table gives
the wall time of ``phong_fit`` (validation and spatial sort included), the splat
count, and two checks on the result: samples not covered within eps (must be 0)
and the mean angle between the interpolated normal field and the samples' own
normals at the samples (vs. the splats' constant center normal).

    python benchmarks/bench_phong_generation.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, write_table  # noqa: E402

from surfsplat import SplatCloud, reference, scenes  # noqa: E402
from surfsplat.geometry.phong import phong_coverage, phong_fit  # noqa: E402
from surfsplat.geometry.sampling import sample_mesh  # noqa: E402
from surfsplat.io import load, load_mesh  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def sphere(n: int) -> SplatCloud:
    c = scenes.sphere(n)
    return SplatCloud(c.positions, c.normals)


def torus(n_major: int, n_minor: int) -> SplatCloud:
    c = scenes.torus(n_major, n_minor)
    return SplatCloud(c.positions, c.normals)


def normal_errors(cloud: SplatCloud, result) -> tuple[float, float]:
    """Mean angle (degrees) at the samples between their normals and the splats' linear
    field (eq. 2) and the splats' constant center normal."""
    splats = result.splats
    j = np.repeat(np.arange(len(splats)), np.diff(result.member_ptr))
    p = cloud.positions[result.member_idx].astype(np.float64)
    c = splats.positions.astype(np.float64)[j]
    u = splats.u.astype(np.float64)[j]
    v = splats.v.astype(np.float64)[j]
    st = np.stack([((p - c) * u).sum(1) / (u * u).sum(1), ((p - c) * v).sum(1) / (v * v).sum(1)], axis=1)
    field = reference.field_normals(splats.normals.astype(np.float64)[j], u, v,
                                    splats.normal_field.astype(np.float64)[j], st[:, None, :])[:, 0]
    truth = cloud.normals[result.member_idx].astype(np.float64)

    def mean_angle(a):
        return float(np.degrees(np.arccos(np.clip(np.abs((a * truth).sum(1)), -1, 1))).mean())

    return mean_angle(field), mean_angle(splats.normals.astype(np.float64)[j])


def run(name: str, cloud: SplatCloud, *, error=None, count=None, sharp_angle=None):
    start = time.perf_counter()
    result = phong_fit(cloud, error, count=count, sharp_angle=sharp_angle)
    seconds = time.perf_counter() - start
    n = result.samples
    points = cloud.validated().positions if len(cloud) != n else cloud.positions
    uncovered = int((phong_coverage(points, result.splats) > result.error).sum())
    field, constant = normal_errors(cloud.validated() if len(cloud) != n else cloud, result)
    target = f"eps {result.error:.3g}" if count is None else f"count {count:,} (eps {result.error:.3g})"
    if sharp_angle is not None:
        target += f", sharp {sharp_angle:g}"
    splats = len(result.splats)
    row = [name, n, target, splats, round(n / splats, 1), round(seconds, 2), round(n / seconds),
           uncovered, round(field, 3), round(constant, 3)]
    print("  " + " | ".join(str(x) for x in row), flush=True)
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 k cases only (no 1 M, no results files)")
    args = parser.parse_args(argv)

    run("warm-up", sphere(20_000), error=1e-3)
    rows = [run("sphere (Fibonacci, R 1)", sphere(100_000), error=1e-3),
            run("torus grid (R 1, r 0.4)", torus(500, 200), error=1e-3),
            run("sphere (Fibonacci, R 1)", sphere(100_000), count=5_000)]
    if not args.quick:
        rows += [run("sphere (Fibonacci, R 1)", sphere(1_000_000), error=1e-4),
                 run("sphere (Fibonacci, R 1)", sphere(1_000_000), error=1e-3),
                 run("torus grid (R 1, r 0.4)", torus(1600, 625), error=2e-4)]
    if (DATA / "bunny.ply").exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")     # 1,113 unused vertices dropped
            bunny = load(DATA / "bunny.ply")
        rows.append(run("bunny vertices (mesh normals)", bunny, error=1e-4))
        if not args.quick:
            mesh = load_mesh(DATA / "bunny.ply")
            rows.append(run("bunny, 1 M mesh samples (face normals)", sample_mesh(mesh, 1_000_000, seed=0),
                            error=5e-5))
    if (DATA / "featuretype.ply").exists():
        mesh = load_mesh(DATA / "featuretype.ply")
        lo, hi = mesh.bounds()
        eps = round(1e-3 * float(np.linalg.norm(hi - lo)), 4)
        cad = sample_mesh(mesh, 200_000, seed=0, sharp_angle=30)
        rows.append(run("CAD part featuretype, 200 k mesh samples with clip lines", cad, error=eps, sharp_angle=30))
    if args.quick:
        return
    columns = ["input", "samples", "tolerance", "splats", "samples per splat", "seconds", "samples/s",
               "uncovered", "field error (deg)", "constant-normal error (deg)"]
    write_table("phong_generation", columns, rows, machine_description())
    print()
    print("One run per case (after a warm-up run); time of phong_fit including validation, sorting, k-d tree, "
          "pilot, candidates, greedy cover, fit, 2 relaxation steps (and clip lines). 'uncovered': samples in "
          "no splat's elliptical cylinder (+-eps); errors: mean angle to the samples' normals at the samples.")


if __name__ == "__main__":
    main()
