"""This tree's shaders against another checkout's, frames alternated in one process: a change to the
``.glsl`` files timed on a shared machine, and whether the pictures are the same.

The peers' 1 M-point scenes (``render_passes.scene_setup``: preprocessed, culled where the view plan
culls, 1024 x 1024, the peers' cameras and lights), one upload into each of two renderers: one reading
the shaders of ``--against`` (a ``rendering/glsl`` folder, e.g. of the main checkout) first, one this
tree's. Per round one frame of each (drawn and read back), timed in wall and process CPU time (llvmpipe's
threads included); medians over ``--rounds`` after a warm-up, their ratio, and the largest colour
difference of the two pictures.

    python benchmarks/shader_ab.py --against ../main/src/surfsplat/rendering/glsl [--work /tmp/peers-data]

Writes benchmarks/results/shader_ab.md and .json.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_description, save_results  # noqa: E402
from render_passes import SCENES, scene_setup  # noqa: E402

from surfsplat.pipeline import local_camera  # noqa: E402
from surfsplat.rendering.renderer import Renderer  # noqa: E402


def compare(scene: str, path: Path, technique: str, kinds: dict, rounds: int, size: int) -> dict:
    """One scene's row: medians of both kinds of frame (``kinds``: the two renderers), alternated."""
    cloud, camera, lights, options = scene_setup(scene, path, size)
    uploads = {}
    for name, r in kinds.items():
        with r.ctx:   # moderngl works on the current context: make each renderer's current for its calls
            uploads[name] = r.upload(cloud)
    local = local_camera(cloud, camera)
    images, wall, cpu = {}, {k: [] for k in kinds}, {k: [] for k in kinds}
    for name, r in kinds.items():
        with r.ctx:
            r.render(uploads[name], local, technique, lights, options, background=(0, 0, 0))   # compile, warm up
    for _ in range(rounds):
        for name, r in kinds.items():
            with r.ctx:
                t, c = time.perf_counter(), time.process_time()
                images[name] = r.render(uploads[name], local, technique, lights, options, background=(0, 0, 0)).color
                wall[name].append(time.perf_counter() - t)
                cpu[name].append(time.process_time() - c)
    for name, r in kinds.items():
        with r.ctx:
            uploads[name].release()
    med = {k: (1e3 * float(np.median(wall[k])), 1e3 * float(np.median(cpu[k]))) for k in kinds}
    diff = np.abs(images["against"] - images["this tree"])
    return {"scene": scene, "technique": technique, "splats": len(cloud),
            "against_ms": med["against"], "this_ms": med["this tree"],
            "cpu_ratio": med["this tree"][1] / med["against"][1], "wall_ratio": med["this tree"][0] / med["against"][0],
            "max_diff": float(diff.max()), "pixels_over_1_255": int(np.count_nonzero(diff.max(-1) > 1 / 255)),
            "cpu_ms": {k: [round(1e3 * x) for x in v] for k, v in cpu.items()}, "load": os.getloadavg()[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, required=True, help="the other checkout's rendering/glsl folder")
    parser.add_argument("--work", default="/tmp/peers-data", help="the peers' bench folder holding the scenes")
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--techniques", nargs="+", default=["ewa"])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--size", type=int, default=1024)
    args = parser.parse_args()
    rows = []
    # one pair of renderers for every scene
    kinds = {"against": Renderer(search_path=[str(args.against)]), "this tree": Renderer()}
    for scene in args.scenes:
        for technique in args.techniques:
            rows.append(compare(scene, Path(args.work) / f"{scene}_1000000.ply", technique, kinds, args.rounds,
                                args.size))
            print(rows[-1], flush=True)
    lines = [f"Machine: {machine_description()}, GL: llvmpipe; {time.strftime('%Y-%m-%d')}; command: "
             f"`python benchmarks/shader_ab.py {shlex.join(sys.argv[1:])}`", "",
             f"{args.size}x{args.size}, frames alternated ({args.rounds} rounds after a warm-up, medians): the "
             "shaders of `--against` and this tree's. The machine is shared: the ratios are the result.", "",
             "| scene | technique | splats | against: wall ms, CPU ms | this tree: wall ms, CPU ms | CPU ratio | "
             "wall ratio | largest difference | pixels > 1/255 | load |",
             "|---|---|---:|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['technique']} | {r['splats']:,} | {r['against_ms'][0]:,.0f}, "
                     f"{r['against_ms'][1]:,.0f} | {r['this_ms'][0]:,.0f}, {r['this_ms'][1]:,.0f} | "
                     f"{r['cpu_ratio']:.2f} | {r['wall_ratio']:.2f} | {r['max_diff']:.1e} | {r['pixels_over_1_255']} | "
                     f"{r['load']:.1f} |")
    save_results("shader_ab", "\n".join(lines) + "\n", rows)


if __name__ == "__main__":
    main()
