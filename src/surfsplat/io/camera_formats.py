"""Cameras from other tools: OpenCV JSON, COLMAP text models and NeRF ``transforms.json``.

:func:`load_cameras` reads any of them (and surfsplat's own camera file of one camera or a
``"cameras"`` list, :mod:`.camera_file`) as a
list of ``(name, Camera)``; the format is told from the file name and content:

OpenCV JSON (``*.json`` with ``"K"``, or ``{"cameras": [...]}`` of such objects)
    ``{"K": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "R": 3x3, "t": [3], "width": W, "height": H,
    "name": "optional"}``. OpenCV convention: camera x right, y down, z forward; world to camera
    ``x_cam = R x_world + t``; pixel (u, v) with u right, v down and the *center* of the top-left
    pixel at (0, 0), so a centered principal point is ``((W - 1) / 2, (H - 1) / 2)``. Names: the
    ``name`` field, else the index (``0``, ``1``, ...).
COLMAP text model (``cameras.txt`` + ``images.txt`` in one folder; give either file or the folder)
    Camera models PINHOLE (fx fy cx cy), SIMPLE_PINHOLE (f cx cy), SIMPLE_RADIAL (f cx cy k) and
    RADIAL (f cx cy k1 k2); distortion is ignored, with a warning. ``images.txt``: two lines per
    image, ``IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`` (unit quaternion, w first, and t:
    world to camera, OpenCV axes) and the 2-D points (ignored). Pixel coordinates have the top-left
    *corner* at (0, 0): a centered principal point is ``(W / 2, H / 2)``. Names: the image name's stem.
NeRF ``transforms.json`` (a JSON object with ``"frames"``)
    ``camera_angle_x`` (horizontal field of view, radians) or ``fl_x`` / ``fl_y`` (pixels), optional
    ``cx``, ``cy``, ``w``, ``h`` at the top level or per frame; each frame's ``transform_matrix`` is
    the 4x4 camera-to-world matrix in OpenGL axes (x right, y up, z backward). Without ``w``/``h``
    the size must be given (``--width``/``--height``). Names: the frame's ``file_path`` stem, else
    the index.

surfsplat's :class:`~surfsplat.camera.Camera` has square pixels and the principal point at the image
center: the vertical field of view comes from fy (a differing fx is warned about) and a principal
point more than 0.5 px off the center is warned about and approximated by the center.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError, file_reader
from .camera_file import CAMERA_FORMAT, load_camera_list

COLMAP_FILES = ("cameras.txt", "images.txt")
#: The sparse points of a COLMAP text model (``load_colmap_points``: an initial cloud for ``surfsplat fit``).
COLMAP_POINTS = "points3D.txt"
#: COLMAP camera models read: the number of parameters and whether they include distortion.
COLMAP_MODELS = {"SIMPLE_PINHOLE": (3, False), "PINHOLE": (4, False), "SIMPLE_RADIAL": (4, True),
                 "RADIAL": (5, True)}


def camera_from_opencv(K, R, t, width: int, height: int, *, center_offset: float = 0.5,
                       where: str = "camera") -> Camera:
    """A Camera from OpenCV intrinsics ``K`` (3x3) and world-to-camera ``R`` (3x3), ``t`` (3).

    ``center_offset``: 0.5 where pixel centers are at integers (OpenCV: the image center is at
    ``(W - 1) / 2``), 0 where they are at half-integers (COLMAP, NeRF: ``W / 2``). Warns when the
    principal point is more than 0.5 px off the center, or fx and fy differ by more than 0.1%.
    """
    K, R, t = (np.asarray(a, dtype=np.float64) for a in (K, R, t))
    if K.shape != (3, 3) or R.shape != (3, 3) or t.reshape(-1).shape != (3,):
        raise InputError(f"{where}: need K 3x3, R 3x3, t 3; got {K.shape}, {R.shape}, {t.shape}")
    t = t.reshape(3)
    if not (np.isfinite(K).all() and np.isfinite(R).all() and np.isfinite(t).all()):
        raise InputError(f"{where}: non-finite camera values")
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
        raise InputError(f"{where}: R is not a rotation (orthonormal, determinant +1)", element="R")
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if not (fx > 0 and fy > 0):
        raise InputError(f"{where}: focal lengths must be positive, got fx={fx}, fy={fy}", element="K")
    width, height = int(width), int(height)
    if abs(fx - fy) > 1e-3 * fy:
        warnings.warn(f"{where}: fx={fx:g} and fy={fy:g} differ; non-square pixels are not supported "
                      f"(the vertical field of view is taken from fy)", stacklevel=3)
    ex, ey = 0.5 * width - center_offset, 0.5 * height - center_offset
    if abs(cx - ex) > 0.5 or abs(cy - ey) > 0.5:
        warnings.warn(f"{where}: principal point ({cx:g}, {cy:g}) is off the image center ({ex:g}, {ey:g}); "
                      f"off-center principal points are not supported and are approximated by the center",
                      stacklevel=3)
    eye = -R.T @ t
    forward, down = R[2], R[1]
    fov = math.degrees(2.0 * math.atan(0.5 * height / fy))
    return Camera(eye=tuple(eye), target=tuple(eye + forward), up=tuple(-down), fov=fov, width=width,
                  height=height)


def opencv_from_camera(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, R, t) in OpenCV conventions (see the module docstring) of a Camera."""
    flip = np.diag([1.0, -1.0, -1.0])   # OpenGL camera axes (y up, z back) -> OpenCV (y down, z forward)
    view = camera.view_matrix
    f = camera.focal_px
    K = np.array([[f, 0.0, 0.5 * camera.width - 0.5], [0.0, f, 0.5 * camera.height - 0.5], [0.0, 0.0, 1.0]])
    return K, flip @ view[:3, :3], flip @ view[:3, 3]


