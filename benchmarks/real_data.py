"""Real data in, the right picture out: the default path (`surfsplat render FILE -o out.png`) before/after.

For each input the command line renders it as a new user would, with nothing but the file name
(512 x 512), in this version and, with ``--before SRC`` (a checkout's ``src`` folder of an older
version, e.g. ``git worktree add /tmp/old 0228d24``), in that one, each in its own process:

* framing: the fraction of the image width and height the model's drawn pixels span, and of the
  pixels covered, with each version's automatic camera;
* against the mesh (where the input is one): both versions render with the same camera (this
  version's automatic one, passed as flags) and are compared with this version's
  ``render --mesh`` (4 x 4 supersampled) of the same camera: PSNR inside the mesh's
  silhouette eroded by 2 px, hole pixels there, leak pixels outside it grown by 2 px;
* splat sizes: the splats drawn (each version's model of the file: this version's prepared view,
  ``surfsplat.prepare``, its surface sampled for the automatic view where it is a mesh; an older
  version's ``api.load_model``), their largest and 99th-percentile radius over the
  median distance between neighbouring splat centers (distinct ones: coincident points skipped).

Inputs: featuretype.ply (CAD mesh), a triangle soup of it (PLY, every triangle its own vertices,
no normals), frag_115.ply (photogrammetric scan mesh), bunny.ply, simple.las (airborne LiDAR),
and a synthetic faulty scan (`surfsplat.scenes_faulty.faulty_scan`: stray points, clusters, scan
lines, a tree, duplicates) written as a raw-point PLY.

    python benchmarks/real_data.py [--before /tmp/old/src] [--images /tmp/real_data]

Writes benchmarks/results/real_data.md and .json; PNGs to --images.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine_description, write_table  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SRC = Path(__file__).resolve().parents[1] / "src"
SIZE = 512

STATS = """
import json, sys, warnings
import numpy as np
from scipy.spatial import cKDTree
warnings.simplefilter("ignore")
import surfsplat.api as api
path, flags = sys.argv[1], sys.argv[2:]
if hasattr(api, "prepare"):   # the view plan: the splats drawn for the automatic view (a mesh sampled for it)
    view = api.prepare(path)
    cloud = view.sample(view.camera(None, {size}, {size})).points()
else:
    model = api.load_model(path)
    if hasattr(api, "surface_model"):
        camera = api.resolve_camera(model, None, {size}, {size}, default_up=api.natural_up(path))
        model = api.surface_model(model, camera)
    cloud = api.model_points(model)
d, _ = cKDTree(cloud.positions).query(cloud.positions, k=2)
spacing = float(np.median(d[:, 1][d[:, 1] > 0]))   # duplicated points (split vertices) have none
r = cloud.radii
print(json.dumps({{"splats": len(cloud), "r_max": float(r.max()) / spacing,
                  "r_p99": float(np.percentile(r, 99)) / spacing}}))
"""


def cli(src: Path, new: bool, args: list, cwd: Path) -> subprocess.CompletedProcess:
    """Run a version's command line (``python -m surfsplat`` or, for old ones, ``surfsplat.cli``)."""
    env = dict(os.environ, PYTHONPATH=str(src))
    module = "surfsplat" if new else "surfsplat.cli"
    return subprocess.run([sys.executable, "-m", module, *map(str, args)], env=env, cwd=cwd, capture_output=True,
                          text=True, timeout=900)


