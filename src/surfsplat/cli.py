"""Command line: ``surfsplat render|demo|build|info|preprocess|phong|sample|view``."""

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
    p.add_argument("--kernel-a", type=float, default=6.0, metavar="A", help="a of the pajarola kernel (default 6, at most 80)")
    p.add_argument("--kernel-b", type=float, default=1.5, metavar="B",
                   help="b: the kernel's support radius r at the splat's rim (default 1.5)")
    p.add_argument("--kernel-n", type=float, default=3.0, metavar="N", help="n of the pajarola kernel (default 3)")
    p.add_argument("--kernel-sigma", type=float, default=0.5, metavar="S",
                   help="sigma of the gaussian kernel, units of b (default 0.5)")


def _add_lod_options(p: argparse.ArgumentParser) -> None:
    from .hierarchy import SHADINGS

    p.add_argument("--lod-tolerance", type=float, metavar="PX",
                   help="level of detail: draw hierarchy nodes whose projected size is at most PX pixels as "
                        "one splat (default 1 for a hierarchy MODEL.npz; a point file given PX gets its "
                        "hierarchy built first; 0: every original splat)")
    p.add_argument("--lod-shading", choices=SHADINGS, default="fit",
                   help="normal field of coarse LOD splats: fit (least squares, default), cone (the normal "
                        "cone, Pajarola 2003 fig. 14) or flat")


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


def _lights(args):
    """Lights from the shared view options (``--light``, ``--no-lighting``)."""
    from .lighting import Lights

    return Lights(directions=tuple(map(tuple, args.light)) if args.light else None, enabled=not args.no_lighting)


