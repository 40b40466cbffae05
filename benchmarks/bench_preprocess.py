"""Preprocessing throughput: points/s of each stage of surfsplat.geometry.preprocess.

Input: points sampled uniformly (by area) on a torus, no normals, so the whole
pipeline runs (spatial sort, kNN, PCA normals + ellipses, MST orientation);
then the same points with their normals given (kNN + ellipses only).

Every case runs once to warm up (the first run in a fresh process also pays
for first-touch page faults of ~1 GB of arrays, reported as "cold"), then
``--repeats`` times; the table shows the fastest repeat.

    python benchmarks/bench_preprocess.py [--points 1000000] [--repeats 3] [--k 8]
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, write_table  # noqa: E402

import surfsplat.progress  # noqa: E402
from surfsplat import SplatCloud  # noqa: E402
from surfsplat.geometry import preprocess  # noqa: E402


def torus(n: int, big: float = 1.0, small: float = 0.35, seed: int = 0):
    """n points uniform by area on a torus (rejection on the tube angle) and their outward normals."""
    rng = np.random.default_rng(seed)
    pts, nrm = [], []
    count = 0
    while count < n:
        m = 2 * (n - count) + 1024
        u = rng.uniform(0, 2 * np.pi, m)
        v = rng.uniform(0, 2 * np.pi, m)
        keep = rng.uniform(0, big + small, m) < big + small * np.cos(v)
        u, v = u[keep], v[keep]
        ring = np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], axis=1)
        normal = np.cos(v)[:, None] * ring + np.sin(v)[:, None] * np.array([0.0, 0.0, 1.0])
        pts.append(big * ring + small * normal)
        nrm.append(normal)
        count += len(u)
    return (np.concatenate(pts)[:n].astype(np.float32), np.concatenate(nrm)[:n].astype(np.float32))


class StageTimer:
    """Stands in for surfsplat.progress.stage and records each stage's wall time."""

    def __init__(self):
        self.times: dict[str, float] = {}

    @contextlib.contextmanager
    def __call__(self, name, count=None, unit="points"):
        start = time.perf_counter()
        yield
        self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - start


def run_case(cloud: SplatCloud, k: int, repeats: int):
    """(cold total, best total, stage times of the best repeat, result)."""
    original = surfsplat.progress.stage
    results = []
    try:
        for _ in range(repeats + 1):
            timer = StageTimer()
            surfsplat.progress.stage = timer
            start = time.perf_counter()
            out = preprocess(cloud, k=k)
            total = time.perf_counter() - start
            results.append((total, timer.times))
    finally:
        surfsplat.progress.stage = original
    cold = results[0][0]
    best_total, best_stages = min(results[1:], key=lambda r: r[0])
    return cold, best_total, best_stages, out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000, help="points on the torus (default 1,000,000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats after a warm-up run (default 3)")
    parser.add_argument("--k", type=int, default=8, help="neighbours per point (default 8)")
    args = parser.parse_args(argv)

    n = args.points
    positions, normals = torus(n)
    rows = []
    checks = []
    for case, cloud in (("no normals", SplatCloud(positions)),
                        ("normals given", SplatCloud(positions, normals=normals))):
        cold, total, stages, out = run_case(cloud, args.k, args.repeats)
        for name, seconds in stages.items():
            rows.append([case, name, n, round(seconds, 3), round(n / seconds)])
        other = total - sum(stages.values())
        other_rate = round(n / other) if other > 0 else "-"
        rows.append([case, "other (validation, reordering)", n, round(other, 3), other_rate])
        rows.append([case, "**total**", n, round(total, 3), round(n / total)])
        rows.append([case, "total, first run (cold memory)", n, round(cold, 3), round(n / cold)])
        outward = float((np.einsum("ij,ij->i", out.normals, normals) > 0).mean())
        checks.append(f"{case}: {len(out):,} splats, normals outward: {outward:.6f}")

    machine = machine_description()
    write_table("preprocess", ["case", "stage", "points", "seconds", "points/s"], rows, machine)
    print()
    print(f"k = {args.k}, best of {args.repeats} repeats after one warm-up run; torus, uniform by area")
    for line in checks:
        print(line)


if __name__ == "__main__":
    main()
