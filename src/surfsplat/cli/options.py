"""Option groups shared by the subcommands (``render``, ``demo``, ``view``, ...), and their
conversion into the typed options of :mod:`surfsplat.api`.

Defaults are read from the dataclasses that own them (``FilterOptions``, ``Lights``, ...), so
each is written once and ``--help`` shows that value. Values are checked by argparse ``type=``
functions as the command line is parsed, before any file is read: a bad value is one usage
error naming the flag, the value and the allowed range (exit status 2).
"""

from __future__ import annotations

import argparse
import dataclasses
import math

from .. import defaults
from ..pipeline import LOD_AUTO, LOD_MODES, CameraSpec, LodOptions, SourceOptions
from ..rendering.lod_auto import AUTO_MIN_DENSITY
from ..camera import MIN_FOV, Camera
from ..colors import ColorOptions, check_colormap
from ..errors import InputError
from ..hierarchy import SHADINGS
from ..io.camera_file import load_camera
from ..geometry.robust import OUTLIER_ACTIONS
from ..io.surface import AUTO
from ..lighting import MAX_LIGHTS, Lights
from ..rendering.frame import BIT_DEPTHS
from ..rendering.options import KERNELS, EdlOptions, FilterOptions, KernelOptions, RenderOptions, VisibilityOptions
from ..rendering.techniques import TECHNIQUES

#: Output image size of ``render`` and ``demo`` (pixels; :mod:`surfsplat.defaults` says why it differs
#: from the Python API's).
IMAGE_SIZE = defaults.CLI_IMAGE_SIZE


