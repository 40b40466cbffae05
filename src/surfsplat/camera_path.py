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
        near, far = min(c.near for c in keys), max(c.far for c in keys)
    first = replace(keys[0], near=near, far=far).resized(width or keys[0].width, height or keys[0].height)
    return [replace(first, eye=tuple(e), target=tuple(g), up=tuple(u / n), fov=float(f))
            for e, g, u, n, f in zip(eye, target, up, size, fov)]


def orbit_cameras(camera: Camera, frames: int, degrees: float = 360.0, elevation: float | None = None) -> list[Camera]:
    """``frames`` cameras turning the eye about the line through the target along ``camera.up``,
    ``degrees / frames`` apart (360: a loop whose last frame leads back to the first). With
    ``elevation`` (degrees above the plane normal to up) the eye is first moved to that height at
    the same distance. Image size, field of view and clip planes are kept (near/far widened to
    hold the whole orbit)."""
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
    cameras = []
    for i in range(int(frames)):
        turned = rotate(offset, up, degrees * i / frames)
        cameras.append(replace(camera, eye=tuple(target + turned)))
    if camera.near is not None and camera.far is not None:
        near, far = camera.near, camera.far
        cameras = [replace(c, near=near, far=far) for c in cameras]
    return cameras
