"""The mesh samples' splat radius factor, old default against new, on the default renders of every
model at several image sizes: holes, PSNR against the mesh, overlap and frame time.

For each model and ``--sizes`` (128, 512, 1024): the view plan's automatic camera, ``View.sample``'s
splats for that camera (circles of radius ``SAMPLE_COVERAGE`` times the distance to the k-th sample,
``CREASED_SAMPLE_COVERAGE`` on a mesh with sharp edges),
rescaled to each factor of ``--factors`` (the axes scaled, clip lines kept in place: the same as
sampling with that factor), drawn with ``ewa`` and the options ``View.render`` uses (back faces culled
where ``View.culls`` culls), hole filling on. Truth: the mesh 4 x 4 supersampled (``render_mesh``).

Columns as in benchmarks/kernel_sizing.py: ``frame ms`` (best of ``--repeat``; a shared machine: compare
rows of one model and size), ``overlap`` (splats a covered pixel lies under), ``psnr`` / ``contour`` /
``smooth`` (dB), ``holes`` (pixels inside the truth's silhouette eroded 2 px left uncovered), ``holes
without fill``, ``fill`` (pixels the hole filling filled).

    python benchmarks/kernel_defaults.py [--sizes 128 512 1024] [--factors 1.25 1.1] [--images DIR]

Writes benchmarks/results/kernel_defaults.md and .json; PNGs go to ``--images`` (not the repo).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, markdown_table, save_results  # noqa: E402
from contour_quality import DATA, contour_mask, detailed_surface  # noqa: E402
from kernel_sizing import measure, scaled  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import RenderOptions  # noqa: E402
from surfsplat.geometry.splats import CREASED_SAMPLE_COVERAGE, SAMPLE_COVERAGE  # noqa: E402
from surfsplat.io.surface import auto_sharp_angle, weld  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.rendering.options import VisibilityOptions  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

#: The peers' torus mesh (``../shared/peers/bench.py --work DIR`` writes it), where it is there.
PEERS_WORK = Path(os.environ.get("SURFSPLAT_PEERS_WORK", "/tmp/peers-data"))


def mixed(cloud, base: float, factor: float, clipped_factor: float):
    """The cloud's splats (sized at ``base`` h_k) at ``factor`` h_k, those with clip lines at
    ``clipped_factor``."""
    if cloud.clip_lines is None:
        return scaled(cloud, factor / base)
    clipped = np.any(cloud.clip_lines[:, :, :2] != 0, axis=(1, 2))
    f = np.where(clipped, clipped_factor, factor).astype(np.float32)[:, None] / np.float32(base)
    lines = cloud.clip_lines.copy()
    lines[:, :, :2] *= f[:, :, None]
    return cloud.replace(u=cloud.u * f, v=cloud.v * f, clip_lines=lines)


def meshes(names: list[str]) -> list[tuple[str, object]]:
    """(name, Mesh) of the models there are (those of ``names`` where it names some): the data's bunny, CAD
    part and scan mesh, the detailed surface, the peers' torus."""
    items = [(name, load_mesh(DATA / file)) for name, file in (("bunny", "bunny.ply"), ("CAD part", "featuretype.ply"),
                                                              ("scan mesh", "frag_115.ply"))
             if (DATA / file).exists() and (not names or name in names)]
    items.append(("detailed surface", detailed_surface()))
    if (PEERS_WORK / "torus_mesh.ply").exists():
        items.append(("torus", load_mesh(PEERS_WORK / "torus_mesh.ply")))
    return [item for item in items if not names or item[0] in names]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 512, 1024])
    parser.add_argument("--factors", type=float, nargs="+", default=[1.25, 1.1],
                        help="radius factors (times h_k) to compare")
    parser.add_argument("--mixed", type=float, nargs=2, action="append", default=[], metavar=("FACTOR", "CLIPPED"),
                        help="also the splats at FACTOR h_k, those with clip lines at CLIPPED h_k")
    parser.add_argument("--models", nargs="*", default=[])
    parser.add_argument("--keep-other-models", action="store_true",
                        help="keep the saved rows of the models not run")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--images", type=Path, default=Path("/tmp/kernel_defaults"))
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, mesh in meshes(args.models):
        for size in args.sizes:
            view = surfsplat.prepare(mesh)   # a fresh plan: a view samples its mesh once, for its first camera
            camera = view.camera(None, size, size)
            cloud = view.sample(camera).points()
            options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=view.culls(camera)))
            truth = surfsplat.render_mesh(mesh, camera, supersample=4)
            contour = contour_mask(truth)
            # the factor View.sample sized them with: larger on a mesh with sharp edges
            base = SAMPLE_COVERAGE if auto_sharp_angle(weld(mesh)) is None else CREASED_SAMPLE_COVERAGE
            variants = [(f"{f:g} h_k" + (" (default)" if f == base else ""), scaled(cloud, f / base))
                        for f in args.factors]
            variants += [(f"{f:g} h_k, clipped {c:g}", mixed(cloud, base, f, c)) for f, c in args.mixed]
            for label, variant in variants:
                tag = f"{name}_{size}_{label}".replace(" ", "_").replace(",", "")
                m = measure(variant, camera, truth, contour, options, args.repeat, args.images, tag)
                rows.append([name, size, label, f"{len(cloud):,}", m["ms"], m["overlap"], m["psnr"],
                             m["contour"], m["smooth"], m["holes"], m["bare holes"], m["fill"]])
                print(rows[-1], flush=True)
    saved = RESULTS / "kernel_defaults.json"
    if args.keep_other_models and saved.exists():
        ran = {row[0] for row in rows}
        rows = [row for row in json.loads(saved.read_text())["rows"] if row[0] not in ran] + rows
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    date = time.strftime("%Y-%m-%d")
    command = "python benchmarks/kernel_defaults.py " + shlex.join(sys.argv[1:])
    load = os.getloadavg()[0]
    columns = ["model", "size", "radius", "splats", "frame ms", "overlap", "psnr", "contour", "smooth", "holes",
               "holes without fill", "fill"]
    text = "\n".join([f"Machine: {machine}; load average {load:.1f} at the end", f"Date: {date}",
                      f"Command: `{command.strip()}`", "",
                      "Mesh samples (`View.sample`) at each size, `ewa`, the default options and headlight, against "
                      "the 4 x 4 mesh. The samples are spread evenly and sized by their spacing: 1.25 h_k stands for "
                      "2.0 mean spacings (2.3 on slivers), 1.1 h_k for 0.88 times that.",
                      ""] + markdown_table(columns, rows))
    save_results("kernel_defaults", text + "\n", {"machine": machine, "date": date, "command": command.strip(),
                                                     "columns": columns, "rows": rows})


if __name__ == "__main__":
    main()
