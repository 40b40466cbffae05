"""What limits fine detail: the default splat picture of a finely detailed surface against variants of its
sample spacing, splat radius, EWA prefilter width and cutoff, and against the mesh's own rasterizer.

Scored like ``benchmarks/contour_quality.py`` (512 x 512, the default camera and headlight, against the mesh
4 x 4 supersampled; ``contour`` / ``smooth`` pixel masks, ``psnr`` over every pixel), with the hole pixels
(inside the truth's silhouette eroded by 2 px, no splat; ``kernel_sizing.inner_holes``). Every picture is
the View's (``surfsplat.prepare(mesh).render(camera, options=...)``: samples for the view, culling, edge
coverage and hole filling as by default) but for the variant's one change:

* ``spacing S px`` / ``N samples``: ``SourceOptions(spacing_px=S)`` (capped at 2 M samples,
  ``geometry.sampling.MAX_SAMPLES``) or ``SourceOptions(samples=N)`` (no cap);
* ``radius R spacings``: the smooth mesh samples' radius (default 1.76 mean spacings, 2.0 x 1.1 / 1.25),
  set through ``geometry.sampling.SPACING_COVERAGE`` for the run (not an option): every radius x 0.8
  (a mesh with sharp edges, the CAD part: 1.6 spacings instead of 2.0; its slivers keep 2.3);
* ``prefilter H px^2``: the EWA prefilter's variance (Zwicker 2004's unit-variance low-pass is 1), set
  through ``rendering.technique.prefilter_variance`` for the run (the option is only on / off);
* ``cutoff c``: ``FilterOptions(cutoff=c)``.

Rows ``truth blurred sigma``: the truth itself low-passed by a Gaussian of ``sigma`` pixels, scored the same
way: the splat picture's blur in pixels of an equivalent Gaussian.

    python benchmarks/detail_limits.py [--models "detailed surface" bunny "CAD part"] [--images /tmp/detail]

Writes benchmarks/results/detail_limits.md and .json; PNGs (not in the repo) go to ``--images``.
"""

from __future__ import annotations

import argparse
import contextlib
import shlex
import sys
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, markdown_table, save_results  # noqa: E402
from contour_quality import contour_mask, models, save_png, score  # noqa: E402
from kernel_sizing import inner_holes  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import FilterOptions, RenderOptions  # noqa: E402
from surfsplat.geometry import sampling  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.pipeline.options import SourceOptions  # noqa: E402
from surfsplat.rendering import technique  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

#: The smooth samples' radius in mean spacings per SPACING_COVERAGE (SAMPLE_COVERAGE / CIRCLE_COVERAGE).
SMOOTH_RATIO = 1.1 / 1.25
#: Variants: label -> (source options, render options, prefilter variance px^2, SPACING_COVERAGE); None: default.
VARIANTS: dict[str, tuple] = {
    "default": (None, RenderOptions(), None, None),
    "prefilter 0.5 px^2": (None, RenderOptions(), 0.5, None),
    "prefilter 0.25 px^2": (None, RenderOptions(), 0.25, None),
    "prefilter off": (None, RenderOptions(filter=FilterOptions(prefilter=False)), None, None),
    "cutoff c = 2": (None, RenderOptions(filter=FilterOptions(cutoff=2.0)), None, None),
    "radius 1.41 spacings": (None, RenderOptions(), None, 1.6),
    "radius 1.41 spacings, prefilter 0.25": (None, RenderOptions(), 0.25, 1.6),
    "spacing 0.5 px (2 M cap)": (SourceOptions(spacing_px=0.5), RenderOptions(), None, None),
    "3.3 M samples (0.5 px)": (SourceOptions(samples=3_300_000), RenderOptions(), None, None),
    "3.3 M samples, prefilter 0.25": (SourceOptions(samples=3_300_000), RenderOptions(), 0.25, None),
}
#: Gaussian widths (pixels) of the blurred-truth rows.
SIGMAS = (0.5, 0.75, 1.0, 1.25)