def splat_stats(src: Path, path: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src))
    out = subprocess.run([sys.executable, "-c", STATS.format(size=SIZE), str(path)], env=env, capture_output=True,
                         text=True, timeout=900)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def image(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB")).astype(np.float64) / 255.0


def covered(img: np.ndarray) -> np.ndarray:
    return (img < 0.985).any(axis=2)   # white background


def framing(img: np.ndarray) -> tuple[float, float, float]:
    mask = covered(img)
    if not mask.any():
        return 0.0, 0.0, 0.0
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return (cols[-1] - cols[0] + 1) / img.shape[1], (rows[-1] - rows[0] + 1) / img.shape[0], float(mask.mean())


def against_truth(img: np.ndarray, truth: np.ndarray) -> tuple[float, int, int]:
    silhouette = covered(truth)
    inner = ndimage.binary_erosion(silhouette, iterations=2)
    outer = ndimage.binary_dilation(silhouette, iterations=2)
    mse = float(np.mean((img[inner] - truth[inner]) ** 2))
    psnr = 10 * np.log10(1.0 / mse) if mse > 0 else float("inf")
    return psnr, int((inner & ~covered(img)).sum()), int((covered(img) & ~outer).sum())


def inputs(folder: Path) -> list[tuple[str, Path, bool]]:
    """(name, file, has a mesh ground truth)."""
    soup = folder / "featuretype_soup.ply"
    mesh = trimesh.load(DATA / "featuretype.ply", process=False)
    tri = mesh.vertices[mesh.faces].reshape(-1, 3)
    trimesh.Trimesh(tri, np.arange(len(tri)).reshape(-1, 3), process=False).export(soup)
    faulty = folder / "faulty_scan.ply"
    env = dict(os.environ, PYTHONPATH=str(SRC))
    subprocess.run([sys.executable, "-c", "import sys; from surfsplat.scenes_faulty import faulty_scan; "
                    "from surfsplat.io import save_ply; from surfsplat import SplatCloud; "
                    "c = faulty_scan().cloud; "
                    "save_ply(SplatCloud(c.positions, colors=c.colors), sys.argv[1], overwrite=True)",
                    str(faulty)], env=env, check=True)
    return [("featuretype.ply (CAD mesh)", DATA / "featuretype.ply", True),
            ("featuretype soup (PLY)", soup, True),
            ("frag_115.ply (scan mesh)", DATA / "frag_115.ply", True),
            ("bunny.ply (scan mesh)", DATA / "bunny.ply", True),
            ("simple.las (LiDAR)", DATA / "simple.las", False),
            ("faulty scan (raw points)", faulty, False)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="src folder of the older version to compare with")
    parser.add_argument("--images", type=Path, default=Path(tempfile.gettempdir()) / "real_data")
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    versions = [("after", SRC, True)] + ([("before", args.before, False)] if args.before else [])
    rows = []
    for name, path, has_mesh in inputs(args.images):
        stem = path.stem
        # this version's automatic camera, as flags, shared by every comparison image
        auto = args.images / f"{stem}_after_auto.png"
        done = cli(SRC, True, ["render", path, "-o", auto, "--width", SIZE, "--height", SIZE, "--force"], args.images)
        if done.returncode:
            raise RuntimeError(done.stderr[-2000:])
        flags = next(line for line in done.stderr.splitlines() if line.startswith("camera: "))[8:].split()
        truth = None
        if has_mesh:
            truth_png = args.images / f"{stem}_truth.png"
            out = cli(SRC, True, ["render", path, "--mesh", "-o", truth_png, *flags, "--force"], args.images)
            if out.returncode:
                raise RuntimeError(out.stderr[-2000:])
            truth = image(truth_png)
        for version, src, new in versions:
            own = args.images / f"{stem}_{version}_auto.png"
            if not new:
                out = cli(src, False, ["-q", "render", path, "-o", own, "--width", SIZE, "--height", SIZE], args.images)
                if out.returncode:
                    raise RuntimeError(out.stderr[-2000:])
            width, height, filled = framing(image(own))
            psnr = holes = leaks = None
            if truth is not None:
                same = args.images / f"{stem}_{version}_same_camera.png"
                same_flags = [f for f in flags]
                extra = ["--force"] if new else []
                out = cli(src, new, ["-q", "render", path, "-o", same, *same_flags, *extra], args.images)
                if out.returncode:
                    raise RuntimeError(out.stderr[-2000:])
                psnr, holes, leaks = against_truth(image(same), truth)
            stats = splat_stats(src, path)
            rows.append([name, version, stats["splats"], round(stats["r_max"], 1), round(stats["r_p99"], 1),
                         round(100 * width), round(100 * height), round(100 * filled),
                         None if psnr is None else round(float(psnr), 1), holes, leaks])
            print(rows[-1], flush=True)
    columns = ["input", "version", "splats", "largest r / spacing", "p99 r / spacing", "width filled %",
               "height filled %", "pixels covered %", "PSNR inner dB", "holes", "leaks"]
    write_table("real_data", columns, rows, machine_description() + f", {SIZE}x{SIZE}, ewa, default options")


if __name__ == "__main__":
    main()
