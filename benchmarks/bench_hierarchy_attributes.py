"""Cost of carrying per-point attributes through the LOD hierarchy.

A LiDAR-like cloud of ``--points`` random points over a flat 100 x 100 x 1 box (z up, circular
splats) with the columns of a LAS point (6 one-bit flags, classification 0..6, return_number
1..3, scan_angle_rank -20..19, point_source_id 10 values, intensity 0..65534 and gps_time):
the time of :func:`surfsplat.hierarchy.nodes.node_attribute_values` per column (fastest of
``--repeats``: majority vote for integer columns, mean for floats), and
:func:`~surfsplat.hierarchy.build_hierarchy` with and without the columns (fastest of
``--repeats``), with the file size of ``save_hierarchy``.

    python benchmarks/bench_hierarchy_attributes.py [--points 1000000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, write_table  # noqa: E402

from surfsplat import SplatCloud  # noqa: E402
from surfsplat.hierarchy import build_hierarchy, octree_topology, save_hierarchy  # noqa: E402
from surfsplat.hierarchy.nodes import node_attribute_values  # noqa: E402


def columns(n: int, rng) -> dict[str, np.ndarray]:
    out = {f"flag{i}": rng.integers(0, 2, n).astype(np.uint8) for i in range(6)}
    out.update(classification=rng.integers(0, 7, n).astype(np.uint8),
               return_number=rng.integers(1, 4, n).astype(np.uint8),
               scan_angle_rank=rng.integers(-20, 20, n).astype(np.int8),
               point_source_id=rng.integers(7000, 7010, n).astype(np.uint16),
               intensity=rng.integers(0, 65535, n).astype(np.uint16),
               gps_time=rng.uniform(3e8, 3e8 + 1e5, n))
    return out


def fastest(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    n = args.points
    pos = rng.uniform(0, 100, size=(n, 3))
    pos[:, 2] *= 0.01
    attrs = columns(n, rng)
    topo = octree_topology(pos.astype(np.float32), 8, 48)
    rows = []
    for name, values in attrs.items():
        ordered = values[topo["order"]]
        seconds = fastest(lambda: node_attribute_values({name: ordered}, topo["point_start"], topo["point_count"],
                                                        topo["child_count"], topo["level_offsets"]), args.repeats)
        rule = "mean" if values.dtype.kind == "f" else "majority"
        rows.append([f"node values: {name} ({values.dtype}, {rule})", n, round(1000 * seconds, 1), "-"])
    cloud = SplatCloud.from_arrays(pos, np.tile([0.0, 0.0, 1.0], (n, 1)), radius=np.full(n, 0.1))
    with tempfile.TemporaryDirectory() as tmp:
        for label, c in (("build, no attributes", cloud), (f"build, {len(attrs)} attributes",
                                                          cloud.replace(attributes=attrs))):
            seconds = fastest(lambda: build_hierarchy(c), args.repeats)
            path = save_hierarchy(build_hierarchy(c), Path(tmp) / "h.npz", overwrite=True)
            rows.append([label, n, round(1000 * seconds, 1), round(path.stat().st_size / 2**20, 1)])
    write_table("hierarchy_attributes", ["step", "points", "ms (fastest)", "file MiB"], rows,
                machine_description() + f", {len(topo['point_start']):,} nodes, "
                f"{len(topo['level_offsets']) - 1} levels")


if __name__ == "__main__":
    main()
