"""Antialiased edges: what supersampling gives, and why fold edges look wrong.

Ground truth: ``render_mesh`` (the mesh, per-pixel Phong shading of its interpolated normals, 4 x 4
supersampled), same camera and lights (one light with highlights, as benchmarks/phong_experiments.py).
Two models: the Stanford bunny (/work/shared/data/bunny.ply) and a procedural one (a thin wavy sheet
folded over itself, a U-turn of 0.05 units radius... gap, open boundaries; plus a thin trefoil-knot tube
of radius 0.025 standing on it).

Splats: ``surface_splats(mesh, N)`` (render-ready circular splats with mesh normals, clip lines at open
boundaries) for ``ewa``/``blend``/``flat``; Phong splats (``phong_splats(count=...)``) of
``--phong-samples`` samples with interpolated normals (``sample_mesh(..., smooth_normals=True)``) for
``phong``.

Measures (``surfsplat.metrics``): ``psnr``: ``compare()``'s PSNR over both silhouettes (the truth's
eroded silhouette or the frame's coverage: the project's convention, rims counted); ``psnr_img``: all
pixels; ``psnr_inner``: inside the truth's silhouette eroded by 2 px; ``ssim``: over both silhouettes;
``psnr_edge``: over the edge mask = pixels within 2 px of a depth discontinuity of the truth (4-neighbours
whose depths differ by more than ``EDGE_JUMP`` of the nearer depth, or covered next to uncovered);
``frame_s``: one frame drawn and read back, splats already uploaded, after a warm-up draw.

Tables: (1) supersampling K per technique (``--variants``: with and without edge coverage,
``VisibilityOptions.edge_coverage``; ``--with-cad`` adds the CAD part), with the 1-spp mesh as reference
row; (2) fold edges of the
procedural model from a low view (wave crests occluding the troughs behind them): visibility and
shading variants of ``ewa``, edge PSNR at the fold edges (internal depth discontinuities of the sheet);
(3) shading: per-splat lighting, deferred shading and the ``phong`` technique against the Phong-shaded mesh.

    python benchmarks/edge_quality.py [--size 1024] [--samples 1000000] [--ks 1 2 3 4]
        [--phong-samples 400000] [--phong-count 30000] [--images /tmp/edge_quality]

Writes benchmarks/results/edge_quality.md and .json; PNGs (crops) go to ``--images`` (not the repo).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, label, machine_description, markdown_table, write_table  # noqa: E402

from surfsplat import (Camera, FilterOptions, Lights, RenderOptions, SplatCloud, VisibilityOptions,  # noqa: E402
                       metrics, phong_splats, preprocess)
from surfsplat.pipeline import auto_camera  # noqa: E402
from surfsplat.geometry.closed import is_closed_surface, outward_splats  # noqa: E402
from surfsplat.geometry.sampling import sample_mesh, surface_splats  # noqa: E402
from surfsplat.io import load_mesh  # noqa: E402
from surfsplat.io.mesh import Mesh  # noqa: E402
from surfsplat.rendering.mesh import render_mesh  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
#: One light with highlights (benchmarks/phong_experiments.py's).
LIGHTS = Lights(directions=((0.5, 0.6, 1.0),), specular=0.5, shininess=40.0)
#: Relative depth step between 4-neighbours of the truth that counts as a discontinuity.
EDGE_JUMP = 0.03
#: Pixels around a discontinuity in the edge mask.
EDGE_PX = 2
#: Side of the fold crops (pixels; saved 4x enlarged).
CROP = 96


# -- the procedural model -----------------------------------------------------------------------------


def grid_faces(nu: int, nv: int, wrap_v: bool = False) -> np.ndarray:
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv if wrap_v else nv - 1), indexing="ij")
    a, b = i * nv + j, (i + 1) * nv + j
    c, d = (i + 1) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])


def folded_sheet(nu: int = 600, nv: int = 300, gap: float = 0.05, length: float = 1.0, width: float = 1.0,
                 amp: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    """A zero-thickness sheet folded over itself: a bottom leaf (y = 0, x in [-length, 0]), a half
    circle of diameter ``gap`` at x = 0, a top leaf back to x = -length; waves of amplitude ``amp``
    across z (crests parallel to x) that fade out toward the fold."""
    r = gap / 2
    arc = np.pi * r
    s = np.linspace(0, 2 * length + arc, nu)
    on_arc = (s >= length) & (s < length + arc)
    x = np.where(s < length, s - length, np.where(on_arc, r * np.sin((s - length) / r), -(s - length - arc)))
    y = np.where(s < length, 0.0, np.where(on_arc, r - r * np.cos((s - length) / r), 2 * r))
    z = np.linspace(-width / 2, width / 2, nv)
    X, Y, Z = np.repeat(x[:, None], nv, 1), np.repeat(y[:, None], nv, 1), np.repeat(z[None, :], nu, 0)
    Y = Y + amp * np.sin(2 * np.pi * 2.5 * Z) * np.clip(-X / 0.3, 0, 1)
    return np.stack([X, Y, Z], -1).reshape(-1, 3), grid_faces(nu, nv)


def knot_tube(nu: int = 900, nv: int = 32, radius: float = 0.025, scale: float = 0.22,
              center=(-0.5, 0.45, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed tube of ``radius`` around a trefoil knot."""
    t = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    c = np.stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)], -1) * scale / 3
    d = np.gradient(c, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = np.cross(d, np.array([0.3, 0.2, 1.0]))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    b = np.cross(d, n)
    a = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    p = c[:, None] + radius * (np.cos(a)[None, :, None] * n[:, None] + np.sin(a)[None, :, None] * b[:, None])
    faces = grid_faces(nu + 1, nv, wrap_v=True) % (nu * nv)   # closed along the knot
    return p.reshape(-1, 3) + np.asarray(center), faces


def procedural() -> tuple[Mesh, Mesh]:
    """(the whole model, the folded sheet alone)."""
    v1, f1 = folded_sheet()
    v2, f2 = knot_tube()
    whole = Mesh(np.concatenate([v1, v2]).astype(np.float32), np.concatenate([f1, f2 + len(v1)]).astype(np.int64))
    return whole, Mesh(v1.astype(np.float32), f1.astype(np.int64))


# -- measures -----------------------------------------------------------------------------------------


def depth_jumps(depth: np.ndarray, both_covered: bool = False) -> np.ndarray:
    """(H, W) bool: pixels next to a depth discontinuity (relative step > EDGE_JUMP between 4-neighbours;
    unless ``both_covered``, also covered next to uncovered)."""
    covered = np.isfinite(depth)
    z = np.where(covered, depth, 0.0)
    out = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        a, b = (z[:-1], z[1:]) if axis == 0 else (z[:, :-1], z[:, 1:])
        ca, cb = (covered[:-1], covered[1:]) if axis == 0 else (covered[:, :-1], covered[:, 1:])
        jump = ca & cb & (np.abs(a - b) > EDGE_JUMP * np.minimum(a, b))
        if not both_covered:
            jump |= ca != cb
        if axis == 0:
            out[:-1] |= jump
            out[1:] |= jump
        else:
            out[:, :-1] |= jump
            out[:, 1:] |= jump
    return out


def edge_mask(truth, px: int = EDGE_PX) -> np.ndarray:
    return ndimage.binary_dilation(depth_jumps(truth.depth), iterations=px)


def scores(frame, truth, edges: np.ndarray) -> dict:
    c = metrics.compare(frame, truth)
    return {"psnr": round(c["psnr"], 2), "psnr_img": round(metrics.psnr(frame.color, truth.color), 2),
            "psnr_inner": round(c["psnr_inner"], 2), "ssim": round(c["ssim"], 4),
            "psnr_edge": round(metrics.psnr(frame.color, truth.color, edges), 2)}


def timed(renderer, splats, camera, technique, options=RenderOptions(), supersample=1):
    start = time.perf_counter()
    frame = renderer.render(splats, camera, technique, LIGHTS, options, supersample=supersample)
    return frame, round(time.perf_counter() - start, 2)


def warm_up(renderer, splats, techniques, options_list=(RenderOptions(),)):
    small = Camera(eye=(0, 0, 3), target=(0, 0, 0), up=(0, 1, 0), fov=40, width=64, height=64)
    for technique in techniques:
        for options in options_list:
            renderer.render(splats, small, technique, LIGHTS, options)


def to_u8(color: np.ndarray) -> np.ndarray:
    return (np.clip(color, 0, 1) * 255 + 0.5).astype(np.uint8)




def save_strip(panels: list[tuple[np.ndarray, str]], path: Path, columns: int = 4) -> None:
    """Labelled panels in a grid (``columns`` a row), 2 px white gaps."""
    h, w = panels[0][0].shape[:2]
    rows = []
    for start in range(0, len(panels), columns):
        row = [label(np.ascontiguousarray(p), t) for p, t in panels[start:start + columns]]
        row += [np.full((h, w, 3), 255, np.uint8)] * (columns - len(row))
        gap = np.full((h, 2, 3), 255, np.uint8)
        rows.append(np.concatenate(sum(([r, gap] for r in row), [])[:-1], axis=1))
    gap = np.full((2, rows[0].shape[1], 3), 255, np.uint8)
    Image.fromarray(np.concatenate(sum(([r, gap] for r in rows), [])[:-1], axis=0)).save(path, optimize=True)
    print("wrote", path, flush=True)


def worst_window(error: np.ndarray, where: np.ndarray, size: int = CROP) -> tuple[slice, slice]:
    """The ``size`` square window (away from the border) with the largest summed ``error`` on ``where``."""
    density = ndimage.uniform_filter(error * where, size, mode="constant")
    h = size // 2
    density[:h + 8], density[-h - 8:], density[:, :h + 8], density[:, -h - 8:] = 0, 0, 0, 0
    y, x = np.unravel_index(np.argmax(density), density.shape)
    return slice(y - h, y - h + size), slice(x - h, x - h + size)


def crop(color: np.ndarray, window, zoom: int = 4) -> np.ndarray:
    """The window of ``color`` as uint8, each pixel ``zoom`` x ``zoom``."""
    return np.kron(to_u8(color[window]), np.ones((zoom, zoom, 1), np.uint8))


# -- the experiments ----------------------------------------------------------------------------------


def prepare(name: str, mesh: Mesh, camera: Camera, args) -> dict:
    start = time.perf_counter()
    splats = surface_splats(mesh, args.samples, seed=0)
    splat_s = time.perf_counter() - start
    start = time.perf_counter()
    dense = sample_mesh(mesh, args.phong_samples, seed=0, smooth_normals=True)
    phong = phong_splats(dense, count=args.phong_count)
    phong_s = time.perf_counter() - start
    closed = is_closed_surface(mesh)
    if closed:   # what render() does with a closed mesh: outward normals, back faces culled
        splats, phong = outward_splats(splats), outward_splats(phong)
    print(f"{name}: {len(splats):,} splats ({splat_s:.1f} s), {len(phong):,} Phong splats from "
          f"{len(dense):,} samples ({phong_s:.1f} s); closed: {closed}", flush=True)
    return {"name": name, "mesh": mesh, "camera": camera, "splats": splats, "phong": phong,
            "options": RenderOptions(visibility=VisibilityOptions(cull_backfaces=closed))}


#: The rows of table (1): label -> (technique, splat set, edge coverage: VisibilityOptions.edge_coverage).
VARIANTS = {"ewa": ("ewa", "splats", False), "ewa + edge coverage": ("ewa", "splats", True),
            "blend": ("blend", "splats", False), "blend + edge coverage": ("blend", "splats", True),
            "phong": ("phong", "phong", False)}


def supersampling(model: dict, renderer, ks, images: Path, docs: Path | None = None,
                  variants=tuple(VARIANTS)) -> list[dict]:
    """Table (1): K per technique against the 4x4 mesh; with ``docs``, a strip of silhouette crops there."""
    camera = model["camera"]
    kept = {}
    truth = render_mesh(model["mesh"], camera, LIGHTS, supersample=4, renderer=renderer)
    edges = edge_mask(truth)
    model["truth"], model["edges"] = truth, edges
    rows = []
    start = time.perf_counter()
    mesh1 = render_mesh(model["mesh"], camera, LIGHTS, supersample=1, renderer=renderer)
    mesh1_s = round(time.perf_counter() - start, 2)
    base = {"model": model["name"], "edge px": int(edges.sum())}
    rows.append(base | {"technique": "mesh, 1 spp", "splats": 0, "K": 1, "frame_s": mesh1_s}
                | scores(mesh1, truth, edges))
    print(rows[-1], flush=True)
    Image.fromarray(truth.image()).save(images / f"{model['name']}_truth.png")
    gpu = renderer.upload(model["splats"])
    gpu_phong = renderer.upload(model["phong"])
    warm_up(renderer, gpu, ("ewa", "blend"))
    warm_up(renderer, gpu_phong, ("phong",))
    for name in variants:
        technique, which, coverage = VARIANTS[name]
        splats, n = (gpu, len(model["splats"])) if which == "splats" else (gpu_phong, len(model["phong"]))
        options = replace(model["options"], visibility=replace(model["options"].visibility, edge_coverage=coverage))
        for k in ks:
            frame, seconds = timed(renderer, splats, camera, technique, options, supersample=k)
            rows.append(base | {"technique": name, "splats": n, "K": k, "frame_s": seconds}
                        | scores(frame, truth, edges))
            print(rows[-1], flush=True)
            if k in (1, max(ks)):
                Image.fromarray(frame.image()).save(images / f"{model['name']}_{name.replace(' ', '_')}_K{k}.png")
                if technique == "ewa":
                    kept[(k, coverage)] = frame
    if model["options"].visibility.cull_backfaces:   # what culling the closed surface's back side changes
        two_sided = RenderOptions(visibility=VisibilityOptions(cull_backfaces=False))
        kept["two-sided"], seconds = timed(renderer, gpu, camera, "ewa", two_sided, supersample=max(ks))
        rows.append(base | {"technique": "ewa two-sided (not culled)", "splats": len(model["splats"]),
                            "K": max(ks), "frame_s": seconds} | scores(kept["two-sided"], truth, edges))
        print(rows[-1], flush=True)
    # the documentation's crops: the window where plain ewa at K = 1 errs most
    if docs is not None and (1, False) in kept:
        window = worst_window(np.abs(kept[(1, False)].color - truth.color).max(axis=2), edges)
        panels = [(crop(truth.color, window, 3), "mesh 4x4 (truth)"), (crop(mesh1.color, window, 3), "mesh 1 spp"),
                  (crop(kept[(1, False)].color, window, 3), "ewa K=1")]
        if (1, True) in kept:
            panels.append((crop(kept[(1, True)].color, window, 3), "ewa K=1 edge cov."))
        panels.append((crop(kept[(max(ks), False)].color, window, 3), f"ewa K={max(ks)}"))
        if (max(ks), True) in kept:
            panels.append((crop(kept[(max(ks), True)].color, window, 3), f"K={max(ks)} edge cov."))
        if "two-sided" in kept:
            panels.append((crop(kept["two-sided"].color, window, 3), f"K={max(ks)} two-sided"))
        save_strip(panels, docs / f"quality_{model['name'].split()[0]}_edges.png", columns=len(panels))
    return rows


def reconstruction_weights(name: str, k: int) -> np.ndarray:
    """1-D weights of the 4 k sub-pixels around an output pixel (offsets in output pixels, centers of
    sub-pixels): box (width 1), tent (width 2) or Mitchell-Netravali (B = C = 1/3, support 2), summing to 1."""
    x = (np.arange(-2 * k, 2 * k) + 0.5) / k
    a = np.abs(x)
    if name == "box":
        w = (a <= 0.5).astype(float)
    elif name == "tent":
        w = np.maximum(1.0 - a, 0.0)
    else:
        b = c = 1.0 / 3.0
        w = np.where(a < 1, (12 - 9 * b - 6 * c) * a ** 3 + (-18 + 12 * b + 6 * c) * a ** 2 + (6 - 2 * b),
                     np.where(a < 2, (-b - 6 * c) * a ** 3 + (6 * b + 30 * c) * a ** 2 + (-12 * b - 48 * c) * a
                              + (8 * b + 24 * c), 0.0)) / 6
    return w / w.sum()


def reconstruction_filters(model: dict, renderer, k: int = 4) -> list[dict]:
    """Table (1b): plain ``ewa`` drawn at k times the size, filtered down to the output pixels by a box,
    a tent and a Mitchell-Netravali filter (separable, NumPy), against the 4 x 4 mesh."""
    camera, truth, edges = model["camera"], model["truth"], model["edges"]
    big = renderer.render(model["splats"], camera.resized(camera.width * k, camera.height * k), "ewa", LIGHTS,
                          model["options"]).color
    h, w = camera.height, camera.width
    rows = []
    for name in ("box", "tent", "mitchell"):
        weights = reconstruction_weights(name, k)
        pad = 2 * k
        image = np.pad(big, ((pad, pad), (pad, pad), (0, 0)), mode="edge")
        taps = np.arange(len(weights)) + k // 2 - 2 * k + pad   # sub-pixel offsets of output pixel 0's taps
        vertical = sum(wj * image[np.arange(h) * k + t] for wj, t in zip(weights, taps))
        color = np.clip(sum(wj * vertical[:, np.arange(w) * k + t] for wj, t in zip(weights, taps)), 0, 1)
        rows.append({"model": model["name"], "filter": name, "K": k,
                     "psnr_img": round(metrics.psnr(color, truth.color), 2),
                     "psnr_inner": round(metrics.psnr(color, truth.color, metrics.erode(truth.mask, 2)), 2),
                     "psnr_edge": round(metrics.psnr(color, truth.color, edges), 2)})
        print(rows[-1], flush=True)
    return rows


FOLD_VARIANTS = {
    "ewa (default: separate_sides, eps 1.0)": ("ewa", RenderOptions()),
    "ewa separate_sides=False": ("ewa", RenderOptions(visibility=VisibilityOptions(separate_sides=False))),
    "ewa depth_epsilon 0.5": ("ewa", RenderOptions(visibility=VisibilityOptions(depth_epsilon=0.5))),
    "ewa depth_epsilon 0.25": ("ewa", RenderOptions(visibility=VisibilityOptions(depth_epsilon=0.25))),
    "ewa depth_epsilon 0.25, separate_sides=False": (
        "ewa", RenderOptions(visibility=VisibilityOptions(depth_epsilon=0.25, separate_sides=False))),
    "ewa deferred": ("ewa", RenderOptions(deferred=True)),
    "ewa no prefilter (footprint = disk)": ("ewa", RenderOptions(filter=FilterOptions(prefilter=False))),
    "perspective": ("perspective", RenderOptions()),
    "blend": ("blend", RenderOptions()),
    "flat": ("flat", RenderOptions()),
}


def folds(sheet: Mesh, whole: Mesh, args, renderer, images: Path) -> tuple[list[dict], dict]:
    """Fold edges of the procedural model seen from low over the waves."""
    size = args.size
    camera = Camera(eye=(0.35, 0.22, 1.25), target=(-0.45, 0.05, 0.0), up=(0, 1, 0), fov=40, width=size,
                    height=size)
    truth = render_mesh(whole, camera, LIGHTS, supersample=4, renderer=renderer)
    sheet_truth = render_mesh(sheet, camera, LIGHTS, supersample=1, renderer=renderer)
    # fold edges: internal depth discontinuities (both sides covered) where the nearest surface is the sheet
    on_sheet = np.isfinite(sheet_truth.depth) & (np.abs(sheet_truth.depth - truth.depth) <= 0.01 * truth.depth)
    folds_mask = ndimage.binary_dilation(depth_jumps(truth.depth, both_covered=True) & on_sheet, iterations=EDGE_PX)
    edges = edge_mask(truth)
    splats = surface_splats(whole, args.samples, seed=0)
    # the same samples' positions with PCA normals (neighbours average across folds and thin parts)
    pca = preprocess(SplatCloud(splats.positions), k=8)
    gpu, gpu_pca = renderer.upload(splats), renderer.upload(pca)
    warm_up(renderer, gpu, ("ewa", "perspective", "blend", "flat"))
    rows, frames = [], {}
    variants = list(FOLD_VARIANTS.items()) + [("ewa, PCA normals (k = 8) instead of the mesh's", ("ewa", None))]
    for name, (technique, options) in variants:
        for k in (1, 4) if name.startswith("ewa (default") or name == "ewa deferred" else (1,):
            data = gpu if options is not None else gpu_pca
            frame, seconds = timed(renderer, data, camera, technique, options or RenderOptions(), supersample=k)
            signed = (frame.color - truth.color).mean(axis=2)[folds_mask]
            rows.append({"variant": name, "K": k, "frame_s": seconds,
                         "psnr_fold": round(metrics.psnr(frame.color, truth.color, folds_mask), 2),
                         "psnr_edge": round(metrics.psnr(frame.color, truth.color, edges), 2),
                         "psnr_inner": round(metrics.compare(frame, truth)["psnr_inner"], 2),
                         "fold px off > 0.1": int((np.abs(signed) > 0.1).sum()),
                         "darker": int((signed < -0.1).sum()), "lighter": int((signed > 0.1).sum())})
            frames[(name, k)] = frame
            print(rows[-1], flush=True)
    default = frames[("ewa (default: separate_sides, eps 1.0)", 1)]
    window = worst_window(np.abs(default.color - truth.color).max(axis=2), folds_mask)
    info = {"fold px": int(folds_mask.sum()), "window rows": [int(window[0].start), int(window[0].stop)],
            "window cols": [int(window[1].start), int(window[1].stop)]}
    Image.fromarray(to_u8(np.where(folds_mask[..., None], [1.0, 0.0, 0.0], truth.color))).save(
        images / "fold_mask.png")
    Image.fromarray(truth.image()).save(images / "fold_truth.png")
    Image.fromarray(default.image()).save(images / "fold_ewa.png")
    panels = [(crop(truth.color, window), "mesh 4x4 (truth)")]
    short = {"ewa (default: separate_sides, eps 1.0)": "ewa default", "ewa separate_sides=False": "no separate_sides",
             "ewa depth_epsilon 0.25": "eps 0.25", "ewa depth_epsilon 0.5": "eps 0.5",
             "ewa depth_epsilon 0.25, separate_sides=False": "eps 0.25, no sep.", "ewa deferred": "deferred",
             "ewa no prefilter (footprint = disk)": "no prefilter", "perspective": "perspective",
             "blend": "blend", "flat": "flat", "ewa, PCA normals (k = 8) instead of the mesh's": "PCA normals"}
    for (name, k), frame in frames.items():
        panels.append((crop(frame.color, window), f"{short[name]} K={k}"))
    save_strip(panels, images / "fold_crops.png", columns=5)
    # error maps of the default and its best alternative, to see the dashes
    err = [(crop(np.repeat((np.abs(f.color - truth.color).max(axis=2) * 4)[..., None], 3, 2), window),
            f"|err| x4 {short[n]} K={k}") for (n, k), f in frames.items() if k == 1]
    save_strip(err, images / "fold_errors.png", columns=5)
    return rows, info


SHADING = {  # name -> (technique, deferred, splat set)
    "ewa per-splat (default)": ("ewa", False, "splats"),
    "ewa deferred": ("ewa", True, "splats"),
    "blend per-pixel (default)": ("blend", False, "splats"),
    "blend deferred": ("blend", True, "splats"),
    "flat per-splat (default)": ("flat", False, "splats"),
    "flat deferred": ("flat", True, "splats"),
    "Phong splats: ewa per-splat": ("ewa", False, "phong"),
    "Phong splats: ewa deferred": ("ewa", True, "phong"),
    "Phong splats: phong (default)": ("phong", False, "phong"),
    "Phong splats: phong deferred": ("phong", True, "phong"),
}


def shading(model: dict, renderer) -> list[dict]:
    truth, edges, camera = model["truth"], model["edges"], model["camera"]
    gpu = {"splats": renderer.upload(model["splats"]), "phong": renderer.upload(model["phong"])}
    warm_up(renderer, gpu["splats"], ("ewa", "blend", "flat"), (RenderOptions(), RenderOptions(deferred=True)))
    warm_up(renderer, gpu["phong"], ("ewa", "phong"), (RenderOptions(), RenderOptions(deferred=True)))
    rows = []
    for name, (technique, deferred, which) in SHADING.items():
        frame, seconds = timed(renderer, gpu[which], camera, technique, replace(model["options"], deferred=deferred))
        rows.append({"model": model["name"], "mode": name, "splats": len(model[which]), "frame_s": seconds}
                    | scores(frame, truth, edges))
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--samples", type=int, default=1_000_000, help="splats of ewa/blend/flat")
    parser.add_argument("--phong-samples", type=int, default=400_000, help="samples the Phong splats are made of")
    parser.add_argument("--phong-count", type=int, default=30_000, help="Phong splats")
    parser.add_argument("--ks", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--images", type=Path, default=Path(tempfile.gettempdir()) / "edge_quality")
    parser.add_argument("--docs", type=Path, default=None, help="write the documentation's crops here (docs/images)")
    parser.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS),
                        help="rows of the supersampling table")
    parser.add_argument("--with-cad", action="store_true", help="table (1) also for the CAD part (featuretype.ply)")
    parser.add_argument("--filters", action="store_true",
                        help="also table (1b): box, tent and Mitchell reconstruction of plain ewa at K = 4")
    parser.add_argument("--supersampling-only", action="store_true",
                        help="table (1) and its targets only, written to results/edge_quality_supersampling.md "
                             "(the fold and shading tables of results/edge_quality.md stay as they are)")
    args = parser.parse_args()
    args.images.mkdir(parents=True, exist_ok=True)
    renderer = default_renderer()
    machine = machine_description(renderer.ctx.info.get("GL_RENDERER"))
    started = time.perf_counter()

    bunny = load_mesh(DATA / "bunny.ply")
    whole, sheet = procedural()
    models = [prepare("bunny", bunny, auto_camera(SplatCloud(bunny.vertices), args.size, args.size), args),
              prepare("folded sheet + knot", whole,
                      Camera(eye=(1.3, 0.7, 1.2), target=(-0.3, 0.15, 0.0), up=(0, 1, 0), fov=38, width=args.size,
                             height=args.size), args)]
    ss_rows = []
    for model in models:
        ss_rows += supersampling(model, renderer, args.ks, args.images, args.docs, args.variants)
    if args.with_cad:   # sharp creases and flat faces: silhouettes along clip lines
        cad = load_mesh(DATA / "featuretype.ply")
        ss_rows += supersampling(prepare("CAD part", cad, auto_camera(SplatCloud(cad.vertices), args.size, args.size),
                                         args), renderer, args.ks, args.images, args.docs, args.variants)
    filter_rows = []
    if args.filters:
        for model in models:
            filter_rows += reconstruction_filters(model, renderer)
    fold_rows, fold_info, shade_rows = [], {}, []
    if not args.supersampling_only:
        fold_rows, fold_info = folds(sheet, whole, args, renderer, args.images)
        cad = load_mesh(DATA / "featuretype.ply")   # sharp creases: where deferred shading loses
        cad_model = prepare("CAD part", cad, auto_camera(SplatCloud(cad.vertices), args.size, args.size), args)
        cad_model["truth"] = render_mesh(cad, cad_model["camera"], LIGHTS, supersample=4, renderer=renderer)
        cad_model["edges"] = edge_mask(cad_model["truth"])
        for model in models + [cad_model]:
            shade_rows += shading(model, renderer)
    name = "edge_quality_supersampling" if args.supersampling_only else "edge_quality"

    ss_cols = ["model", "technique", "splats", "K", "psnr", "psnr_img", "psnr_inner", "ssim", "psnr_edge",
               "frame_s"]
    write_table(name, ss_cols, [[r[c] for c in ss_cols] for r in ss_rows], machine)
    # targets
    targets = []
    for model in models:
        ref = next(r for r in ss_rows if r["model"] == model["name"] and r["technique"] == "mesh, 1 spp")
        for r in ss_rows:
            if r["model"] == model["name"] and r["K"] == 1 and r["technique"] != "mesh, 1 spp":
                targets.append({"target": f"K=1 edge PSNR >= 1-spp mesh's ({ref['psnr_edge']} dB)",
                                "model": model["name"], "technique": r["technique"], "value": r["psnr_edge"],
                                "met": "yes" if r["psnr_edge"] >= ref["psnr_edge"] else "no"})
    for r in ss_rows:
        if r["model"] == "bunny" and r["K"] == 4 and r["technique"] != "mesh, 1 spp":
            targets.append({"target": "K=4 PSNR >= 42 dB (both silhouettes / whole image)", "model": "bunny",
                            "technique": r["technique"], "value": f"{r['psnr']} / {r['psnr_img']}",
                            "met": f"{r['psnr'] >= 42} / {r['psnr_img'] >= 42}"})
    fold_cols = ["variant", "K", "psnr_fold", "psnr_edge", "psnr_inner", "fold px off > 0.1", "darker", "lighter",
                 "frame_s"]
    shade_cols = ["model", "mode", "splats", "psnr", "psnr_inner", "ssim", "psnr_edge", "frame_s"]
    notes = [
        "", f"Sizes: {args.size} x {args.size}; {args.samples:,} surface splats (ewa, blend, flat); Phong splats: "
        f"{args.phong_count:,} requested from {args.phong_samples:,} samples with interpolated normals. Truth: "
        "render_mesh, 4 x 4 supersampled, one light with highlights (0.5, 0.6, 1), specular 0.5, shininess 40. "
        "psnr: over both silhouettes (compare()); psnr_img: whole image; psnr_inner: truth silhouette eroded 2 px; "
        f"psnr_edge: pixels within {EDGE_PX} px of a truth depth discontinuity (relative step > {EDGE_JUMP:g}, or "
        "covered next to uncovered); frame_s: one frame drawn and read back (llvmpipe, splats uploaded).",
        "", "## Targets", ""]
    notes += markdown_table(["target", "model", "technique", "value", "met"],
                            [[t[c] for c in ("target", "model", "technique", "value", "met")] for t in targets])
    if filter_rows:
        notes += ["", "## Reconstruction filters for K > 1 (plain ewa, K = 4, filtered down in NumPy)", ""]
        notes += markdown_table(["model", "filter", "K", "psnr_img", "psnr_inner", "psnr_edge"],
                                [[r[c] for c in ("model", "filter", "K", "psnr_img", "psnr_inner", "psnr_edge")]
                                 for r in filter_rows])
    if not args.supersampling_only:
        notes += ["", f"## Fold edges (procedural sheet, low view over the waves; {fold_info['fold px']:,} "
                  "fold-edge px: internal depth discontinuities of the sheet, dilated 2 px; crop rows "
                  f"{fold_info['window rows']}, cols {fold_info['window cols']})", "",
                  "psnr_fold: PSNR on the fold-edge pixels; fold px off > 0.1: fold-edge pixels whose mean channel "
                  "error exceeds 0.1 (darker / lighter than the truth).", ""]
        notes += markdown_table(fold_cols, [[r[c] for c in fold_cols] for r in fold_rows])
        notes += ["", "## Shading: per-splat, deferred, phong against the Phong-shaded mesh (K = 1)", ""]
        notes += markdown_table(shade_cols, [[r[c] for c in shade_cols] for r in shade_rows])
    notes += ["", f"Total run time: {time.perf_counter() - started:.0f} s. "
              "Rerun: `python benchmarks/edge_quality.py " + shlex.join(sys.argv[1:]) + "`"]
    text = "\n".join(notes)
    print(text)
    with open(RESULTS / f"{name}.md", "a") as out:
        out.write(text + "\n")
    data = json.loads((RESULTS / f"{name}.json").read_text())
    data.update({"args": {k: str(v) for k, v in vars(args).items()}, "supersampling": ss_rows, "targets": targets,
                 "folds": fold_rows, "fold_info": fold_info, "shading": shade_rows, "filters": filter_rows})
    (RESULTS / f"{name}.json").write_text(json.dumps(data, indent=1, default=str))


if __name__ == "__main__":
    main()
