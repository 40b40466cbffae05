"""Rendering speed: splats per second per technique at fixed resolutions.

Usage: python benchmarks/bench_render.py [--splats 1000000] [--sizes 1024] [--repeat 3]

Scenes: a procedural sphere (every splat a few pixels wide, half of them
back-facing) and, when ../shared/data is present, the Stanford bunny sampled
to the same count. The time is one frame's passes with the splats already on
the GPU (glFinish after the frame), excluding the read-back to NumPy, which is
reported separately.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import machine_description, write_table  # noqa: E402

from surfsplat import scenes  # noqa: E402
from surfsplat.api import auto_camera  # noqa: E402
from surfsplat.lighting import Lights  # noqa: E402
from surfsplat.render.context import renderer_name  # noqa: E402
from surfsplat.render.renderer import Renderer  # noqa: E402
from surfsplat.render.options import RenderOptions  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def models(n: int) -> dict:
    """The benchmark scenes, each with n splats."""
    out = {"sphere": scenes.sphere(n)}
    # the cost of clip lines: the same cube with and without them (its edge splats clipped)
    cube = scenes.cube(max(2, int(round(np.sqrt(n / 6)))))
    out["cube, clip lines"] = cube
    out["cube, no clip lines"] = cube.replace(clip_lines=None)
    bunny = SHARED / "bunny.ply"
    if bunny.exists():
        from surfsplat.geometry.sampling import sample_mesh
        from surfsplat.geometry.preprocess import preprocess
        from surfsplat.io import load_mesh

        out["bunny (sampled)"] = preprocess(sample_mesh(load_mesh(bunny), n, seed=0))
    return out


def time_frames(renderer: Renderer, splats, camera, technique: str, repeat: int) -> float:
    """Mean seconds per frame of ``repeat`` frames after one warm-up frame."""
    options = RenderOptions()
    renderer.draw(splats, camera, technique, Lights(), options)
    renderer.ctx.finish()
    start = time.perf_counter()
    for _ in range(repeat):
        renderer.draw(splats, camera, technique, Lights(), options)
    renderer.ctx.finish()
    return (time.perf_counter() - start) / repeat


def primitive_floor(renderer: Renderer, n: int, size: int, repeat: int) -> float:
    """Seconds to draw n instanced 2x2-pixel quads with trivial shaders: the rasterizer's floor per splat.

    Every technique draws one quad (two triangles) per splat, so this bounds
    the splat rate of any of them on this OpenGL implementation.
    """
    import moderngl
    import numpy as np

    ctx = renderer.ctx
    program = ctx.program(
        vertex_shader="#version 330 core\nin vec2 in_corner; in vec2 in_position; uniform float u_px;\n"
                      "void main() { gl_Position = vec4(in_position + in_corner * u_px, 0.0, 1.0); }",
        fragment_shader="#version 330 core\nout vec4 color; void main() { color = vec4(1.0); }")
    program["u_px"].value = 1.0 / size
    positions = ctx.buffer(np.random.default_rng(0).uniform(-0.9, 0.9, (n, 2)).astype("f4"))
    vao = ctx.vertex_array(program, [(renderer._quad, "2f", "in_corner"), (positions, "2f/i", "in_position")])
    target = ctx.framebuffer([ctx.renderbuffer((size, size))])
    target.use()
    vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=n)
    ctx.finish()
    start = time.perf_counter()
    for _ in range(repeat):
        vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=n)
    ctx.finish()
    seconds = (time.perf_counter() - start) / repeat
    for item in (vao, positions, program, target):
        item.release()
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1024])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--techniques", nargs="+", default=["flat", "ewa"])
    parser.add_argument("--name", default="render")
    args = parser.parse_args()

    renderer = Renderer()
    rows = []
    for model, cloud in models(args.splats).items():
        gpu = renderer.upload(cloud)
        for size in args.sizes:
            camera = auto_camera(cloud, size, size).with_clip_from_bounds(*cloud.bounds(), margin=gpu.max_radius)
            for technique in args.techniques:
                seconds = time_frames(renderer, gpu, camera, technique, args.repeat)
                start = time.perf_counter()
                frame = renderer.render(gpu, camera, technique)
                total = time.perf_counter() - start
                passes = 3 if technique != "flat" else 1
                rows.append([model, technique, passes, f"{size}x{size}", len(cloud), round(seconds * 1000, 1),
                             round(len(cloud) / seconds / 1e6, 2), round(total * 1000, 1),
                             f"{frame.mask.mean():.0%}"])
                print(rows[-1], flush=True)
        gpu.release()
    for size in args.sizes:
        seconds = primitive_floor(renderer, args.splats, size, args.repeat)
        rows.append(["(floor: trivial 2x2 px quads)", "-", 1, f"{size}x{size}", args.splats,
                     round(seconds * 1000, 1), round(args.splats / seconds / 1e6, 2), "-", "-"])
        print(rows[-1], flush=True)
    columns = ["model", "technique", "passes", "resolution", "splats", "frame ms", "M splats/s",
               "frame + read-back ms", "coverage"]
    write_table(args.name, columns, rows, machine_description(renderer_name(renderer.ctx)))


if __name__ == "__main__":
    main()
