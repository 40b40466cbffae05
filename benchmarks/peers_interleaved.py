"""surfsplat against VTK points with their frames interleaved in one process (a busy shared machine's load
changes within a run of the peers' harness, whose renderers run one after the other).

Run with the peers' venv (VTK, PyVista; ``../shared/peers``'s README) and surfsplat on the path; the
harness's points (``bench.py --work DIR`` samples them: ``{scene}_1000000.ply``), cameras, lights and
VTK points exactly as ``render_vtk.py --mode points`` sets them up (baked shading, the harness's point
size). surfsplat is timed as a user calls it: ``surfsplat.render(cloud, camera, technique=...)`` of the
preprocessed cloud, read-back included. Each round draws one frame of every renderer in turn; the
medians over the rounds and their ratios are reported.

    SURFSPLAT_PEERS=../shared/peers PYTHONPATH=src $PEERS_VENV/bin/python benchmarks/peers_interleaved.py \\
        --work /tmp/peers-data [--rounds 5] [--techniques ewa flat] [--size 1024]

Writes benchmarks/results/peers_interleaved.md and .json.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
PEERS = Path(os.environ.get("SURFSPLAT_PEERS", HERE.parents[1] / "shared" / "peers"))

SCENES = {   # the harness's bench.py
    "bunny": ["--eye", "0.08", "0.16", "0.30", "--target", "-0.017", "0.11", "0.0", "--up", "0", "1", "0",
              "--fov", "36", "--light", "0.5", "1.0", "0.8"],
    "torus": ["--eye", "0.0", "-3.2", "2.4", "--target", "0.0", "0.0", "0.0", "--up", "0", "0", "1",
              "--fov", "42", "--light", "0.3", "-0.5", "1.0"],
}


def vtk_points(pts, args, cam):
    """``render_vtk.py --mode points`` (baked shading): a function drawing and reading back one frame."""
    import common
    import pyvista as pv
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    pv.OFF_SCREEN = True
    _, px, _ = common.splat_sizes(pts, args, cam, shape="square")
    cloud = pv.PolyData(pts.xyz)
    cloud.point_data["rgb"] = common.point_display_colors(pts, args, cam)
    pv.global_theme.multi_samples = 0
    pv.global_theme.anti_aliasing = None
    plotter = pv.Plotter(off_screen=True, window_size=(args.width, args.height), lighting="none")
    plotter.set_background(np.asarray(args.bg) / 255.0)
    plotter.disable_anti_aliasing()
    plotter.add_mesh(cloud, style="points", point_size=px, render_points_as_spheres=False, scalars="rgb", rgb=True,
                     lighting=False, show_scalar_bar=False, reset_camera=False)
    plotter.camera_position = [tuple(cam.eye), tuple(cam.target), tuple(cam.up)]
    vcam = plotter.renderer.GetActiveCamera()
    vcam.SetViewAngle(args.fov)
    vcam.SetClippingRange(cam.near, cam.far)
    plotter.renderer.SetAutomaticLightCreation(False)
    window = plotter.render_window
    window.SetMultiSamples(0)
    buf = vtk.vtkUnsignedCharArray()
    width, height = args.width, args.height

    def frame():
        vcam.SetClippingRange(cam.near, cam.far)
        window.Render()
        window.GetPixelData(0, 0, width - 1, height - 1, 0, buf, 0)
        return vtk_to_numpy(buf).reshape(height, width, 3)[::-1].copy()

    return frame, plotter


def surfsplat_frames(pts, args, techniques):
    """``surfsplat.render`` of the preprocessed points for each technique: functions drawing one frame each
    (the headless context made current around each call: VTK's window context is current otherwise)."""
    import common
    import surfsplat
    from surfsplat.camera import Camera
    from surfsplat.cloud import SplatCloud
    from surfsplat.geometry.preprocess import preprocess
    from surfsplat.lighting import Lights
    from surfsplat.rendering.renderer import default_renderer

    colors = None if pts.colors is None else np.asarray(pts.colors, np.float32) / 255.0
    cloud = preprocess(SplatCloud(np.asarray(pts.xyz, np.float64), pts.normals, colors))
    lo, hi = cloud.bounds()
    camera = Camera(eye=tuple(args.eye), target=tuple(args.target), up=tuple(args.up), fov=args.fov,
                    width=args.width, height=args.height)
    camera = camera.with_clip_from_bounds(lo, hi, margin=float(cloud.radii.max()))
    lights = Lights(directions=[tuple(common.light_from_args(args))], ambient=args.ka, diffuse=args.kd,
                    specular=args.ks, shininess=args.shininess)
    background = tuple(np.asarray(args.bg, float) / 255.0)
    ctx = default_renderer().ctx

    def make(technique):
        def frame():
            with ctx:
                return np.round(np.clip(surfsplat.render(cloud, camera, technique=technique, lights=lights,
                                                         background=background).color, 0, 1) * 255).astype(np.uint8)
        return frame

    return {f"surfsplat_{t}": make(t) for t in techniques}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default="/tmp/peers-data")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--techniques", nargs="+", default=["ewa", "flat"])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--images", default=None, help="folder for the last frame of each renderer (PNG)")
    parser.add_argument("--keep-other-scenes", action="store_true",
                        help="keep the saved rows of the scenes not run (one process per scene)")
    args = parser.parse_args()
    sys.path.insert(0, str(PEERS))   # its common.py (this folder's is loaded by path below)
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import importlib.util

    import common as peers_common
    spec = importlib.util.spec_from_file_location("surfsplat_bench_common", HERE / "common.py")
    ours = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ours)
    machine_description = ours.machine_description

    rows = []
    for scene in args.scenes:
        ply = str(Path(args.work) / f"{scene}_1000000.ply")
        cli = peers_common.base_parser("interleaved")
        peers_common.add_point_args(cli)
        run_args = cli.parse_args(["--input", ply, "--out", "/dev/null", "--width", str(args.size), "--height",
                                   str(args.size)] + SCENES[scene])
        pts = peers_common.read_points_ply(ply)
        cam = peers_common.camera_from_args(run_args, pts.xyz.min(0), pts.xyz.max(0))
        renderers = {}
        vtk_frame, plotter = vtk_points(pts, run_args, cam)
        renderers["vtk_points"] = vtk_frame
        renderers |= surfsplat_frames(pts, run_args, args.techniques)
        images = {name: frame() for name, frame in renderers.items()}   # warm-up
        times: dict[str, list] = {name: [] for name in renderers}
        for _ in range(args.rounds):
            for name, frame in renderers.items():
                start = time.perf_counter()
                images[name] = frame()
                times[name].append(time.perf_counter() - start)
        plotter.close()
        if args.images:
            from PIL import Image
            Path(args.images).mkdir(parents=True, exist_ok=True)
            for name, image in images.items():
                Image.fromarray(image).save(Path(args.images) / f"{scene}_{name}.png")
        vtk_ms = 1e3 * float(np.median(times["vtk_points"]))
        for name in renderers:
            ms = 1e3 * float(np.median(times[name]))
            rows.append({"scene": scene, "renderer": name, "frame_ms_median": ms, "x_vtk_points": ms / vtk_ms,
                         "frames_ms": [round(1e3 * t, 1) for t in times[name]]})
            print(rows[-1], flush=True)

    saved = HERE / "results" / "peers_interleaved.json"
    if args.keep_other_scenes and saved.exists():   # one process per scene: the others' rows stay
        rows = [r for r in json.loads(saved.read_text()) if r["scene"] not in args.scenes] + rows
    lines = [f"Machine: {machine_description()}, GL: llvmpipe; {time.strftime('%Y-%m-%d')}; command: "
             f"`python {' '.join(shlex.quote(a) for a in sys.argv)}`",
             "",
             f"1 M points, {args.size}x{args.size}, the harness's cameras and lights; one frame of each renderer "
             f"in turn, {args.rounds} rounds after a warm-up, medians; VTK points as `render_vtk.py --mode points`, "
             f"surfsplat as `surfsplat.render(cloud, camera, technique=...)` of the preprocessed cloud (read-back "
             f"included in both). The machine is shared: the ratios are the result.",
             "",
             "| scene | renderer | frame ms (median) | x VTK points | frames ms |",
             "|---|---|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['renderer']} | {r['frame_ms_median']:,.0f} | {r['x_vtk_points']:.2f} | "
                     f"{', '.join(f'{t:,.0f}' for t in r['frames_ms'])} |")
    text = "\n".join(lines) + "\n"
    ours.save_results("peers_interleaved", text, rows)


if __name__ == "__main__":
    main()
