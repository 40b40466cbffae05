"""Fringe clipping: `ewa` with the papers' full prefiltered footprints against footprints that end at the
surface (`VisibilityOptions.clip_fringe`), against the 4x4-supersampled mesh.

Models: the bunny (400,000 surface splats) and the folded sheet with a knot of
`benchmarks/edge_quality.py`; 512x512, the automatic camera of the mesh's vertices; K = 1 and 2.
Metrics from `edge_quality.scores`: PSNR over both silhouettes, the whole image, the interior
(eroded 2 px), SSIM, and PSNR on edge pixels (within 2 px of a depth jump of the truth).

    python benchmarks/fringe_clip.py

Writes benchmarks/results/fringe_clip.md and .json.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import surfsplat  # noqa: E402
from common import machine_description, write_table  # noqa: E402
from edge_quality import edge_mask, procedural, scores  # noqa: E402
from surfsplat.geometry.sampling import surface_splats  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.rendering.context import renderer_name  # noqa: E402
from surfsplat.rendering.options import RenderOptions, VisibilityOptions  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SIZE = 512


def main() -> None:
    renderer = default_renderer()
    rows = []
    for name, mesh in (("bunny", load_mesh(DATA / "bunny.ply")), ("folded sheet + knot", procedural()[1])):
        camera = surfsplat.auto_camera(surfsplat.SplatCloud(mesh.vertices), SIZE, SIZE)
        truth = surfsplat.render_mesh(mesh, camera, supersample=4)
        splats = surface_splats(mesh, 400_000)
        edges = edge_mask(truth)
        for clip in (False, True):
            for k in (1, 2):
                options = RenderOptions(visibility=VisibilityOptions(clip_fringe=clip))
                frame = renderer.render(splats, camera, "ewa", surfsplat.Lights(), options, supersample=k)
                s = {key: float(value) for key, value in scores(frame, truth, edges).items()
                     if isinstance(value, (float, np.floating))}
                rows.append([name, "clipped" if clip else "full (papers)", k, round(s["psnr"], 2),
                             round(s["psnr_img"], 2), round(s["psnr_inner"], 2), round(s["ssim"], 3),
                             round(s["psnr_edge"], 2)])
                print(rows[-1], flush=True)
    write_table("fringe_clip", ["model", "footprints", "K", "PSNR silhouettes", "PSNR image", "PSNR interior",
                                "SSIM", "PSNR edges"], rows,
                machine_description(renderer_name(renderer.ctx)) + f", {SIZE}x{SIZE}, ewa")


if __name__ == "__main__":
    main()
