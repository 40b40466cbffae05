"""Hidden splats skipped per 8 x 8-pixel block (``passes.HizPass``, ``hiz.glsl``) against every splat drawn.

The peers' 1 M-point scenes (``../shared/peers``'s ``bench.py`` samples them into ``--work``: the bunny and
the torus, their cameras and lights), preprocessed as ``bench_peers.py`` does, drawn by
``Renderer.render`` (read-back included) with the test on (``passes.HIZ_BLOCK = 8``) and off (0), frames
alternated in one process, and the largest difference between the two frames (0: the same picture).

    python benchmarks/hiz_culling.py [--work /tmp/peers-data] [--size 1024] [--repeat 3] [--techniques ewa flat]

Writes benchmarks/results/hiz_culling.md and .json.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_description, save_results  # noqa: E402

SCENES = {   # the peers' bench.py cameras and lights
    "bunny": dict(eye=(0.08, 0.16, 0.30), target=(-0.017, 0.11, 0.0), up=(0, 1, 0), fov=36, light=(0.5, 1.0, 0.8)),
    "torus": dict(eye=(0.0, -3.2, 2.4), target=(0.0, 0.0, 0.0), up=(0, 0, 1), fov=42, light=(0.3, -0.5, 1.0)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default="/tmp/peers-data", help="the peers' bench.py --work folder (its PLYs)")
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--techniques", nargs="+", default=["ewa", "flat"])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    args = parser.parse_args()

    from surfsplat.camera import Camera
    from surfsplat.geometry.preprocess import preprocess
    from surfsplat.io import load
    from surfsplat.lighting import Lights
    from surfsplat.pipeline import View, local_camera
    from surfsplat.rendering import passes
    from surfsplat.rendering.options import RenderOptions, VisibilityOptions
    from surfsplat.rendering.renderer import default_renderer

    renderer = default_renderer()
    rows = []
    for scene in args.scenes:
        spec = SCENES[scene]
        cloud = preprocess(load(Path(args.work) / f"{scene}_1000000.ply"))
        camera = Camera(eye=spec["eye"], target=spec["target"], up=spec["up"], fov=spec["fov"], width=args.size,
                        height=args.size)
        camera = camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))
        lights = Lights(directions=[spec["light"]], ambient=0.2, diffuse=0.8, specular=0.3, shininess=32)
        view = View(cloud)
        options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=view.culls(camera)))
        drawn = view.sample(camera).data
        gpu = renderer.upload(drawn)
        local = local_camera(drawn, camera)
        for technique in args.techniques:
            def frame(block: int):
                passes.HIZ_BLOCK = block
                return renderer.render(gpu, local, technique, lights, options, background=(1.0, 1.0, 1.0))

            frames = {block: frame(block) for block in (0, 8)}   # warm-up, and the pictures compared
            wall: dict[int, list] = {0: [], 8: []}
            cpu: dict[int, list] = {0: [], 8: []}
            for _ in range(args.repeat):
                for block in (0, 8):
                    start, start_cpu = time.perf_counter(), time.process_time()
                    frame(block)
                    wall[block].append(time.perf_counter() - start)
                    cpu[block].append(time.process_time() - start_cpu)
            passes.HIZ_BLOCK = 8
            diff = float(np.abs(frames[0].color - frames[8].color).max())
            row = {"scene": scene, "technique": technique, "splats": len(drawn), "size": args.size,
                   "off_wall_ms": 1e3 * float(np.median(wall[0])), "on_wall_ms": 1e3 * float(np.median(wall[8])),
                   "off_cpu_ms": 1e3 * float(np.median(cpu[0])), "on_cpu_ms": 1e3 * float(np.median(cpu[8])),
                   "largest_color_difference": diff}
            rows.append(row)
            print(row, flush=True)
        gpu.release()

    lines = [f"Machine: {machine_description()}, GL: llvmpipe; {time.strftime('%Y-%m-%d')}; command: "
             f"`python {' '.join(shlex.quote(a) for a in sys.argv)}`",
             "",
             f"The peers' 1 M-point scenes at {args.size}x{args.size}, `Renderer.render` with read-back, the test "
             f"on and off alternated in one process ({args.repeat} frames each, median; wall and process CPU "
             f"time, llvmpipe's threads included); the machine is shared: read the ratios.",
             "",
             "| scene | technique | off: wall ms | on: wall ms | wall ratio | off: CPU ms | on: CPU ms | CPU ratio | "
             "largest colour difference |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['technique']} | {r['off_wall_ms']:,.0f} | {r['on_wall_ms']:,.0f} | "
                     f"{r['on_wall_ms'] / r['off_wall_ms']:.2f} | {r['off_cpu_ms']:,.0f} | {r['on_cpu_ms']:,.0f} | "
                     f"{r['on_cpu_ms'] / r['off_cpu_ms']:.2f} | {r['largest_color_difference']:g} |")
    text = "\n".join(lines) + "\n"
    save_results("hiz_culling", text, rows)


if __name__ == "__main__":
    main()
