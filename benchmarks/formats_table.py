"""Inputs and outputs at a glance: every input kind and every output kind, made by the real CLI.

Usage: python benchmarks/formats_table.py [--width 160] [--height 120] [--keep DIR]

In a temporary folder (or ``--keep DIR``), small inputs of every kind are generated from the real models in
../shared/data (bunny.ply, featuretype.ply, frag_115.ply, simple.las; read, never copied into the repo) and from
procedural data: PLY points and mesh, OBJ, STL, OFF, GLB, XYZ, PTS, CSV with a header, PCD ascii and binary,
E57, LAS, LAZ, a trained Gaussian-splat PLY (trainer conventions: log-scales, quaternions w first and not
normalized, logit opacity, SH DC colour), a hierarchy ``.npz`` (``surfsplat build``) and Python objects (an
(N, 3) array, a dict of columns, a ``trimesh.Trimesh`` and ``PointCloud``; Open3D when installed). Each is
rendered by the command a user would type (``surfsplat.cli.main``, in this process, so the OpenGL context
is made once) or by ``surfsplat.render`` for the objects; then every output kind is made from bunny.ply.

Every row is checked against something independent of the file it checks: the same model read from
another format (mask IoU against the reference render), the model's analytic silhouette (the Gaussian
sphere), the colours written into the file, the other outputs of the same view (depth finite exactly where
the image is covered, EXR/PNG/NPY depth equal, the 16-bit PNG equal to the 8-bit one), frame counts and
sizes read back from the GIF/MP4/WebM files. Saved: results/formats.md and .json, and the contact sheets
docs/images/formats_inputs.png and docs/images/formats_outputs.png.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shlex
import sys
import tempfile
import time
import warnings
from pathlib import Path

import laspy
import numpy as np
import png
import trimesh
from matplotlib import colormaps
from PIL import Image, ImageDraw
from plyfile import PlyData, PlyElement
from scipy.spatial.transform import Rotation

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import RESULTS, machine_description, markdown_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat.api import orbit_cameras  # noqa: E402
from surfsplat.cli import main as cli_main  # noqa: E402
from surfsplat.io import SplatCloud, save_ply  # noqa: E402
from surfsplat.io.camera_file import load_camera, save_cameras  # noqa: E402
from surfsplat.io.camera_formats import opencv_from_camera  # noqa: E402
from surfsplat.io.depth_image import load_depth_png  # noqa: E402
from surfsplat.io.exr import load_depth_exr  # noqa: E402
from surfsplat.io.gaussians import SH_C0  # noqa: E402
from surfsplat.rendering.context import headless_context, renderer_name  # noqa: E402

try:
    import pye57
except ImportError:  # the e57 extra
    pye57 = None
try:
    import imageio_ffmpeg
except ImportError:  # the video extra
    imageio_ffmpeg = None
try:
    import open3d
except ImportError:  # never a dependency: shown only where installed
    open3d = None

SHARED = HERE.parents[1] / "shared" / "data"
if not SHARED.is_dir():
    SHARED = Path("/work/shared/data")
IMAGES = HERE.parent / "docs" / "images"
#: Points read from frag_115.ply's vertices for the point formats (every k-th vertex).
POINT_STRIDE = 3


class Table:
    """The rows of the table and the thumbnails of the contact sheets."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.rows: list[dict] = []
        self.failures: list[str] = []

    def add(self, section: str, kind: str, command: str, outputs: list[Path], shape: str, seconds: float,
            check: str, ok: bool, thumb: np.ndarray | None = None):
        """Record one row (``outputs`` inside the work folder; their total size on disk)."""
        size = sum(p.stat().st_size for p in outputs if p.exists())
        names = ", ".join(p.relative_to(self.folder).as_posix() for p in outputs)
        self.rows.append({"section": section, "kind": kind, "command": command, "output": names, "bytes": size,
                          "shape": shape, "seconds": round(seconds, 2), "check": check, "ok": bool(ok),
                          "thumb": thumb})
        if not ok:
            self.failures.append(f"{kind}: {check}")
        print(f"{'ok ' if ok else 'BAD'} {kind:28s} {seconds:6.2f} s  {check}", flush=True)


def run_cli(argv: list) -> tuple[float, str]:
    """Run ``surfsplat ARGV`` in this process; (seconds, stderr). Raises on a non-zero status."""
    argv = [str(a) for a in argv]
    err = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        status = cli_main(argv)
    seconds = time.perf_counter() - start
    if status != 0:
        raise RuntimeError(f"surfsplat {' '.join(argv)} -> status {status}: {err.getvalue()[-500:]}")
    return seconds, err.getvalue()


def shown(argv: list, folder: Path) -> str:
    """The command as a user would type it: paths relative to the work folder, data files by name."""
    parts = ["surfsplat"]
    for a in argv:
        text = str(a)
        for root in (str(folder) + os.sep, str(SHARED) + os.sep):
            text = text.replace(root, "")
        parts.append(text)
    return shlex.join(parts).replace("'", "")


