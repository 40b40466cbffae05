"""Command line: ``surfsplat render|demo|info|preprocess|sample``."""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from . import progress
from .errors import InputError, SurfsplatError


def _add_view_options(p: argparse.ArgumentParser) -> None:
    from .render.technique import KERNELS, TECHNIQUES, get_technique

    get_technique("ewa")  # registers the techniques
    p.add_argument("--technique", default="ewa", choices=sorted(TECHNIQUES), help="rendering technique (default ewa)")
    p.add_argument("--width", type=int, default=1024, help="image width in pixels (default 1024)")
    p.add_argument("--height", type=int, default=1024, help="image height in pixels (default 1024)")
    p.add_argument("--eye", type=float, nargs=3, metavar=("X", "Y", "Z"), help="camera position (world)")
    p.add_argument("--target", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="point looked at (default: the model's center)")
    p.add_argument("--up", type=float, nargs=3, metavar=("X", "Y", "Z"), default=(0.0, 1.0, 0.0),
                   help="camera up vector (default 0 1 0)")
    p.add_argument("--fov", type=float, default=40.0, help="vertical field of view in degrees (default 40)")
    p.add_argument("--light", type=float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="world direction toward a directional light; repeat for up to 4 (default: headlight)")
    p.add_argument("--no-lighting", action="store_true", help="render unlit colors")
    p.add_argument("--background", type=float, nargs=3, metavar=("R", "G", "B"), default=(1.0, 1.0, 1.0),
                   help="background color, components in [0, 1] (default white)")
    p.add_argument("--no-prefilter", action="store_true", help="disable the EWA prefilter (H = I)")
    p.add_argument("--cutoff", type=float, default=1.0, help="EWA kernel cutoff c (default 1)")
    p.add_argument("--depth-epsilon", type=float, default=1.0,
                   help="visibility offset along the viewing rays, in splat radii (default 1)")
    p.add_argument("--cull-backfaces", action="store_true",
                   help="drop splats facing away from the eye (closed models with outward normals only)")
    p.add_argument("--deferred", action="store_true",
                   help="deferred shading: blend albedo and normals, light each pixel once (any technique)")
    p.add_argument("--kernel", choices=KERNELS, default="pajarola",
                   help="blend technique's kernel: pajarola exp(-a (r/b)^n) or gaussian exp(-r^2 / 2 sigma^2) "
                        "(default pajarola)")
    p.add_argument("--kernel-a", type=float, default=6.0, metavar="A", help="a of the pajarola kernel (default 6)")
    p.add_argument("--kernel-b", type=float, default=1.5, metavar="B",
                   help="b: the kernel's support radius r at the splat's rim (default 1.5)")
    p.add_argument("--kernel-n", type=float, default=3.0, metavar="N", help="n of the pajarola kernel (default 3)")
    p.add_argument("--kernel-sigma", type=float, default=0.5, metavar="S",
                   help="sigma of the gaussian kernel, units of b (default 0.5)")


def _render_options(args) -> dict:
    """The RenderOptions fields from the shared view options."""
    return dict(prefilter=not args.no_prefilter, cutoff=args.cutoff, depth_epsilon=args.depth_epsilon,
                cull_backfaces=args.cull_backfaces, deferred=args.deferred, kernel=args.kernel,
                kernel_a=args.kernel_a, kernel_b=args.kernel_b, kernel_n=args.kernel_n,
                kernel_sigma=args.kernel_sigma)


def _camera(args, cloud):
    from .api import auto_camera
    from .camera import Camera

    if args.eye is None:
        if args.target is not None:
            raise InputError("--target needs --eye (without camera flags the model is framed automatically)")
        return auto_camera(cloud, args.width, args.height, args.fov, up=tuple(args.up))
    lo, hi = cloud.bounds()
    target = args.target if args.target is not None else 0.5 * (lo + hi)
    camera = Camera(eye=tuple(args.eye), target=tuple(target), up=tuple(args.up), fov=args.fov,
                    width=args.width, height=args.height)
    return camera.with_clip_from_bounds(lo, hi, margin=float(cloud.radii.max()) if cloud.u is not None else 0.0)