def _render_and_save(model, args, out: Path, inputs: tuple[Path, ...] = ()) -> None:
    from .api import as_hierarchy, model_points, render, view_splats
    from .render.frame import Frame

    _refuse_overwriting_inputs(out, inputs)
    tau = getattr(args, "lod_tolerance", None)
    if tau is not None:
        model = as_hierarchy(model)
    camera = _camera(args, model_points(model))
    start = time.perf_counter()
    cloud, selection = view_splats(model, camera, tau, cull_backfaces=args.cull_backfaces, shading=args.lod_shading)
    what = f"{len(cloud):,} splats"
    if selection is not None:
        what = (f"{len(cloud):,} LOD splats (tolerance {selection.tolerance_px:g} px, {selection.node_count:,} "
                f"nodes, {selection.point_total:,} points)")
    if len(cloud):
        frame = render(cloud, camera, technique=args.technique, lights=_lights(args), background=args.background,
                       **_render_options(args))
    else:
        frame = Frame.empty(camera, args.background)
    elapsed = time.perf_counter() - start
    frame.save(out)
    progress.message(f"rendered {what} with {args.technique} at {camera.width}x{camera.height} "
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
    from .api import as_splats, is_hierarchy_file
    from .hierarchy import load_hierarchy
    from .io import load

    if args.mesh:
        _render_mesh(args)
        return
    if is_hierarchy_file(args.input):
        with progress.stage(f"loading the hierarchy {args.input}"):
            model = load_hierarchy(args.input)
        progress.message(f"{len(model.points):,} points, {len(model):,} nodes in {model.levels} levels")
    else:
        with progress.stage(f"loading {args.input}"):
            cloud = load(args.input)
        progress.message(f"{len(cloud):,} points")
        model = as_splats(cloud, k=args.k)
    _render_and_save(model, args, Path(args.output), (Path(args.input),))


def _render_mesh(args) -> None:
    """``render --mesh``: the input's triangles with the same camera and lighting (ground truth)."""
    from .api import render_mesh
    from .cloud import SplatCloud
    from .io import load_mesh

    out = Path(args.output)
    _refuse_overwriting_inputs(out, (Path(args.input),))
    with progress.stage(f"loading {args.input}"):
        mesh = load_mesh(args.input)
    vertices = SplatCloud(mesh.vertices)
    camera = _camera(args, vertices)
    start = time.perf_counter()
    frame = render_mesh(mesh, camera, lights=_lights(args), background=args.background)
    frame.save(out)
    progress.message(f"rendered {len(mesh.faces):,} triangles at {camera.width}x{camera.height} "
                     f"in {time.perf_counter() - start:.2f} s -> {out}")


def cmd_demo(args) -> None:
    from .scenes import demo_scene

    with progress.stage(f"building scene {args.scene}"):
        cloud = demo_scene(args.scene)
    _render_and_save(cloud, args, Path(args.output))


def cmd_info(args) -> None:
    from .api import is_hierarchy_file
    from .geometry.preprocess import neighbour_spacing
    from .io import load

    if is_hierarchy_file(args.input):
        _hierarchy_info(args.input)
        return
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


def _hierarchy_info(path) -> None:
    from .hierarchy import load_hierarchy

    d = load_hierarchy(path).describe()
    print(f"file:       {path} (surfsplat LOD hierarchy, format {d['format_version']})")
    print(f"points:     {d['points']:,}")
    print(f"nodes:      {d['nodes']:,} in {d['levels']} levels ({d['leaves']:,} leaves, capacity "
          f"{d['leaf_capacity']}, mean {d['mean_leaf_points']:.2f} points a leaf)")
    print(f"per level:  {', '.join(f'{n:,}' for n in d['nodes_per_level'])}")
    lo, hi = (np.array(b) for b in d["bounds"])
    print(f"bounds:     min {np.array2string(lo, precision=4)}  max {np.array2string(hi, precision=4)}")
    present = [name for name in ("colors", "normal_field", "clip_lines") if d[f"has_{name}"]]
    print(f"properties: positions, normals, u, v{', ' + ', '.join(present) if present else ''}")
    print(f"memory:     {d['bytes'] / 2**20:.1f} MiB")


def cmd_build(args) -> None:
    from .api import as_splats, is_hierarchy_file
    from .hierarchy import build_hierarchy
    from .io import load

    out = Path(args.output)
    _refuse_overwriting_inputs(out, (Path(args.input),))
    if not is_hierarchy_file(out):
        raise InputError(f"{out}: a hierarchy is saved as .npz; name the output MODEL.npz")
    if out.exists() and not args.force:
        raise InputError(f"{out}: exists; use --force to overwrite it")
    with progress.stage(f"loading {args.input}"):
        cloud = load(args.input)
    progress.message(f"{len(cloud):,} points")
    cloud = as_splats(cloud, k=args.k)
    start = time.perf_counter()
    with progress.stage(f"building the point-octree of {len(cloud):,} splats"):
        hierarchy = build_hierarchy(cloud, args.leaf_capacity, source=args.input)
    seconds = time.perf_counter() - start
    hierarchy.save(out, overwrite=args.force)
    progress.message(f"{len(hierarchy):,} nodes in {hierarchy.levels} levels, built in {seconds:.2f} s "
                     f"({len(cloud) / max(seconds, 1e-9):,.0f} points/s) -> {out}")


def cmd_phong(args) -> None:
    from .geometry.phong import phong_splats
    from .io import load, save_ply

    out = Path(args.output)
    _refuse_overwriting_inputs(out, (Path(args.input),))
    if (args.error is None) == (args.count is None):
        raise InputError("give exactly one of --error EPS (model units) and --count N")
    if out.exists() and not args.force:
        raise InputError(f"{out}: exists; use --force to overwrite it")
    with progress.stage(f"loading {args.input}"):
        cloud = load(args.input)
    progress.message(f"{len(cloud):,} samples")
    start = time.perf_counter()
    splats = phong_splats(cloud, args.error, count=args.count, sharp_angle=args.sharp_angle, relax=args.relax,
                          margin=args.margin, source=args.input)
    seconds = time.perf_counter() - start
    save_ply(splats, out, overwrite=args.force)
    progress.message(f"{len(splats):,} Phong splats from {len(cloud):,} samples in {seconds:.1f} s "
                     f"({len(cloud) / max(seconds, 1e-9):,.0f} samples/s) -> {out}")


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

    p = sub.add_parser("render", help="render a point cloud, splat model or LOD hierarchy to an image")
    p.add_argument("input", help="PLY, OBJ or LAS file, or a hierarchy MODEL.npz (surfsplat build)")
    p.add_argument("-o", "--output", required=True, help="output image (.png)")
    p.add_argument("--k", type=int, default=8, help="neighbours for preprocessing raw points (default 8)")
    p.add_argument("--depth", metavar="OUT.npy", help="also save the depth map (camera-space, inf = empty)")
    _add_lod_options(p)
    p.add_argument("--mesh", action="store_true",
                   help="render the input's triangles instead (the ground truth: same camera and lighting, "
                        "per-pixel shading, 4x4 supersampled); camera and lighting flags apply")
    _add_view_options(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("demo", help="render a built-in procedural scene (no input file needed)")
    p.add_argument("-o", "--output", default="demo.png", help="output image (default demo.png)")
    p.add_argument("--scene", default="torus", choices=sorted(SCENES), help="scene (default torus)")
    _add_lod_options(p)
    _add_view_options(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("build", help="build the point-octree LOD hierarchy of a model; save it as one .npz file")
    p.add_argument("input", help="PLY, OBJ or LAS file (raw points are preprocessed first)")
    p.add_argument("-o", "--output", required=True, help="output hierarchy MODEL.npz")
    p.add_argument("--leaf-capacity", type=int, default=8, metavar="N",
                   help="at most N points in a leaf node (default 8)")
    p.add_argument("--k", type=int, default=8, help="neighbours for preprocessing raw points (default 8)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(func=cmd_build)

    p = sub.add_parser("info", help="counts, bounds, properties and spacing of a point file or hierarchy")
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

    p = sub.add_parser("phong", help="Phong splats: far fewer splats with linear normal fields (Botsch 2004)")
    p.add_argument("input", help="dense samples: PLY, OBJ or LAS (normals estimated where missing)")
    p.add_argument("-o", "--output", required=True, help="output .ply (splats with alpha beta normal fields)")
    p.add_argument("--error", type=float, metavar="EPS",
                   help="every sample within EPS (model units) of a splat's plane, inside its ellipse")
    p.add_argument("--count", type=int, metavar="N", help="instead of --error: about N splats (within 3%%)")
    p.add_argument("--sharp-angle", type=sharp_angle_argument, metavar="DEG",
                   help="keep splats from growing across edges sharper than DEG degrees and clip them there")
    p.add_argument("--relax", type=int, default=2, metavar="N", help="relaxation iterations (default 2)")
    p.add_argument("--margin", type=float, default=0.75, metavar="F",
                   help="grow each ellipse by F times its samples' spacing so the surface between samples is "
                        "covered too (default 0.75; 0: the paper's bare smallest enclosing ellipses)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(func=cmd_phong)

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
