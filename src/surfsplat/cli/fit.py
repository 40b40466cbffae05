"""The ``surfsplat fit`` subcommand: splats fitted to images with known cameras (:func:`surfsplat.fit`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import progress
from ..api import fit
from ..io import save_ply
from . import options as opt
from .commands import check_output, inputs_of

FIT_EPILOG = """\
CAMERAS: a COLMAP text model (folder with cameras.txt, images.txt; points3D.txt for the initial cloud),
a NeRF transforms.json, an OpenCV camera JSON or a surfsplat camera list; each camera's image is the file
named like it (its stem) beside the camera file (COLMAP: also ../images), or under --images.
Colours are learned as seen (render the result with --no-lighting); an RGBA image's alpha is its mask.
example: surfsplat fit views/transforms.json --init scan.ply -o model.ply
         surfsplat render model.ply --no-lighting -o model.png"""


def add_fit_command(subparsers) -> argparse.ArgumentParser:
    """Define ``fit`` on ``subparsers``; returns the subparser."""
    p = subparsers.add_parser(
        "fit", help="fit splats to photographs with known cameras (differentiable EWA splatting; needs PyTorch)",
        description="Fit splats (positions, normals, radii, colours, opacity) to images with known cameras by "
                    "gradient descent through the differentiable EWA renderer (the optional extra diff: PyTorch).",
        epilog=FIT_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("cameras", help="camera file or COLMAP folder (see below)")
    p.add_argument("-o", "--output", required=True, help="output .ply of the fitted splats")
    p.add_argument("--init", metavar="CLOUD", help="initial points or splats (default: the COLMAP points3D.txt)")
    p.add_argument("--images", metavar="DIR", help="folder of the images (default: beside the camera file)")
    p.add_argument("--iterations", type=opt.number(int, low=1, high=10_000_000), default=None, metavar="N",
                   help="optimizer steps, one view each (default 1000)")
    p.add_argument("--max-splats", type=opt.number(int, low=1), default=None, metavar="N",
                   help="most splats densification may grow to (default 500,000)")
    p.add_argument("--coarse-fraction", type=opt.number(float, low=0, high=1), default=None, metavar="F",
                   help="fraction of the steps (the first) on the images at half the resolution (default 0.5)")
    p.add_argument("--plane-weight", type=opt.number(float, low=0), default=None, metavar="W",
                   help="weight of the term tying each splat's normal to its neighbours' plane (default 0.2; 0: off)")
    p.add_argument("--sharpen-fraction", type=opt.number(float, low=0, high=1), default=None, metavar="F",
                   help="fraction of the steps (the last) over which the splats' soft rims and depth tests sharpen "
                        "to the renderer's defaults (default 0.3)")
    p.add_argument("--crease-angle", type=opt.number(float, low=0, high=90), default=None, metavar="DEG",
                   help="neighbours whose normals differ by more than this weigh little in the plane term, "
                        "which then keeps sharp edges (default 20; 0: all weigh alike)")
    p.add_argument("--max-radius", type=opt.number(float, low=0), default=None, metavar="F",
                   help="largest splat radius, as a multiple of the mean distance to its 8 nearest splats "
                        "(default 0.7; 0: no limit)")
    p.add_argument("--seed", type=opt.number(int, low=0, high=2**63 - 1), default=0, help="random seed (default 0)")
    p.add_argument("--device", default=None, help="PyTorch device: cpu (default), cuda, mps")
    p.add_argument("--loss", metavar="FILE.json", help="where to write the loss curve (default: OUTPUT.loss.json)")
    opt.add_force_option(p)
    p.set_defaults(func=cmd_fit)
    return p


def cmd_fit(args) -> None:
    """``surfsplat fit``: fit, save the splats as PLY and the loss curve as JSON."""
    out = Path(args.output)
    check_output(out, inputs_of(args) + tuple(Path(p) for p in (args.cameras, args.init) if p))
    loss = Path(args.loss) if args.loss else out.with_name(out.name + ".loss.json")
    check_output(loss, inputs_of(args))
    settings = {k: v for k, v in (("iterations", args.iterations), ("max_splats", args.max_splats),
                                  ("coarse_fraction", args.coarse_fraction), ("plane_weight", args.plane_weight),
                                  ("sharpen_fraction", args.sharpen_fraction), ("crease_angle", args.crease_angle),
                                  ("max_radius", args.max_radius),
                                  ("seed", args.seed)) if v is not None}
    result = fit(args.cameras, init=args.init, images=args.images, device=args.device, **settings)
    save_ply(result.cloud, out)
    result.save_loss_curve(loss)
    progress.message(f"fitted {len(result.cloud):,} splats in {result.seconds:.1f} s (loss {result.losses[0]:.4g} "
                     f"-> {result.losses[-1]:.4g}) -> {out}; loss curve -> {loss}")
