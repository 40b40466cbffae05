"""The ``surfsplat view`` subcommand: the interactive window (:func:`surfsplat.viewer.view`)."""

from __future__ import annotations

import argparse

from .. import defaults
from ..viewer import MOTION_MODES, MotionOptions, view
from . import options as opt
from .commands import check_output, inputs_of

VIEW_EPILOG = """\
keys in the window: mouse left drag orbit, right/middle drag pan, wheel zoom; F fly mode
(W A S D Q E move, arrows look); R reset view; T or 1..9 technique; P prefilter; L lighting;
B back-face culling; O eye-dome lighting; C colour by (own, elevation, attributes); +/- LOD tolerance;
S screenshot; H help; Esc or Q quit.
scripted: surfsplat view demo:torus --frames 36 --orbit 10 --screenshot turn.png
without a display: xvfb-run -s '-screen 0 1280x1024x24' surfsplat view ... --screenshot out.png"""

WINDOW_SIZE = defaults.WINDOW_SIZE


def add_view_command(subparsers) -> argparse.ArgumentParser:
    """Define ``view`` on ``subparsers``; returns the subparser."""
    p = subparsers.add_parser(
        "view", help="open an interactive window on a model (orbit, pan, zoom, fly; H for help)",
        description="Interactive viewer: the same renderer as `surfsplat render`, in a window.",
        epilog=VIEW_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="PLY, OBJ or LAS file, a hierarchy MODEL.npz (surfsplat build), or demo:NAME "
                                 "for a built-in scene (e.g. demo:torus)")
    opt.add_source_options(p)
    opt.add_render_options(p, window=True)
    p.add_argument("--size", type=opt.number(int, low=1, high=defaults.MAX_WINDOW_SIDE, what="pixels"), nargs=2,
                   metavar=("W", "H"), default=WINDOW_SIZE,
                   help=f"window size in pixels (default {WINDOW_SIZE[0]} {WINDOW_SIZE[1]}; larger framebuffer on "
                        f"HiDPI screens); --width/--height override one side")
    opt.add_lod_options(p, window=True)

    p.add_argument("--record", metavar="OUT.mp4|OUT.gif",
                   help="record the frames the window shows (24 frames/s; .gif, or .mp4/.webm with the video extra)")
    motion = MotionOptions()
    p.add_argument("--motion", choices=MOTION_MODES, default=motion.mode,
                   help="while the camera moves draw: flat one-pass disks, the same technique, or full "
                        "quality (off); auto (default): flat where a full-quality frame takes over 50 ms")
    p.add_argument("--motion-budget", type=opt.number(int, low=0, what="splats; 0: all"), default=motion.budget,
                   metavar="N", help=f"about N splats (at most) while moving (default {motion.budget:,}; 0: all)")
    p.add_argument("--motion-scale", type=opt.number(float, low=0.0, high=1.0, low_open=True), default=motion.scale,
                   metavar="S", help=f"internal resolution while moving, fraction of the window's "
                                     f"(default {motion.scale:g}, upscaled bilinearly)")
    p.add_argument("--motion-fps", type=opt.number(float, low=0.0, high=1000.0), default=motion.fps, metavar="F",
                   help=f"frames per second kept while moving: the preview steps to coarser or finer "
                        f"levels (of at most --motion-budget splats) to keep it (default {motion.fps:g}; 0: off)")
    p.add_argument("--no-hud", action="store_true", help="hide the heads-up display")
    p.add_argument("--frames", type=opt.number(int, low=1), metavar="N",
                   help="scripted mode: render N frames, then exit (with --orbit, --screenshot)")
    p.add_argument("--orbit", type=opt.number(float), default=0.0, metavar="DEG",
                   help="scripted mode: turn the eye DEG degrees about the up axis before each frame")
    p.add_argument("--screenshot", metavar="OUT.png",
                   help="scripted mode: save the last frame (full quality, no HUD) to OUT.png and exit")
    p.set_defaults(func=cmd_view)
    return p


def cmd_view(args) -> None:
    """Run ``surfsplat view`` with parsed arguments."""
    for out in (args.screenshot, args.record):   # replaced when written, unless it is an input
        if out:
            check_output(out, inputs_of(args))
    width, height = args.size
    view(args.input, opt.camera_spec(args), technique=args.technique,
         size=(args.width or width, args.height or height), lights=opt.lights(args),
         background=tuple(args.background), options=opt.render_options(args), lod=opt.lod_options(args),
         motion=MotionOptions(mode=args.motion, budget=args.motion_budget, scale=args.motion_scale,
                              fps=args.motion_fps),
         hud=not args.no_hud, frames=args.frames, orbit=args.orbit, screenshot=args.screenshot,
         source_options=opt.source_options(args), record=args.record)