def read_rgb(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 of an image file (first frame), composited over white when it has alpha."""
    with Image.open(path) as image:
        if image.mode in ("RGBA", "LA"):
            rgba = np.asarray(image.convert("RGBA")).astype(np.float32) / 255.0
            rgb = rgba[..., :3] * rgba[..., 3:] + (1.0 - rgba[..., 3:])
            return (rgb * 255.0 + 0.5).astype(np.uint8)
        return np.asarray(image.convert("RGB"))


def covered(rgb: np.ndarray, background=(255, 255, 255)) -> np.ndarray:
    """Pixels that differ from the background by more than 8 levels in some channel."""
    return (np.abs(rgb.astype(int) - np.array(background)) > 8).any(axis=2)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two masks."""
    return float((a & b).sum() / max((a | b).sum(), 1))


def png_bit_depth(path: Path) -> tuple[int, int]:
    """(bit depth, color type) from a PNG's IHDR chunk."""
    data = path.read_bytes()[:33]
    return data[24], data[25]


def video_frames(path: Path) -> list[np.ndarray]:
    """Every frame of a GIF (Pillow) or an MP4/WebM (imageio-ffmpeg) as (H, W, 3) uint8."""
    if path.suffix == ".gif":
        frames = []
        with Image.open(path) as image:
            for i in range(image.n_frames):
                image.seek(i)
                frames.append(np.asarray(image.convert("RGB")))
        return frames
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    w, h = meta["size"]
    return [np.frombuffer(f, np.uint8).reshape(h, w, 3).copy() for f in reader]


def tile(rgb: np.ndarray, width: int, height: int) -> np.ndarray:
    """An image fitted into width x height (aspect kept, letterboxed in light grey)."""
    picture = Image.fromarray(rgb)
    picture.thumbnail((width, height), Image.LANCZOS)
    canvas = Image.new("RGB", (width, height), (235, 235, 235))
    canvas.paste(picture, ((width - picture.width) // 2, (height - picture.height) // 2))
    return np.asarray(canvas)


def contact_sheet(items: list[tuple[str, np.ndarray]], path: Path, columns: int, width: int, height: int) -> Path:
    """Labelled tiles (label under each picture), ``columns`` a row, saved as an optimized palette PNG."""
    label_h = 14
    rows = (len(items) + columns - 1) // columns
    sheet = Image.new("RGB", (columns * (width + 4) + 4, rows * (height + label_h + 4) + 4), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (text, rgb) in enumerate(items):
        x, y = 4 + (i % columns) * (width + 4), 4 + (i // columns) * (height + label_h + 4)
        sheet.paste(Image.fromarray(tile(rgb, width, height)), (x, y))
        draw.rectangle((x, y, x + width - 1, y + height - 1), outline=(180, 180, 180))
        draw.text((x + 2, y + height + 1), text, fill=(0, 0, 0))
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(path, optimize=True)
    return path


# -- inputs ----------------------------------------------------------------------------------------------


def frag_points() -> tuple[np.ndarray, np.ndarray]:
    """Every POINT_STRIDE-th vertex of frag_115.ply: positions (float64) and colours (uint8)."""
    vertex = PlyData.read(str(SHARED / "frag_115.ply"))["vertex"]
    xyz = np.column_stack([vertex[c] for c in "xyz"]).astype(np.float64)[::POINT_STRIDE]
    rgb = np.column_stack([vertex[c] for c in ("red", "green", "blue")]).astype(np.uint8)[::POINT_STRIDE]
    return xyz, rgb


def write_point_files(folder: Path, xyz: np.ndarray, rgb: np.ndarray) -> dict[str, Path]:
    """The same points (positions and colours, no normals) as PLY, XYZ, PTS, CSV, PCD ascii/binary, E57."""
    files = {}
    cloud = SplatCloud(xyz.astype(np.float32), colors=(rgb / 255.0).astype(np.float32))
    files["PLY points"] = save_ply(cloud, folder / "frag_points.ply")
    rows = np.column_stack([xyz, rgb])
    files["XYZ"] = folder / "frag.xyz"
    np.savetxt(files["XYZ"], rows, fmt=["%.6f"] * 3 + ["%d"] * 3)          # 6 columns: xyz + rgb (not unit)
    files["PTS"] = folder / "frag.pts"
    intensity = np.full(len(xyz), 0.5)
    with open(files["PTS"], "w") as f:                                        # Leica: count, x y z i r g b
        f.write(f"{len(xyz)}\n")
        np.savetxt(f, np.column_stack([xyz, intensity, rgb]), fmt=["%.6f"] * 4 + ["%d"] * 3)
    files["CSV with header"] = folder / "frag.csv"
    np.savetxt(files["CSV with header"], rows, fmt=["%.6f"] * 3 + ["%d"] * 3, delimiter=",",
               header="x,y,z,red,green,blue", comments="")
    packed = ((rgb[:, 0].astype(np.uint32) << 16) | (rgb[:, 1].astype(np.uint32) << 8) | rgb[:, 2]).astype(np.uint32)
    header = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F {t}\nCOUNT 1 1 1 1\n"
              f"WIDTH {len(xyz)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(xyz)}\nDATA {{d}}\n")
    files["PCD ascii"] = folder / "frag_ascii.pcd"
    with open(files["PCD ascii"], "w") as f:
        f.write(header.format(t="U", d="ascii"))
        np.savetxt(f, np.column_stack([xyz, packed]), fmt=["%.6f"] * 3 + ["%d"])
    files["PCD binary"] = folder / "frag_binary.pcd"
    binary = np.zeros(len(xyz), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<f4")])
    for i, c in enumerate("xyz"):
        binary[c] = xyz[:, i]
    binary["rgb"] = packed.view(np.float32)                                    # PCL's packed float rgb
    files["PCD binary"].write_bytes(header.format(t="F", d="binary").encode() + binary.tobytes())
    if pye57 is not None:
        files["E57"] = folder / "frag.e57"
        with pye57.E57(str(files["E57"]), mode="w") as e57:
            e57.write_scan_raw({"cartesianX": xyz[:, 0], "cartesianY": xyz[:, 1], "cartesianZ": xyz[:, 2],
                                "colorRed": rgb[:, 0], "colorGreen": rgb[:, 1], "colorBlue": rgb[:, 2]})
    return files


def write_mesh_files(folder: Path) -> dict[str, Path]:
    """bunny.ply (read in place) and its triangles re-exported by trimesh as OBJ, STL, OFF and GLB."""
    mesh = trimesh.load(SHARED / "bunny.ply", process=False)
    files = {"PLY mesh": SHARED / "bunny.ply"}
    for kind, ext in (("OBJ", "obj"), ("STL", "stl"), ("OFF", "off"), ("GLB", "glb")):
        files[kind] = folder / f"bunny.{ext}"
        mesh.export(files[kind])
    return files


def write_laz(folder: Path) -> Path:
    """simple.las re-written compressed (lazrs) with every point record unchanged."""
    las = laspy.read(SHARED / "simple.las")
    path = folder / "simple.laz"
    las.write(str(path), do_compress=True)
    return path


#: The Gaussian sphere's two colours: upper half (y > 0) and lower half.
TOP, BOTTOM = np.array([0.95, 0.55, 0.1]), np.array([0.1, 0.55, 0.6])


def write_gaussians(path: Path, n: int = 6000) -> None:
    """A unit sphere of n flat 3D Gaussians as a 3D Gaussian splatting trainer writes them.

    Fibonacci-sphere centres; per Gaussian a rotation whose *first* column is the normal (the smallest
    scale), so the reader must sort the axes; quaternions w first and scaled by a random factor (trainers
    store them unnormalized), log scales, logit opacity, SH degree 0 (``f_dc = (c - 0.5) / C0``) plus
    zero higher-order coefficients, and 1% transparent floaters (opacity logit -8) that must be culled.
    """
    rng = np.random.default_rng(3)
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1 - 2 * i / n), np.pi * (1 + 5 ** 0.5) * i
    normal = np.column_stack([np.sin(polar) * np.cos(azimuth), np.cos(polar), np.sin(polar) * np.sin(azimuth)])
    helper = np.where(np.abs(normal[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(normal, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normal, t1)
    matrices = np.stack([normal, t1, t2], axis=2)                              # columns: n, t1, t2
    xyzw = Rotation.from_matrix(matrices).as_quat()
    quats = np.column_stack([xyzw[:, 3], xyzw[:, :3]]) * rng.uniform(0.5, 2.0, (n, 1))
    spacing = np.sqrt(4 * np.pi / n)
    log_scales = np.log(np.column_stack([np.full(n, 1e-3), np.full(n, 0.6 * spacing), np.full(n, 0.45 * spacing)]))
    colour = np.where(normal[:, 1:2] > 0, TOP, BOTTOM)
    opacity = np.where(rng.random(n) < 0.01, -8.0, 4.0)
    positions = normal.copy()
    positions[opacity < 0] *= 1.5                                               # floaters off the surface
    names = (["x", "y", "z", "nx", "ny", "nz"] + [f"f_dc_{k}" for k in range(3)] + [f"f_rest_{k}" for k in range(9)]
             + ["opacity"] + [f"scale_{k}" for k in range(3)] + [f"rot_{k}" for k in range(4)])
    data = np.zeros(n, dtype=[(name, "<f4") for name in names])
    for k, c in enumerate("xyz"):
        data[c] = positions[:, k]
    for k in range(3):
        data[f"f_dc_{k}"] = (colour[:, k] - 0.5) / SH_C0
        data[f"scale_{k}"] = log_scales[:, k]
    for k in range(4):
        data[f"rot_{k}"] = quats[:, k]
    data["opacity"] = opacity
    PlyData([PlyElement.describe(data, "vertex")]).write(str(path))


def inputs(table: Table, folder: Path, size: list) -> Path:
    """Render every input kind (rows of ``table``); returns the path of bunny.ply, the outputs' input."""
    xyz, rgb = frag_points()
    points = write_point_files(folder, xyz, rgb)
    meshes = write_mesh_files(folder)
    out = folder / "inputs"
    out.mkdir()
    refs: dict[str, np.ndarray] = {}

    def render_file(kind: str, source: Path, stem: str, extra: list = (), model: str | None = None,
                    note: str = "", section: str = "file"):
        png = out / f"{stem}.png"
        argv = ["render", source, "-o", png, *size, *extra]
        seconds, _ = run_cli(argv)
        image = read_rgb(png)
        mask = covered(image)
        frac = float(mask.mean())
        ok = 0.08 < frac < 0.9
        check = f"coverage {frac:.0%}"
        if model is not None and model in refs:
            score = iou(mask, refs[model])
            ok &= score > 0.9
            check += f", mask IoU vs {model} reference {score:.3f}"
        elif model is not None:
            refs[model] = mask
            check += " (reference)"
        table.add(section, kind, shown(argv, folder), [png], f"{image.shape[1]}x{image.shape[0]}", seconds,
                  check + note, ok, image)
        return image, mask

    # meshes: the same bunny through every mesh format; all must give the PLY mesh's silhouette
    for kind, path in meshes.items():
        render_file(kind, path, f"bunny_{path.suffix[1:]}", model="bunny mesh")
    render_file("PLY mesh, CAD part", SHARED / "featuretype.ply", "featuretype")

    # points: the same frag_115 points through every point format, colours from the file
    camera = folder / "frag_camera.json"
    image, mask = render_file("PLY points", points["PLY points"], "frag_points", ["--save-camera", camera],
                              model="frag points")
    ref_colour = np.median(image[mask], axis=0)
    for kind in ("XYZ", "PTS", "CSV with header", "PCD ascii", "PCD binary"):
        path = points[kind]
        image, mask = render_file(kind, path, path.name.replace(".", "_"), model="frag points")
        diff = float(np.abs(np.median(image[mask], axis=0) - ref_colour).max())
        table.rows[-1]["check"] += f", median colour off by {diff:.0f} levels"
        if diff > 6:
            table.rows[-1]["ok"] = False
            table.failures.append(f"{kind}: median colour off by {diff:.0f} levels")
    if "E57" in points:
        # E57 is z-up (a scan): its own automatic view; the PLY points rendered with that camera are the reference
        e57_camera = folder / "e57_camera.json"
        image, mask = render_file("E57", points["E57"], "frag_e57", ["--save-camera", e57_camera])
        run_cli(["render", points["PLY points"], "-o", out / "frag_points_e57view.png", "--camera", e57_camera])
        score = iou(mask, covered(read_rgb(out / "frag_points_e57view.png")))
        table.rows[-1]["check"] += f", mask IoU vs PLY points with its camera {score:.3f}"
        table.rows[-1]["ok"] &= score > 0.9

    # LiDAR: simple.las as it is, and the same records compressed
    render_file("LAS", SHARED / "simple.las", "simple_las", model="simple.las")
    render_file("LAZ", write_laz(folder), "simple_laz", model="simple.las")

    # a trained Gaussian-splat file of known content: a two-coloured unit sphere, seen unlit
    gaussians = folder / "point_cloud.ply"
    write_gaussians(gaussians)
    image, mask = render_file("Gaussian-splat PLY (3DGS)", gaussians, "gaussians", ["--no-lighting"])
    ys, xs = np.nonzero(mask)
    radius_px = 0.5 * (xs.max() - xs.min() + 1)
    box = (xs.max() - xs.min() + 1, ys.max() - ys.min() + 1)   # square: no floater drawn outside the sphere
    disc = np.pi * radius_px ** 2 / mask.size
    middle_row = int(round(ys.mean()))
    top = np.median(image[:middle_row][mask[:middle_row]], axis=0) / 255.0
    bottom = np.median(image[middle_row + 1:][mask[middle_row + 1:]], axis=0) / 255.0
    colour_err = float(max(np.abs(top - TOP).max(), np.abs(bottom - BOTTOM).max()))
    fill = float(mask.mean()) / disc
    table.rows[-1]["check"] += (f", bounding box {box[0]}x{box[1]} px, covered / disc of its width {fill:.3f}, "
                                f"colours (top, bottom) off by <= {colour_err:.3f}")
    table.rows[-1]["ok"] &= 0.97 < fill < 1.03 and colour_err < 0.06 and abs(int(box[0]) - int(box[1])) <= 2

    # a hierarchy file of the bunny (surfsplat build), drawn with the LOD cut
    npz = folder / "bunny.npz"
    seconds, _ = run_cli(["build", meshes["PLY mesh"], "-o", npz, "--samples", 200_000])
    render_file("hierarchy .npz (build)", npz, "bunny_npz", model="bunny mesh",
                note=f"; build {seconds:.1f} s", section="file")

    # Python objects through the API
    def render_object(kind: str, obj, code: str, model: str | None):
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            frame = surfsplat.render(obj, width=int(size[1]), height=int(size[3]))
        seconds = time.perf_counter() - start
        png = out / f"object_{len(table.rows)}.png"
        frame.save(png)
        image = read_rgb(png)
        mask = covered(image)
        check = f"coverage {mask.mean():.0%}"
        ok = 0.08 < mask.mean() < 0.9
        if model:
            score = iou(mask, refs[model])
            check += f", mask IoU vs {model} reference {score:.3f}"
            ok &= score > 0.9
        table.add("object", kind, code, [png], f"{image.shape[1]}x{image.shape[0]}", seconds, check, ok, image)

    render_object("ndarray (N, 3)", xyz, "surfsplat.render(xyz)", "frag points")
    render_object("dict of columns", {"positions": xyz, "colors": rgb / 255.0},
                  "surfsplat.render({'positions': xyz, 'colors': rgb})", "frag points")
    bunny = trimesh.load(SHARED / "bunny.ply", process=False)
    render_object("trimesh.Trimesh", bunny, "surfsplat.render(trimesh.load('bunny.ply'))", "bunny mesh")
    render_object("trimesh.PointCloud", trimesh.PointCloud(xyz, colors=rgb),
                  "surfsplat.render(trimesh.PointCloud(xyz, colors))", "frag points")
    if open3d is not None:
        cloud = open3d.geometry.PointCloud(open3d.utility.Vector3dVector(xyz))
        render_object("open3d PointCloud", cloud, "surfsplat.render(o3d_cloud)", "frag points")
    return meshes["PLY mesh"]


# -- outputs ---------------------------------------------------------------------------------------------


def read_png16(path: Path) -> np.ndarray:
    """(H, W, C) uint16 of a 16-bit PNG (pypng: Pillow reads 16-bit RGB as 8-bit)."""
    width, height, rows, info = png.Reader(filename=str(path)).asDirect()
    return np.vstack([np.asarray(r, np.uint16) for r in rows]).reshape(height, width, info["planes"])


def png_depth_step(path: Path) -> float:
    """One step of a depth PNG's 16-bit values in model units ((far - near) / 65534, from its text chunks)."""
    with Image.open(path) as image:
        return (float(image.text["surfsplat:far"]) - float(image.text["surfsplat:near"])) / 65534


def depth_picture(depth: np.ndarray) -> np.ndarray:
    """A depth map shown near = dark, far = light (viridis), empty white."""
    finite = np.isfinite(depth)
    shown_ = np.full(depth.shape + (3,), 255, np.uint8)
    if finite.any():
        d = depth[finite]
        t = (d - d.min()) / max(float(d.max() - d.min()), 1e-12)
        shown_[finite] = (colormaps["viridis"](t)[:, :3] * 255).astype(np.uint8)
    return shown_


def args_size(size: list) -> str:
    """"WxH" of the ``--width W --height H`` arguments."""
    return f"{size[1]}x{size[3]}"


def grid(frames: list[np.ndarray]) -> np.ndarray:
    """Four frames as a 2 x 2 picture (for a video's tile)."""
    if len(frames) < 4:
        frames = list(frames) + [np.full_like(frames[0], 255)] * (4 - len(frames))
    picks = [frames[int(round(k * (len(frames) - 1) / 3))] for k in range(4)]
    return np.vstack([np.hstack(picks[:2]), np.hstack(picks[2:])])


def over_checker(path: Path) -> np.ndarray:
    """An RGBA image composited over a grey checkerboard (to show its transparency)."""
    rgba = np.asarray(Image.open(path).convert("RGBA")).astype(np.float32) / 255.0
    h, w = rgba.shape[:2]
    yy, xx = np.mgrid[:h, :w]
    checker = np.where(((yy // 8 + xx // 8) % 2)[..., None] == 0, 0.6, 0.85)
    return ((rgba[..., :3] * rgba[..., 3:] + checker * (1 - rgba[..., 3:])) * 255 + 0.5).astype(np.uint8)


def write_colmap(folder: Path, views: list) -> Path:
    """A COLMAP text model (one PINHOLE camera, one image per view; principal point at W/2, H/2)."""
    folder.mkdir()
    K, _, _ = opencv_from_camera(views[0])
    w, h = views[0].width, views[0].height
    fx, fy = float(K[0, 0]), float(K[1, 1])
    (folder / "cameras.txt").write_text(f"# camera list\n1 PINHOLE {w} {h} {fx} {fy} {w / 2} {h / 2}\n")
    lines = ["# image list"]
    for i, camera in enumerate(views):
        _, R, t = opencv_from_camera(camera)
        x, y, z, qw = Rotation.from_matrix(R).as_quat()
        values = " ".join(str(float(v)) for v in (qw, x, y, z, *t))
        lines += [f"{i + 1} {values} 1 view_{i}.jpg", ""]
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    return folder


def write_nerf(path: Path, views: list) -> Path:
    """A NeRF transforms.json of the views (camera-to-world in OpenGL axes, camera_angle_x, w, h)."""
    flip = np.diag([1.0, -1.0, -1.0])
    frames = []
    for i, camera in enumerate(views):
        _, R, t = opencv_from_camera(camera)
        c2w = np.eye(4)
        c2w[:3, :3] = R.T @ flip
        c2w[:3, 3] = -R.T @ t
        frames.append({"file_path": f"./train/view_{i}", "transform_matrix": c2w.tolist()})
    K, _, _ = opencv_from_camera(views[0])
    w, h = views[0].width, views[0].height
    angle_x = 2 * np.arctan(0.5 * w / K[0, 0])
    path.write_text(json.dumps({"camera_angle_x": angle_x, "w": w, "h": h, "frames": frames}, indent=1))
    return path


def outputs(table: Table, folder: Path, size: list, bunny: Path, frames: int) -> None:
    """Every output kind from bunny.ply, each checked against the others of the same view."""
    out = folder / "outputs"
    out.mkdir()

    def add(kind, argv, files, shape, seconds, check, ok, thumb):
        table.add("output", kind, shown(argv, folder), files, shape, seconds, check, ok, thumb)

    base, camera = out / "bunny.png", out / "camera.json"
    argv = ["render", bunny, "-o", base, *size, "--save-camera", camera]
    seconds, _ = run_cli(argv)
    image = read_rgb(base)
    mask = covered(image)
    depth_bits = png_bit_depth(base)
    add("PNG 8-bit", argv, [base], f"{image.shape[1]}x{image.shape[0]}", seconds,
        f"bit depth {depth_bits[0]}, coverage {mask.mean():.0%}", depth_bits == (8, 2) and 0.08 < mask.mean() < 0.9,
        image)
    again = out / "bunny_again.png"
    argv = ["render", bunny, "-o", again, "--camera", camera]
    seconds, _ = run_cli(argv)
    diff = int(np.abs(read_rgb(again).astype(int) - image).max())
    cam = load_camera(camera)
    add("camera JSON (--save-camera, --camera)", argv, [camera], f"{cam.width}x{cam.height}, fov {cam.fov:.0f}",
        seconds, f"re-render from the file: max difference {diff} levels", diff <= 1, read_rgb(again))

    png16 = out / "bunny16.png"
    argv = ["render", bunny, "-o", png16, *size, "--bit-depth", "16", "--camera", camera]
    seconds, _ = run_cli(argv)
    deep = read_png16(png16)
    diff = float(np.abs(deep / 65535.0 * 255.0 - image).max())
    add("PNG 16-bit (--bit-depth 16)", argv, [png16], f"{deep.shape[1]}x{deep.shape[0]}, 16-bit", seconds,
        f"bit depth {png_bit_depth(png16)[0]}, {len(np.unique(deep))} levels, max abs(16-bit - 8-bit) {diff:.2f}/255",
        png_bit_depth(png16)[0] == 16 and diff <= 0.51, (deep >> 8).astype(np.uint8))

    rgba = out / "bunny_rgba.png"
    argv = ["render", bunny, "-o", rgba, "--transparent", "--camera", camera]
    seconds, _ = run_cli(argv)
    alpha = np.asarray(Image.open(rgba))[..., 3]
    score = iou(alpha > 127, mask)
    add("RGBA PNG (--transparent)", argv, [rgba], f"{alpha.shape[1]}x{alpha.shape[0]}, RGBA", seconds,
        f"alpha > 0.5 vs covered IoU {score:.3f}, corners alpha {int(alpha[[0, 0, -1, -1], [0, -1, 0, -1]].max())}",
        score > 0.95 and alpha[[0, 0, -1, -1], [0, -1, 0, -1]].max() == 0, over_checker(rgba))

    for kind, ext, limit in (("TIFF", "tif", 0.0), ("WebP", "webp", 12.0), ("JPEG", "jpg", 12.0)):
        path = out / f"bunny.{ext}"
        argv = ["render", bunny, "-o", path, "--camera", camera]
        seconds, _ = run_cli(argv)
        other = read_rgb(path)
        diff = float(np.abs(other.astype(float) - image).mean())
        add(kind, argv, [path], f"{other.shape[1]}x{other.shape[0]}", seconds,
            f"mean abs({ext} - png) {diff:.2f} levels", diff <= limit, other)

    depth_files = [out / "depth.npy", out / "depth.png", out / "depth.exr"]
    argv = ["render", bunny, "-o", out / "d.png", "--camera", camera, "--depth", depth_files[0]]
    seconds, _ = run_cli(argv)
    depth = np.load(depth_files[0])
    finite = np.isfinite(depth)
    distance = float(np.linalg.norm(np.subtract(cam.eye, cam.target)))
    extent = float(np.linalg.norm(np.ptp(trimesh.load(bunny, process=False).vertices, axis=0)))
    in_range = bool(np.all((depth[finite] > distance - extent) & (depth[finite] < distance + extent)))
    score = iou(finite, mask)
    add("depth .npy", argv, [depth_files[0]], f"{depth.shape[1]}x{depth.shape[0]} float32", seconds,
        f"finite vs covered IoU {score:.3f}, within eye distance +- model size: {in_range}",
        score > 0.97 and in_range, depth_picture(depth))
    for path, loader, tol in ((depth_files[1], load_depth_png, None), (depth_files[2], load_depth_exr, 0.0)):
        argv = ["render", bunny, "-o", out / f"d_{path.suffix[1:]}.png", "--camera", camera, "--depth", path]
        seconds, _ = run_cli(argv)
        other = loader(path)
        same_mask = bool(np.array_equal(np.isfinite(other), finite))
        err = float(np.abs(other[finite] - depth[finite]).max()) if same_mask else float("inf")
        limit = tol if tol is not None else 0.51 * png_depth_step(path)   # half a 16-bit step, rounding
        add(f"depth {path.suffix}", argv, [path], f"{other.shape[1]}x{other.shape[0]}", seconds,
            f"empty pixels equal to .npy's: {same_mask}, max abs(depth - npy) {err:.2g} (limit {limit:.2g})",
            same_mask and err <= limit, depth_picture(other))

    normals = out / "normals.png"
    argv = ["render", bunny, "-o", out / "n.png", "--camera", camera, "--normals", normals]
    seconds, _ = run_cli(argv)
    rgb = np.asarray(Image.open(normals).convert("RGB")).astype(float) / 255.0
    n = rgb * 2 - 1
    length = np.linalg.norm(n[finite], axis=1)
    facing = float((n[finite][:, 2] > 0).mean())
    empty_black = bool((rgb[~finite] == 0).all())
    add("normal map (--normals)", argv, [normals], f"{rgb.shape[1]}x{rgb.shape[0]} RGB", seconds,
        f"median length {np.median(length):.3f}, facing the eye {facing:.0%}, empty pixels black: {empty_black}",
        abs(np.median(length) - 1) < 0.02 and facing > 0.95 and empty_black, (rgb * 255).astype(np.uint8))

    coverage = out / "coverage.png"
    argv = ["render", bunny, "-o", out / "a.png", "--camera", camera, "--coverage", coverage]
    seconds, _ = run_cli(argv)
    alpha = np.asarray(Image.open(coverage)) / 255.0
    score = iou(alpha > 0.5, mask)
    add("coverage map (--coverage)", argv, [coverage], f"{alpha.shape[1]}x{alpha.shape[0]} grey", seconds,
        f"coverage > 0.5 vs covered IoU {score:.3f}, mean {alpha.mean():.2f}", score > 0.95,
        (np.repeat(alpha[..., None], 3, 2) * 255).astype(np.uint8))

    # camera files of other tools: four views turned 90 degrees apart; view 0 is the saved camera
    views = orbit_cameras(cam, 4)
    colmap, nerf = write_colmap(folder / "colmap", views), write_nerf(folder / "transforms.json", views)
    rendered = {}
    for kind, source in (("COLMAP", colmap), ("NeRF", nerf)):
        pattern = out / kind.lower() / "{name}.png"
        pattern.parent.mkdir()
        argv = ["render", bunny, "-o", pattern, "--cameras", source]
        seconds, _ = run_cli(argv)
        files = sorted(pattern.parent.glob("*.png"))
        rendered[kind] = [read_rgb(p) for p in files]
        first = iou(covered(rendered[kind][0]), mask)
        fracs = [covered(r).mean() for r in rendered[kind]]
        check = f"{len(files)} views, view_0 vs the saved camera's image IoU {first:.3f}, coverage " + \
            "/".join(f"{f:.0%}" for f in fracs)
        ok = len(files) == 4 and first > 0.97 and min(fracs) > 0.05
        if kind == "NeRF":
            same = min(iou(covered(a), covered(b)) for a, b in zip(rendered["COLMAP"], rendered["NeRF"]))
            check += f", vs COLMAP views IoU >= {same:.3f}"
            ok &= same > 0.97
        add(f"--cameras {kind} -> folder", argv, files, f"4 x {cam.width}x{cam.height}", seconds, check, ok,
            grid(rendered[kind]))

    # a batch: three point files, one image each, compared with the PLY points' image of the same view
    batch = out / "batch" / "{stem}.png"
    batch.parent.mkdir()
    argv = ["render", folder / "frag.xyz", folder / "frag_ascii.pcd", folder / "frag_binary.pcd", "-o", batch,
            "--camera", folder / "frag_camera.json"]
    seconds, _ = run_cli(argv)
    files = sorted(batch.parent.glob("*.png"))
    reference = covered(read_rgb(folder / "inputs" / "frag_points.png"))
    scores = [iou(covered(read_rgb(p)), reference) for p in files]
    add("batch -o out/{stem}.png", argv, files, f"{len(files)} x {args_size(size)}", seconds,
        f"{len(files)} images, IoU vs the PLY points' image " + "/".join(f"{s:.3f}" for s in scores),
        len(files) == 3 and min(scores) > 0.97, grid([read_rgb(p) for p in files]))

    # animations: an orbit as GIF, MP4, WebM, and a fly-through along key views
    kinds = [("turntable GIF", "gif")] + ([("turntable MP4", "mp4"), ("turntable WebM", "webm")]
                                         if imageio_ffmpeg is not None else [])
    for kind, ext in kinds:
        path = out / f"spin.{ext}"
        argv = ["turntable", bunny, "-o", path, *size, "--frames", frames, "--elevation", 20]
        seconds, _ = run_cli(argv)
        video = video_frames(path)
        fracs = [covered(f).mean() for f in video]
        h, w = video[0].shape[:2]
        add(kind, argv, [path], f"{len(video)} frames {w}x{h}", seconds,
            f"{len(video)} frames (asked {frames}), coverage per frame {min(fracs):.0%}..{max(fracs):.0%}",
            len(video) == frames and (w, h) == (int(size[1]), int(size[3])) and min(fracs) > 0.08, grid(video))
    keys = out / "keys.json"
    save_cameras([(f"key{i}", c) for i, c in enumerate(orbit_cameras(cam, 3, degrees=180.0))], keys)
    path = out / ("fly.mp4" if imageio_ffmpeg is not None else "fly.gif")
    argv = ["turntable", bunny, "--path", keys, "-o", path, "--frames", 2 * frames]
    seconds, _ = run_cli(argv)
    video = video_frames(path)
    start = iou(covered(video[0]), mask)
    fracs = [covered(f).mean() for f in video]
    add(f"fly-through --path ({path.suffix[1:]})", argv, [path, keys], f"{len(video)} frames "
        f"{video[0].shape[1]}x{video[0].shape[0]}", seconds,
        f"{len(video)} frames (asked {2 * frames}), first frame vs key 0 IoU {start:.3f}, coverage >= {min(fracs):.0%}",
        len(video) == 2 * frames and start > 0.9 and min(fracs) > 0.05, grid(video))


def main() -> int:
    """Make every input and output kind, print and save the table and the two contact sheets."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=120)
    parser.add_argument("--frames", type=int, default=12, help="frames of each turntable")
    parser.add_argument("--keep", type=Path, help="work in this (new) folder and keep it")
    args = parser.parse_args()
    start = time.perf_counter()
    size = ["--width", args.width, "--height", args.height]
    with contextlib.ExitStack() as stack:
        if args.keep:
            args.keep.mkdir(parents=True)
            folder = args.keep.resolve()
        else:
            folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="formats_")))
        table = Table(folder)
        bunny = inputs(table, folder, size)
        outputs(table, folder, size, bunny, args.frames)
        machine = machine_description(renderer_name(headless_context()))
        columns = ["kind", "command", "output", "size", "image / frames", "time (s)", "check", "ok"]
        rows = [[r["kind"], f"`{r['command']}`", r["output"], f"{r['bytes'] / 1024:.1f} KB", r["shape"],
                 r["seconds"], r["check"], "yes" if r["ok"] else "**NO**"] for r in table.rows]
        total = time.perf_counter() - start
        lines = [f"Machine: {machine}", f"Date: {time.strftime('%Y-%m-%d')}",
                 f"Made by `python benchmarks/formats_table.py` (width {args.width}, height {args.height}, "
                 f"{args.frames} turntable frames) in {total:.0f} s; times are in-process (one OpenGL context), "
                 "the first render includes its start-up.", ""] + markdown_table(columns, rows)
        text = "\n".join(lines)
        print(text)
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "formats.md").write_text(text + "\n")
        (RESULTS / "formats.json").write_text(json.dumps(
            {"machine": machine, "date": time.strftime("%Y-%m-%d"), "seconds": round(total, 1),
             "rows": [{k: v for k, v in r.items() if k != "thumb"} for r in table.rows]}, indent=1))
        tiles = args.width, args.height
        for section, name in (("in", "formats_inputs.png"), ("output", "formats_outputs.png")):
            items = [(r["kind"].split(" (")[0], r["thumb"]) for r in table.rows
                     if (r["section"] == "output") == (section == "output")]
            path = contact_sheet(items, IMAGES / name, 5, *tiles)
            print(f"{path}: {Image.open(path).size}, {path.stat().st_size / 1024:.0f} KB")
    if table.failures:
        print("FAILED CHECKS:\n  " + "\n  ".join(table.failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
