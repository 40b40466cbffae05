"""The default view of an exported page: :func:`surfsplat.camera.fit_points` reduced to what the page's
size changes.

``surfsplat render`` without a camera frames the model with :func:`~surfsplat.pipeline.framing.auto_camera`,
whose fit depends on the image's aspect ratio. For a fixed direction every quantity of that fit is a
maximum or minimum, over the points, of a function linear (``z + (x + m) / t``) or linear-fractional
(``(x + m - c) / (D - z)``) in the point's coordinates ``(x, z)`` (or ``(y, z)``) in the view's basis, and
such functions reach their extremes over a set at the vertices of its convex hull. So the page gets the
basis and the two 2-D hulls (:func:`fit_frame`), and :func:`camera_from_frame` (the Python twin of the
viewer's ``defaultCamera``) reproduces the fit at any size; near and far enclose the model's bounds grown
by its largest radius (:func:`~surfsplat.pipeline.framing.clipped_to`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..camera import Camera, centering_offset, fit_basis


def _hull(points: np.ndarray) -> np.ndarray:
    """The vertices of the 2-D convex hull of ``points`` (M, 2); the extreme points where it is degenerate."""
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        index = np.unique([points[:, 0].argmin(), points[:, 0].argmax(), points[:, 1].argmin(),
                           points[:, 1].argmax()])
        return points[index]


def fit_frame(points: np.ndarray, direction, up, margin: float) -> dict:
    """What :func:`surfsplat.camera.fit_points` needs of ``points`` for any fov and size: the basis
    (``right``, ``screen_up``, ``direction``, ``up``: world unit vectors, ``up`` replaced as fit_points
    replaces it where the direction runs along it), the points' box ``center`` and diagonal ``extent``,
    ``margin`` and the hulls of ``(x, z)`` and ``(y, z)`` (model units, relative to the center)."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    d, up, right, screen_up = fit_basis(direction, up)
    lo, hi = p.min(axis=0), p.max(axis=0)
    center = 0.5 * (lo + hi)
    q = p - center
    x, y, z = q @ right, q @ screen_up, q @ d
    return {"center": center.tolist(), "right": right.tolist(), "screen_up": screen_up.tolist(),
            "direction": d.tolist(), "up": np.asarray(up, np.float64).tolist(), "margin": float(margin),
            "extent": float(np.linalg.norm(hi - lo)) or 1.0, "zmax": float(z.max()),
            "hull_x": _hull(np.stack([x, z], axis=1)).tolist(), "hull_y": _hull(np.stack([y, z], axis=1)).tolist()}


def camera_from_frame(frame: dict, fov: float, width: int, height: int, fill: float = 0.9) -> Camera:
    """The camera :func:`surfsplat.camera.fit_points` gives for the points of :func:`fit_frame` (no near/far)."""
    m = frame["margin"]
    half_v = np.radians(fov) / 2.0
    ty = fill * np.tan(half_v)
    tx = ty * width / height
    hulls = [np.asarray(frame["hull_x"], np.float64), np.asarray(frame["hull_y"], np.float64)]
    offsets, distances = [], []
    for hull, t in zip(hulls, (tx, ty)):
        lateral, z = hull[:, 0], hull[:, 1]
        a = float(np.max(z + (lateral + m) / t))
        b = float(np.max(z + (m - lateral) / t))
        offsets.append(0.5 * t * (a - b))
        distances.append(0.5 * (a + b))
    dist = max(max(distances), frame["zmax"] + m + 1e-3 * frame["extent"])
    for axis, hull in enumerate(hulls):
        if distances[axis] < dist:
            offsets[axis] = centering_offset(hull[:, 0], dist - hull[:, 1], m)
    right, screen_up, d = (np.asarray(frame[k], np.float64) for k in ("right", "screen_up", "direction"))
    target = np.asarray(frame["center"], np.float64) + offsets[0] * right + offsets[1] * screen_up
    return Camera(eye=tuple(target + dist * d), target=tuple(target), up=tuple(frame["up"]), fov=fov, width=width,
                  height=height)
