"""COPC export: time and bytes per point of :func:`surfsplat.io.copc.write_copc` for 1M-point clouds.

Clouds: the built-in torus at 1,000,000 splats (colours, normals, tangent axes: 9 float32 extra bytes a
point), the same points without splats (positions and colours only), and a LiDAR-like terrain of
1,000,000 points (georeferenced coordinates, 16-bit intensity and a classification, no splats).
Columns: octree nodes and levels, the write time (median of 3 runs, wall; the cloud is already in
memory), the file size and bytes per point, the size of the same point records as a plain LAZ file
(laspy with lazrs, fixed chunks of 50,000 points) for the cost of the octree, and the time laspy's
``CopcReader`` takes to read every point back. Last row: ``surfsplat.export`` of the torus, the whole
front door (view plan, then the writer).

    python benchmarks/copc_export.py [--points 1000000]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import laspy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, write_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat.cloud import SplatCloud  # noqa: E402
from surfsplat.io.copc import write_copc  # noqa: E402
from surfsplat.scenes import torus  # noqa: E402


def terrain(n: int, seed: int = 0) -> SplatCloud:
    """LiDAR-like points: a 1 km x 1 km wavy terrain at UTM coordinates with intensity and classes."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 1000, size=(n, 2))
    z = 20 * np.sin(xy[:, 0] / 90) * np.cos(xy[:, 1] / 130) + rng.normal(0, 0.05, n)
    world = np.column_stack([xy + [512_000.0, 4_100_000.0], z + 150.0])
    shade = (0.35 + 0.1 * np.sin(xy[:, 1] / 40))[:, None]
    return SplatCloud(positions=world, colors=np.clip(shade + [0.1, 0.2, 0.0], 0, 1),
                      attributes={"intensity": rng.integers(0, 4000, n).astype(np.uint16),
                                  "classification": rng.choice([2, 3, 5, 6], n).astype(np.uint8)},
                      up=(0.0, 0.0, 1.0))


def measure(name: str, cloud: SplatCloud, folder: Path) -> list:
    path = folder / f"{name.split()[0]}.copc.laz"
    times = []
    for _ in range(3):
        start = time.perf_counter()
        result = write_copc(cloud, path)
        times.append(time.perf_counter() - start)
    start = time.perf_counter()
    with laspy.CopcReader.open(path) as reader:
        assert len(reader.query()) == len(cloud)
    read = time.perf_counter() - start
    plain = folder / "plain.laz"
    las = laspy.read(path)
    las.header.vlrs = laspy.vlrs.vlrlist.VLRList([v for v in las.header.vlrs if v.user_id != "copc"])
    las.evlrs = laspy.vlrs.vlrlist.VLRList()
    las.write(plain)
    return [name, result.points, result.nodes, result.levels, statistics.median(times), result.bytes / 1e6,
            result.bytes / result.points, plain.stat().st_size / result.points, read]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    args = parser.parse_args()
    n_major = int(round(np.sqrt(args.points * 1.5625)))
    splats = torus(n_major, args.points // n_major)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        rows.append(measure("torus, splats", splats, Path(folder)))
        rows.append(measure("torus, points and colours",
                            SplatCloud(positions=splats.positions, colors=splats.colors, up=splats.up), Path(folder)))
        rows.append(measure("terrain (LiDAR-like)", terrain(args.points), Path(folder)))
        start = time.perf_counter()
        result = surfsplat.export(splats, Path(folder) / "api.copc.laz")
        rows.append(["surfsplat.export(torus)", result.splats, "", "", time.perf_counter() - start,
                     result.bytes / 1e6, result.bytes / result.splats, "", ""])
    write_table("copc_export", ["cloud", "points", "nodes", "levels", "write s", "MB", "bytes/point",
                                "plain LAZ bytes/point", "CopcReader read-all s"], rows, machine_description())
    command = "python benchmarks/copc_export.py" + (f" --points {args.points}" if args.points != 1_000_000 else "")
    with open(RESULTS / "copc_export.md", "a") as table:
        table.write(f"\nCommand: `{command}`\n")
    print(f"\nCommand: `{command}`")


if __name__ == "__main__":
    main()