def _load_json(path: Path):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: no such camera file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a camera file (JSON): {exc}") from None


@file_reader
def load_opencv(path: Path, data) -> list[tuple[str, Camera]]:
    """The cameras of an OpenCV JSON file (parsed ``data``)."""
    entries = data["cameras"] if isinstance(data, dict) and "cameras" in data else [data]
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: \"cameras\" must be a non-empty list")
    views = []
    for i, entry in enumerate(entries):
        where = f"{path}: camera {i}"
        try:
            name = str(entry.get("name", i))
            camera = camera_from_opencv(entry["K"], entry["R"], entry["t"], entry["width"], entry["height"],
                                        where=where)
        except KeyError as exc:
            raise InputError(f"{where} lacks {exc.args[0]!r}", element=exc.args[0], row=i) from None
        except (AttributeError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: bad camera: {exc}", element=getattr(exc, "element", None), row=i) from None
        views.append((name, camera))
    return views


def _quaternion_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not n > 0:
        raise ValueError("zero quaternion")
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _data_lines(path: Path) -> list[tuple[int, str]]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file (a COLMAP model needs {' and '.join(COLMAP_FILES)})",
                         file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read: {exc}", file=path) from None
    return [(n, line.strip()) for n, line in enumerate(text.splitlines(), 1) if not line.startswith("#")]


def load_colmap(folder: Path) -> list[tuple[str, Camera]]:
    """The cameras of a COLMAP text model (``cameras.txt`` and ``images.txt`` in ``folder``)."""
    cameras_txt, images_txt = (folder / name for name in COLMAP_FILES)
    intrinsics = {}
    for n, line in _data_lines(cameras_txt):
        if not line:
            continue
        fields = line.split()
        try:
            model = fields[1]
            if model not in COLMAP_MODELS:
                raise InputError(f"{cameras_txt}:{n}: camera model {model}; surfsplat reads "
                                 f"{', '.join(COLMAP_MODELS)}", file=cameras_txt, row=n - 1)
            count, distorted = COLMAP_MODELS[model]
            params = [float(v) for v in fields[4:]]
            if len(params) != count:
                raise ValueError(f"{model} has {count} parameters, got {len(params)}")
            if distorted:
                if any(params[3:]):
                    warnings.warn(f"{cameras_txt}:{n}: {model} lens distortion is ignored", stacklevel=3)
                params = params[:3]
            fx, fy, cx, cy = (params[0], params[0], params[1], params[2]) if len(params) == 3 else params
            intrinsics[int(fields[0])] = (np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]),
                                          int(fields[2]), int(fields[3]))
        except (IndexError, ValueError) as exc:
            raise InputError(f"{cameras_txt}:{n}: bad camera line: {exc}", file=cameras_txt, row=n - 1) from None
    lines = _data_lines(images_txt)
    views, i = [], 0
    while i < len(lines):
        n, line = lines[i]
        i += 1
        if not line:
            continue
        fields = line.split(maxsplit=9)
        try:
            if len(fields) < 10:
                raise ValueError("need IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME")
            q = [float(v) for v in fields[1:5]]
            t = [float(v) for v in fields[5:8]]
            camera_id, name = int(fields[8]), fields[9]
            if camera_id not in intrinsics:
                raise ValueError(f"camera {camera_id} is not in {cameras_txt.name}")
            K, width, height = intrinsics[camera_id]
            camera = camera_from_opencv(K, _quaternion_matrix(*q), t, width, height, center_offset=0.0,
                                        where=f"{images_txt}:{n}")
        except ValueError as exc:
            raise InputError(f"{images_txt}:{n}: bad image line: {exc}", file=images_txt, row=n - 1) from None
        views.append((Path(name).stem, camera))
        i += 1   # the image's 2-D points line (possibly empty)
    if not views:
        raise InputError(f"{images_txt}: no images", file=images_txt)
    return views


