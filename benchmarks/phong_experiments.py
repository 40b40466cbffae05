"""The experiments of Botsch, Spernat & Kobbelt 2004 (Phong splatting): numbers and documentation pictures.

Usage: python benchmarks/phong_experiments.py [--size 512] [--samples 1000000] [--out docs/images]
       [--cache DIR] [--skip-timing]

Runs the experiments of tests/test_phong_experiments.py (whose helpers build the inputs, the
ground truth and the measures) at full size:

1. Equal count (figure 4): the bunny's Phong splats (``--phong-count``, from ``--samples``
   dense samples with interpolated vertex normals) drawn ``flat``, ``ewa``, ``deferred``
   (ewa + deferred shading) and ``phong``, and standard splats (a preprocessed random subsample)
   of the same count, against the mesh rendered by ``render_mesh`` (same camera and lights).
2. Equal quality (figure 5): sweeps over the splat count of the Phong generator's geometry
   drawn without its normal fields and of standard splats; the counts at which flat, ewa and
   deferred reach the PSNR (and the SSIM) of ``phong`` at ``--phong-count``, log-interpolated
   between the sweep points, and their ratios to it.
3. Clip lines (figure 9): the CAD part (featuretype.ply, crease-smoothed normals) as Phong
   splats with clip lines, with and without the lines: silhouette leaks, PSNR near the creases
   and on the curved parts.
4. The sphere: RMSE against the exact ray-cast sphere per technique, same splat set.
5. Speed: ``phong`` (and ``ewa``, ``flat``) splats per second at 512^2 and 1024^2 on the bunny's
   Phong splats (``--timing-count``) and on 10 copies of them in place (1M splats: the same
   per-splat footprint, 10x overdraw).

Tables: benchmarks/results/phong_experiments.md / .json. Pictures (docs/images/):
``phong_equal_count.png`` (mesh | flat | ewa | deferred | phong, same Phong splats),
``phong_highlight_crop.png`` (the same, 2x crops around the brightest highlight),
``phong_equal_quality.png`` (mesh | flat | ewa at their equal-PSNR counts, Phong-fit geometry without
the normal fields | phong), ``phong_equal_quality_standard.png`` (the same with standard splats),
``phong_cad.png`` (mesh | flat | phong with clip lines | phong without) and
``phong_sphere.png`` (exact | flat | ewa | phong).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import numpy as np  # noqa: E402
from common import label, machine_description, write_table  # noqa: E402
from PIL import Image  # noqa: E402
from test_phong_experiments import (  # noqa: E402
    CAD_DIRECTION, CAD_UP, ERODE_PX, LIGHTS, MODES, SHARP_ANGLE, STANDARD_MODES, cad_error, cad_measures,
    cad_samples, count_for_quality, crease_normals, curved_faces, dense_samples, face_mask, load_model,
    measure_modes, mesh_silhouette, mesh_truth, render_mode, sphere_camera, sphere_errors, sphere_samples,
    standard_splats, used_clip_lines, view_camera)
from test_render import exact_sphere  # noqa: E402

from surfsplat.cloud import SplatCloud  # noqa: E402
from surfsplat.geometry.phong import phong_splats  # noqa: E402
from surfsplat.metrics import erode  # noqa: E402
from surfsplat.rendering.context import renderer_name  # noqa: E402
from surfsplat.rendering.renderer import Renderer  # noqa: E402
from surfsplat.rendering.options import RenderOptions  # noqa: E402

ROOT = HERE.parent
SHARED = ROOT.parent / "shared" / "data"
#: Side of the picture panels.
PANEL = 384
#: Second view of the CAD part (from the front right).
CAD_DIRECTION_2 = (0.8, -0.6, 0.5)


# -- helpers ------------------------------------------------------------------------------------------


def cached(cache: Path | None, key: str, make) -> SplatCloud:
    """``make()``, or its result stored under ``cache`` (an .npz per key) from an earlier run."""
    if cache is None:
        return make()
    path = cache / f"{hashlib.sha1(key.encode()).hexdigest()[:16]}.npz"
    if path.exists():
        data = np.load(path)
        return SplatCloud(**{name: data[name] for name in data.files})
    cloud = make()
    arrays = {name: getattr(cloud, name) for name in ("positions", "normals", "colors", "u", "v", "normal_field",
                                                      "clip_lines") if getattr(cloud, name) is not None}
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(path, **arrays)
    return cloud




def save_strip(panels: list[tuple[np.ndarray, str]], path: Path) -> Path:
    """Labelled panels side by side, 2 px white gaps, as an optimized PNG."""
    gap = np.full((panels[0][0].shape[0], 2, 3), 255, dtype=np.uint8)
    parts = []
    for image, text in panels:
        parts += [label(np.ascontiguousarray(image), text), gap]
    Image.fromarray(np.concatenate(parts[:-1], axis=1)).save(path, optimize=True)
    print("wrote", path, flush=True)
    return path


def highlight_window(truth, size: int) -> tuple[slice, slice]:
    """The ``size`` x ``size`` window of the truth image holding the most near-white pixels."""
    from scipy import ndimage

    bright = (truth.color.min(axis=2) > 0.9) & erode(truth.mask, ERODE_PX)
    density = ndimage.uniform_filter(bright.astype(np.float64), size, mode="constant")
    h = size // 2
    density[:h], density[-h:], density[:, :h], density[:, -h:] = 0, 0, 0, 0
    y, x = np.unravel_index(np.argmax(density), density.shape)
    return slice(y - h, y - h + size), slice(x - h, x - h + size)


def time_frames(renderer: Renderer, gpu, camera, mode: str, repeat: int) -> float:
    """Mean seconds per frame (``draw`` + ``ctx.finish``) of ``repeat`` frames after a warm-up."""
    technique, deferred = MODES[mode]
    options = RenderOptions(deferred=deferred)
    renderer.draw(gpu, camera, technique, LIGHTS, options)
    renderer.ctx.finish()
    start = time.perf_counter()
    for _ in range(repeat):
        renderer.draw(gpu, camera, technique, LIGHTS, options)
    renderer.ctx.finish()
    return (time.perf_counter() - start) / repeat


def r2(value) -> float:
    return round(float(value), 2)


def r3(value) -> float:
    return round(float(value), 3)


# -- experiments ------------------------------------------------------------------------------------------


def bunny_experiments(renderer: Renderer, args, out: Path) -> tuple[list, list, list, dict]:
    """Figures 4 and 5 on the bunny: equal-count rows, sweep rows, equal-quality rows, Phong sets."""
    mesh = load_model(SHARED, "bunny.ply")
    samples = dense_samples(mesh, args.samples)
    camera = view_camera(mesh, args.size)
    truth = mesh_truth(renderer, mesh, camera)
    view = f"{args.size}x{args.size}"
    print(f"bunny: {len(samples):,} samples, {view}", flush=True)

    def phong_set(count: int) -> SplatCloud:
        start = time.perf_counter()
        cloud = cached(args.cache, f"bunny-phong-{args.samples}-{count}", lambda: phong_splats(samples, count=count))
        print(f"  Phong splats for {count:,}: {len(cloud):,} ({time.perf_counter() - start:.0f} s)", flush=True)
        return cloud

    def standard_set(count: int) -> SplatCloud:
        if count <= len(samples):
            return standard_splats(samples, count)
        # beyond the dense set: fresh uniform samples (the same distribution as a subsample)
        from surfsplat.geometry.preprocess import preprocess

        return preprocess(dense_samples(mesh, count, seed=1), k=8)

    phong_sets = {count: phong_set(count) for count in sorted(set(args.phong_sweep) | {args.phong_count})}
    reference = phong_sets[args.phong_count]

    # 1. equal count
    equal = []
    base = measure_modes(renderer, reference, camera, truth)
    standard = measure_modes(renderer, standard_set(args.phong_count), camera, truth, STANDARD_MODES)
    for geometry, results in (("Phong splats", base), ("standard splats", standard)):
        for mode, r in results.items():
            count = len(reference) if results is base else args.phong_count
            equal.append(["bunny, equal count (fig. 4)", geometry, mode, view, count, r2(r["psnr_inner"]),
                          r2(r["psnr"]), r3(r["ssim"]), r["holes"], r["see_through"], r["leaks"]])
            print(equal[-1], flush=True)
    target_psnr, target_ssim = base["phong"]["psnr_inner"], base["phong"]["ssim"]

    # pictures: the same splats four ways, and crops around the highlight
    small = camera.resized(PANEL, PANEL)
    truth_small = mesh_truth(renderer, mesh, small)
    gpu = renderer.upload(reference)
    frames = {mode: render_mode(renderer, gpu, small, mode) for mode in MODES}
    big = {mode: render_mode(renderer, gpu, camera, mode) for mode in MODES}
    gpu.release()
    n = f"{len(reference):,}"
    save_strip([(truth_small.image(), "mesh (Phong shaded)")] +
               [(frames[m].image(), f"{m}, {n} Phong splats") for m in MODES], out / "phong_equal_count.png")
    ys, xs = highlight_window(truth, args.size // 4)
    crop = [(truth.image()[ys, xs], "mesh")] + [(big[m].image()[ys, xs], m) for m in MODES]
    crop = [(np.asarray(Image.fromarray(im).resize((2 * im.shape[1], 2 * im.shape[0]), Image.NEAREST)), t)
            for im, t in crop]
    save_strip(crop, out / "phong_highlight_crop.png")

    # 2. sweeps
    sweep = []
    curves = {}
    for _count, cloud in sorted(phong_sets.items()):
        r = measure_modes(renderer, cloud, camera, truth)
        for mode, q in r.items():
            curves.setdefault(("Phong geometry", mode), []).append((len(cloud), q["psnr_inner"], q["ssim"]))
            sweep.append(["bunny sweep", "Phong splats" + ("" if mode == "phong" else ", field unused"), mode, view,
                          len(cloud), r2(q["psnr_inner"]), r3(q["ssim"]), q["see_through"]])
            print(sweep[-1], flush=True)
    for count in args.standard_sweep:
        r = measure_modes(renderer, standard_set(count), camera, truth, STANDARD_MODES)
        for mode, q in r.items():
            curves.setdefault(("standard", mode), []).append((count, q["psnr_inner"], q["ssim"]))
            sweep.append(["bunny sweep", "standard splats", mode, view, count, r2(q["psnr_inner"]), r3(q["ssim"]),
                          q["see_through"]])
            print(sweep[-1], flush=True)

    quality_rows = []
    needed = {}
    for (geometry, mode), points in curves.items():
        if mode == "phong":
            continue
        counts, psnrs, ssims = (np.array(v) for v in zip(*points))
        by_psnr = count_for_quality(counts, psnrs, target_psnr)
        by_ssim = count_for_quality(counts, ssims, target_ssim)
        needed[geometry, mode] = by_psnr
        top = f"> {int(counts.max()):,} (not reached)"
        quality_rows.append([
            "bunny, equal quality (fig. 5)", geometry, mode, view,
            f"phong {len(reference):,}: {target_psnr:.2f} dB / SSIM {target_ssim:.3f}",
            top if by_psnr is None else int(round(by_psnr)),
            "-" if by_psnr is None else round(by_psnr / len(reference), 1),
            top if by_ssim is None else int(round(by_ssim)),
            "-" if by_ssim is None else round(by_ssim / len(reference), 1)])
        print(quality_rows[-1], flush=True)

    # the figure-5 triple: flat and ewa at the counts where they reach phong's PSNR (interpolated),
    # once with the Phong generator's geometry (the paper's setup), once with standard splats
    for geometry, suffix in (("Phong geometry", ""), ("standard", "_standard")):
        panels = [(truth_small.image(), "mesh")]
        for mode in ("flat", "ewa"):
            count = needed.get((geometry, mode))
            below = count is None
            if below:
                count = curves[geometry, mode][-1][0]
            count = int(round(count))
            cloud = phong_set(count) if geometry == "Phong geometry" else standard_set(count)
            kind = "Phong-fit splats, field unused" if geometry == "Phong geometry" else "standard splats"
            panels.append((render_mode(renderer, cloud, small, mode).image(),
                           f"{mode}, {len(cloud):,} {kind}" + (" (below target)" if below else "")))
            # check of the interpolation: the quality at that count
            q = measure_modes(renderer, cloud, camera, truth, (mode,))[mode]
            sweep.append(["bunny, at the equal-quality count", kind, mode, view, len(cloud), r2(q["psnr_inner"]),
                          r3(q["ssim"]), q["see_through"]])
            print(sweep[-1], flush=True)
        panels.append((frames["phong"].image(), f"phong, {len(reference):,} Phong splats"))
        save_strip(panels, out / f"phong_equal_quality{suffix}.png")
    return equal, sweep, quality_rows, phong_sets


def cad_experiment(renderer: Renderer, args, out: Path) -> list:
    """Figure 9: the CAD part's Phong splats with and without clip lines, two views."""
    mesh = crease_normals(load_model(SHARED, "featuretype.ply"))
    samples = cad_samples(mesh, args.cad_samples)
    splats = cached(args.cache, f"cad-{args.cad_samples}",
                    lambda: phong_splats(samples, cad_error(mesh), sharp_angle=SHARP_ANGLE))
    clipped_share = used_clip_lines(splats).mean()
    print(f"CAD part: {len(samples):,} samples, {len(splats):,} Phong splats, {clipped_share:.0%} with clip lines",
          flush=True)
    rows = []
    view = f"{args.size}x{args.size}"
    for name, direction in (("front left", CAD_DIRECTION), ("front right", CAD_DIRECTION_2)):
        camera = view_camera(mesh, args.size, direction=direction, up=CAD_UP)
        truth = mesh_truth(renderer, mesh, camera)
        silhouette = mesh_silhouette(renderer, mesh, camera)
        curved = face_mask(renderer, mesh, curved_faces(mesh), camera) & erode(silhouette, ERODE_PX)
        r = cad_measures(renderer, splats, camera, truth, silhouette, curved, modes=tuple(MODES))
        for (clipped, mode), m in r.items():
            rows.append([f"CAD part, {name}", "with clip lines" if clipped else "lines removed", mode, view,
                         len(splats), m["leaks_1px"], m["leaks_2px"], m["missing_1px"], r2(m["psnr_inner"]),
                         r2(m["psnr_creases"]), r2(m["psnr_curved"])])
            print(rows[-1], flush=True)
        if name == "front left":
            small = camera.resized(PANEL, PANEL)
            options = dict(cull_backfaces=True)
            n = f"{len(splats):,}"
            save_strip([(mesh_truth(renderer, mesh, small).image(), "mesh"),
                        (render_mode(renderer, splats, small, "flat", **options).image(), f"flat, {n}, clip lines"),
                        (render_mode(renderer, splats, small, "phong", **options).image(), f"phong, {n}, clip lines"),
                        (render_mode(renderer, splats.replace(clip_lines=None), small, "phong", **options).image(),
                         "phong, lines removed")], out / "phong_cad.png")
    return rows


