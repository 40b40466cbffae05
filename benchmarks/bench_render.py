"""Rendering speed and memory: where a frame's time and bytes go, per technique.

Usage:
    python benchmarks/bench_render.py [--splats 1000000] [--size 1024] [--repeat 3] [--techniques ...]
    python benchmarks/bench_render.py --memory [--memory-splats 1000000 5000000] [--memory-size 4096]
    python benchmarks/bench_render.py ... --before SRC   # the same runs with another checkout's src/

Speed (results/render.md): the Stanford bunny (../shared/data) sampled to ``--splats`` splats, the
automatic camera, ``Renderer.render`` of the uploaded splats with read-back into a Frame, the median of
``--repeat`` frames after a warm-up; wall and CPU time (the process's, llvmpipe's threads included: on a
shared machine CPU time is the steadier number). The breakdown times one frame's parts with a glFinish
after each: the geometry passes, the fixed per-frame cost (clears, normalization pass), the read-back
into NumPy, and the upload. ``--before SRC`` runs each measurement again in a child process importing
surfsplat from SRC (e.g. ``git archive HEAD src | tar -x -C /tmp/old``), in the same run.

Memory (results/render_memory.md): in child processes, the peak resident memory (VmHWM, reset before the
render) of ``Renderer.render(cloud)`` (upload included) minus the resident memory before it, per splat
(random sphere of N splats at 256x256) and per output pixel (1,000 splats at 256x256 and at
``--memory-size``, the difference over the pixels).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
SHARED = HERE.parents[1] / "shared" / "data"
CACHE = Path(os.environ.get("TMPDIR", "/tmp")) / "surfsplat-bench-render"


def bunny(n: int):
    """The bunny sampled to n splats, preprocessed (cached under $TMPDIR between runs)."""
    import numpy as np

    from surfsplat.cloud import SplatCloud

    cached = CACHE / f"bunny{n}.npz"
    if cached.exists():
        with np.load(cached) as data:
            return SplatCloud(**{k: data[k] for k in data.files})
    from surfsplat.geometry.preprocess import preprocess
    from surfsplat.geometry.sampling import sample_mesh
    from surfsplat.io import load_mesh

    cloud = preprocess(sample_mesh(load_mesh(SHARED / "bunny.ply"), n, seed=0))
    CACHE.mkdir(parents=True, exist_ok=True)
    np.savez(cached, positions=cloud.positions, normals=cloud.normals, colors=cloud.albedo, u=cloud.u, v=cloud.v)
    return cloud


def sphere(n: int):
    """n random splats on the unit sphere, radius for full coverage."""
    import numpy as np

    from surfsplat.cloud import SplatCloud, circle_axes

    rng = np.random.default_rng(0)
    p = rng.normal(size=(n, 3)).astype("f4")
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    u, v = circle_axes(p, np.full(n, 2.5 / np.sqrt(n), "f4"))
    return SplatCloud(p, p, np.full((n, 3), 0.7, "f4"), u, v)


# -- speed -----------------------------------------------------------------------------------------

class _Timed:
    """A vertex array whose draws are timed (glFinish before and after), summed into ``log``."""

    def __init__(self, vao, ctx, log: dict, key: str):
        self.vao, self.ctx, self.log, self.key = vao, ctx, log, key

    def __getattr__(self, name):
        return getattr(self.vao, name)

    def render(self, *args, **kwargs):
        self.ctx.finish()
        start = time.perf_counter()
        self.vao.render(*args, **kwargs)
        self.ctx.finish()
        self.log[self.key] = self.log.get(self.key, 0.0) + time.perf_counter() - start


def speed_rows(n: int, size: int, repeat: int, techniques: list[str]) -> list[dict]:
    """One dict per technique: wall/CPU ms per frame and the breakdown (this process's surfsplat)."""
    import numpy as np

    from surfsplat.pipeline import auto_camera
    from surfsplat.lighting import Lights
    from surfsplat.rendering.context import renderer_name
    from surfsplat.rendering.renderer import Renderer

    cloud = bunny(n)
    renderer = Renderer()
    ctx = renderer.ctx
    start = time.perf_counter()
    gpu = renderer.upload(cloud)
    ctx.finish()
    upload = time.perf_counter() - start
    camera = auto_camera(cloud, size, size)
    rows = []
    for technique in techniques:
        renderer.render(gpu, camera, technique, Lights())   # warm-up: programs, targets
        walls, cpus = [], []
        for _ in range(repeat):
            wall, cpu = time.perf_counter(), time.process_time()
            frame = renderer.render(gpu, camera, technique, Lights())
            walls.append(time.perf_counter() - wall)
            cpus.append(time.process_time() - cpu)
        # breakdown of one more frame: geometry draws, normalization pass, read-back
        log: dict = {}
        vao, full = renderer._vao, renderer._fullscreen
        renderer._vao = lambda *a, **k: _Timed(vao(*a, **k), ctx, log, "geometry")
        # the full-screen passes: one vertex array (older renderers) or one per pass (normalization, cracks)
        renderer._fullscreen = ({key: _Timed(value, ctx, log, "normalize") for key, value in full.items()}
                                if isinstance(full, dict) else _Timed(full, ctx, log, "normalize"))
        read = renderer._read_tile
        def timed_read(*size):
            begin = time.perf_counter()
            out = read(*size)
            log["read-back"] = log.get("read-back", 0.0) + time.perf_counter() - begin
            return out
        renderer._read_tile = timed_read
        try:
            ctx.finish()
            begin = time.perf_counter()
            renderer.render(gpu, camera, technique, Lights())
            total = time.perf_counter() - begin
        finally:
            renderer._vao, renderer._fullscreen, renderer._read_tile = vao, full, read
        quads = getattr(gpu, "quad_count", None)
        if quads is not None:
            from surfsplat.rendering.options import RenderOptions
            from surfsplat.rendering.renderer import point_radius
            from surfsplat.rendering.techniques import get_technique

            big = camera.with_clip_from_bounds(*gpu.bounds, margin=gpu.max_radius)
            share = 1.0 - quads(point_radius(big, gpu, get_technique(technique), RenderOptions())) / gpu.count
        else:
            share = 0.0
        rows.append({"technique": technique, "splats": gpu.count, "points": share,
                     "wall": float(np.median(walls)), "cpu": float(np.median(cpus)),
                     "geometry": log.get("geometry", 0.0), "normalize": log.get("normalize", 0.0),
                     "read-back": log.get("read-back", 0.0), "total": total, "upload": upload,
                     "coverage": float(frame.mask.mean()), "gl": renderer_name(ctx)})
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    gpu.release()
    return rows


# -- memory ----------------------------------------------------------------------------------------

def _rss(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {field} in /proc/self/status")


def memory_child(n: int, size: int) -> dict:
    """Peak bytes of one Renderer.render(cloud) of n sphere splats at size x size above the resident
    memory before it (the cloud, the context and the compiled programs already there)."""
    import numpy as np

    from surfsplat.pipeline import auto_camera
    from surfsplat.lighting import Lights
    from surfsplat.rendering.renderer import Renderer

    renderer = Renderer()
    cloud = sphere(n)
    small = sphere(1000)
    renderer.render(small, auto_camera(small, 64, 64), "ewa", Lights())   # programs compiled
    camera = auto_camera(cloud, size, size)
    before = _rss("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")   # reset the peak (VmHWM) to the current RSS
    frame = renderer.render(cloud, camera, "ewa", Lights())
    peak = _rss("VmHWM")
    del frame
    return {"splats": n, "size": size, "bytes": peak - before, "check": float(np.float32(0))}


def run_child(src: str | None, *args: str) -> list | dict:
    """This script as a child process (surfsplat from ``src`` when given); its JSON answer."""
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = str(Path(src).resolve()) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, __file__, *args], env=env, check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def memory_tables(splat_counts: list[int], size: int, before: str | None) -> tuple[list, list]:
    """Rows: bytes per splat for each count, bytes per output pixel at ``size``; after and before."""
    trees = [("this tree", None)] + ([("before", before)] if before else [])
    rows = []
    for label, src in trees:
        base = run_child(src, "--child-memory", "1000", "256")
        pixels = run_child(src, "--child-memory", "1000", str(size))
        per_pixel = (pixels["bytes"] - base["bytes"]) / (size * size - 256 * 256)
        for n in splat_counts:
            got = run_child(src, "--child-memory", str(n), "256")
            rows.append([label, "splats", f"{n:,} splats at 256x256", round(got["bytes"] / 2**20),
                         round((got["bytes"] - base["bytes"]) / (n - 1000), 1)])
            print(rows[-1], flush=True)
        rows.append([label, "pixels", f"1,000 splats at {size}x{size}", round(pixels["bytes"] / 2**20),
                     round(per_pixel, 1)])
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    from common import machine_description, write_table

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--techniques", nargs="+", default=["ewa", "blend", "phong", "flat", "points", "perspective"])
    parser.add_argument("--before", metavar="SRC", help="also run each measurement with surfsplat from SRC")
    parser.add_argument("--memory", action="store_true", help="the memory table instead of the speed table")
    parser.add_argument("--memory-splats", type=int, nargs="+", default=[1_000_000, 5_000_000])
    parser.add_argument("--memory-size", type=int, default=4096)
    parser.add_argument("--child-speed", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--child-memory", nargs=2, type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()

    if args.child_speed:
        n, size, repeat, techniques = args.child_speed
        print(json.dumps(speed_rows(int(n), int(size), int(repeat), techniques.split(","))))
        return
    if args.child_memory:
        print(json.dumps(memory_child(*args.child_memory)))
        return
    from surfsplat.rendering.context import headless_context, renderer_name

    machine = machine_description(renderer_name(headless_context()))
    if args.memory:
        rows = memory_tables(args.memory_splats, args.memory_size, args.before)
        write_table("render_memory", ["surfsplat", "per", "run", "peak above baseline MiB", "bytes per splat or pixel"],
                    rows, machine)
        return
    rows = []
    trees = [("this tree", None)] + ([("before", args.before)] if args.before else [])
    for technique in args.techniques:   # before and after alternate, so both see the same machine load
        for label, src in trees:
            got = run_child(src, "--child-speed", str(args.splats), str(args.size), str(args.repeat), technique)[0]
            ms = {k: round(got[k] * 1000) for k in ("wall", "cpu", "geometry", "normalize", "read-back", "upload")}
            rows.append(["bunny (sampled)", technique, label, f"{args.size}x{args.size}", got["splats"],
                         f"{got['points']:.0%}", ms["wall"], ms["cpu"], round(got["splats"] / got["wall"] / 1e6, 2),
                         ms["geometry"], ms["normalize"], ms["read-back"], ms["upload"], f"{got['coverage']:.0%}"])
            print(rows[-1], flush=True)
    columns = ["model", "technique", "surfsplat", "resolution", "splats", "drawn as points", "frame ms (wall)",
               "frame ms (CPU)", "M splats/s (wall)", "geometry passes ms", "clears + normalization ms",
               "read-back ms", "upload ms", "coverage"]
    write_table("render", columns, rows, machine + "; frame = Renderer.render of uploaded splats with read-back; "
                "median of " + str(args.repeat) + "; CPU = process time incl. llvmpipe threads")


if __name__ == "__main__":
    main()
