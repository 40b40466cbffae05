"""The blending kernels of Pajarola et al. 2003 (figures 10, 18 and 19): documentation pictures.

Usage: python benchmarks/pajarola_kernels.py [--out docs/images] [--size 384]

Draws, with the ``blend`` technique:

- ``blend_kernel_profiles.png``: psi_E(r) = exp(-a (r/b)^n) over r in [0, b] for the kernels
  below (figure 10's curves) and the Gaussian option;
- ``blend_checker_<name>.png``: a checkerboard of 96 x 96 point samples (8 per square),
  close enough that each splat covers ~10 pixels, where the kernels differ (figure 18 uses
  512 x 512 samples);
- ``blend_scan_<name>.png``: a close-up of the colored scan fragment frag_115.ply (its
  64,365 vertices as points, preprocessed), splats ~15 pixels wide (figure 19);

for the kernels ``round`` (a = 1, b = 1.5, n = 2: figure 18 a), ``default`` (a = 6, b = 1.5,
n = 3: figures 18 b and 19 a, the paper's default), ``plateau`` (a = 4, b = 1.5, n = 5:
figure 19 b) and ``gaussian`` (EQ 11, sigma = 0.5).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from surfsplat.rendering.options import KernelOptions, RenderOptions

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent / "shared" / "data"

KERNELS = {
    "round": KernelOptions(name="pajarola", a=1.0, b=1.5, n=2.0),
    "default": KernelOptions(name="pajarola", a=6.0, b=1.5, n=3.0),
    "plateau": KernelOptions(name="pajarola", a=4.0, b=1.5, n=5.0),
    "gaussian": KernelOptions(name="gaussian", b=1.5, sigma=0.5),
}
COLORS = {"round": (200, 60, 40), "default": (30, 90, 200), "plateau": (20, 150, 60), "gaussian": (120, 120, 120)}


def profiles(path: Path, size=(480, 240)) -> None:
    """Plot the kernels' profiles psi(r), r in [0, b], with Pillow."""
    image = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(image)
    w, h, pad = size[0], size[1], 24
    draw.line([(pad, h - pad), (w - 8, h - pad)], fill="black")
    draw.line([(pad, 8), (pad, h - pad)], fill="black")
    draw.text((w - 40, h - pad + 4), "r = b", fill="black")
    draw.text((2, 8), "1", fill="black")
    rho = np.linspace(0.0, 1.0, 400)
    for i, (name, kernel) in enumerate(KERNELS.items()):
        a, n = kernel.exponent()
        psi = np.exp(-a * rho ** n)
        xs = pad + rho * (w - 8 - pad)
        ys = (h - pad) - psi * (h - pad - 8)
        draw.line(list(zip(xs, ys)), fill=COLORS[name], width=2)
        draw.text((w - 150, 12 + 14 * i), name, fill=COLORS[name])
    image.save(path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(HERE.parent / "docs" / "images"))
    parser.add_argument("--size", type=int, default=384)
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    import surfsplat
    from surfsplat import scenes
    from surfsplat.camera import Camera

    profiles(out / "blend_kernel_profiles.png")
    checker = scenes.checkerboard(96, size=2.0, squares=12)
    checker_cam = Camera(eye=(0.1, -0.55, 0.35), target=(0.0, 0.1, 0.0), up=(0, 0, 1), fov=45,
                         width=args.size, height=args.size)
    scan = None
    if (DATA / "frag_115.ply").exists():
        from surfsplat.io import load_mesh

        mesh = load_mesh(DATA / "frag_115.ply")
        scan = surfsplat.preprocess(surfsplat.SplatCloud(mesh.vertices, mesh.vertex_normals, mesh.vertex_colors))
        lo, hi = scan.bounds()
        center = 0.5 * (lo + hi)
        scan_cam = surfsplat.auto_camera(scan, args.size, args.size)
        # a close-up: a quarter of the framing distance, toward the center
        eye = np.asarray(scan_cam.eye)
        scan_cam = Camera(eye=tuple(center + 0.12 * (eye - center)), target=tuple(center), up=scan_cam.up,
                          fov=40, width=args.size, height=args.size)
    else:
        print(f"{DATA} has no frag_115.ply: scan pictures skipped", file=sys.stderr)
    for name, kernel in KERNELS.items():
        frame = surfsplat.render(checker, checker_cam, technique="blend", lights=surfsplat.Lights(enabled=False),
                                 options=RenderOptions(kernel=kernel))
        frame.save(out / f"blend_checker_{name}.png")
        if scan is not None:
            frame = surfsplat.render(scan, scan_cam, technique="blend", lights=surfsplat.Lights(enabled=False),
                                     options=RenderOptions(kernel=kernel))
            frame.save(out / f"blend_scan_{name}.png")
        print(f"{name}: done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
