"""Meshes are surfaces: vertices as splats against the sampled surface, and the density rule.

For each mesh the ground truth is ``surfsplat.rendering.mesh.render_mesh`` of the mesh (what
``surfsplat.render_mesh`` draws) with the automatic camera of its vertices
(``surfsplat.auto_camera(SplatCloud(mesh.vertices))``, as ``surfsplat.api.render_mesh`` frames
it); the splat images use the same camera, technique "ewa", default lights. Metrics from
``surfsplat.metrics.compare``: PSNR over both silhouettes ("psnr", counts the silhouette rim)
and inside the ground truth's silhouette eroded by 2 px ("psnr_inner"), hole pixels inside that
eroded silhouette, leak pixels outside the silhouette grown by 2 px.

Cases:

* featuretype.ply as given (a CAD part, vertices split at creases, stored face normals);
* a triangle soup of it (every triangle with its own 3 vertices, no normals), written as a
  binary STL file, as CAD systems export;
* frag_115.ply (scan with colors and normals); bunny.ply (scan without normals).

Tables: (1) vertices as splats (the file read with ``surfsplat.io.load`` and preprocessed
with k = 8, what ``surfsplat.render(path)`` drew before meshes were sampled) against the
sampled surface (``surfsplat.geometry.sampling.surface_splats`` at the default density) at
512 x 512; (2) the density sweep: sample spacing on screen (pixels, at the mesh's center)
against PSNR, holes, leaks and time at 512 and 1024 pixels; (3) dihedral-angle
distributions and the automatic sharp angle; (4) the density rule without a camera against
the automatic view's; (5) how much the ground truth of a mesh without normals (the bunny)
changed with crease-aware (angle-weighted) normals.

    python benchmarks/mesh_sampling.py [--quick] [--images /tmp/mesh_sampling]

Writes benchmarks/results/mesh_sampling.md and .json; PNGs go to ``--images`` (not the repo).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, fmt, machine_description, markdown_table  # noqa: E402

from surfsplat import SplatCloud, metrics  # noqa: E402
from surfsplat.pipeline import as_splats, auto_camera  # noqa: E402
from surfsplat.geometry.sampling import (DEFAULT_SPACING_PX, MAX_SAMPLES, samples_for_pixels,  # noqa: E402
                                         surface_splats, view_spacing)
from surfsplat.io import load, load_input, load_mesh  # noqa: E402
from surfsplat.io.mesh import Mesh, area_weighted_normals  # noqa: E402
from surfsplat.io.surface import CREASE_BAND, auto_sharp_angle, dihedral_angles  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402
from surfsplat.rendering.mesh import render_mesh  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SPACINGS = (4.0, 2.0, 1.5, 1.0, 0.75, 0.5)
SIZES = (512, 1024)


def save_png(frame, path: Path) -> None:
    Image.fromarray((np.clip(frame.color, 0, 1) * 255 + 0.5).astype(np.uint8)).save(path)


def soup_file(folder: Path) -> Path:
    """featuretype.ply as a triangle soup in a binary STL file (every triangle its own 3 vertices)."""
    mesh = load_mesh(DATA / "featuretype.ply")
    soup = trimesh.Trimesh(mesh.vertices[mesh.faces.reshape(-1)], np.arange(3 * len(mesh.faces)).reshape(-1, 3),
                           process=False)
    path = folder / "featuretype_soup.stl"
    soup.export(path)
    return path


def camera_of(mesh: Mesh, size: int):
    return auto_camera(SplatCloud(mesh.vertices), size, size)


def scores(frame, truth) -> dict:
    c = metrics.compare(frame, truth)
    return {"psnr": round(c["psnr"], 2), "psnr_inner": round(c["psnr_inner"], 2), "ssim": round(c["ssim"], 4),
            "holes": c["holes"], "leaks": c["leaks"]}


def sampled(mesh: Mesh, camera, pixels: float, renderer) -> tuple[dict, object]:
    n = samples_for_pixels(mesh, pixels, camera=camera)
    start = time.perf_counter()
    splats = surface_splats(mesh, n)
    sample_s = time.perf_counter() - start
    start = time.perf_counter()
    frame = renderer.render(splats, camera, "ewa", Lights())
    render_s = time.perf_counter() - start
    return {"n": n, "sample_s": round(sample_s, 2), "render_s": round(render_s, 2)}, frame


def comparison(cases: dict, renderer, images: Path) -> list[dict]:
    rows = []
    for name, path in cases.items():
        mesh = load_input(path)
        raw = load_mesh(path)
        camera = camera_of(raw, 512)
        truth = render_mesh(mesh, camera, renderer=renderer)
        save_png(truth, images / f"{name}_truth.png")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # bunny: unused vertices dropped
            start = time.perf_counter()
            vertices = as_splats(load(path))
            prep_s = time.perf_counter() - start
        frame = renderer.render(vertices, camera, "ewa", Lights())
        save_png(frame, images / f"{name}_vertices.png")
        rows.append({"mesh": name, "splats": "vertices", "n": len(vertices), "sample_s": round(prep_s, 2)}
                    | scores(frame, truth))
        info, frame = sampled(mesh, camera, DEFAULT_SPACING_PX, renderer)
        save_png(frame, images / f"{name}_sampled.png")
        rows.append({"mesh": name, "splats": f"surface, {DEFAULT_SPACING_PX:g} px"} | info | scores(frame, truth))
        print(rows[-2], "\n", rows[-1], flush=True)
    return rows


def sweep(names: dict, spacings, sizes, renderer, images: Path) -> list[dict]:
    rows = []
    for name, path in names.items():
        mesh = load_input(path)
        for size in sizes:
            camera = camera_of(mesh, size)
            truth = render_mesh(mesh, camera, renderer=renderer)
            for pixels in spacings:
                info, frame = sampled(mesh, camera, pixels, renderer)
                # the spacing the capped count actually gives, pixels at the mesh's center
                actual = float(np.sqrt(mesh.face_areas().sum() / info["n"]) / view_spacing(mesh, camera, 1.0))
                rows.append({"mesh": name, "size": size, "spacing_px": pixels, "actual_px": round(actual, 2)}
                            | info | scores(frame, truth))
                if size == 512:
                    save_png(frame, images / f"{name}_{size}_{pixels:g}px.png")
                print(rows[-1], flush=True)
    return rows


def dihedral_table(names: dict) -> list[dict]:
    rows = []
    bands = [(0, 5), (5, 15), (15, 20), (20, 30), (30, 40), (40, 60), (60, 180)]
    for name, path in names.items():
        mesh = load_input(path)
        angles, lengths = dihedral_angles(mesh)
        ok = np.isfinite(angles)
        angles, lengths = angles[ok], lengths[ok]
        total = lengths.sum()
        row = {"mesh": name, "edges": len(angles)}
        for lo, hi in bands:
            row[f"{lo}-{hi}"] = round(100 * float(lengths[(angles > lo) & (angles <= hi)].sum() / total), 3)
        lo, hi = CREASE_BAND
        band = lengths[(angles > lo) & (angles <= hi)].sum()
        sharp = lengths[angles > hi].sum()
        row["above 40 / above 20"] = round(float(sharp / max(band + sharp, 1e-300)), 3)
        row["auto sharp angle"] = auto_sharp_angle(mesh)
        rows.append(row)
    return rows


def camera_free_rule(names: dict) -> list[dict]:
    """The count without a camera (diagonal spans the image) against the automatic view's, 512 px."""
    rows = []
    for name, path in names.items():
        mesh = load_input(path)
        with_camera = samples_for_pixels(mesh, DEFAULT_SPACING_PX, camera=camera_of(mesh, 512), max_samples=10**9)
        without = samples_for_pixels(mesh, DEFAULT_SPACING_PX, image_size=512, max_samples=10**9)
        rows.append({"mesh": name, "n (auto camera)": with_camera, "n (no camera)": without,
                     "ratio": round(without / with_camera, 2)})
    return rows


