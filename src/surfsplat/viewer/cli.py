"""The ``surfsplat view`` subcommand.

``surfsplat.cli`` adds it with ``add_view_command(subparsers, _add_view_options)``.
``python -m surfsplat.viewer.cli view ...`` runs it on its own (tests use that).
"""

from __future__ import annotations

import argparse
import sys


VIEW_EPILOG = """\
keys in the window: mouse left drag orbit, right/middle drag pan, wheel zoom; F fly mode
(W A S D Q E move, arrows look); R reset view; T or 1..9 technique; P prefilter; L lighting;
B back-face culling; +/- LOD tolerance; S screenshot; H help; Esc or Q quit.
scripted: surfsplat view demo:torus --frames 36 --orbit 10 --screenshot turn.png
without a display: xvfb-run -s '-screen 0 1280x1024x24' surfsplat view ... --screenshot out.png"""


def add_view_command(subparsers, add_view_options) -> argparse.ArgumentParser:
    """Define ``view`` on ``subparsers``; ``add_view_options(parser)`` adds the shared render options
    (technique, camera, lighting, prefilter, ...). Returns the subparser."""
    from .app import DEFAULT_MOTION_BUDGET, DEFAULT_MOTION_SCALE

    p = subparsers.add_parser(
        "view", help="open an interactive window on a model (orbit, pan, zoom, fly; H for help)",
        description="Interactive viewer: the same renderer as `surfsplat render`, in a window.",
        epilog=VIEW_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="PLY, OBJ or LAS file, a hierarchy MODEL.npz (surfsplat build), or demo:NAME "
                                 "for a built-in scene (e.g. demo:torus)")
    p.add_argument("--k", type=int, default=8, help="neighbours for preprocessing raw points (default 8)")
    add_view_options(p)
    # The window's size is --size; --width/--height (from the shared options) override one side.
    for action in p._actions:  # argparse has no public way to change an added option's default/help
        if action.dest in ("width", "height"):
            action.default = None
            action.help = f"window {action.dest} in pixels (overrides --size)"
    p.add_argument("--size", type=int, nargs=2, metavar=("W", "H"), default=(1280, 720),
                   help="window size in pixels (default 1280 720; larger framebuffer on HiDPI screens)")
    p.add_argument("--lod-tolerance", "--tolerance", dest="tolerance", type=float, default=1.0, metavar="PX",
                   help="LOD screen tolerance in pixels (default 1; +/- in the window): the model's point-octree "
                        "is cut where nodes project to at most PX pixels")
    p.add_argument("--motion", choices=("auto", "flat", "same", "off"), default="auto",
                   help="while the camera moves draw: flat one-pass disks, the same technique, or full "
                        "quality (off); auto (default): flat where a full-quality frame takes over 50 ms")
    p.add_argument("--motion-budget", type=int, default=DEFAULT_MOTION_BUDGET, metavar="N",
                   help=f"about N splats (at most) while moving (default {DEFAULT_MOTION_BUDGET:,}; 0: all)")
    p.add_argument("--motion-scale", type=float, default=DEFAULT_MOTION_SCALE, metavar="S",
                   help=f"internal resolution while moving, fraction of the window's "
                        f"(default {DEFAULT_MOTION_SCALE:g}, upscaled bilinearly)")
    p.add_argument("--no-hud", action="store_true", help="hide the heads-up display")
    p.add_argument("--frames", type=int, metavar="N",
                   help="scripted mode: render N frames, then exit (with --orbit, --screenshot)")
    p.add_argument("--orbit", type=float, default=0.0, metavar="DEG",
                   help="scripted mode: turn the eye DEG degrees about the up axis before each frame")
    p.add_argument("--screenshot", metavar="OUT.png",
                   help="scripted mode: save the last frame (full quality, no HUD) to OUT.png and exit")
    p.set_defaults(func=cmd_view)
    return p


def cmd_view(args) -> None:
    """Run ``surfsplat view`` with parsed arguments."""
    from ..cli import _lights, _render_options
    from .app import view

    width, height = args.size
    size = (args.width or width, args.height or height)
    view(args.input, technique=args.technique, size=size, eye=args.eye, target=args.target, up=tuple(args.up),
         fov=args.fov, lights=_lights(args), background=tuple(args.background), tolerance=args.tolerance,
         motion=args.motion, motion_budget=args.motion_budget,
         motion_scale=args.motion_scale, hud=not args.no_hud, frames=args.frames, orbit=args.orbit,
         screenshot=args.screenshot, k=args.k, **_render_options(args))


def main(argv: list[str] | None = None) -> int:
    """``surfsplat view`` on its own (``python -m surfsplat.viewer.cli view ...``); returns the exit status."""
    from ..cli import main as surfsplat_main

    return surfsplat_main(argv)


if __name__ == "__main__":
    sys.exit(main())
