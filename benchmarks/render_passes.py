"""Where a frame's time goes: CPU time of each pass of Renderer.render, per technique (llvmpipe).

The input is the peers' scenes (../shared/peers: ``bench.py`` writes ``bunny_1000000.ply`` and
``torus_1000000.ply`` into its ``--work`` folder, 1M points sampled from the meshes with normals),
preprocessed as ``bench_peers.py`` does, back faces culled where ``surfsplat.pipeline.View.culls``
culls them, uploaded once, drawn at 1024x1024 with the peers' cameras. Every draw call is wrapped in
glFinish and timed in process CPU time (llvmpipe's threads included), which a busy machine disturbs
less than wall time, and so are the compute passes of the small splats (``render/compute_visibility.py``,
where the context has OpenGL 4.3; ``--raster-only`` draws every splat instead); the frame is also timed whole
(wall and CPU, median of ``--repeat``).

    python benchmarks/render_passes.py [--work /tmp/peers-data] [--techniques ewa flat blend] [--raster-only]
    python benchmarks/render_passes.py --interleaved   # compute passes against raster only, alternated

Tables: results/render_passes.md (render_passes_raster.md with ``--raster-only``; compute_passes.md with
``--interleaved``).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import sys
import time
from pathlib import Path

import moderngl
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import machine_description, write_table  # noqa: E402

from surfsplat.camera import Camera  # noqa: E402
from surfsplat.geometry.preprocess import preprocess  # noqa: E402
from surfsplat.io import load  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402
from surfsplat.pipeline import View, local_camera  # noqa: E402
from surfsplat.rendering import compute_visibility  # noqa: E402
from surfsplat.rendering.options import RenderOptions, VisibilityOptions  # noqa: E402
from surfsplat.rendering.renderer import Renderer  # noqa: E402

#: The peers' cameras and lights (../shared/peers/bench.py SCENES).
SCENES = {
    "bunny": dict(eye=(0.08, 0.16, 0.30), target=(-0.017, 0.11, 0.0), up=(0, 1, 0), fov=36, light=(0.5, 1.0, 0.8)),
    "torus": dict(eye=(0.0, -3.2, 2.4), target=(0.0, 0.0, 0.0), up=(0, 0, 1), fov=42, light=(0.3, -0.5, 1.0)),
}
PASS_NAMES = {0: "opaque", 1: "visibility", 2: "accumulation"}


def pass_name(key: tuple) -> str:
    """A readable name of a program cache key of Renderer.program."""
    vertex, fragment, defines = key[:3]
    if fragment == "opaque_resolve.frag":
        return "resolve"
    if fragment == "normalize.frag":
        return "normalization"
    if fragment == "cracks.frag":
        return "cracks"
    if fragment == "hiz.frag":
        return "hiz"
    if fragment == "fill.frag":
        return "fill"
    return PASS_NAMES.get(dict(defines).get("PASS"), fragment)


def scene_setup(scene: str, path: Path, size: int):
    """``(cloud, camera, lights, options)`` of a peers' scene: its points preprocessed, back faces culled
    where ``View.culls`` culls them (normals turned outward where they point in), its camera at ``size`` x
    ``size`` and its light."""
    spec = SCENES[scene]
    cloud = preprocess(load(path))
    camera = Camera(eye=spec["eye"], target=spec["target"], up=spec["up"], fov=spec["fov"], width=size, height=size)
    camera = camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))
    light = np.asarray(spec["light"], float) / np.linalg.norm(spec["light"])
    lights = Lights(directions=[tuple(light)], ambient=0.2, diffuse=0.8, specular=0.3, shininess=32)
    view = View(cloud)
    cull = view.culls(camera)
    cloud = view.sample(camera).data
    return cloud, camera, lights, RenderOptions(visibility=VisibilityOptions(cull_backfaces=cull))


def measure(scene: str, path: Path, techniques: list[str], repeat: int, size: int, compute: bool) -> list[list]:
    """Rows of the table for one scene (``compute``: ``RenderOptions.compute``)."""
    cloud, camera, lights, options = scene_setup(scene, path, size)
    options = replace(options, compute=compute)
    renderer = Renderer()
    gpu = renderer.upload(cloud)
    local = local_camera(cloud, camera)
    ctx, rows = renderer.ctx, []
    for technique in techniques:
        renderer.render(gpu, local, technique, lights, options, background=(0, 0, 0))   # compile, warm up
        wall, cpu = [], []
        for _ in range(repeat):
            t, c = time.perf_counter(), time.process_time()
            renderer.render(gpu, local, technique, lights, options, background=(0, 0, 0))
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        names = {id(built.program): pass_name(key) for key, built in renderer._programs.items()}
        spent: dict[str, float] = {}
        original = moderngl.VertexArray.render

        def timed(vao, *args, **kwargs):
            ctx.finish()
            start = time.process_time()
            original(vao, *args, **kwargs)
            ctx.finish()
            name = names.get(id(vao.program), "?")
            spent[name] = spent.get(name, 0.0) + (time.process_time() - start) / repeat

        dispatch = compute_visibility.dispatch

        def timed_dispatch(*args, **kwargs):
            ctx.finish()
            start = time.process_time()
            dispatch(*args, **kwargs)
            ctx.finish()
            spent["compute"] = spent.get("compute", 0.0) + (time.process_time() - start) / repeat

        moderngl.VertexArray.render = timed
        compute_visibility.dispatch = timed_dispatch
        try:
            for _ in range(repeat):
                renderer.render(gpu, local, technique, lights, options, background=(0, 0, 0))
        finally:
            moderngl.VertexArray.render = original
            compute_visibility.dispatch = dispatch
        passes = sum(spent.values())
        frame_cpu = float(np.median(cpu))
        rows.append([scene, technique, len(cloud), f"{size}x{size}", round(1000 * float(np.median(wall))),
                     round(1000 * frame_cpu)]
                    + [round(1000 * spent.get(name, 0.0)) for name in
                       ("compute", "visibility", "cracks", "hiz", "accumulation", "opaque", "resolve", "normalization",
                        "fill")]
                    + [round(1000 * max(frame_cpu - passes, 0.0))])
        print(rows[-1], flush=True)
    gpu.release()
    renderer.release()
    return rows


def interleaved(scene: str, path: Path, techniques: list[str], repeat: int, size: int) -> list[list]:
    """Rows comparing the compute passes with raster only (``RenderOptions(compute=False)``) in one process,
    frame for frame alternated on the same upload: per technique, median wall and CPU time of each, and
    the largest colour difference of their pictures."""
    cloud, camera, lights, options = scene_setup(scene, path, size)
    modes = {"compute": replace(options, compute=True), "raster": replace(options, compute=False)}
    renderer = Renderer()
    gpu = renderer.upload(cloud)
    local = local_camera(cloud, camera)
    rows = []
    for technique in techniques:
        frames = {name: renderer.render(gpu, local, technique, lights, mode, background=(0, 0, 0))
                  for name, mode in modes.items()}   # compile, warm up
        difference = float(np.abs(frames["compute"].color - frames["raster"].color).max())
        times: dict[str, list] = {name: [] for name in modes}
        for _ in range(repeat):
            for name, mode in modes.items():
                renderer.ctx.finish()
                t, c = time.perf_counter(), time.process_time()
                renderer.render(gpu, local, technique, lights, mode, background=(0, 0, 0))
                times[name].append((time.perf_counter() - t, time.process_time() - c))
        (cw, cc), (rw, rc) = (np.median(times[name], axis=0) * 1000 for name in ("compute", "raster"))
        rows.append([scene, technique, len(cloud), f"{size}x{size}", round(rw), round(rc), round(cw), round(cc),
                     f"{cw / rw - 1:+.0%}", f"{difference:.2g}"])
        print(rows[-1], flush=True)
    gpu.release()
    renderer.release()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default="/tmp/peers-data", help="the peers' bench folder holding the scenes")
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--techniques", nargs="+", default=["ewa", "flat", "blend"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--raster-only", action="store_true", help="no compute visibility pass")
    parser.add_argument("--interleaved", action="store_true",
                        help="compute passes against raster only, frames alternated (results/compute_passes.md)")
    args = parser.parse_args()
    rows = []
    for scene in args.scenes:
        path = Path(args.work) / f"{scene}_1000000.ply"
        if not path.exists():
            raise SystemExit(f"{path} is missing: run the peers' bench (../shared/peers/bench.py --work {args.work}) "
                             f"or benchmarks/bench_peers.py --run once to create it")
        if args.interleaved:
            rows += interleaved(scene, path, args.techniques, args.repeat, args.size)
        else:
            rows += measure(scene, path, args.techniques, args.repeat, args.size, not args.raster_only)
    if args.interleaved:
        columns = ["scene", "technique", "splats", "resolution", "raster only: wall ms", "raster only: CPU ms",
                   "compute passes: wall ms", "compute passes: CPU ms", "wall change", "largest colour difference"]
        write_table("compute_passes", columns, rows, machine_description("Mesa llvmpipe") +
                    "; the two renderers' frames alternated in one process, median of --repeat")
        return
    columns = ["scene", "technique", "splats", "resolution", "frame wall ms", "frame CPU ms", "compute passes CPU ms",
               "visibility raster CPU ms",
               "cracks CPU ms", "hiz CPU ms", "accumulation CPU ms", "opaque pass CPU ms", "opaque resolve CPU ms",
               "normalization CPU ms", "fill CPU ms", "rest CPU ms (clears, read-back, Python)"]
    name = "render_passes_raster" if args.raster_only else "render_passes"
    write_table(name, columns, rows, machine_description("Mesa llvmpipe") +
                "; CPU time of each draw call between glFinish calls, process-wide (llvmpipe's threads)")


if __name__ == "__main__":
    main()
