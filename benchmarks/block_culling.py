"""The per-block choices of a frame (``Renderer._drawn_ranges``) against the global ones, in one process.

Usage:
    python benchmarks/block_culling.py [--splats 1000000] [--size 1024] [--repeat 5] [--techniques ewa flat ...]

The Stanford bunny (../shared/data) sampled to ``--splats`` splats (``bench_render.bunny``), three views:
the whole model (the automatic camera), a close-up of the head (a quarter of the splats in the view) and a
view from inside the model's bounds (at half the size). Each frame is ``Renderer.render`` with read-back; "global" draws
every block with the radius classes' choice of quads and points (the nearest depth of the whole model),
"per block" skips the blocks that cannot reach the view and draws as points the blocks of quads far
enough away: frames alternated, median of ``--repeat``. Also: the splats given to the GPU, and the
largest colour difference between the two frames. Writes ``results/block_culling.md`` (and ``.json``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_render import bunny  # noqa: E402
from common import machine_description, write_table  # noqa: E402


def views(cloud, size: int) -> dict:
    """The three cameras: whole model, close-up, inside the bounds."""
    from surfsplat.pipeline import CameraSpec
    from surfsplat.camera import Camera

    lo, hi = cloud.bounds()
    margin = float(cloud.radii.max())
    whole = CameraSpec(up=(0, 1, 0)).camera_for(cloud, size, size)
    # the head and ears from in front, about a quarter of the splats in the view (Stanford frame, y up)
    head = lo + np.array([0.22, 0.76, 0.68]) * (hi - lo)
    close = Camera(eye=tuple(head + np.array([0.03, 0.02, 0.08])), target=tuple(head), up=(0, 1, 0), fov=36,
                   width=size, height=size)
    # half the size: splats next to the eye cover most of the image (seconds per frame)
    inside = Camera(eye=tuple(0.5 * (lo + hi)), target=tuple(hi), up=(0, 1, 0), fov=60, width=size // 2,
                    height=size // 2)
    return {name: camera.with_clip_from_bounds(lo, hi, margin=margin)
            for name, camera in (("whole model", whole), ("close-up", close), ("inside the bounds", inside))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--techniques", nargs="+", default=["ewa", "flat", "points"])
    args = parser.parse_args()

    from surfsplat.lighting import Lights
    from surfsplat.rendering.options import RenderOptions, VisibilityOptions
    from surfsplat.rendering.renderer import Renderer, point_radius

    cloud = bunny(args.splats)
    renderer = Renderer()
    gpu = renderer.upload(cloud)
    per_block = Renderer._drawn_ranges
    given: list[int] = []

    def global_choice(self, splats, camera, technique, options, supersample, tile=None):
        return splats.draw_ranges(camera, point_radius(camera, splats, technique, options, supersample,
                                                       self.point_px))

    def counted(choice):
        def ranges(self, *a):
            quads, points = choice(self, *a)
            given.append(sum(n for _, n in quads + points))
            return quads, points
        return ranges

    options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=True))   # a closed model seen from outside
    rows = []
    for view, camera in views(cloud, args.size).items():
        view_options = options if view != "inside the bounds" else RenderOptions()
        for technique in args.techniques:
            times = {"global": [], "per block": []}
            frames, counts = {}, {}
            for _ in range(args.repeat + 1):   # the first round warms up
                for mode, choice in (("global", global_choice), ("per block", per_block)):
                    Renderer._drawn_ranges = counted(choice)
                    given.clear()
                    start = time.perf_counter()
                    frames[mode] = renderer.render(gpu, camera, technique, Lights(), view_options).color
                    times[mode].append(time.perf_counter() - start)
                    counts[mode] = given[0]
            Renderer._drawn_ranges = per_block
            ms = {mode: 1000 * float(np.median(t[1:])) for mode, t in times.items()}
            diff = float(np.abs(frames["global"] - frames["per block"]).max())
            rows.append([view, technique, f"{counts['global']:,}", f"{counts['per block']:,}", f"{ms['global']:,.0f}",
                         f"{ms['per block']:,.0f}", f"{ms['global'] / ms['per block']:.2f}x", f"{diff:.2g}"])
            print(rows[-1], flush=True)
    gpu.release()
    machine = machine_description(renderer.ctx.info["GL_RENDERER"])
    columns = ["view", "technique", "splats given (global)", "splats given (per block)", "frame ms (global)",
               "frame ms (per block)", "speed-up", "largest colour difference"]
    write_table("block_culling", columns, rows,
                f"{machine}; bunny {len(cloud):,} splats at {args.size}x{args.size}, median of {args.repeat}")


if __name__ == "__main__":
    main()