def default(cls, name: str):
    """The default value of field ``name`` of dataclass ``cls`` (the one place it is written)."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            if f.default is not dataclasses.MISSING:
                return f.default
            return f.default_factory()  # type: ignore[operator]  # a field has a default or a factory
    raise KeyError(name)


def number(kind=float, *, low: float | None = None, high: float | None = None, low_open: bool = False,
           high_open: bool = False, what: str = ""):
    """An argparse ``type=`` parsing a finite ``kind`` (int or float) within [low, high] (a bound
    excluded when ``*_open``); argparse turns the error into a usage message naming the flag."""
    def parse(text: str):
        try:
            value = kind(text)
            ok = math.isfinite(value)
        except (ValueError, OverflowError):   # OverflowError: an integer beyond float's range
            value, ok = None, False
        if ok and low is not None:
            ok = value > low if low_open else value >= low
        if ok and high is not None:
            ok = value < high if high_open else value <= high
        if not ok:
            lo = "" if low is None else f"{'>' if low_open else '>='} {low:g}"
            hi = "" if high is None else f"{'<' if high_open else '<='} {high:g}"
            bounds = " and ".join(b for b in (lo, hi) if b)
            noun = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"must be {noun}{' ' + bounds if bounds else ''}"
                                             f"{' (' + what + ')' if what else ''}, got {text!r}")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in some messages
    return parse


UNIT = number(float, low=0.0, high=1.0, what="a color component")
SHARP_ANGLE = number(float, low=0.0, high=180.0, low_open=True, high_open=True,
                     what="the dihedral angle in degrees above which an edge is sharp")


def add_supersample_option(p: argparse.ArgumentParser) -> None:
    """``--supersample K``."""
    p.add_argument("--supersample", type=number(int, low=1, high=defaults.MAX_SUPERSAMPLE), default=1, metavar="K",
                   help=f"antialiasing: K x K samples per pixel, box-filtered (1..{defaults.MAX_SUPERSAMPLE}; "
                        f"default 1); any image size is drawn in tiles")


def add_output_options(p: argparse.ArgumentParser) -> None:
    """``--force``, ``--save-camera``, ``--supersample``, ``--transparent``, ``--bit-depth`` of the
    commands that write an image."""
    add_force_option(p)
    add_supersample_option(p)
    p.add_argument("--transparent", action="store_true",
                   help="write RGBA: alpha is the surface's coverage (antialiased with --supersample), for "
                        "compositing over any background (.png, .tif, .webp)")
    p.add_argument("--bit-depth", type=int, choices=BIT_DEPTHS, default=8, help="bits per channel (16: PNG only)")
    p.add_argument("--save-camera", metavar="FILE.json",
                   help="also write the camera used (for --camera; the chosen camera is printed as flags too)")


def sharp_angle_or_auto(text: str):
    """argparse ``type=`` of ``--sharp-angle``: degrees in (0, 180), ``auto`` or ``none``."""
    if text.lower() in ("auto", "none"):
        return text.lower()
    return SHARP_ANGLE(text)


def add_source_options(p: argparse.ArgumentParser) -> None:
    """How inputs become splats: raw points (``--k``, ``--outliers``), meshes (``--vertices``,
    ``--samples``), both (``--sharp-angle``)."""
    add_k_option(p)
    p.add_argument("--outliers", choices=OUTLIER_ACTIONS, default=default(SourceOptions, "outliers"),
                   help="raw points with no surface of their own (stray points, isolated clusters): drop them "
                        "(default), cap their splats to the local size, or keep them")
    p.add_argument("--vertices", action="store_true",
                   help="a mesh (a file with faces) is drawn as its vertices, preprocessed like scanned points, "
                        "instead of as its sampled surface")
    p.add_argument("--samples", type=number(int, low=2), metavar="N",
                   help=f"a mesh's surface gets N samples (default: {default(SourceOptions, 'spacing_px'):g} px "
                        "apart in the image, at most 2,000,000)")
    p.add_argument("--sharp-angle", type=sharp_angle_or_auto, default="auto", metavar="DEG",
                   help="edges sharper than DEG degrees (0 < DEG < 180) get clip lines and crisp shading; auto "
                        "(default): 30 for meshes with creases (CAD parts), none for smooth scans and for raw "
                        "points; none: no sharp edges; a number also detects sharp features in raw points)")
    add_color_options(p)


def colormap_name(text: str) -> str:
    """argparse ``type=`` of ``--colormap``: a name :func:`surfsplat.colors.check_colormap` knows
    (matplotlib's registry, or asprs), checked as the command line is parsed, before any file is read."""
    try:
        return check_colormap(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_color_options(p: argparse.ArgumentParser) -> None:
    """Colour by attribute: ``--color-by``, ``--colormap``, ``--color-range`` (:mod:`surfsplat.colors`)."""
    g = p.add_argument_group("colour by attribute")
    g.add_argument("--color-by", metavar="NAME",
                   help="colour the splats by elevation (along the up axis: +z for LAS/LAZ) or a per-point "
                        "attribute of the file: intensity, classification, return_number, gps_time, a PLY "
                        "property such as confidence, ... (`surfsplat info FILE` lists them)")
    g.add_argument("--colormap", type=colormap_name, metavar="NAME",
                   help="matplotlib colormap (viridis, turbo, magma, ...; needs the `color` extra) or asprs "
                        "(LAS class palette); default: asprs for classification, else viridis")
    g.add_argument("--color-range", type=number(float), nargs=2, metavar=("LO", "HI"),
                   help="values mapped to the ends of the colormap (default: the 2nd and 98th percentiles)")


def color_options(args) -> ColorOptions | None:
    """The ColorOptions of :func:`add_color_options`, or None without ``--color-by``."""
    if getattr(args, "color_by", None) is None:
        if getattr(args, "colormap", None) or getattr(args, "color_range", None):
            raise InputError("--colormap and --color-range need --color-by NAME")
        return None
    return ColorOptions(args.color_by, args.colormap, tuple(args.color_range) if args.color_range else None)


def source_options(args) -> SourceOptions:
    """The SourceOptions of :func:`add_source_options` (and ``--hybrid`` of the render options); the
    defaults for a command without them (``demo``)."""
    if not hasattr(args, "sharp_angle"):
        return SourceOptions(hybrid=getattr(args, "hybrid", None))
    angle = {"auto": AUTO, "none": None}.get(args.sharp_angle, args.sharp_angle)
    return SourceOptions(k=args.k, outliers=args.outliers, vertices=args.vertices, samples=args.samples,
                         sharp_angle=angle, color=color_options(args), hybrid=getattr(args, "hybrid", None))


def add_k_option(p: argparse.ArgumentParser) -> None:
    """``--k``: neighbours for preprocessing raw points."""
    p.add_argument("--k", type=number(int, low=3, what="neighbours"), default=default(SourceOptions, "k"),
                   help="neighbours for preprocessing raw points (default %(default)s)")


def add_force_option(p: argparse.ArgumentParser) -> None:
    """``--force``: accepted and ignored (outputs are always replaced), so older scripts keep working."""
    p.add_argument("--force", action="store_true",
                   help="no effect, kept for compatibility: an existing output is always replaced (atomically); "
                        "an input file is never overwritten")


def add_lod_options(p: argparse.ArgumentParser, *, window: bool = False) -> None:
    """``--lod-tolerance``, ``--lod-shading``, ``--lod-mode`` and ``--point-budget`` (:class:`LodOptions`);
    ``window``: the viewer's (its tolerance is a positive number of pixels, changed with +/-)."""
    pixels = number(float, low=0.0, low_open=window, what="pixels" if window else "pixels or auto")
    tolerance = pixels if window else (lambda text: LOD_AUTO if text == LOD_AUTO else pixels(text))
    p.add_argument("--lod-tolerance", type=tolerance, metavar="PX",
                   help=(f"LOD screen tolerance in pixels (default {defaults.LOD_TOLERANCE:g}; +/- in the window): the "
                         f"model's point-octree is cut where nodes project to at most PX pixels" if window else
                         f"level of detail: draw hierarchy nodes whose projected size is at most PX pixels as "
                         f"one splat (default {defaults.LOD_TOLERANCE:g} for a hierarchy MODEL.npz, every splat of a "
                         f"point file; a point file given PX > 0 gets its hierarchy built first); auto: a hierarchy "
                         f"cut at one pixel of the drawn image, a point file's points merged per half pixel where "
                         f"the view holds {AUTO_MIN_DENSITY:g} or more per pixel (no hierarchy built)"))
    p.add_argument("--lod-shading", choices=SHADINGS, default=defaults.LOD_SHADING,
                   help="normal field of coarse LOD splats: fit (least squares, default), cone (the normal "
                        "cone, Pajarola 2003 fig. 14) or flat")
    p.add_argument("--lod-mode", choices=LOD_MODES, default=defaults.LOD_MODE,
                   help="where a hierarchy's LOD cut is chosen: cpu (selected, gathered and uploaded per view), "
                        "gpu (sequential point trees: every node and point uploaded once, the vertex shader keeps "
                        "the cut; tolerance cut only, no --point-budget or hybrid points) or auto (default: gpu in "
                        "the window where it can, cpu for pictures)")
    p.add_argument("--point-budget", type=number(int, low=1, what="splats"), metavar="N",
                   help="draw at most N splats: the LOD cut refined largest node on screen first (Potree's "
                        "priority; a point file gets its hierarchy built first)")


def lod_options(args) -> LodOptions:
    """The LodOptions of :func:`add_lod_options`."""
    return LodOptions(tolerance=args.lod_tolerance, shading=args.lod_shading, point_budget=args.point_budget,
                      mode=args.lod_mode)


def add_camera_options(p: argparse.ArgumentParser) -> None:
    """``--eye``, ``--target``, ``--up``, ``--fov``."""
    p.add_argument("--eye", type=number(float), nargs=3, metavar=("X", "Y", "Z"), help="camera position (world)")
    p.add_argument("--target", type=number(float), nargs=3, metavar=("X", "Y", "Z"),
                   help="point looked at (default: the model's center)")
    p.add_argument("--up", type=number(float), nargs=3, metavar=("X", "Y", "Z"),
                   help="camera up vector (default: the data's up axis: 0 0 1 for LAS/LAZ and E57 files, else 0 1 0)")
    p.add_argument("--fov", type=number(float, low=MIN_FOV, high=180.0, high_open=True, what="degrees"),
                   default=default(CameraSpec, "fov"), help="vertical field of view in degrees (default %(default)s)")
    p.add_argument("--camera", metavar="FILE.json",
                   help="the camera of a file written by --save-camera (instead of the camera flags; its image "
                        "size unless --width/--height are given)")


def add_render_options(p: argparse.ArgumentParser, *, window: bool = False) -> None:
    """Technique, image size, camera, lighting, background and the render options (filter,
    visibility, deferred shading, blend kernel). ``window``: the sizes are a window's."""
    p.add_argument("--technique", default="ewa", choices=list(TECHNIQUES), help="rendering technique (default ewa)")
    side = number(int, low=1, high=defaults.MAX_IMAGE_SIDE, what="pixels")
    what = "window" if window else "image"
    size_help = " (overrides --size)" if window else f" (default {IMAGE_SIZE}, or the --camera file's)"
    p.add_argument("--width", type=side, help=f"{what} width in pixels{size_help}")
    p.add_argument("--height", type=side, help=f"{what} height in pixels{size_help}")
    add_camera_options(p)
    p.add_argument("--light", type=number(float), nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help=f"world direction toward a directional light; repeat for up to {MAX_LIGHTS} "
                        f"(default: headlight)")
    p.add_argument("--no-lighting", action="store_true", help="render unlit colors")
    p.add_argument("--background", type=UNIT, nargs=3, metavar=("R", "G", "B"), default=defaults.BACKGROUND,
                   help="background color, components in [0, 1] (default white)")
    p.add_argument("--no-prefilter", action="store_true", help="disable the EWA prefilter (H = I)")
    p.add_argument("--cutoff", type=number(float, low=0.0, low_open=True), default=default(FilterOptions, "cutoff"),
                   help="EWA kernel cutoff c (default %(default)s)")
    p.add_argument("--depth-epsilon", type=number(float, low=0.0), default=default(VisibilityOptions, "depth_epsilon"),
                   help="visibility offset along the viewing rays, in splat radii (default %(default)s)")
    p.add_argument("--cull-backfaces", action=argparse.BooleanOptionalAction, default=None,
                   help="drop splats facing away from the eye (closed models with outward normals only; "
                        "default: on for the surface of a closed mesh seen from outside with ewa/perspective, off "
                        "for other techniques, point clouds and open surfaces)")
    p.add_argument("--no-separate-sides", action="store_true",
                   help="blend splats seen from the back with the front surface within the depth epsilon "
                        "(default: a pixel blends only splats seen from the side of its nearest one, so hidden "
                        "walls never show through)")
    p.add_argument("--no-clip-fringe", action="store_true",
                   help="ewa/perspective: draw the papers' full prefiltered footprints, also beyond the surface over "
                        "the background and farther surfaces (default: they end at the surface: thinner, sharper "
                        "silhouettes and fold crests)")
    p.add_argument("--edge-coverage", action=argparse.BooleanOptionalAction,
                   default=default(VisibilityOptions, "edge_coverage"),
                   help="antialias silhouettes over the background without supersampling: a rim pixel's alpha is "
                        "the area of it the splats' disks cover (ewa/perspective both sides of the rim, blend/phong "
                        "its inner side; default on: --no-edge-coverage draws all-or-nothing rims)")
    p.add_argument("--fill-holes", action=argparse.BooleanOptionalAction, default=default(RenderOptions, "fill_holes"),
                   help="fill holes of up to 3 pixels between the pixels of the front surface in screen space "
                        "(depth-aware: never from a surface behind; silhouettes do not grow; default %(default)s)")
    p.add_argument("--no-compute", action="store_true",
                   help="draw every splat through the raster pipeline, not the small splats' first pass with "
                        "compute shaders (used where OpenGL 4.3 is there: faster on the CPU renderer, the same "
                        "pictures)")
    p.add_argument("--deferred", action="store_true",
                   help="deferred shading: blend albedo and normals, light each pixel once (any technique; "
                        "better on smooth surfaces, worse at creases)")
    p.add_argument("--kernel", choices=KERNELS, default=default(KernelOptions, "name"),
                   help="blend technique's kernel: pajarola exp(-a (r/b)^n) or gaussian exp(-r^2 / 2 sigma^2) "
                        "(default %(default)s)")
    positive = number(float, low=0.0, low_open=True)
    p.add_argument("--kernel-a", type=positive, default=default(KernelOptions, "a"), metavar="A",
                   help="a of the pajarola kernel (default %(default)s)")
    p.add_argument("--kernel-b", type=positive, default=default(KernelOptions, "b"), metavar="B",
                   help="b: the kernel's support radius r at the splat's rim (default %(default)s)")
    p.add_argument("--kernel-n", type=positive, default=default(KernelOptions, "n"), metavar="N",
                   help="n of the pajarola kernel (default %(default)s)")
    p.add_argument("--kernel-sigma", type=positive, default=default(KernelOptions, "sigma"), metavar="S",
                   help="sigma of the gaussian kernel, units of b (default %(default)s)")
    p.add_argument("--hybrid", action=argparse.BooleanOptionalAction, default=None,
                   help="draw non-planar neighbourhoods (vegetation, wires) as round points facing the eye and "
                        "planar ones as surface splats, in one frame (default: on for LAS/LAZ input)")
    p.add_argument("--edl", action="store_true",
                   help="eye-dome lighting (Boucheny 2009): shade by depth discontinuities alone, for clouds "
                        "without normals or colors (any technique; in the window still views, key O)")
    p.add_argument("--edl-strength", type=positive, default=default(EdlOptions, "strength"), metavar="S",
                   help="EDL strength s in exp(-s sum max(0, log2 z - log2 z_neighbour)) (default %(default)s)")
    p.add_argument("--edl-radius", type=number(float, low=1.0, high=64.0, what="pixels"),
                   default=default(EdlOptions, "radius_px"), metavar="PX",
                   help="EDL neighbour distance in pixels (default %(default)s)")


# -- parsed flags -> typed options -------------------------------------------------------

def render_options(args) -> RenderOptions:
    """The RenderOptions the flags of :func:`add_render_options` ask for."""
    return RenderOptions(
        filter=FilterOptions(prefilter=not args.no_prefilter, cutoff=args.cutoff),
        visibility=VisibilityOptions(depth_epsilon=args.depth_epsilon, cull_backfaces=args.cull_backfaces,
                                     separate_sides=not args.no_separate_sides, clip_fringe=not args.no_clip_fringe,
                                     edge_coverage=args.edge_coverage),
        kernel=KernelOptions(name=args.kernel, a=args.kernel_a, b=args.kernel_b, n=args.kernel_n,
                             sigma=args.kernel_sigma),
        deferred=args.deferred,
        edl=EdlOptions(strength=args.edl_strength, radius_px=args.edl_radius) if args.edl else None,
        fill_holes=args.fill_holes, compute=not args.no_compute)


def lights(args) -> Lights:
    """The Lights of ``--light`` (repeatable) and ``--no-lighting``."""
    directions = tuple(tuple(d) for d in args.light) if args.light else None
    return Lights(directions=directions, enabled=not args.no_lighting)


def camera_spec(args) -> Camera | CameraSpec:
    """The Camera of ``--camera FILE`` (sized by ``--width``/``--height`` when given), else the
    CameraSpec of ``--eye``, ``--target``, ``--up``, ``--fov``."""
    if args.camera:
        if args.eye is not None or args.target is not None or args.up is not None:
            raise InputError("give either --camera FILE or --eye/--target/--up, not both")
        camera = load_camera(args.camera)
        return camera.resized(args.width or camera.width, args.height or camera.height)
    return CameraSpec(eye=tuple(args.eye) if args.eye is not None else None,
                      target=tuple(args.target) if args.target is not None else None,
                      up=tuple(args.up) if args.up is not None else None, fov=args.fov)


def image_size(args, camera=None) -> tuple[int, int]:
    """(width, height): the flags', else the camera file's, else :data:`IMAGE_SIZE`."""
    width = args.width or (camera.width if isinstance(camera, Camera) else IMAGE_SIZE)
    height = args.height or (camera.height if isinstance(camera, Camera) else IMAGE_SIZE)
    return width, height
