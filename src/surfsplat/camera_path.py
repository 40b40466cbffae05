"""Smooth camera paths through key views (``surfsplat turntable INPUT --path cams.json``).

Eye, target and up of the key cameras are each interpolated by a uniform Catmull-Rom spline (a
cubic Hermite spline whose tangent at key i is ``(P[i+1] - P[i-1]) / 2``, Catmull & Rom 1974): it
passes through every key, and its first derivative is continuous across keys (C1). An open path's
end tangents come from mirrored phantom keys (``P[-1] = 2 P[0] - P[1]``), so two keys give a
straight line at constant speed; a closed path wraps around. The vertical field of view is
interpolated the same way; the up vector is made orthogonal to the view direction per frame.
Optionally the frames are spaced at equal arc length of the eye's path (constant speed).

:func:`orbit_cameras` gives the circular path of a turntable.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .camera import MIN_FOV, Camera, rotate
from .errors import InputError

#: Samples per key interval used to measure the eye path's arc length (constant speed).
ARC_SAMPLES = 256
#: Larger point sets are framed by the corners of the grid cells they occupy (:func:`framing_points`).
FRAME_POINTS = 200_000
#: Cells along the longest side of that grid (the frame grows by at most a cell's diagonal).
FRAME_CELLS = 64


def _check_keys(keys) -> np.ndarray:
    keys = np.asarray(keys, dtype=np.float64)
    if keys.ndim == 1:
        keys = keys[:, None]
    if keys.ndim != 2 or len(keys) < 2:
        raise InputError(f"a spline needs at least 2 keys of shape (K, D), got shape {keys.shape}")
    if not np.isfinite(keys).all():
        raise InputError("spline keys must be finite")
    return keys


def _neighbours(keys: np.ndarray, closed: bool) -> np.ndarray:
    """The keys with one neighbour added at each end: wrapped (closed) or mirrored (open)."""
    if closed:
        return np.concatenate([keys[-1:], keys, keys[:2]])
    return np.concatenate([2 * keys[:1] - keys[1:2], keys, 2 * keys[-1:] - keys[-2:-1]])


def catmull_rom(keys, t, *, closed: bool = False, derivative: bool = False) -> np.ndarray:
    """Points (or with ``derivative`` their derivatives d/dt) of the uniform Catmull-Rom spline
    through ``keys`` (K, D) at parameters ``t`` (M,): key i at t = i; t in [0, K - 1] for an open
    path, [0, K] for a closed one (t = K is key 0 again). Returns (M, D) float64."""
    keys = _check_keys(keys)
    k = len(keys)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    span = k if closed else k - 1
    if not (np.isfinite(t).all() and (t >= 0).all() and (t <= span).all()):
        raise InputError(f"spline parameters must lie in [0, {span}]")
    p = _neighbours(keys, closed)   # p[i + 1] is key i
    i = np.minimum(np.floor(t).astype(np.int64), span - 1)
    s = (t - i)[:, None]
    p0, p1 = p[i + 1], p[i + 2]
    m0, m1 = 0.5 * (p[i + 2] - p[i]), 0.5 * (p[i + 3] - p[i + 1])
    if derivative:   # d/ds of the Hermite basis below
        return ((6 * s**2 - 6 * s) * p0 + (3 * s**2 - 4 * s + 1) * m0 + (-6 * s**2 + 6 * s) * p1
                + (3 * s**2 - 2 * s) * m1)
    return ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * m0 + (-2 * s**3 + 3 * s**2) * p1
            + (s**3 - s**2) * m1)


def path_parameters(keys, frames: int, *, closed: bool = False, constant_speed: bool = False) -> np.ndarray:
    """``frames`` spline parameters along the path through ``keys``: evenly spaced in t (each key
    interval gets the same time; an open path's first and last frames are its first and last keys, a
    closed path's last frame leads back to the first), or with ``constant_speed`` at equal arc
    length of the spline (uniform in t where the whole path has no length; a key interval where the
    eye stands still, turning only, then gets no frames)."""
    keys = _check_keys(keys)
    if not (isinstance(frames, (int, np.integer)) and frames >= 2):
        raise InputError(f"a camera path needs an integer number of frames >= 2, got {frames!r}")
    span = len(keys) if closed else len(keys) - 1
    uniform = np.arange(frames) * span / frames if closed else np.linspace(0.0, span, frames)
    if not constant_speed:
        return uniform
    dense = np.linspace(0.0, span, span * ARC_SAMPLES + 1)
    points = catmull_rom(keys, dense, closed=closed)
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    if not length[-1] > 1e-12 * (1.0 + np.abs(keys).max()):
        return uniform
    wanted = (np.arange(frames) / frames if closed else np.linspace(0.0, 1.0, frames)) * length[-1]
    return np.interp(wanted, length, dense)


def interpolate_cameras(keys: list[Camera], frames: int, *, closed: bool = False, constant_speed: bool = False,
                        width: int | None = None, height: int | None = None) -> list[Camera]:
    """``frames`` cameras along a smooth path through the key cameras (see the module docstring).

    ``closed``: the path returns to the first key (a loop). ``constant_speed``: equal eye distance
    between frames (see :func:`path_parameters`). ``width``, ``height``: the image size (default: the
    first key's). Clip planes: the widest of the keys' where every key has them, else None (from the
    model's bounds per frame). InputError for fewer than 2 keys or a frame whose up vector is
    parallel to its view direction.
    """
    keys = list(keys)
    if len(keys) < 2 or not all(isinstance(c, Camera) for c in keys):
        raise InputError(f"a camera path needs at least 2 key cameras, got {len(keys)}")
    t = path_parameters([c.eye for c in keys], frames, closed=closed, constant_speed=constant_speed)
    ups = np.array([c.up for c in keys], dtype=np.float64)
    ups /= np.linalg.norm(ups, axis=1, keepdims=True)
    eye = catmull_rom([c.eye for c in keys], t, closed=closed)
    target = catmull_rom([c.target for c in keys], t, closed=closed)
    up = catmull_rom(ups, t, closed=closed)
    fov = np.clip(catmull_rom([c.fov for c in keys], t, closed=closed)[:, 0], MIN_FOV, 179.0)
    forward = target - eye
    distance = np.linalg.norm(forward, axis=1, keepdims=True)
    if not (distance > 0).all():
        raise InputError(f"camera path: eye and target meet at frame {int(np.argmin(distance))}")
    forward /= distance
    up -= np.sum(up * forward, axis=1, keepdims=True) * forward   # orthogonal to the view direction
    size = np.linalg.norm(up, axis=1)
    if not (size > 1e-6).all():
        raise InputError(f"camera path: the up vector is parallel to the view direction at frame "
                         f"{int(np.argmin(size))}; give the key cameras up vectors away from their view")
    near = far = None
    if all(c.near is not None and c.far is not None for c in keys):
        near = min(float(c.near) for c in keys if c.near is not None)
        far = max(float(c.far) for c in keys if c.far is not None)
    first = replace(keys[0], near=near, far=far).resized(width or keys[0].width, height or keys[0].height)
    return [replace(first, eye=tuple(e), target=tuple(g), up=tuple(u / n), fov=float(f))
            for e, g, u, n, f in zip(eye, target, up, size, fov)]


def orbit_cameras(camera: Camera, frames: int, degrees: float = 360.0, elevation: float | None = None, *,
                  points=None, margin: float = 0.0, fill: float = 0.9) -> list[Camera]:
    """``frames`` cameras turning the eye about the line through the target along ``camera.up``,
    ``degrees / frames`` apart (360: a loop whose last frame leads back to the first). With
    ``elevation`` (degrees above the plane normal to up) the eye is first moved to that height at
    the same distance. Image size, field of view and clip planes are kept (near/far widened to
    hold the whole orbit).

    With ``points`` ((N, 3) world positions, model units) the orbit is framed for them
    (:func:`orbit_distance`; more than :data:`FRAME_POINTS` points through :func:`framing_points`): the
    target moves to the center of their bounding box and the eye to the one distance at which every
    frame shows every point, grown by ``margin`` (model units: the largest splat radius), within
    ``fill`` of the image's half-extent; near/far then enclose the points in every frame.
    """
    if not (isinstance(frames, (int, np.integer)) and frames >= 1):
        raise InputError(f"frames must be an integer >= 1, got {frames!r}")
    if not np.isfinite(degrees):
        raise InputError(f"degrees must be finite, got {degrees}")
    up = np.asarray(camera.up, dtype=np.float64)
    up /= np.linalg.norm(up)
    target = np.asarray(camera.target, dtype=np.float64)
    offset = np.asarray(camera.eye, dtype=np.float64) - target
    if elevation is not None:
        if not -89.0 <= elevation <= 89.0:
            raise InputError(f"elevation must be within -89..89 degrees, got {elevation}")
        flat = offset - (offset @ up) * up
        if np.linalg.norm(flat) < 1e-12 * np.linalg.norm(offset):
            flat = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
        flat /= np.linalg.norm(flat)
        angle = np.radians(elevation)
        offset = np.linalg.norm(offset) * (np.cos(angle) * flat + np.sin(angle) * up)
    angles = degrees * np.arange(int(frames)) / frames
    if points is not None:
        p = framing_points(points)
        lo, hi = p.min(axis=0), p.max(axis=0)
        target = 0.5 * (lo + hi)
        unit = offset / np.linalg.norm(offset)
        directions = np.array([rotate(unit, up, a) for a in angles])
        offset = unit * orbit_distance(p, target, directions, up, fov=camera.fov, aspect=camera.width / camera.height,
                                       margin=margin, fill=fill)
    cameras = [replace(camera, eye=tuple(target + rotate(offset, up, a)), target=tuple(target)) for a in angles]
    if points is not None:
        clipped = [replace(c, near=None, far=None).with_clip_from_bounds(lo, hi, margin) for c in cameras]
        near = min(float(c.near) for c in clipped if c.near is not None)
        far = max(float(c.far) for c in clipped if c.far is not None)
        return [replace(c, near=near, far=far) for c in cameras]
    if camera.near is not None and camera.far is not None:
        near, far = camera.near, camera.far
        cameras = [replace(c, near=near, far=far) for c in cameras]
    return cameras


def orbit_distance(points, target, directions, up, *, fov: float, aspect: float = 1.0, margin: float = 0.0,
                   fill: float = 0.9) -> float:
    """The smallest eye distance from ``target`` at which cameras looking at it from every one of
    ``directions`` ((F, 3) world vectors toward the eye, screen axes from ``up``) show all ``points``
    ((N, 3) world, model units) grown by ``margin`` within ``fill`` of the image's half-extent.

    A point at lateral offsets (x, y) from the view axis and depth z toward the eye is inside when
    ``|x| + margin <= t_x (D - z)`` and ``|y| + margin <= t_y (D - z)``, t_y = fill tan(fov / 2),
    t_x = t_y aspect (``aspect`` = width / height); D is the largest of ``z + (|x| + margin) / t_x``,
    ``z + (|y| + margin) / t_y`` over points and directions, at least a little beyond the nearest
    point. Model units.
    """
    p = _checked_points(points) - np.asarray(target, dtype=np.float64)
    directions = np.atleast_2d(np.asarray(directions, dtype=np.float64))
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    if not (0.0 < fov < 180.0 and aspect > 0 and 0.0 < fill and margin >= 0):
        raise InputError(f"orbit_distance: needs 0 < fov < 180, aspect > 0, fill > 0, margin >= 0; got fov {fov}, "
                         f"aspect {aspect}, fill {fill}, margin {margin}")
    ty = fill * np.tan(np.radians(fov) / 2.0)
    tx = ty * aspect
    pt = np.ascontiguousarray(p.T)
    extent = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))) or 1.0
    distance = 0.0
    for d in directions:   # one view per frame, vectorized over the points
        right = np.cross(-d, up)
        if np.linalg.norm(right) < 1e-9:
            raise InputError("orbit_distance: a view direction is parallel to up")
        right /= np.linalg.norm(right)
        screen_up = np.cross(right, -d)
        x, y, z = (a[0] * pt[0] + a[1] * pt[1] + a[2] * pt[2] for a in (right, screen_up, d))
        need = max(float(np.max(z + (np.abs(x) + margin) / tx)), float(np.max(z + (np.abs(y) + margin) / ty)),
                   float(z.max()) + margin + 1e-3 * extent)
        distance = max(distance, need)
    return distance


def framing_points(points, limit: int = FRAME_POINTS, cells: int = FRAME_CELLS) -> np.ndarray:
    """Points whose framing frames ``points`` ((N, 3) world, model units): the finite points
    themselves up to ``limit``; beyond it the distinct corners of the cells of a grid (``cells`` along
    the longest side of the bounding box) that hold a point. Every point lies in the convex hull of
    its cell's corners and a view frustum is convex, so a frame that holds the corners holds the
    points (at most a cell's diagonal looser)."""
    p = _checked_points(points)
    if len(p) <= limit:
        return p
    lo, hi = p.min(axis=0), p.max(axis=0)
    size = float((hi - lo).max()) / cells or 1.0
    dims = np.maximum(np.ceil((hi - lo) / size).astype(np.int64), 1)
    cell = np.minimum(((p - lo) / size).astype(np.int64), dims - 1)
    occupied = np.unique((cell[:, 0] * (dims[1] + 1) + cell[:, 1]) * (dims[2] + 1) + cell[:, 2])
    ijk = np.column_stack([occupied // ((dims[1] + 1) * (dims[2] + 1)), occupied // (dims[2] + 1) % (dims[1] + 1),
                           occupied % (dims[2] + 1)])
    offsets = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    corners = np.unique((ijk[:, None, :] + offsets[None]).reshape(-1, 3), axis=0)
    return lo + corners * size


def _checked_points(points) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not len(p):
        raise InputError(f"points must have shape (N, 3) with N >= 1, got {p.shape}")
    p = p[np.isfinite(p).all(axis=1)]
    if not len(p):
        raise InputError("points: none is finite")
    return p