@contextlib.contextmanager
def overridden(prefilter: float | None, coverage: float | None):
    """The prefilter variance and the samples' SPACING_COVERAGE replaced for the block (None: kept)."""
    old_prefilter, old_coverage = technique.prefilter_variance, sampling.SPACING_COVERAGE
    if prefilter is not None:
        technique.prefilter_variance = lambda on: prefilter  # type: ignore[assignment]
    if coverage is not None:
        sampling.SPACING_COVERAGE = coverage
    try:
        yield
    finally:
        technique.prefilter_variance, sampling.SPACING_COVERAGE = old_prefilter, old_coverage


class Picture:
    """A color and alpha pair scored like a frame."""

    def __init__(self, color: np.ndarray, alpha: np.ndarray) -> None:
        self.color, self.alpha = color, alpha


def rows_for(name: str, mesh, size: int, variants: list[str], repeat: int, images: Path) -> list[list]:
    view = surfsplat.prepare(mesh)
    camera = view.camera(None, size, size)
    truth = surfsplat.render_mesh(mesh, camera, supersample=4)
    contour = contour_mask(truth)
    slug = name.replace(" ", "_")
    start = time.perf_counter()
    mesh1 = surfsplat.render_mesh(mesh, camera, supersample=1)
    s = score(mesh1, truth, contour)
    rows = [[name, "mesh, 1 sample", "", s["psnr"], s["contour"], s["smooth"], inner_holes(mesh1, truth),
             round(1000 * (time.perf_counter() - start))]]
    print(rows[-1], flush=True)
    for sigma in SIGMAS:
        s = score(Picture(ndimage.gaussian_filter(truth.color, (sigma, sigma, 0)), truth.alpha), truth, contour)
        rows.append([name, f"truth blurred sigma {sigma:g} px", "", s["psnr"], s["contour"], s["smooth"], "", ""])
        print(rows[-1], flush=True)
    for label in variants:
        source, options, prefilter, coverage = VARIANTS[label]
        with overridden(prefilter, coverage):
            v = view if source is None and coverage is None else surfsplat.prepare(mesh, source_options=source)
            v.render(camera, options=options)   # warm: sampling, upload, programs
            result = min((v.render(camera, options=options) for _ in range(repeat)), key=lambda r: r.seconds)
        save_png(result.frame, images / f"{slug}_{label.replace(' ', '_').replace('/', '-')}.png")
        s = score(result.frame, truth, contour)
        rows.append([name, label, result.splats, s["psnr"], s["contour"], s["smooth"],
                     inner_holes(result.frame, truth), round(1000 * result.seconds)])
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=2, help="timed frames per picture (the best is kept)")
    parser.add_argument("--models", nargs="+", default=["detailed surface", "bunny", "CAD part"])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--other-variants", nargs="+", default=["default", "prefilter 0.5 px^2",
                                                                "prefilter 0.25 px^2", "radius 1.41 spacings",
                                                                "3.3 M samples (0.5 px)"],
                        choices=list(VARIANTS), help="the variants of the models other than the detailed surface")
    parser.add_argument("--images", type=Path, default=Path("/tmp/detail_limits"))
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    rows: list[list] = []
    for name, source in models():
        if name not in args.models:
            continue
        mesh = load_mesh(source) if isinstance(source, Path) else source
        rows += rows_for(name, mesh, args.size, args.variants if name == "detailed surface" else args.other_variants,
                         args.repeat, args.images)
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    date = time.strftime("%Y-%m-%d")
    command = "python benchmarks/detail_limits.py " + shlex.join(sys.argv[1:])
    columns = ["model", "picture", "splats", "psnr", "contour", "smooth", "hole px", "frame ms"]
    text = "\n".join([f"Machine: {machine}", f"Date: {date}", f"Command: `{command.strip()}`", "",
                      f"{args.size} x {args.size}, ewa, headlight, against the 4 x 4 mesh "
                      "(dB; hole px: inside the truth's silhouette, no splat).", ""]
                     + markdown_table(columns, rows))
    save_results("detail_limits", text + "\n", {"machine": machine, "date": date, "command": command.strip(),
                                         "columns": columns, "rows": rows})


if __name__ == "__main__":
    main()