def _render_and_save(cloud, args, out: Path, inputs: tuple[Path, ...] = ()) -> None:
    from .api import render
    from .lighting import Lights

    _refuse_overwriting_inputs(out, inputs)
    camera = _camera(args, cloud)
    lights = Lights(directions=tuple(map(tuple, args.light)) if args.light else None, enabled=not args.no_lighting)
    start = time.perf_counter()
    frame = render(cloud, camera, technique=args.technique, lights=lights, background=args.background,
                   **_render_options(args))
    elapsed = time.perf_counter() - start
    frame.save(out)
    progress.message(f"rendered {len(cloud):,} splats with {args.technique} at {camera.width}x{camera.height} "
                     f"in {elapsed:.2f} s -> {out}")
    depth = getattr(args, "depth", None)
    if depth:
        _refuse_overwriting_inputs(Path(depth), inputs)
        np.save(depth, frame.depth)
        progress.message(f"depth (camera-space, inf = empty) -> {depth}")


def _refuse_overwriting_inputs(out: Path, inputs: tuple[Path, ...]) -> None:
    for path in inputs:
        if out.exists() and path.exists() and out.resolve() == path.resolve():
            raise InputError(f"{out}: refusing to overwrite the input file")


def cmd_render(args) -> None:
    from .api import as_splats
    from .io import load

    if args.mesh:
        _render_mesh(args)
        return
    with progress.stage(f"loading {args.input}"):
        cloud = load(args.input)
    progress.message(f"{len(cloud):,} points")
    cloud = as_splats(cloud, k=args.k)
    _render_and_save(cloud, args, Path(args.output), (Path(args.input),))


def _render_mesh(args) -> None:
    """``render --mesh``: the input's triangles with the same camera and lighting (ground truth)."""
    from .api import render_mesh
    from .cloud import SplatCloud
    from .io import load_mesh
    from .lighting import Lights

    out = Path(args.output)
    _refuse_overwriting_inputs(out, (Path(args.input),))
    with progress.stage(f"loading {args.input}"):
        mesh = load_mesh(args.input)
    vertices = SplatCloud(mesh.vertices)
    camera = _camera(args, vertices)
    lights = Lights(directions=tuple(map(tuple, args.light)) if args.light else None, enabled=not args.no_lighting)
    start = time.perf_counter()
    frame = render_mesh(mesh, camera, lights=lights, background=args.background)
    frame.save(out)
    progress.message(f"rendered {len(mesh.faces):,} triangles at {camera.width}x{camera.height} "
                     f"in {time.perf_counter() - start:.2f} s -> {out}")


def cmd_demo(args) -> None:
    from .scenes import demo_scene

    with progress.stage(f"building scene {args.scene}"):
        cloud = demo_scene(args.scene)
    _render_and_save(cloud, args, Path(args.output))


def cmd_info(args) -> None:
    from .geometry.preprocess import neighbour_spacing
    from .io import load

    cloud = load(args.input)
    lo, hi = cloud.bounds()
    print(f"file:       {args.input}")
    print(f"points:     {len(cloud):,}")
    print(f"bounds:     min {np.array2string(lo, precision=4)}  max {np.array2string(hi, precision=4)}")
    print(f"size:       {np.array2string(hi - lo, precision=4)} (diagonal {np.linalg.norm(hi - lo):.4g})")
    present = [name for name in ("normals", "colors", "u", "v", "normal_field", "clip_lines")
               if getattr(cloud, name) is not None]
    print(f"properties: positions{', ' + ', '.join(present) if present else ''}")
    if cloud.u is not None:
        r = cloud.radii
        print(f"splat radius: min {r.min():.4g}  median {np.median(r):.4g}  max {r.max():.4g}")
    if len(cloud) > 1:
        stats = neighbour_spacing(cloud.positions)
        print("neighbour spacing: " + "  ".join(f"{key} {value:.4g}" for key, value in stats.items()))


def cmd_preprocess(args) -> None:
    from .geometry.preprocess import preprocess
    from .io import load, save_ply

    out = Path(args.output)
    _refuse_overwriting_inputs(out, (Path(args.input),))
    with progress.stage(f"loading {args.input}"):
        cloud = load(args.input)
    progress.message(f"{len(cloud):,} points")
    cloud = preprocess(cloud, k=args.k, shape=args.shape, sharp_angle=args.sharp_angle)
    save_ply(cloud, out, overwrite=args.force)
    progress.message(f"wrote {len(cloud):,} splats -> {out}")


