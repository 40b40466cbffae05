"""What a splat costs the OpenGL implementation, apart from any splat math: GL_POINTS against a compute loop.

The two ways surfsplat's first pass can keep, per pixel, the nearest of N small disks at random places
(random radii in ``--radius`` pixels, all in view): as GL_POINTS points whose fragment shader discards
outside the disk, kept by MIN blending into an RG32F target (the raster visibility pass), and as one
compute invocation per disk that loops over its box and keeps the minimum by ``imageAtomicMin`` on a
r32ui image (``render/compute_visibility.py``). Both with trivial per-pixel math, in random order and
in Morton order (neighbours together: what ``Renderer.upload`` does). Also the bare per-point cost:
trivial GL_POINTS of size 1. Each timed between glFinish calls; median of ``--repeat``; CPU time
(llvmpipe's threads included) and wall time. Table: results/primitive_costs.md.

    python benchmarks/primitive_costs.py [--points 440000] [--size 1024] [--radius 0.8 1.8]

On llvmpipe a point costs mostly per primitive (the vertex pipeline, setup, binning, a 4x4-pixel block
shaded for each block it touches), which the compute loop does not pay.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import moderngl
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import machine_description, write_table  # noqa: E402

from surfsplat.geometry.neighbors import spatial_order  # noqa: E402
from surfsplat.rendering.context import headless_context  # noqa: E402

POINTS_VS = """#version 330 core
in vec4 in_disk;   // center (px), depth, radius (px)
uniform vec2 u_size;
uniform float u_point_size;   // 0: the disk's box
flat out vec4 v_disk;
void main() {
    gl_Position = vec4(in_disk.xy / u_size * 2.0 - 1.0, 0.0, 1.0);
    gl_PointSize = u_point_size > 0.0 ? u_point_size : 2.0 * ceil(in_disk.w) + 1.0;
    v_disk = in_disk;
}"""
POINTS_FS = """#version 330 core
flat in vec4 v_disk;
uniform float u_point_size;
out vec2 out_depth;
void main() {
    vec2 q = gl_FragCoord.xy - v_disk.xy;
    if (u_point_size == 0.0 && dot(q, q) > v_disk.w * v_disk.w) discard;
    out_depth = vec2(v_disk.z, 0.0);
}"""
COMPUTE = """#version 430 core
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Disks { vec4 disks[]; };
layout(r32ui, binding = 0) uniform uimage2D u_depth;
uniform int u_count;
void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    vec4 d = disks[i];
    ivec2 lo = ivec2(ceil(d.xy - d.w - 0.5)), hi = ivec2(floor(d.xy + d.w - 0.5));
    for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            vec2 q = vec2(x, y) + 0.5 - d.xy;
            if (dot(q, q) <= d.w * d.w) imageAtomicMin(u_depth, ivec2(x, y), floatBitsToUint(d.z));
        }
    }
}"""


def timed(ctx: moderngl.Context, run, repeat: int) -> tuple[float, float]:
    """Median (wall, CPU) seconds of ``run()`` between glFinish calls, after a warm-up."""
    run()
    ctx.finish()
    times = []
    for _ in range(repeat):
        ctx.finish()
        wall, cpu = time.perf_counter(), time.process_time()
        run()
        ctx.finish()
        times.append((time.perf_counter() - wall, time.process_time() - cpu))
    return tuple(float(v) for v in np.median(times, axis=0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=440_000, help="disks (default: the bunny's front-facing ones)")
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--radius", type=float, nargs=2, default=(0.8, 1.8), help="radius range, pixels")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    ctx = headless_context()
    if ctx.version_code < 430:
        raise SystemExit("this comparison needs OpenGL 4.3 (compute shaders)")
    rng = np.random.default_rng(0)
    n, size = args.points, args.size
    disks = np.empty((n, 4), "f4")
    disks[:, :2] = rng.uniform(0.1 * size, 0.9 * size, (n, 2))
    disks[:, 2] = rng.uniform(0.1, 1.0, n)
    disks[:, 3] = rng.uniform(*args.radius, n)
    orders = {"random": np.arange(n), "Morton": spatial_order(np.c_[disks[:, :2], np.zeros(n)])}
    side = ctx.texture((size, size), 2, dtype="f4")
    fbo = ctx.framebuffer([side])
    image = ctx.texture((size, size), 1, dtype="u4")
    image_fbo = ctx.framebuffer([image])
    points = ctx.program(vertex_shader=POINTS_VS, fragment_shader=POINTS_FS)
    points["u_size"].value = (float(size), float(size))
    compute = ctx.compute_shader(COMPUTE)
    compute["u_count"].value = n
    rows = []
    for name, order in orders.items():
        buffer = ctx.buffer(np.ascontiguousarray(disks[order]))
        vao = ctx.vertex_array(points, [(buffer, "4f", "in_disk")])

        def raster(point_size: float) -> None:
            fbo.use()
            fbo.clear(1.0, 1.0)
            points["u_point_size"].value = point_size
            ctx.enable(moderngl.BLEND | moderngl.PROGRAM_POINT_SIZE)
            ctx.blend_equation = moderngl.MIN
            vao.render(moderngl.POINTS)
            ctx.blend_equation = moderngl.FUNC_ADD
            ctx.disable(moderngl.BLEND | moderngl.PROGRAM_POINT_SIZE)

        def loop() -> None:
            image_fbo.clear(1.0)
            buffer.bind_to_storage_buffer(0)
            image.bind_to_image(0, read=True, write=True)
            compute.run(group_x=-(-n // 64))

        for method, run in (("GL_POINTS of size 1 (no disk)", lambda: raster(1.0)),
                            ("GL_POINTS disks, MIN blending", lambda: raster(0.0)),
                            ("compute loop, imageAtomicMin", loop)):
            wall, cpu = timed(ctx, run, args.repeat)
            rows.append([method, name, f"{n:,}", f"{size}x{size}", f"{args.radius[0]:g}-{args.radius[1]:g}",
                         round(1000 * wall, 1), round(1000 * cpu, 1), round(1e9 * cpu / n)])
            print(rows[-1], flush=True)
        vao.release()
        buffer.release()
    columns = ["method", "order", "disks", "resolution", "radius px", "wall ms", "CPU ms", "CPU ns per disk"]
    write_table("primitive_costs", columns, rows, machine_description(ctx.info["GL_RENDERER"]))


if __name__ == "__main__":
    main()