@file_reader
def load_nerf(path: Path, data, width: int | None = None, height: int | None = None) -> list[tuple[str, Camera]]:
    """The cameras of a NeRF ``transforms.json`` (parsed ``data``); ``width``, ``height`` where it has no w, h."""
    frames = data.get("frames")
    if not isinstance(frames, list) or not frames:
        raise InputError(f"{path}: \"frames\" must be a non-empty list")
    flip = np.diag([1.0, -1.0, -1.0])
    views = []
    for i, frame in enumerate(frames):
        where = f"{path}: frame {i}"
        try:
            keys = {**data, **frame}
            w = int(keys["w"]) if "w" in keys else width
            h = int(keys["h"]) if "h" in keys else height
            if w is None or h is None:
                raise InputError(f"{where}: no image size (w, h) in the file; give --width and --height")
            if "fl_x" in keys or "fl_y" in keys:
                fx = float(keys["fl_x"] if "fl_x" in keys else keys["fl_y"])
                fy = float(keys.get("fl_y", fx))
            elif "camera_angle_x" in keys:
                fx = 0.5 * w / math.tan(0.5 * float(keys["camera_angle_x"]))
                fy = 0.5 * h / math.tan(0.5 * float(keys["camera_angle_y"])) if "camera_angle_y" in keys else fx
            else:
                raise InputError(f"{where}: no camera_angle_x or fl_x/fl_y")
            cx, cy = float(keys.get("cx", 0.5 * w)), float(keys.get("cy", 0.5 * h))
            c2w = np.asarray(frame["transform_matrix"], dtype=np.float64)
            if c2w.shape != (4, 4):
                raise ValueError(f"transform_matrix must be 4x4, got shape {c2w.shape}")
            rotation = c2w[:3, :3]
            R = flip @ rotation.T   # world -> OpenGL camera is rotation^T; then OpenGL -> OpenCV axes
            t = -R @ c2w[:3, 3]
            K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
            camera = camera_from_opencv(K, R, t, w, h, center_offset=0.0, where=where)
        except KeyError as exc:
            raise InputError(f"{where} lacks {exc.args[0]!r}", element=exc.args[0], row=i) from None
        except (AttributeError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: bad camera: {exc}", element=getattr(exc, "element", None), row=i) from None
        file_path = frame.get("file_path")
        views.append((Path(str(file_path)).stem if file_path else str(i), camera))
    return views


@file_reader
def load_cameras(path: str | os.PathLike, *, width: int | None = None,
                 height: int | None = None) -> list[tuple[str, Camera]]:
    """The named cameras of ``path``: a COLMAP text model (``cameras.txt``, ``images.txt`` or their
    folder), a NeRF ``transforms.json``, an OpenCV JSON file or a surfsplat camera file (see the module
    docstring). ``width``, ``height``: the image size where a NeRF file gives none. InputError naming
    the file when it is none of them or malformed."""
    path = Path(path)
    if path.is_dir() or path.name in COLMAP_FILES:
        folder = path if path.is_dir() else path.parent
        if not all((folder / name).is_file() for name in COLMAP_FILES):
            raise InputError(f"{path}: a COLMAP text model needs {' and '.join(COLMAP_FILES)} in {folder}")
        return load_colmap(folder)
    data = _load_json(path)
    if isinstance(data, dict) and data.get("format") == CAMERA_FORMAT:
        return load_camera_list(path)
    if isinstance(data, dict) and "frames" in data:
        return load_nerf(path, data, width, height)
    if isinstance(data, dict) and ("K" in data or "cameras" in data):
        return load_opencv(path, data)
    raise InputError(f"{path}: not a camera file: expected a surfsplat camera, an OpenCV JSON (\"K\", \"R\", "
                     f"\"t\"), a NeRF transforms.json (\"frames\") or a COLMAP cameras.txt/images.txt")


def load_colmap_points(folder: str | os.PathLike) -> SplatCloud:
    """The sparse points of a COLMAP text model: ``points3D.txt`` in ``folder`` (or the file itself).

    Lines ``POINT3D_ID X Y Z R G B ERROR TRACK...``: positions in world units, colours 0-255 (sRGB as
    COLMAP stores them, read as given). InputError naming the file and line when it is malformed or empty.
    """
    path = Path(folder)
    path = path / COLMAP_POINTS if path.is_dir() else path
    rows = []
    for n, line in _data_lines(path):
        if not line:
            continue
        fields = line.split()
        try:
            rows.append([float(v) for v in fields[1:7]])
            if len(fields) < 7 or not all(math.isfinite(v) for v in rows[-1]):
                raise ValueError("expected POINT3D_ID X Y Z R G B with finite numbers")
        except ValueError as exc:
            raise InputError(f"{path}:{n}: {exc}", file=path, row=n - 1) from None
    if not rows:
        raise InputError(f"{path}: no points", file=path)
    data = np.asarray(rows, dtype=np.float64)
    return SplatCloud(data[:, :3], colors=np.clip(data[:, 3:6] / 255.0, 0.0, 1.0))
