"""Per-pixel maps of a rendered frame beside the image: depth, normals and coverage, as files.

Depth (``--depth``): ``.npy`` float32 camera-space depth (distance from the eye along the view axis,
scene units; +inf where empty), ``.exr`` the same as a float32 OpenEXR channel ``Z`` (:mod:`.exr`),
``.png`` 16-bit with near..far stated in the file (:mod:`.depth_image`).

Normals (``--normals``): unit normals of the nearest visible surface, **camera space** (OpenGL camera
axes: x right, y up, z toward the viewer; every visible normal has z >= 0 up to noise) unless world
space is asked for (API). They are computed from the depth map (:func:`normals_from_depth`): the
renderer blends per-pixel normals but does not read them back, so the map is the normal of the
surface the depth image describes, not the splats' shading normals. ``.png``: 8-bit RGB
``0.5 + 0.5 n``, (0, 0, 0) where empty; ``.exr`` / ``.npy``: float32 (H, W, 3), NaN where empty.

Coverage (``--coverage``): :attr:`Frame.alpha <surfsplat.rendering.frame.Frame.alpha>`, the fraction of
each pixel the surface covers (antialiased with ``--supersample``): ``.png`` grey, 8 or 16 bits
(0 = empty, 255 or 65535 = covered), ``.npy`` float32 in [0, 1], ``.exr`` a float32 channel ``A``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image

from ..camera import Camera
from ..errors import InputError
from .atomic import atomic_path
from .depth_image import save_depth_png, save_normal_png
from .exr import check_exr, save_depth_exr, save_exr

#: The file kinds each map is written as, by suffix.
MAP_SUFFIXES = {"depth": (".npy", ".exr", ".png"), "normals": (".png", ".exr", ".npy"),
                "coverage": (".png", ".npy", ".exr")}
#: Normal spaces of :func:`normals_from_depth`.
SPACES = ("camera", "world")


def check_map_path(kind: str, path: str | os.PathLike) -> Path:
    """``path`` as a Path; InputError naming the flag when its suffix is not one ``kind`` ("depth",
    "normals", "coverage") is written as, or when EXR is asked for without the ``exr`` extra."""
    path = Path(path)
    suffix = path.suffix.lower()
    allowed = MAP_SUFFIXES[kind]
    if suffix not in allowed:
        raise InputError(f"{path}: --{kind} writes {', '.join('OUT' + s for s in allowed)}; "
                         f"not {suffix or 'no suffix'!r}")
    if suffix == ".exr":
        check_exr(path)
    return path


def _save_npy(values: np.ndarray, path: Path, overwrite: bool) -> None:
    with atomic_path(path, overwrite=overwrite) as temp:
        with open(temp, "wb") as handle:
            np.save(handle, values)


def save_depth(depth: np.ndarray, path: str | os.PathLike, near: float, far: float, *,
               overwrite: bool = True) -> str:
    """Write camera-space ``depth`` (+inf where empty) as ``.npy``, ``.exr`` or 16-bit ``.png``
    (``near``..``far``: the PNG's range, model units); returns a description of the convention."""
    path = check_map_path("depth", path)
    suffix = path.suffix.lower()
    if suffix == ".png":
        save_depth_png(depth, near, far, path, overwrite=overwrite)
        return f"16-bit: 0 = empty, 1..65535 = {near:.6g}..{far:.6g}"
    if suffix == ".exr":
        save_depth_exr(depth, path, overwrite=overwrite)
        return "float32 EXR channel Z: camera-space depth, inf = empty"
    _save_npy(np.asarray(depth, dtype=np.float32), path, overwrite)
    return "camera-space, inf = empty"


def pixel_points(depth: np.ndarray, camera: Camera) -> np.ndarray:
    """(H, W, 3) float64 camera-space points (OpenGL axes) of a depth map, row 0 at the top: pixel
    centers at half-integers, principal point at the image center, ``z = -depth``."""
    depth = np.asarray(depth, dtype=np.float64)
    h, w = depth.shape
    if (h, w) != (camera.height, camera.width):
        raise InputError(f"depth map is {w}x{h} but the camera is {camera.width}x{camera.height}")
    f = camera.focal_px
    x = (np.arange(w) + 0.5 - 0.5 * w) / f
    y = (h - (np.arange(h) + 0.5) - 0.5 * h) / f   # window y runs up, rows run down
    return np.stack([depth * x[None, :], depth * y[:, None], -depth], axis=-1)


def _tangent(points: np.ndarray, depth: np.ndarray, axis: int, footprint: np.ndarray) -> np.ndarray:
    """The surface's tangent along ``axis`` (0: rows, 1: columns) per pixel: the central difference
    where both neighbours lie on the same smooth surface, else the one-sided difference across the
    smaller depth step (so silhouettes do not bend the normals); NaN where neither neighbour is drawn.
    ``footprint``: a pixel's width at its depth (model units)."""
    pad = [(0, 0)] * 3
    pad[axis] = (1, 1)
    p = np.pad(points, pad, constant_values=np.nan)
    d = np.pad(depth, pad[:2], constant_values=np.inf)
    n = depth.shape[axis]
    with np.errstate(invalid="ignore"):   # inf - inf between empty pixels: NaN, not drawn
        ahead, behind = (np.take(p, range(2, n + 2), axis=axis) - points,
                         points - np.take(p, range(0, n), axis=axis))
        step_ahead = np.take(d, range(2, n + 2), axis=axis) - depth
        step_behind = depth - np.take(d, range(0, n), axis=axis)
        # central differences are second-order accurate; use them where the depth's slope changes
        # by less than half of itself plus a pixel's footprint (no silhouette or crease between)
        bend = np.abs(step_ahead - step_behind)
        smooth = np.isfinite(bend) & (bend <= 0.5 * np.maximum(np.abs(step_ahead), np.abs(step_behind)) + footprint)
        central = 0.5 * (ahead + behind)
        one_sided = np.where((np.abs(step_ahead) <= np.abs(step_behind))[..., None], ahead, behind)
    tangent = np.where(smooth[..., None], central, one_sided)
    tangent[~(np.isfinite(step_ahead) | np.isfinite(step_behind))] = np.nan
    return tangent


def normals_from_depth(depth: np.ndarray, camera: Camera, *, space: str = "camera") -> np.ndarray:
    """(H, W, 3) float32 unit normals of the surface a depth map shows (row 0 at the top), NaN where
    empty or where a pixel has no drawn neighbour along a row or a column.

    The normal is the cross product of the surface's tangents along the image's x and y axes, from
    the pixels' camera-space points (:func:`pixel_points`), turned toward the eye. ``space``:
    "camera" (OpenGL camera axes: x right, y up, z toward the viewer) or "world" (model axes).
    """
    if space not in SPACES:
        raise InputError(f"normal space must be one of {', '.join(SPACES)}, got {space!r}")
    depth = np.asarray(depth, dtype=np.float64)
    depth = np.where(np.isfinite(depth) & (depth > 0), depth, np.inf)
    points = pixel_points(np.where(np.isfinite(depth), depth, np.nan), camera)
    footprint = depth / camera.focal_px
    along_x = _tangent(points, depth, 1, footprint)
    along_y = -_tangent(points, depth, 0, footprint)   # rows run down, window y up
    normal = np.cross(along_x, along_y)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        normal *= np.where(np.sum(normal * points, axis=-1, keepdims=True) > 0, -1.0, 1.0)   # toward the eye
        if space == "world":
            normal = normal @ camera.view_matrix[:3, :3]   # camera -> world: the rotation's transpose
    return normal.astype(np.float32)


def save_normals(normals: np.ndarray, path: str | os.PathLike, *, overwrite: bool = True) -> Path:
    """Write (H, W, 3) unit normals (NaN where empty) as ``.png`` (``0.5 + 0.5 n``, black where empty),
    ``.exr`` (channels R, G, B = x, y, z) or ``.npy`` (float32); returns the path."""
    path = check_map_path("normals", path)
    normals = np.asarray(normals, dtype=np.float32)
    if normals.ndim != 3 or normals.shape[-1] != 3:
        raise InputError(f"{path}: a normal map is (H, W, 3), got shape {normals.shape}")
    suffix = path.suffix.lower()
    if suffix == ".png":
        return save_normal_png(normals, path, overwrite=overwrite)
    if suffix == ".exr":
        return save_exr({"RGB": normals}, path, attributes={"surfsplat:normals": "unit normals x, y, z; NaN = empty"},
                        overwrite=overwrite)
    _save_npy(normals, path, overwrite)
    return path


def save_coverage(alpha: np.ndarray, path: str | os.PathLike, *, bit_depth: int = 8,
                  overwrite: bool = True) -> Path:
    """Write (H, W) coverage in [0, 1] as a grey ``.png`` of ``bit_depth`` 8 or 16 bits, ``.npy``
    (float32) or ``.exr`` (channel A); returns the path."""
    path = check_map_path("coverage", path)
    alpha = np.clip(np.asarray(alpha, dtype=np.float32), 0.0, 1.0)
    if alpha.ndim != 2:
        raise InputError(f"{path}: a coverage map is (H, W), got shape {alpha.shape}")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        _save_npy(alpha, path, overwrite)
    elif suffix == ".exr":
        save_exr({"A": alpha}, path, attributes={"surfsplat:coverage": "fraction of the pixel covered"},
                 overwrite=overwrite)
    else:
        if bit_depth not in (8, 16):
            raise InputError(f"{path}: coverage PNGs have 8 or 16 bits, got {bit_depth!r}")
        top, dtype = (255.0, np.uint8) if bit_depth == 8 else (65535.0, np.uint16)
        with atomic_path(path, overwrite=overwrite) as temp:
            Image.fromarray(np.round(alpha * top).astype(dtype)).save(temp, format="PNG")
    return path
