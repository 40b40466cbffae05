"""Which stream of the web format costs the page its PSNR: the bunny's splats (``shared/data/bunny.ply``,
sampled for a 1024 x 768 page as ``surfsplat export`` samples it) rendered on the desktop at 1024 x 768
against the unquantized splats in the page's order, for each technique:

* 16-bit positions (the compact hierarchy files' format) with every stream decoded, then with one stream
  exact at a time (positions, the shading normals, the axes ``u``, ``v``, the colours);
* positions alone quantized to 18, 20 and 24 bits a coordinate (every other stream exact);
* the page's splats (:func:`surfsplat.web.page.as_drawn`: 24-bit positions).

Each row: PSNR, and the pixels that differ (any channel) and differ by more than 0.1.

    python benchmarks/web_quantization.py [--techniques phong,flat,ewa]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, write_table  # noqa: E402
from web_viewer import BUNNY, options_for  # noqa: E402

from surfsplat import metrics  # noqa: E402
from surfsplat.cloud import SplatCloud  # noqa: E402
from surfsplat.pipeline import View  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402
from surfsplat.web import format as wf  # noqa: E402
from surfsplat.web.page import as_drawn, exported_splats, web_order  # noqa: E402
from surfsplat.web.shaders import WEB_TECHNIQUES  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, nargs=2, default=(1024, 768))
    parser.add_argument("--techniques", default=",".join(WEB_TECHNIQUES))
    args = parser.parse_args()
    width, height = args.size
    plan = View(BUNNY)
    camera = plan.camera(None, width, height)
    splats = exported_splats(plan, camera, None)
    order = web_order(splats)[0]
    colors = splats.colors if splats.colors is not None else np.full((len(splats), 3), 0.8, np.float32)
    exact = {"positions": splats.positions[order].astype(np.float64), "normals": splats.normals[order],
             "colors": colors[order], "u": splats.u[order], "v": splats.v[order]}
    streams, header = wf.encode(exact["positions"], exact["normals"], exact["colors"], exact["u"], exact["v"])
    decoded = wf.decode(streams, header)
    lo, hi = exact["positions"].min(axis=0), exact["positions"].max(axis=0)

    def positions(bits: int) -> np.ndarray:
        return wf.dequantize_unit(wf.quantize_unit(exact["positions"], lo, hi, 2.0 ** bits - 1, np.uint32),
                                  lo, hi, 2.0 ** bits - 1)

    def cloud(arrays: dict) -> SplatCloud:
        return SplatCloud(*(np.asarray(arrays[k], np.float32) for k in ("positions", "normals", "colors", "u", "v")),
                          origin=splats.origin, up=splats.up)

    variants: dict[str, SplatCloud] = {"16-bit positions, every stream decoded": cloud(decoded)}
    for name, keys in (("positions", ("positions",)), ("normals", ("normals",)), ("axes u, v", ("u", "v")),
                       ("colours", ("colors",))):
        variants[f"16-bit, {name} exact"] = cloud({**decoded, **{k: exact[k] for k in keys}})
    for bits in (18, 20, 24):
        variants[f"positions alone in {bits} bits"] = cloud({**exact, "positions": positions(bits)})
    variants["a page exported with --position-bits 24"] = as_drawn(splats, fine_positions=True)
    reference = View(cloud(exact))
    rows = []
    for technique in args.techniques.split(","):
        options = options_for(technique, plan.culls(camera, technique=technique))
        ref = reference.render(camera, technique=technique, options=options).frame.image() / 255.0
        for name, variant in variants.items():
            image = View(variant).render(camera, technique=technique, options=options).frame.image() / 255.0
            diff = np.abs(image - ref).max(axis=2)
            rows.append([technique, name, round(metrics.psnr(image, ref), 2), int((diff > 0).sum()),
                         int((diff > 0.1).sum())])
            print(rows[-1], flush=True)
    command = " ".join(["python benchmarks/web_quantization.py", *sys.argv[1:]])
    write_table("web_quantization", ["technique", "splats", "dB vs unquantized", "pixels differing", "by > 0.1"],
                rows, f"{machine_description(default_renderer().ctx.info['GL_RENDERER'])}; bunny, {len(splats):,} "
                      f"splats, {width}x{height}; `{command}`")


if __name__ == "__main__":
    main()
