"""Frame times of every technique at 1920x1080 for 1M, 10M and 50M splats: the GPU benchmark.

Usage:
    python benchmarks/bench_gpu.py [--sizes 1000000 10000000 50000000] [--width 1920 --height 1080]
                                   [--repeat 5] [--techniques ...] [--allow-software] [--name gpu]

Run it through ``benchmarks/gpu.sh`` on a machine with a GPU: that script checks EGL on the vendor's
driver first. The scene is the generated torus (``surfsplat.scenes.torus``: one elliptical splat per
(theta, phi) grid cell, about two splats over each surface point) scaled to each size, so that no input
file is needed and 50M splats are generated in seconds. The camera is the automatic one. A frame is
``Renderer.render`` of the uploaded splats with read-back into a Frame (as users call it once the cloud is
uploaded); the median of ``--repeat`` frames after one warm-up frame. Splats/s = splats / median frame.
Without ``--allow-software`` the script refuses to run on a software rasterizer (llvmpipe, softpipe,
SwiftShader), whose numbers belong in ``render.md``. Writes ``results/{name}.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swiftshader", "software")
DEFAULT_TECHNIQUES = ["ewa", "flat", "points", "perspective", "phong", "blend"]


def torus_splats(n: int):
    """The generated torus with about ``n`` splats (tube circumference 0.4 of the ring's: 2.5 : 1 cells)."""
    import math

    from surfsplat.scenes import torus

    n_minor = max(3, round(math.sqrt(n / 2.5)))
    n_major = max(3, round(n / n_minor))
    return torus(n_major=n_major, n_minor=n_minor)


def is_software(renderer_name: str) -> bool:
    """Whether a GL_RENDERER string names a software rasterizer."""
    return any(word in renderer_name.lower() for word in SOFTWARE_RENDERERS)


def time_frames(renderer, gpu, camera, technique: str, repeat: int) -> float:
    """Median wall time of ``repeat`` frames (render and read-back), seconds, after one warm-up frame."""
    from surfsplat.lighting import Lights

    renderer.render(gpu, camera, technique, Lights())
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        renderer.render(gpu, camera, technique, Lights())
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1_000_000, 10_000_000, 50_000_000])
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--techniques", nargs="+", default=DEFAULT_TECHNIQUES)
    parser.add_argument("--allow-software", action="store_true",
                        help="run on a software rasterizer too (to check the script, not to measure a GPU)")
    parser.add_argument("--name", default="gpu", help="results/NAME.md and .json")
    args = parser.parse_args(argv)

    from common import machine_description, write_table

    from surfsplat.pipeline import auto_camera
    from surfsplat.rendering.context import renderer_name
    from surfsplat.rendering.renderer import Renderer

    renderer = Renderer()
    gl = renderer_name(renderer.ctx)
    print(f"GL: {gl}", flush=True)
    if is_software(gl) and not args.allow_software:
        print("bench_gpu: the OpenGL renderer is a software rasterizer; this benchmark measures a GPU "
              "(pass --allow-software to run it anyway)", file=sys.stderr)
        return 2
    rows = []
    for n in args.sizes:
        start = time.perf_counter()
        cloud = torus_splats(n)
        made = time.perf_counter() - start
        start = time.perf_counter()
        gpu = renderer.upload(cloud)
        renderer.ctx.finish()
        upload = time.perf_counter() - start
        camera = auto_camera(cloud, args.width, args.height)
        print(f"{len(cloud):,} splats: generated in {made:.1f} s, uploaded in {upload:.2f} s", flush=True)
        for technique in args.techniques:
            frame = time_frames(renderer, gpu, camera, technique, args.repeat)
            row = [f"{args.width}x{args.height}", len(cloud), technique, round(frame * 1e3, 2),
                   round(len(cloud) / frame / 1e6, 1), round(upload, 2)]
            print("  ", row, flush=True)
            rows.append(row)
        renderer.forget_upload()
        del gpu, cloud
    write_table(args.name, ["resolution", "splats", "technique", "frame ms (median)", "M splats/s", "upload s"],
                rows, machine_description(gl) + f"; generated torus, automatic camera, median of {args.repeat} "
                f"frames; command: python benchmarks/bench_gpu.py {' '.join(argv or sys.argv[1:])}".rstrip())
    return 0


if __name__ == "__main__":
    sys.exit(main())
