"""Level of detail (Pajarola et al. 2003): splats drawn, selection and render time, and quality against tau.

Usage: python benchmarks/lod_experiments.py [--size 1024] [--technique blend] [--points 1200000]

For each model, a point-octree is built once (``build_hierarchy``), then for tau in
{0, 0.5, 1, 2, 4, 8} pixels the LOD cut is selected for a fixed view (frustum culling on,
back-face culling off), gathered and rendered; the table lists the splats drawn, the
selection and gather times, the frame time (the passes, splats on the GPU), and the PSNR
inside the mesh's eroded silhouette against the tau = 0 image and against the mesh itself
rendered with the same camera and lighting (``render_mesh``, 4x4 supersampled).

Models: the Stanford bunny sampled to ``--points`` points (normals interpolated from the
mesh's vertex normals) and the colored scan fragment frag_115 sampled to half as many
(its vertex colors interpolated). Pictures: ``docs/images/lod_<model>_tau<tau>.png``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_description, write_table  # noqa: E402

DATA = HERE.parent.parent / "shared" / "data"
TAUS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0)


def model(name: str, points: int):
    """(samples as a render-ready SplatCloud, mesh) of a shared model."""
    from surfsplat import preprocess
    from surfsplat.geometry import sample_mesh
    from surfsplat.io import load_mesh

    mesh = load_mesh(DATA / f"{name}.ply")
    return preprocess(sample_mesh(mesh, points, seed=0, smooth_normals=True)), mesh


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--technique", default="blend")
    parser.add_argument("--points", type=int, default=1_200_000)
    parser.add_argument("--images", default=str(HERE.parent / "docs" / "images"))
    args = parser.parse_args(argv)

    from surfsplat import auto_camera, metrics
    from surfsplat.hierarchy import build_hierarchy, select
    from surfsplat.lighting import Lights
    from surfsplat.rendering.context import renderer_name
    from surfsplat.rendering.mesh import render_mesh
    from surfsplat.rendering.options import RenderOptions
    from surfsplat.rendering.renderer import default_renderer

    renderer = default_renderer()
    lights = Lights(directions=((0.5, 0.6, 1.0),), specular=0.3, shininess=32)
    rows = []
    for name, points in (("bunny", args.points), ("frag_115", args.points // 2)):
        if not (DATA / f"{name}.ply").exists():
            print(f"{DATA / name}.ply missing: skipped", file=sys.stderr)
            continue
        cloud, mesh = model(name, points)
        start = time.perf_counter()
        hierarchy = build_hierarchy(cloud)
        build_s = time.perf_counter() - start
        camera = auto_camera(cloud, args.size, args.size)
        camera = camera.with_clip_from_bounds(*cloud.bounds(), margin=float(cloud.radii.max()))
        truth = render_mesh(mesh, camera, lights, renderer=renderer)
        inner = metrics.erode(truth.weight >= 1.0, 2)
        base = None
        for tau in TAUS:
            select(hierarchy, camera, lod_tolerance=tau)  # warm-up (the first call builds the traversal's arrays)
            select_s, gather_s = [], []
            for _ in range(3):
                start = time.perf_counter()
                selection = select(hierarchy, camera, lod_tolerance=tau)
                middle = time.perf_counter()
                splats = hierarchy.splats(selection)
                select_s.append(middle - start)
                gather_s.append(time.perf_counter() - middle)
            gpu = renderer.upload(splats)
            options = RenderOptions()
            renderer.draw(gpu, camera, args.technique, lights, options)
            renderer.ctx.finish()
            start = time.perf_counter()
            renderer.draw(gpu, camera, args.technique, lights, options)
            renderer.ctx.finish()
            frame_s = time.perf_counter() - start
            frame = renderer.render(gpu, camera, args.technique, lights, options)
            gpu.release()
            image = frame.image() / 255.0
            if base is None:
                base = image
            psnr_base = metrics.psnr(image, base, inner)
            psnr_mesh = metrics.psnr(image, truth.image() / 255.0, inner)
            frame.save(Path(args.images) / f"lod_{name}_tau{tau:g}.png")
            rows.append([name, len(cloud), f"{tau:g}", len(splats), f"{len(cloud) / len(splats):.2f}x",
                         round(1000 * min(select_s), 1), round(1000 * min(gather_s), 1), round(1000 * frame_s, 1),
                         "-" if tau == 0 else round(psnr_base, 2), round(psnr_mesh, 2)])
            print(rows[-1], flush=True)
        print(f"{name}: built in {build_s:.2f} s", flush=True)
    columns = ["model", "points", "tau px", "splats drawn", "fewer", "select ms", "gather ms",
               f"{args.technique} frame ms", "PSNR vs tau=0 (dB)", "PSNR vs mesh (dB)"]
    write_table("lod", columns, rows, machine_description(renderer_name(renderer.ctx)) +
                f"; {args.size}x{args.size}, technique {args.technique}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
