"""Sharpness: PSNR on the contours and on the smooth parts, splats against the mesh's own rasterizer.

Ground truth: the mesh rendered 4 x 4 supersampled (``render_mesh``), same camera and lights (the default
headlight). Contour pixels: within ``CONTOUR_PX`` = 2 px of an intensity jump of the truth (4-neighbours
whose luminance differs by more than ``CONTOUR_JUMP``, or covered beside uncovered: silhouettes, creases,
occlusion edges, color edges); smooth pixels: the other pixels either image covers. Scored on the same
pixels: the mesh's own 1-sample rasterization (``render_mesh(..., supersample=1)``) and the default splat
picture of the mesh file (``surfsplat.prepare(path).render(camera)``: the mesh sampled for the view) for
each technique of ``--techniques``, with the variants of ``--variants``: the defaults before edge coverage
and automatic culling were (``before``: no edge coverage, back faces drawn), and each of them alone
(``no edge coverage``, ``two-sided``), hole filling off (``no fill``). ``--views N`` scores N orbit views
(the CAD part's pocket rims and thin walls are seen from every side) instead of the automatic camera.

Models: the Stanford bunny and the CAD part (``../shared/data``), and a finely detailed generated surface
(a sphere with 96 x 64 ridges of 2 % of its radius and color stripes a few pixels wide).

Columns: ``psnr``: every pixel; ``contour`` / ``smooth``: the two masks; ``contour share``: the share of
the squared error on the contour pixels; ``frame ms``: the splat frame's draw and read-back (the View's
time; the mesh's: its render call); ``coverage``: the summed alpha against the 4 x 4 truth's (silhouette
width, %).

A second table (``silhouettes``): unlit, the summed alpha of the default splat picture (what
``--transparent`` writes) against the mesh's (``--mesh``, 1 sample and 4 x 4) at 128 x 128 and 512 x 512,
with the targets: within 2 % of the mesh's pixels at 128 x 128, 0.5 % at 512 x 512.

    python benchmarks/contour_quality.py [--size 512] [--images /tmp/contour_quality]
        [--techniques ewa perspective blend phong] [--variants default before ...] [--views 1]

Writes benchmarks/results/contour_quality.md and .json; PNGs (not in the repo) go to ``--images``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, markdown_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import Lights, RenderOptions, VisibilityOptions  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.io.mesh import Mesh  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
#: Luminance step between 4-neighbours of the truth that makes a contour (colors in [0, 1]).
CONTOUR_JUMP = 0.1
#: Pixels around a jump in the contour mask.
CONTOUR_PX = 2
#: Rec. 709 luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: The splat variants: name -> RenderOptions.
VARIANTS = {
    "default": RenderOptions(),
    "before": RenderOptions(visibility=VisibilityOptions(edge_coverage=False, cull_backfaces=False)),
    "no edge coverage": RenderOptions(visibility=VisibilityOptions(edge_coverage=False)),
    "two-sided": RenderOptions(visibility=VisibilityOptions(cull_backfaces=False)),
    "no fill": RenderOptions(fill_holes=False),
}
#: Timed frames per picture (the best is kept; ``--repeat``).
REPEAT = 2
#: Silhouette targets: size -> largest |coverage - mesh's| in % of the mesh's (1 sample).
SILHOUETTE_TARGETS = {128: 2.0, 512: 0.5}


def detailed_surface(nu: int = 1536, nv: int = 768) -> Mesh:
    """A sphere of radius 1 with 96 x 64 ridges (2 % of the radius) and color stripes: fine detail on
    screen (a ridge every ~13 px, stripes ~6 px wide at 512 x 512). Open at the poles (latitude +-87
    degrees)."""
    lon = np.linspace(0.0, 2 * np.pi, nu, endpoint=False)
    lat = np.linspace(-np.radians(87), np.radians(87), nv)
    lon_g, lat_g = np.meshgrid(lon, lat, indexing="ij")
    r = 1.0 + 0.02 * np.sin(96 * lon_g / 2) * np.sin(64 * lat_g)
    p = np.stack([r * np.cos(lat_g) * np.cos(lon_g), r * np.sin(lat_g), r * np.cos(lat_g) * np.sin(lon_g)], -1)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv - 1), indexing="ij")
    a, b = i * nv + j, ((i + 1) % nu) * nv + j
    faces = np.concatenate([np.stack([a, a + 1, b + 1], -1).reshape(-1, 3), np.stack([a, b + 1, b], -1).reshape(-1, 3)])
    stripe = (np.sin(40 * lon_g + 6 * np.sin(5 * lat_g)) > 0.3).astype(np.float32)
    colors = np.stack([0.85 - 0.5 * stripe, 0.75 - 0.2 * stripe, 0.55 + 0.3 * stripe], -1)
    return Mesh(p.reshape(-1, 3).astype(np.float32), faces.astype(np.int64),
                vertex_colors=colors.reshape(-1, 3).astype(np.float32))


#: The models scored (``--models``); empty: all.
MODELS: list[str] = []


def models() -> list[tuple[str, object]]:
    """(name, mesh source) of the models: the files where the data is there, and the generated one
    (those of :data:`MODELS` where it names some)."""
    items: list[tuple[str, object]] = []
    for name, file in (("bunny", "bunny.ply"), ("CAD part", "featuretype.ply")):
        if (DATA / file).exists():
            items.append((name, DATA / file))
    items.append(("detailed surface", detailed_surface()))
    return [item for item in items if not MODELS or item[0] in MODELS]


def contour_mask(truth) -> np.ndarray:
    """(H, W) bool: within CONTOUR_PX of a luminance jump or a coverage edge of the truth."""
    lum = truth.color @ LUMA
    covered = truth.alpha > 0
    jump = np.zeros(lum.shape, bool)
    for axis in (0, 1):
        d = np.abs(np.diff(lum, axis=axis)) > CONTOUR_JUMP
        d |= np.diff(covered.astype(np.int8), axis=axis) != 0
        if axis == 0:
            jump[:-1] |= d
            jump[1:] |= d
        else:
            jump[:, :-1] |= d
            jump[:, 1:] |= d
    return ndimage.binary_dilation(jump, iterations=CONTOUR_PX)


def psnr(err2: np.ndarray, mask: np.ndarray) -> float:
    """PSNR (dB, peak 1) of the per-pixel squared errors (summed over channels) on ``mask``."""
    mse = err2[mask].mean() / 3.0 if mask.any() else 0.0
    return round(float(10 * np.log10(1.0 / mse)), 2) if mse > 0 else float("inf")


def score(frame, truth, contour: np.ndarray) -> dict:
    """The columns of one picture against the truth."""
    err2 = ((np.clip(frame.color, 0, 1) - np.clip(truth.color, 0, 1)) ** 2).sum(axis=-1)
    covered = (frame.alpha > 0) | (truth.alpha > 0)
    smooth = covered & ~contour
    total = err2.sum()
    return {"psnr": psnr(err2, np.ones_like(contour)), "contour": psnr(err2, contour), "smooth": psnr(err2, smooth),
            "contour share": round(float(err2[contour].sum() / total), 3) if total > 0 else 0.0,
            "coverage": round(float(100 * (frame.alpha.sum() / truth.alpha.sum() - 1)), 2)}


def save_png(frame, path: Path) -> None:
    Image.fromarray((np.clip(frame.color, 0, 1) * 255 + 0.5).astype(np.uint8)).save(path)


def quality_rows(size: int, variants: list[str], techniques: list[str], views: int, images: Path) -> list[list]:
    rows = []
    for name, source in models():
        mesh = load_mesh(source) if isinstance(source, Path) else source
        view = surfsplat.prepare(mesh)
        cameras = [view.camera(None, size, size)] if views == 1 else view.orbit(None, views, width=size, height=size)
        for v, camera in enumerate(cameras):
            truth = surfsplat.render_mesh(mesh, camera, supersample=4)
            contour = contour_mask(truth)
            slug = name.replace(" ", "_") + (f"_{v}" if views > 1 else "")
            label = "" if views == 1 else f" {v}"
            save_png(truth, images / f"{slug}_truth.png")
            Image.fromarray((contour * 255).astype(np.uint8)).save(images / f"{slug}_contour.png")
            start = time.perf_counter()
            mesh1 = surfsplat.render_mesh(mesh, camera, supersample=1)
            mesh_ms = round(1000 * (time.perf_counter() - start))
            save_png(mesh1, images / f"{slug}_mesh1.png")
            s = score(mesh1, truth, contour)
            rows.append([name + label, "mesh, 1 sample", "", s["psnr"], s["contour"], s["smooth"], s["contour share"],
                         s["coverage"], mesh_ms, int(contour.sum())])
            print(rows[-1], flush=True)
            for technique in techniques:
                for variant in variants:
                    options = VARIANTS[variant]
                    view.render(camera, technique=technique, options=options)   # warm: sampling, upload, programs
                    result = min((view.render(camera, technique=technique, options=options)
                                  for _ in range(REPEAT)), key=lambda r: r.seconds)
                    save_png(result.frame, images / f"{slug}_{technique}_{variant.replace(' ', '_')}.png")
                    s = score(result.frame, truth, contour)
                    rows.append([name + label, f"{technique} ({result.splats:,}), {variant}",
                                 "culled" if view.culls(camera, options, technique) else "two-sided", s["psnr"],
                                 s["contour"],
                                 s["smooth"], s["contour share"], s["coverage"], round(1000 * result.seconds),
                                 int(contour.sum())])
                    print(rows[-1], flush=True)
    return rows


def silhouette_rows(sizes: list[int]) -> list[list]:
    """Unlit coverage (summed alpha) of the default splat picture against the mesh's, per size."""
    unlit = Lights(enabled=False)
    rows = []
    for name, source in models():
        if name == "detailed surface":
            continue
        mesh = load_mesh(source) if isinstance(source, Path) else source
        for size in sizes:
            view = surfsplat.prepare(mesh)   # sampled for this size (a View samples for its first camera)
            camera = view.camera(None, size, size)
            mesh1 = surfsplat.render_mesh(mesh, camera, lights=unlit, supersample=1).alpha.sum()
            mesh4 = surfsplat.render_mesh(mesh, camera, lights=unlit, supersample=4).alpha.sum()
            for variant in ("default", "no edge coverage", "before"):
                splat = view.render(camera, lights=unlit, options=VARIANTS[variant]).frame.alpha.sum()
                off = float(100 * (splat / mesh1 - 1))
                rows.append([name, size, variant, round(float(mesh1)), round(float(mesh4)), round(float(splat)),
                             round(off, 2), round(float(100 * (splat / mesh4 - 1)), 2),
                             f"{'met' if abs(off) <= SILHOUETTE_TARGETS.get(size, 0.5) else 'missed'} "
                             f"(<= {SILHOUETTE_TARGETS.get(size, 0.5):g} %)" if variant == "default" else ""])
                print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--techniques", nargs="+", default=["ewa", "perspective", "blend", "phong"],
                        choices=["ewa", "perspective", "blend", "phong", "flat"])
    parser.add_argument("--repeat", type=int, default=2, help="timed frames per picture (the best is kept)")
    parser.add_argument("--views", type=int, default=1, help="orbit views per model (1: the automatic camera)")
    parser.add_argument("--output", default="contour_quality", help="results name (benchmarks/results/NAME.md)")
    parser.add_argument("--silhouette-sizes", type=int, nargs="*", default=[128, 512])
    parser.add_argument("--models", nargs="+", default=None, help="model names (default: all)")
    parser.add_argument("--images", type=Path, default=Path("/tmp/contour_quality"))
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    if args.models:
        MODELS[:] = args.models
    global REPEAT
    REPEAT = args.repeat
    quality = quality_rows(args.size, args.variants, args.techniques, args.views, args.images)
    silhouettes = silhouette_rows(args.silhouette_sizes) if args.silhouette_sizes else []
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    date = time.strftime("%Y-%m-%d")
    command = "python benchmarks/contour_quality.py " + shlex.join(sys.argv[1:])
    q_cols = ["model", "picture", "back faces", "psnr", "contour", "smooth", "contour share", "coverage %", "frame ms",
              "contour px"]
    s_cols = ["model", "size", "splats", "mesh 1 sample", "mesh 4x4", "splats (summed alpha)", "vs mesh 1 %",
              "vs mesh 4x4 %", "target"]
    text = "\n".join([f"Machine: {machine}", f"Date: {date}", f"Command: `{command.strip()}`", "",
                      f"## Contours and smooth parts, {args.size} x {args.size}, against the 4 x 4 mesh", ""]
                     + markdown_table(q_cols, quality)
                     + (["", "## Silhouettes, unlit: summed alpha against the mesh's", ""]
                        + markdown_table(s_cols, silhouettes) if silhouettes else []))
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.output}.md").write_text(text + "\n")
    (RESULTS / f"{args.output}.json").write_text(json.dumps(
        {"machine": machine, "date": date, "command": command.strip(), "quality": {"columns": q_cols, "rows": quality},
         "silhouettes": {"columns": s_cols, "rows": silhouettes}}, indent=1))


if __name__ == "__main__":
    main()