def cmd_sample(args) -> None:
    from .geometry.sampling import sample_mesh
    from .io import load_mesh, save_ply

    out = Path(args.output)
    _refuse_overwriting_inputs(out, (Path(args.mesh),))
    mesh = load_mesh(args.mesh)
    with progress.stage(f"sampling {args.n:,} points", count=args.n):
        cloud = sample_mesh(mesh, args.n, seed=args.seed, sharp_angle=args.sharp_angle,
                            smooth_normals=args.smooth_normals)
    save_ply(cloud, out, overwrite=args.force)
    progress.message(f"wrote {len(cloud):,} samples -> {out}")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``surfsplat`` command."""
    from .scenes import SCENES

    parser = argparse.ArgumentParser(prog="surfsplat", description="High-quality surface splatting of point clouds.")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("render", help="render a point cloud or splat model to an image")
    p.add_argument("input", help="PLY, OBJ or LAS file")
    p.add_argument("-o", "--output", required=True, help="output image (.png)")
    p.add_argument("--k", type=int, default=8, help="neighbours for preprocessing raw points (default 8)")
    p.add_argument("--depth", metavar="OUT.npy", help="also save the depth map (camera-space, inf = empty)")
    p.add_argument("--mesh", action="store_true",
                   help="render the input's triangles instead (the ground truth: same camera and lighting, "
                        "per-pixel shading, 4x4 supersampled); camera and lighting flags apply")
    _add_view_options(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("demo", help="render a built-in procedural scene (no input file needed)")
    p.add_argument("-o", "--output", default="demo.png", help="output image (default demo.png)")
    p.add_argument("--scene", default="torus", choices=sorted(SCENES), help="scene (default torus)")
    _add_view_options(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("info", help="counts, bounds, properties and spacing of a point file")
    p.add_argument("input")
    p.set_defaults(func=cmd_info)

    from .geometry.sharp import sharp_angle_argument

    p = sub.add_parser("preprocess", help="estimate normals and splat ellipses; write a splat PLY")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True, help="output .ply")
    p.add_argument("--k", type=int, default=8, help="neighbours (default 8)")
    p.add_argument("--shape", choices=("ellipse", "circle"), default="ellipse", help="splat shape (default ellipse)")
    p.add_argument("--sharp-angle", type=sharp_angle_argument, metavar="DEG",
                   help="clip lines at sharp edges and corners: where neighbouring normals split into groups "
                        "more than DEG degrees apart (0 < DEG < 180; default: none)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(func=cmd_preprocess)

    p = sub.add_parser("sample", help="sample points uniformly by area on a triangle mesh")
    p.add_argument("mesh", help="PLY or OBJ triangle mesh")
    p.add_argument("-n", type=int, required=True, help="number of samples")
    p.add_argument("-o", "--output", required=True, help="output .ply")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--smooth-normals", action="store_true",
                   help="interpolate the vertex normals (as Phong shading of the mesh does) instead of "
                        "giving each sample its face's normal")
    p.add_argument("--sharp-angle", type=sharp_angle_argument, metavar="DEG",
                   help="also give the samples splats, and clip lines where they cross an edge whose faces' "
                        "normals differ by more than DEG degrees (0 < DEG < 180; default: points only)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(func=cmd_sample)

    from .viewer.cli import add_view_command

    add_view_command(sub, _add_view_options)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``surfsplat`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    progress.enable(not args.quiet)

    def show_warning(message, category, filename, lineno, file=None, line=None):
        print(f"surfsplat: warning: {message}", file=sys.stderr)

    warnings.showwarning = show_warning
    try:
        args.func(args)
    except SurfsplatError as exc:
        print(f"surfsplat: error: {exc}", file=sys.stderr)
        return 2
    except (FileNotFoundError, PermissionError, IsADirectoryError) as exc:
        print(f"surfsplat: error: {exc.filename}: {exc.strerror}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
