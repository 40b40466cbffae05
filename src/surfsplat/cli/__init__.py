"""Command line: ``surfsplat render|demo|build|info|preprocess|phong|sample|export|view``.

The parser (:class:`surfsplat.cli.parser.Parser`: short usage errors with suggestions) is built
here from the shared option groups of :mod:`surfsplat.cli.options`; each
subcommand (:mod:`surfsplat.cli.commands`, :mod:`surfsplat.cli.view`) converts its flags into
the typed options of :mod:`surfsplat.api` and calls it.
"""

from __future__ import annotations

import argparse
import sys
import warnings

from .. import defaults, progress
from ..version import __version__
from ..errors import SurfsplatError
from ..scenes import SCENES
from ..web.format import POSITION_BITS
from ..web.shaders import MAX_PAGE_SUPERSAMPLE, WEB_TECHNIQUES
from . import chunked, commands
from . import options as opt
from .parser import Parser
from .fit import add_fit_command
from .view import add_view_command

PROG = "surfsplat"


def _add_quiet(p: argparse.ArgumentParser, default) -> None:
    # on the main parser and on every subcommand, so -q works in any position; a subcommand's
    # default SUPPRESS keeps a -q given before the subcommand
    p.add_argument("-q", "--quiet", action="store_true", default=default, help="no progress messages")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``surfsplat`` command."""
    parser = Parser(prog=PROG, description="High-quality surface splatting of point clouds.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    _add_quiet(parser, False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("render", help="render a point cloud, splat model or LOD hierarchy to an image")
    p.add_argument("input", nargs="+", help="point, splat or mesh files or hierarchies MODEL.npz (surfsplat "
                                            "build); several: -o names each output with {stem} or {name}")
    p.add_argument("-o", "--output", required=True,
                   help="output image (.png); with several inputs a pattern such as out/{stem}.png")
    opt.add_source_options(p)
    p.add_argument("--depth", metavar="OUT.npy|OUT.exr|OUT.png",
                   help="also save the depth map: .npy or .exr (float32 channel Z; the exr extra) camera-space "
                        "depth along the view axis in model units (inf = empty), or .png 16-bit "
                        "(0 = empty, 1..65535 = near..far, stated in its surfsplat:near/far text chunks)")
    p.add_argument("--normals", metavar="OUT.png|OUT.exr|OUT.npy",
                   help="also save camera-space unit normals (x right, y up, z toward the viewer) computed from "
                        "the depth map: .png RGB = 0.5 + 0.5 n (black = empty), .exr/.npy float32 (NaN = empty)")
    p.add_argument("--coverage", metavar="OUT.png|OUT.npy|OUT.exr",
                   help="also save the antialiased coverage (alpha) in [0, 1]: .png grey with --bit-depth bits, "
                        ".npy/.exr float32")
    p.add_argument("--cameras", metavar="FILE",
                   help="render every camera of FILE (OpenCV JSON, COLMAP cameras.txt/images.txt, NeRF "
                        "transforms.json, or a --save-camera file), each to -o with {name} the view's name")
    opt.add_lod_options(p)
    p.add_argument("--mesh", action="store_true",
                   help="render the input's triangles instead (the ground truth: same camera and lighting, "
                        "per-pixel shading, 4x4 supersampled); camera and lighting flags apply")
    opt.add_output_options(p)
    opt.add_render_options(p)
    p.set_defaults(func=commands.cmd_render)

    p = sub.add_parser("demo", help="render a built-in procedural scene (no input file needed)")
    p.add_argument("-o", "--output", default="demo.png", help="output image (default demo.png)")
    p.add_argument("--scene", default="torus", choices=sorted(SCENES), help="scene (default torus)")
    opt.add_output_options(p)
    opt.add_lod_options(p)
    opt.add_render_options(p)
    p.set_defaults(func=commands.cmd_demo)

    p = sub.add_parser("turntable", help="an animation orbiting the model: GIF, MP4 or WebM")
    p.add_argument("input", help="a point, splat or mesh file, a hierarchy MODEL.npz, or demo:NAME")
    p.add_argument("-o", "--output", required=True, help="output animation (.gif; .mp4, .webm with the video extra)")
    p.add_argument("--frames", type=opt.number(int, low=1, high=100_000), default=72, metavar="N",
                   help="frames in one turn, or along the --path (default %(default)s)")
    p.add_argument("--seconds", type=opt.number(float, low=0.0, low_open=True), metavar="S",
                   help="duration (default: frames / 24)")
    p.add_argument("--degrees", type=opt.number(float), default=360.0, help="angle of the turn (default 360)")
    p.add_argument("--elevation", type=opt.number(float, low=-89.0, high=89.0), metavar="DEG",
                   help="eye height above the plane normal to up, degrees (default: the starting camera's)")
    p.add_argument("--path", metavar="CAMERAS",
                   help="instead of an orbit, a smooth path (Catmull-Rom spline of eye, target, up and fov) "
                        "through the key views of CAMERAS (a camera file with a \"cameras\" list, OpenCV JSON, "
                        "COLMAP or NeRF transforms.json), --frames in all")
    p.add_argument("--loop", action="store_true", help="with --path: a closed path back to the first key view")
    p.add_argument("--constant-speed", action="store_true",
                   help="with --path: frames at equal distances along the eye's path (default: equal time "
                        "between key views)")
    opt.add_force_option(p)
    opt.add_supersample_option(p)
    opt.add_source_options(p)
    opt.add_lod_options(p)
    opt.add_render_options(p)
    p.set_defaults(func=commands.cmd_turntable)

    p = sub.add_parser("build", help="build the point-octree LOD hierarchy of a model; save it as one .npz file")
    p.add_argument("input", help="a point, splat or mesh file (raw points are preprocessed, meshes sampled first); "
                   "with --chunked also a folder of LAS/LAZ/PLY tiles")
    p.add_argument("-o", "--output", required=True, help="output hierarchy MODEL.npz (a MODEL.ssh directory "
                   "with --chunked)")
    p.add_argument("--leaf-capacity", type=opt.number(int, low=1, high=2**31 - 1), default=8, metavar="N",
                   help="at most N points in a leaf node (default %(default)s)")
    p.add_argument("--compact", action="store_true",
                   help="store the splats quantized, 19 bytes each instead of 60 (the web viewer's format: "
                        "16-bit positions in the bounding box, octahedral normals, log radii, 8-bit colours); "
                        "loaded like a full file")
    opt.add_source_options(p)
    opt.add_force_option(p)
    chunked.add_build_options(p)
    p.set_defaults(func=chunked.cmd_build)

    p = sub.add_parser("info", help="counts, bounds, properties and spacing of a point file or hierarchy")
    p.add_argument("input")
    p.set_defaults(func=chunked.cmd_info)

    p = sub.add_parser("preprocess", help="splats from raw points (normals, ellipses) or from a mesh's surface; "
                                          "write a splat PLY")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True, help="output .ply")
    opt.add_source_options(p)
    p.add_argument("--shape", choices=("ellipse", "circle"), default="ellipse",
                   help="splat shape of raw points (default ellipse)")
    opt.add_force_option(p)
    p.set_defaults(func=commands.cmd_preprocess)

    p = sub.add_parser("phong", help="Phong splats: far fewer splats with linear normal fields (Botsch 2004)")
    p.add_argument("input", help="dense samples: PLY, OBJ or LAS (normals estimated where missing)")
    p.add_argument("-o", "--output", required=True, help="output .ply (splats with alpha beta normal fields)")
    p.add_argument("--error", type=opt.number(float, low=0.0, low_open=True, what="model units"), metavar="EPS",
                   help="every sample within EPS (model units) of a splat's plane, inside its ellipse")
    p.add_argument("--count", type=opt.number(int, low=1), metavar="N",
                   help="instead of --error: about N splats (within 3%%)")
    p.add_argument("--sharp-angle", type=opt.SHARP_ANGLE, metavar="DEG",
                   help="keep splats from growing across edges sharper than DEG degrees and clip them there")
    p.add_argument("--relax", type=opt.number(int, low=0, high=1000), default=2, metavar="N",
                   help="relaxation iterations (default %(default)s)")
    p.add_argument("--margin", type=opt.number(float, low=0.0, high=100.0), default=0.75, metavar="F",
                   help="grow each ellipse by F times its samples' spacing so the surface between samples is "
                        "covered too (default %(default)s; 0: the paper's bare smallest enclosing ellipses)")
    opt.add_force_option(p)
    p.set_defaults(func=commands.cmd_phong)

    p = sub.add_parser("sample", help="sample points uniformly by area on a triangle mesh")
    p.add_argument("mesh", help="PLY or OBJ triangle mesh")
    p.add_argument("-n", type=opt.number(int, low=1), required=True, help="number of samples")
    p.add_argument("-o", "--output", required=True, help="output .ply")
    p.add_argument("--seed", type=opt.number(int, low=0, high=2**63 - 1), default=0, help="random seed (default 0)")
    p.add_argument("--smooth-normals", action="store_true",
                   help="interpolate the vertex normals (as Phong shading of the mesh does) instead of "
                        "giving each sample its face's normal")
    p.add_argument("--sharp-angle", type=opt.SHARP_ANGLE, metavar="DEG",
                   help="also give the samples splats, and clip lines where they cross an edge whose faces' "
                        "normals differ by more than DEG degrees (0 < DEG < 180; default: points only)")
    opt.add_force_option(p)
    p.set_defaults(func=commands.cmd_sample)

    p = sub.add_parser("export", help="write a static web viewer of a model (WebGL2; open index.html, no server "
                                      "needed)")
    p.add_argument("input", help="a point, splat or mesh file, a hierarchy MODEL.npz or MODEL.ssh, or demo:NAME")
    p.add_argument("-o", "--output", required=True,
                   help="output folder (index.html, viewer.js, shaders.js, data.js), or one self-contained "
                        "page where it ends in .html, or a COPC file (--format copc; implied by .copc.laz)")
    p.add_argument("--format", choices=["web", "copc"], default=None,
                   help="web: the WebGL2 viewer; copc: a COPC 1.0 file (LAZ 1.4 octree with the splats' "
                        "normals and axes as extra bytes) for Potree, QGIS and PDAL (default: copc where "
                        "the output ends in .copc.laz, else web)")
    p.add_argument("--technique", default="ewa", choices=list(WEB_TECHNIQUES),
                   help="the page's first technique (switchable on the page; default ewa)")
    p.add_argument("--background", type=opt.UNIT, nargs=3, metavar=("R", "G", "B"), default=defaults.BACKGROUND,
                   help="the page's first background colour, components in [0, 1] (default white)")
    p.add_argument("--browser-lod", action="store_true",
                   help="export the whole hierarchy (a cloud's built) and let the page cut it per view: a point "
                        "budget (--point-budget: the page's first, default 1,000,000) refined largest node first "
                        "when the camera stops")
    p.add_argument("--memory-budget", type=opt.number(float, low=1), metavar="MB",
                   help="with --browser-lod of a chunked hierarchy (its cells loaded on demand): the page's first "
                        "memory budget for loaded cells, MB (default 512; least recently drawn cells let go)")
    p.add_argument("--size", type=opt.number(int, low=1, high=defaults.MAX_IMAGE_SIDE, what="pixels"), nargs=2,
                   metavar=("W", "H"), default=defaults.WINDOW_SIZE,
                   help=f"the page size the model is prepared for: a mesh sampled as `surfsplat render --width W "
                        f"--height H` samples it, a hierarchy cut at that default view (default "
                        f"{defaults.WINDOW_SIZE[0]} {defaults.WINDOW_SIZE[1]})")
    p.add_argument("--supersample", type=opt.number(int, low=1, high=MAX_PAGE_SUPERSAMPLE), default=1, metavar="K",
                   help=f"the page's first supersampling: K x K sub-pixels a pixel, as `surfsplat render "
                        f"--supersample K` (1 to {MAX_PAGE_SUPERSAMPLE}; ?supersample=K on the page; default 1)")
    p.add_argument("--position-bits", type=int, choices=POSITION_BITS, default=16,
                   help="the splat centres' precision in the page's box, bits a coordinate: 16 (19 bytes a splat, "
                        "the default) or 24 (22 bytes a splat; draws the desktop's very silhouette pixels)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing file or non-empty folder that surfsplat export did not write "
                        "(an earlier export is always replaced)")
    p.add_argument("--hybrid", action=argparse.BooleanOptionalAction, default=None,
                   help="the page draws non-planar neighbourhoods (vegetation, wires) as round points facing the "
                        "eye, as surface splats the planar ones, as `surfsplat render --hybrid` (default: on for "
                        "LAS/LAZ and E57 input)")
    opt.add_source_options(p)
    opt.add_lod_options(p)
    p.set_defaults(func=commands.cmd_export)

    add_view_command(sub)
    add_fit_command(sub)
    for subparser in sub.choices.values():
        _add_quiet(subparser, argparse.SUPPRESS)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    progress.write(f"{PROG}: warning: {message}")   # above any live progress bar


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``surfsplat`` command; returns the exit status (0, or 2 for a usage error,
    bad input or a failed render, after one line on stderr).

    Progress messages and the warning format apply only while the command runs: the
    process's settings are restored on return (so ``main`` can be called from Python).
    """
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a usage error argparse has printed
        return exc.code if isinstance(exc.code, int) else 2
    with progress.enabled(not args.quiet), warnings.catch_warnings():
        warnings.showwarning = _show_warning
        try:
            args.func(args)
        except SurfsplatError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            return 2
        except (FileNotFoundError, PermissionError, IsADirectoryError) as exc:
            print(f"{PROG}: error: {exc.filename}: {exc.strerror}", file=sys.stderr)
            return 2
        except MemoryError as exc:   # last resort: the commands check sizes against the memory available first
            print(f"{PROG}: error: out of memory{': ' + str(exc) if str(exc) else ''}", file=sys.stderr)
            return 2
    return 0