def sphere_experiment(renderer: Renderer, args, out: Path) -> list:
    """The unit sphere: RMSE of each technique against the exact sphere, same Phong splats."""
    samples = sphere_samples(args.sphere_samples)
    camera = sphere_camera(args.size)
    rows = []
    for count in args.sphere_counts:
        splats = cached(args.cache, f"sphere-{args.sphere_samples}-{count}", lambda: phong_splats(samples, count=count))
        e = sphere_errors(renderer, splats, camera, modes=tuple(MODES))
        rows.append(["sphere vs exact", f"{args.sphere_samples:,} samples", f"{args.size}x{args.size}", len(splats),
                     round(e["flat"], 4), round(e["ewa"], 4), round(e["deferred"], 4), round(e["phong"], 5),
                     round(e["flat"] / e["phong"], 1), round(e["ewa"] / e["phong"], 1)])
        print(rows[-1], flush=True)
        if count == args.sphere_counts[len(args.sphere_counts) // 2]:
            small = sphere_camera(PANEL)
            exact, _ = exact_sphere(small, LIGHTS, supersample=4)
            panels = [((np.clip(exact, 0, 1) * 255 + 0.5).astype(np.uint8), "exact sphere")]
            panels += [(render_mode(renderer, splats, small, m).image(), f"{m}, {len(splats):,} Phong splats")
                       for m in ("flat", "ewa", "phong")]
            save_strip(panels, out / "phong_sphere.png")
    return rows


def timing_experiment(renderer: Renderer, args, phong_sets: dict) -> list:
    """Splats per second of phong (ewa, flat for comparison) on the bunny's Phong splats."""
    mesh = load_model(SHARED, "bunny.ply")
    if args.timing_count in phong_sets:
        cloud = phong_sets[args.timing_count]
    else:
        samples = dense_samples(mesh, args.samples)
        cloud = cached(args.cache, f"bunny-phong-{args.samples}-{args.timing_count}",
                       lambda: phong_splats(samples, count=args.timing_count))
    copies = max(1, int(round(args.timing_total / len(cloud))))
    replicated = SplatCloud(**{name: np.tile(getattr(cloud, name), (copies,) + (1,) * (getattr(cloud, name).ndim - 1))
                               for name in ("positions", "normals", "u", "v", "normal_field")})
    rows = []
    for model, splats in (("bunny Phong splats", cloud), (f"bunny Phong splats x{copies} in place", replicated)):
        gpu = renderer.upload(splats)
        for size in args.timing_sizes:
            camera = view_camera(mesh, size)
            for mode in ("phong", "ewa", "flat"):
                seconds = time_frames(renderer, gpu, camera, mode, args.repeat)
                rows.append([model, mode, f"{size}x{size}", len(splats), round(seconds * 1000, 1),
                             round(len(splats) / seconds / 1e6, 2)])
                print(rows[-1], flush=True)
        gpu.release()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--samples", type=int, default=1_000_000, help="dense samples of the bunny")
    parser.add_argument("--phong-count", type=int, default=3_000)
    parser.add_argument("--phong-sweep", type=int, nargs="+", default=[3_000, 5_000, 10_000, 20_000, 50_000, 100_000])
    parser.add_argument("--standard-sweep", type=int, nargs="+",
                        default=[3_000, 10_000, 30_000, 100_000, 200_000, 300_000, 500_000, 1_000_000, 2_000_000])
    parser.add_argument("--cad-samples", type=int, default=300_000)
    parser.add_argument("--sphere-samples", type=int, default=200_000)
    parser.add_argument("--sphere-counts", type=int, nargs="+", default=[300, 1_000, 3_000])
    parser.add_argument("--timing-count", type=int, default=100_000)
    parser.add_argument("--timing-total", type=int, default=1_000_000)
    parser.add_argument("--timing-sizes", type=int, nargs="+", default=[512, 1024])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--skip-timing", action="store_true")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images")
    parser.add_argument("--cache", type=Path, default=None, help="folder to keep generated Phong splats between runs")
    parser.add_argument("--name", default="phong_experiments")
    args = parser.parse_args()
    if not SHARED.is_dir():
        sys.exit(f"the shared data folder {SHARED} is absent")
    args.out.mkdir(parents=True, exist_ok=True)

    renderer = Renderer()
    machine = machine_description(renderer_name(renderer.ctx))
    start = time.perf_counter()
    equal, sweep, quality_rows, phong_sets = bunny_experiments(renderer, args, args.out)
    cad = cad_experiment(renderer, args, args.out)
    sphere = sphere_experiment(renderer, args, args.out)
    timing = [] if args.skip_timing else timing_experiment(renderer, args, phong_sets)
    print(f"total {time.perf_counter() - start:.0f} s", flush=True)

    # one table per experiment, all in one Markdown file (and its JSON copy)
    sections = [
        ("Equal count (figure 4): PSNR inside the mesh's silhouette eroded by 2 px, PSNR over it or the "
         "splats' own coverage, SSIM; holes, see-through (front splats missing: empty or a surface behind "
         "the mesh's), leaks (covered beyond 2 px)",
         ["experiment", "splats", "mode", "resolution", "count", "PSNR inside dB", "PSNR dB", "SSIM", "holes",
          "see-through", "leaks"], equal),
        ("Sweeps over the splat count (PSNR inside, SSIM)",
         ["experiment", "splats", "mode", "resolution", "count", "PSNR inside dB", "SSIM", "see-through"], sweep),
        ("Equal quality (figure 5; paper: flat 170k, blended 33k, Phong 3k): counts needed to reach phong's "
         "PSNR inside / SSIM, log-interpolated between sweep points, and their ratio to the Phong count",
         ["experiment", "splats", "mode", "resolution", "target", "count (PSNR)", "ratio (PSNR)", "count (SSIM)",
          "ratio (SSIM)"], quality_rows),
        ("CAD part (figure 9), back-faces culled: pixels covered beyond the mesh's silhouette grown by 1 / 2 px, "
         "pixels of the silhouette shrunk by 1 px left empty, PSNR inside, within 2 px of creases, on curved faces",
         ["experiment", "clip lines", "mode", "resolution", "splats", "leaks > 1 px", "leaks > 2 px", "missing",
          "PSNR inside dB", "PSNR creases dB", "PSNR curved dB"], cad),
        ("Sphere: RMSE against the exact sphere (4x4 supersampled) inside its silhouette eroded by 2 px",
         ["experiment", "input", "resolution", "splats", "flat", "ewa", "deferred", "phong", "flat / phong",
          "ewa / phong"], sphere),
        ("Speed: one frame's passes (draw + glFinish), splats on the GPU, after a warm-up",
         ["model", "mode", "resolution", "splats", "frame ms", "M splats/s"], timing),
    ]
    texts, payload = [], []
    import json

    from common import RESULTS

    for title, columns, rows in sections:
        if not rows:
            continue
        text = write_table(args.name, columns, rows, machine)
        texts.append(f"## {title}\n\n" + text)
        payload.append({"title": title, "columns": columns, "rows": rows})
    (RESULTS / f"{args.name}.md").write_text("# Phong splatting experiments (Botsch et al. 2004)\n\n"
                                             "Command: `python benchmarks/phong_experiments.py "
                                             + " ".join(sys.argv[1:]) + "`\n\n" + "\n\n".join(texts) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"machine": machine, "date": time.strftime("%Y-%m-%d"), "tables": payload}, indent=1))


if __name__ == "__main__":
    main()