def truth_change(renderer) -> list[dict]:
    """The bunny's ground truth with crease-aware normals against the area-weighted normals it had."""
    mesh = load_mesh(DATA / "bunny.ply")
    before = Mesh(mesh.vertices, mesh.faces, vertex_normals=area_weighted_normals(mesh.vertices, mesh.faces))
    rows = []
    for size in SIZES:
        camera = camera_of(mesh, size)
        old = render_mesh(before, camera, renderer=renderer)
        for angle in ("auto", 30.0, 45.0, 60.0):
            new = render_mesh(mesh, camera, sharp_angle=angle, renderer=renderer)
            both = old.mask | new.mask
            changed = int((np.abs(new.color - old.color).max(axis=2) > 1 / 255).sum())
            rows.append({"size": size, "sharp_angle": angle, "psnr": round(metrics.psnr(new.color, old.color, both), 2),
                         "pixels changed": changed, "of": int(both.sum())})
    return rows


def table(rows: list[dict], columns: list[str]) -> list[str]:
    return markdown_table(columns, [[r.get(c, "") for c in columns] for r in rows])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="512 px only, three spacings")
    parser.add_argument("--images", type=Path, default=Path(tempfile.gettempdir()) / "mesh_sampling")
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    renderer = default_renderer()
    machine = machine_description(renderer.ctx.info.get("GL_RENDERER"))
    with tempfile.TemporaryDirectory() as tmp:
        cases = {"featuretype": DATA / "featuretype.ply", "featuretype soup (STL)": soup_file(Path(tmp)),
                 "frag_115": DATA / "frag_115.ply", "bunny": DATA / "bunny.ply"}
        compared = comparison(cases, renderer, args.images)
    meshes = {k: DATA / f"{k}.ply" for k in ("featuretype", "bunny", "frag_115")}
    spacings = (2.0, 1.0, 0.5) if args.quick else SPACINGS
    swept = sweep(meshes, spacings, (512,) if args.quick else SIZES, renderer, args.images)
    dihedral = dihedral_table(meshes)
    rule = camera_free_rule(meshes)
    change = truth_change(renderer)

    score_cols = ["psnr", "psnr_inner", "ssim", "holes", "leaks"]
    notes = ["Ground truth: render_mesh of the mesh (4x4 supersampled), same automatic camera (the mesh's "
             "vertices), ewa, default lights. psnr: over both silhouettes (mostly the silhouette rim: EWA "
             "splats are not antialiased there and reach ~1 px past the mesh's outline); psnr_inner: inside "
             "the ground truth's silhouette eroded by 2 px; holes: uncovered pixels there; leaks: covered "
             "pixels outside the silhouette grown by 2 px. Vertices: the file read with surfsplat.io.load "
             "and preprocessed (k = 8), as surfsplat.render(path) drew meshes before surface sampling. "
             "sample_s: sampling, welding, normals, sizes and clip lines (vertices: preprocessing); "
             "render_s: drawing and read-back."]
    lines = [f"Machine: {machine}", f"Date: {time.strftime('%Y-%m-%d')}", ""] + notes + ["",
             f"## Vertices as splats against the sampled surface (512 x 512, ewa, default spacing "
             f"{DEFAULT_SPACING_PX:g} px, cap {MAX_SAMPLES:,})", ""]
    lines += table(compared, ["mesh", "splats", "n", "sample_s"] + score_cols)
    lines += ["", "## Density sweep: sample spacing on screen (pixels at the mesh's center)", ""]
    lines += table(swept, ["mesh", "size", "spacing_px", "actual_px", "n", "sample_s", "render_s"] + score_cols)
    lines += ["", "## Dihedral angles: % of edge length per band (degrees), and the automatic sharp angle", ""]
    lines += table(dihedral, list(dihedral[0].keys()))
    lines += ["", f"## The density rule without a camera (bounding-box diagonal = 512 px) against the automatic "
              f"512-px view, {DEFAULT_SPACING_PX:g} px, uncapped", ""]
    lines += table(rule, list(rule[0].keys()))
    lines += ["", "## Ground truth of the bunny (no stored normals): crease-aware against area-weighted normals", ""]
    lines += table(change, ["size", "sharp_angle", "psnr", "pixels changed", "of"])
    text = "\n".join(lines)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "mesh_sampling.md").write_text(text + "\n")
    (RESULTS / "mesh_sampling.json").write_text(json.dumps(
        {"machine": machine, "date": time.strftime("%Y-%m-%d"), "default_spacing_px": DEFAULT_SPACING_PX,
         "max_samples": MAX_SAMPLES, "comparison": compared, "sweep": swept, "dihedral": dihedral,
         "camera_free_rule": rule, "truth_change": change}, indent=1, default=fmt))


if __name__ == "__main__":
    main()
