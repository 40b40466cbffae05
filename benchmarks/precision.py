"""Precision independent of where the data sits: the same torus rendered at large offsets and scales.

A torus (major radius 0.5 m, tube 0.2 m, 64,000 splats about 8 mm apart) is moved to offsets
1e6 and 1e7 (world units, as georeferenced survey data sit) and scaled by 1e-9..1e9 about
the origin, with the camera moved and scaled with it; each view (256x256, ``ewa`` and ``flat``; ``ewa`` of the
point-octree's 1-pixel LOD cut at offset 1e7)
is compared with the view at the origin: PSNR of the colour (8-bit image) and the difference
in covered pixels. Two file paths are measured too: a LAS file (scale 0.001, offset 1e7;
16,000 raw points preprocessed with k = 8) against the same file at offset 0, and a PLY with
double coordinates at offset 1e7 against the same PLY at the origin.

    python benchmarks/precision.py --label before   # once with the old code
    python benchmarks/precision.py --label after

("before" was measured with the code of the commit before the change: once in the working tree
before editing, then again, with the added rows, from ``git archive HEAD src`` on PYTHONPATH.)

Each run stores its column in results/precision.json and rewrites results/precision.md with
every label measured so far.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import surfsplat  # noqa: E402
from common import RESULTS, machine_description, markdown_table  # noqa: E402
from surfsplat.hierarchy import build_hierarchy  # noqa: E402
from surfsplat.rendering.context import renderer_name  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402
from surfsplat.scenes import torus  # noqa: E402

SIZE = 256
EYE = np.array([0.9, -1.3, 1.0])
UP = (0.0, 0.0, 1.0)
OFFSET_DIRECTION = np.array([1.0, 0.8, 0.1])
TECHNIQUES = ("ewa", "flat")


def base_cloud(n_major: int = 400, n_minor: int = 160) -> surfsplat.SplatCloud:
    """The torus about the origin, float64 arrays kept for exact moves."""
    return torus(n_major, n_minor, major=0.5, minor=0.2)


def moved(cloud, offset: np.ndarray, scale: float):
    """``cloud`` scaled by ``scale`` about the origin then moved by ``offset``, built from float64
    world positions (the way a user's arrays arrive)."""
    world = cloud.positions.astype(np.float64) * scale + offset
    return surfsplat.SplatCloud(world, cloud.normals, cloud.colors, cloud.u.astype(np.float64) * scale,
                                cloud.v.astype(np.float64) * scale)


def camera(offset: np.ndarray, scale: float) -> surfsplat.Camera:
    """The reference view moved and scaled with the model."""
    return surfsplat.Camera(eye=tuple(offset + scale * EYE), target=tuple(offset.astype(np.float64)), up=UP,
                            fov=40.0, width=SIZE, height=SIZE)


def compare(frame, reference) -> tuple[float, int]:
    """(PSNR of the 8-bit colour in dB, inf when equal; covered pixels minus the reference's)."""
    a = frame.image().astype(np.float64)
    b = reference.image().astype(np.float64)
    mse = float(np.mean((a - b) ** 2))
    psnr = float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)
    return psnr, int(frame.mask.sum()) - int(reference.mask.sum())


def render(source, offset, scale, technique):
    """The frame of ``source`` through the moved camera (NaN PSNR cases are caught by the caller)."""
    return surfsplat.render(source, camera(offset, scale), technique=technique)


def write_las(path: Path, points: np.ndarray, offset: np.ndarray) -> None:
    """A LAS 1.2 file of ``points`` (world units) with scale 0.001 and ``offset``."""
    import laspy

    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = offset
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    las.write(str(path))


def write_double_ply(path: Path, cloud, offset: np.ndarray) -> None:
    """A binary PLY splat file with double x y z (world = local + offset) and float32 normals and axes."""
    from plyfile import PlyData, PlyElement

    world = cloud.positions.astype(np.float64) + offset
    names = [("x", "f8"), ("y", "f8"), ("z", "f8"), ("nx", "f4"), ("ny", "f4"), ("nz", "f4"),
             ("ux", "f4"), ("uy", "f4"), ("uz", "f4"), ("vx", "f4"), ("vy", "f4"), ("vz", "f4")]
    data = np.empty(len(cloud), dtype=names)
    for i, axis in enumerate("xyz"):
        data[axis] = world[:, i]
        data["n" + axis] = cloud.normals[:, i]
        data["u" + axis] = cloud.u[:, i]
        data["v" + axis] = cloud.v[:, i]
    PlyData([PlyElement.describe(data, "vertex")]).write(str(path))


