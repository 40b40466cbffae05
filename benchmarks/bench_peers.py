"""surfsplat in the peers' table: the same input, camera, light, timing and scoring as VTK and Open3D.

The harness is ../shared/peers (its README: setup of the venv with VTK/PyVista and Open3D, scenes,
conventions). Two modes:

Runner (what the harness calls, with the common CLI of every renderer; run with a Python that has
surfsplat installed)::

    python benchmarks/bench_peers.py --technique ewa --input P.ply --out O.png --eye ... --target ...

  The points PLY is read with the harness's own reader; normals and colours as given; splat axes
  from surfsplat's preprocessing (k nearest neighbours), one-time setup like the peers' radius
  estimation. A frame is ``surfsplat.render(cloud, camera, technique=...)`` of the preprocessed cloud,
  as a user calls it again and again, with read-back into NumPy (the call finds the view it prepared
  and the upload it made; the peers draw from buffers they keep); each is alternated with a frame of
  the renderer drawing the cloud uploaded once (``Renderer.render``, the back faces culled where
  ``View.culls`` culls them by default), whose median is reported as ``renderer_ms_median`` and the
  difference as ``call_overhead_ms``; ``--uploaded`` times that alone; ``--lod-tolerance PX`` times
  ``View.render`` of a view of the hierarchy instead (cut, upload, draw, read-back; the build is setup),
  ``--lod-tolerance auto`` that of the cloud (merged per half pixel where dense); with ``--lod-mode gpu``
  the hierarchy's sequential layout is uploaded once (setup) and each frame's cut is the vertex
  shaders' (the viewer's default path).

Driver (one run of the peers' bench with surfsplat's techniques added; the table is saved as
results/peers.md)::

    python benchmarks/bench_peers.py --run --peers-python $PEERS_VENV/bin/python \\
        [--techniques ewa flat] [--only vtk_points,vtk_disks,open3d_points] [--sizes 1000000] [--gpu-lod 1] \\
        [--raster-too]   # also every splat drawn, the compute passes off (same run)
        [--kernel='--cutoff 0.5' --kernel=--no-prefilter]   # also ewa with other kernels (same run)
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PEERS = Path(os.environ.get("SURFSPLAT_PEERS", HERE.parents[1] / "shared" / "peers"))


def runner(argv: list[str]) -> None:
    """Render one scene as the harness asks and print its RESULT line."""
    sys.path.insert(0, str(PEERS))
    import numpy as np
    from common import Timer, add_point_args, base_parser, light_from_args, read_points_ply, report, save_png, \
        time_frames

    import surfsplat
    from surfsplat.camera import Camera
    from surfsplat.cloud import SplatCloud
    from surfsplat.geometry.preprocess import preprocess
    from surfsplat.lighting import Lights
    from surfsplat.pipeline import LodOptions, View, as_model
    from surfsplat.rendering.options import FilterOptions, RenderOptions, VisibilityOptions

    parser = base_parser("surfsplat")
    add_point_args(parser)   # accepted for the common CLI; surfsplat sizes its splats itself
    parser.add_argument("--technique", default="ewa")
    parser.add_argument("--lod-tolerance", default=None, help="auto or pixels: time the hierarchy's cut")
    parser.add_argument("--lod-mode", default="cpu", choices=["cpu", "gpu"], help="where the cut is made")
    parser.add_argument("--no-compute", action="store_true", help="RenderOptions(compute=False): every splat drawn")
    parser.add_argument("--cutoff", type=float, default=FilterOptions().cutoff, help="EWA cutoff c (FilterOptions)")
    parser.add_argument("--no-prefilter", action="store_true", help="FilterOptions(prefilter=False)")
    parser.add_argument("--uploaded", action="store_true",
                        help="time the renderer drawing the cloud uploaded once instead of surfsplat.render")
    args = parser.parse_args(argv)
    timer = Timer()
    points = read_points_ply(args.input)
    colors = None if points.colors is None else np.asarray(points.colors, np.float32) / 255.0
    cloud = SplatCloud(np.asarray(points.xyz, np.float64), points.normals, colors)
    timer.mark("load_s")
    cloud = preprocess(cloud)
    user_cloud = cloud   # what a user hands surfsplat.render: the preprocessed cloud
    lo, hi = cloud.bounds()
    camera = Camera(eye=tuple(args.eye), target=tuple(args.target), up=tuple(args.up), fov=args.fov,
                    width=args.width, height=args.height, near=args.near, far=args.far)
    if camera.near is None or camera.far is None:
        camera = camera.with_clip_from_bounds(lo, hi, margin=float(cloud.radii.max()))
    lights = Lights(directions=[tuple(light_from_args(args))], ambient=args.ka, diffuse=args.kd, specular=args.ks,
                    shininess=args.shininess)
    background = tuple(np.asarray(args.bg, float) / 255.0)
    # the default a user gets: back faces culled where the cloud is closed and seen from outside (its
    # normals turned outward where they point in)
    view = View(cloud)
    cull = view.culls(camera)
    cloud = view.sample(camera).data
    kernel = FilterOptions(cutoff=args.cutoff, prefilter=not args.no_prefilter)
    options = RenderOptions(visibility=VisibilityOptions(cull_backfaces=cull), compute=not args.no_compute,
                            filter=kernel)
    user_options = None if kernel == FilterOptions() else RenderOptions(filter=kernel)   # else the defaults
    if args.lod_tolerance is not None:
        tolerance = args.lod_tolerance if args.lod_tolerance == "auto" else float(args.lod_tolerance)
        model = cloud if tolerance == "auto" else as_model(cloud).tree().data   # auto: a cloud merged per view
        lod_view = View(model, lod=LodOptions(tolerance=tolerance, mode=args.lod_mode))
        render_once = lambda: lod_view.render(camera, technique=args.technique, lights=lights,  # noqa: E731
                                              background=background, options=options).frame.color
        render_once()   # the sequential layout's upload (gpu) is setup, as the peers' buffers are
    elif args.uploaded:
        render_once = uploaded_once(cloud, camera, args.technique, lights, options, background)
    else:
        # as a user calls it: the preprocessed cloud handed to surfsplat.render every frame (the call
        # finds its view and upload); the renderer drawing the cloud uploaded once, frames alternated
        # in this process, gives the call's own overhead
        def render_once():
            return surfsplat.render(user_cloud, camera, technique=args.technique, lights=lights,
                                    background=background, options=user_options).color

        direct = uploaded_once(cloud, camera, args.technique, lights, options, background)
        direct_times: list[float] = []

        def alternated():
            start = time.perf_counter()
            direct()
            direct_times.append(time.perf_counter() - start)
            return render_once()

    timer.mark("setup_s")
    if args.lod_tolerance is None and not args.uploaded:
        render_once()
        direct()   # warm-up of both, then the user's call timed with the renderer's alternated
        image, times = time_frames_alternated(render_once, alternated, args.repeat)
        uploaded_ms = 1e3 * float(np.median(direct_times))
        extra = {"renderer_ms_median": round(uploaded_ms, 3),
                 "call_overhead_ms": round(1e3 * float(np.median(times)) - uploaded_ms, 3)}
    else:
        image, times = time_frames(render_once, args.repeat)
        extra = {}
    save_png(args.out, np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8))
    suffix = ("" if args.lod_tolerance is None
              else f"_{'gpu_' if args.lod_mode == 'gpu' else ''}lod_{args.lod_tolerance}")
    suffix += "_raster" if args.no_compute else ""
    suffix += "_uploaded" if args.uploaded else ""
    suffix += "" if args.cutoff == FilterOptions().cutoff else f"_c{args.cutoff:g}"
    suffix += "_noprefilter" if args.no_prefilter else ""
    report(f"surfsplat_{args.technique}{suffix}", args, len(cloud), times, timer, extra)


def uploaded_once(cloud, camera, technique, lights, options, background):
    """A frame of the renderer drawing ``cloud`` uploaded once (no view, no look-up of the upload)."""
    from surfsplat.pipeline import local_camera
    from surfsplat.rendering.renderer import default_renderer

    renderer = default_renderer()
    gpu = renderer.upload(cloud)
    local = local_camera(cloud, camera)
    return lambda: renderer.render(gpu, local, technique, lights, options, background=background).color


def time_frames_alternated(render_once, alternated, repeat: int):
    """``repeat`` timed calls of ``render_once``, each after an untimed (self-timing) ``alternated`` step."""
    image, times = None, []
    for _ in range(max(1, repeat)):
        alternated()
        start = time.perf_counter()
        image = render_once()
        times.append(time.perf_counter() - start)
    return image, times


def driver(argv: list[str]) -> None:
    """Run the peers' bench.py with surfsplat's techniques added; save its table as results/peers.md."""
    sys.path.insert(0, str(HERE))
    from common import machine_description

    parser = argparse.ArgumentParser(description="the peers' bench with surfsplat added")
    parser.add_argument("--run", action="store_true")
    parser.add_argument("--peers-python", required=True, help="the Python of the peers' venv (VTK, Open3D)")
    parser.add_argument("--techniques", nargs="+", default=["ewa", "flat"])
    parser.add_argument("--lod-auto", action="store_true", help="also the default technique at --lod-tolerance auto")
    parser.add_argument("--raster-too", action="store_true",
                        help="also each technique with every splat drawn (RenderOptions(compute=False))")
    parser.add_argument("--gpu-lod", type=float, default=None, metavar="PX",
                        help="also each technique cut on the GPU at this tolerance (the viewer's path)")
    parser.add_argument("--kernel", action="append", default=[], metavar="ARGS",
                        help="also ewa with these runner arguments (repeatable: --kernel='--cutoff 0.5' "
                             "--kernel=--no-prefilter)")
    parser.add_argument("--only", default="vtk_points,vtk_disks,open3d_points")
    parser.add_argument("--sizes", nargs="+", default=["1000000"])
    parser.add_argument("--scenes", nargs="+", default=["bunny", "torus"])
    parser.add_argument("--repeat", default="3")
    parser.add_argument("--work", default="/tmp/peers-data")
    args = parser.parse_args(argv)
    me = f"{shlex.quote(sys.executable)} {shlex.quote(str(Path(__file__).resolve()))}"
    adds = [f"surfsplat_{t}={me} --technique {t}" for t in args.techniques]
    if args.gpu_lod is not None:
        adds += [f"surfsplat_{t}_gpu_lod={me} --technique {t} --lod-tolerance {args.gpu_lod:g} --lod-mode gpu"
                 for t in args.techniques]
    adds += [f"surfsplat_ewa_{k.strip('-').replace(' ', '')}={me} --technique ewa {k}" for k in args.kernel]
    if args.raster_too:
        adds += [f"surfsplat_{t}_raster={me} --technique {t} --no-compute" for t in args.techniques]
    if args.lod_auto:
        first = args.techniques[0]
        adds.append(f"surfsplat_{first}_lod_auto={me} --technique {first} --lod-tolerance auto")
    command = [args.peers_python, str(PEERS / "bench.py"), "--work", args.work, "--sizes", *args.sizes,
               "--scenes", *args.scenes, "--repeat", args.repeat, "--only", args.only]
    for add in adds:
        command += ["--add", add]
    print(" ".join(shlex.quote(c) for c in command), flush=True)
    results = Path(args.work) / "bench_results.jsonl"
    seen = len(results.read_text().splitlines()) if results.exists() else 0
    subprocess.run(command, check=True)
    table = (Path(args.work) / "bench_results.md").read_text()
    rows = [json.loads(line) for line in results.read_text().splitlines()[seen:]]
    table += overhead_table(rows)
    header = (f"Machine: {machine_description()}; GL: Mesa llvmpipe; {time.strftime('%Y-%m-%d')}; one run of the "
              f"peers' bench.py (../shared/peers), {args.repeat} frames each, median, read-back included; "
              f"the machine is shared: compare ratios within the table.\n\n")
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "peers.md").write_text(header + table)
    print(header + table)


def overhead_table(rows: list[dict]) -> str:
    """The surfsplat rows' call overhead and their ratios to VTK points in the same scene (markdown)."""
    vtk = {r["scene"]: r for r in rows if r.get("label") == "vtk_points" and "frame_ms_median" in r}
    lines = ["", "surfsplat.render (as a user calls it) against the renderer drawing the cloud uploaded once, frames "
             "alternated in one process, and against VTK points in the same run:", "",
             "| scene | renderer | surfsplat.render ms | renderer ms | call overhead ms | x VTK points | "
             "PSNR - VTK points dB |", "|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        if "renderer_ms_median" not in r or "psnr_mask" not in r:
            continue
        ref = vtk.get(r["scene"])
        ratio = f"{r['frame_ms_median'] / ref['frame_ms_median']:.2f}" if ref else "-"
        gain = f"{r['psnr_mask'] - ref['psnr_mask']:+.2f}" if ref else "-"
        lines.append(f"| {r['scene']} | {r['label']} | {r['frame_ms_median']:.1f} | {r['renderer_ms_median']:.1f} | "
                     f"{r['call_overhead_ms']:.1f} | {ratio} | {gain} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    (driver if "--run" in sys.argv[1:] else runner)(sys.argv[1:])