def measure() -> dict:
    """{case: [psnr, coverage difference]} for every case and technique."""
    results = {}
    base = base_cloud()
    zero = np.zeros(3)
    references = {t: render(base, zero, 1.0, t) for t in TECHNIQUES}
    cases = [(f"offset {o:.0e}", o * OFFSET_DIRECTION, 1.0) for o in (1e6, 1e7)]
    cases += [(f"scale {s:.0e}", zero, s) for s in (1e-12, 1e-9, 1e-6, 1e6, 1e9, 1e12, 1e18)]
    cases += [("offset 1e7, scale 1e-3", 1e7 * OFFSET_DIRECTION, 1e-3)]
    for name, offset, scale in cases:
        for technique in TECHNIQUES:
            try:
                frame = render(moved(base, offset, scale), offset, scale, technique)
                results[f"{name} | {technique}"] = compare(frame, references[technique])
            except Exception as error:  # the old code may refuse: record it
                results[f"{name} | {technique}"] = (float("nan"), f"error: {type(error).__name__}")
    try:   # the point-octree's LOD cut (1 px) at an offset against the cut at the origin
        far = 1e7 * OFFSET_DIRECTION
        reference = surfsplat.render(build_hierarchy(base), camera(zero, 1.0), technique="ewa")
        frame = surfsplat.render(build_hierarchy(moved(base, far, 1.0)), camera(far, 1.0), technique="ewa")
        results["hierarchy (LOD 1 px), offset 1e7 | ewa"] = compare(frame, reference)
    except Exception as error:
        results["hierarchy (LOD 1 px), offset 1e7 | ewa"] = (float("nan"), f"error: {type(error).__name__}")
    small = base_cloud(200, 80)
    local = np.round(small.positions.astype(np.float64), 3)
    with tempfile.TemporaryDirectory() as folder:
        far = np.round(1e7 * OFFSET_DIRECTION, 3)
        for label, offset in (("origin", zero), ("far", far)):
            write_las(Path(folder) / f"{label}.las", local + offset, offset)
            write_double_ply(Path(folder) / f"{label}.ply", small, offset)
        for suffix, what in ((".las", "LAS scale 1e-3, offset 1e7 (preprocessed)"),
                             (".ply", "PLY doubles, offset 1e7")):
            for technique in TECHNIQUES:
                try:
                    reference = render(str(Path(folder) / f"origin{suffix}"), zero, 1.0, technique)
                    frame = render(str(Path(folder) / f"far{suffix}"), far, 1.0, technique)
                    results[f"{what} | {technique}"] = compare(frame, reference)
                except Exception as error:
                    results[f"{what} | {technique}"] = (float("nan"), f"error: {type(error).__name__}")
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", default="after", help="the column these numbers go to (before / after)")
    args = parser.parse_args()
    machine = machine_description(renderer_name(default_renderer().ctx))
    results = measure()
    store = RESULTS / "precision.json"
    saved = json.loads(store.read_text()) if store.exists() else {"labels": {}}
    saved["machine"] = machine
    saved["labels"][args.label] = {k: [None if isinstance(v, float) and np.isnan(v) else v for v in pair]
                                   for k, pair in results.items()}   # inf (bit-equal) is stored as Infinity
    RESULTS.mkdir(exist_ok=True)
    store.write_text(json.dumps(saved, indent=1))
    labels = list(saved["labels"])
    columns = ["case", "technique"] + [f"{what} {label}" for label in labels
                                       for what in ("PSNR dB", "coverage diff px")]
    rows = []
    for case in saved["labels"][labels[-1]]:
        what, technique = case.split(" | ")
        row = [what, technique]
        for label in labels:
            psnr, coverage = saved["labels"][label].get(case, [None, None])
            row += ["-" if psnr is None else ("identical" if psnr > 200 else f"{psnr:.1f}"), coverage]
        rows.append(row)
    lines = [f"Machine: {machine}", f"{SIZE}x{SIZE} pixels, against the same model at the origin "
             "(PSNR of the 8-bit image; identical: bit-equal)", ""] + markdown_table(columns, rows)
    text = "\n".join(lines)
    print(text)
    (RESULTS / "precision.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
