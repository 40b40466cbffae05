"""Checking a Phong splat cover: the error bound of Botsch 2004, sec. 3, measured per sample."""

from __future__ import annotations

import itertools

import numpy as np

from ...cloud import SplatCloud
from ...errors import InputError
from ..common import dot
from ..neighbors import kdtree


def phong_coverage(samples, splats: SplatCloud, *, clip_tolerance: float = 1e-4) -> np.ndarray:
    """Distance of each sample from the nearest splat plane whose ellipse contains it, model units.

    For checking a Phong splat cover: sample ``i`` is covered within ``eps``
    (Botsch 2004, sec. 3) when the result is ``<= eps``. A splat contains a
    sample when the sample's orthogonal projection into the splat's plane
    (``u x v``) has ``s^2 + t^2 <= 1`` and is on the kept side of its clip
    lines (``a s + b t + c >= -clip_tolerance``).

    Args:
        samples: (N, 3) positions or a :class:`SplatCloud`, model units.
        splats: splats with ``u`` and ``v``.
        clip_tolerance: slack of the clip-line test, in ``(s, t)`` units.

    Returns:
        (N,) float64: the smallest ``|distance from the plane|`` over the
        splats containing the sample, ``inf`` where none does. (Samples more
        than about one splat radius from a splat's plane are not tested
        against that splat.)
    """
    pts = np.asarray(samples.positions if isinstance(samples, SplatCloud) else samples, dtype=np.float64)
    if splats.u is None or splats.v is None:
        raise InputError("phong_coverage: the splats need axes u and v")
    center = splats.positions.astype(np.float64)
    u = splats.u.astype(np.float64)
    v = splats.v.astype(np.float64)
    normal = np.cross(u, v)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    radius = np.sqrt(np.maximum((u * u).sum(1), (v * v).sum(1)))
    best = np.full(len(pts), np.inf)
    if len(pts) == 0 or len(center) == 0:
        return best
    tree = kdtree(pts)
    # a contained sample is within the splat's radius of its center along the
    # plane; the plane distance bound is unknown here, so search a bit wider
    reach = radius * 1.5 + 1e-12
    chunk = 4096
    for start in range(0, len(center), chunk):
        sl = slice(start, min(start + chunk, len(center)))
        hits = tree.query_ball_point(center[sl], reach[sl], workers=-1)
        counts = np.fromiter((len(h) for h in hits), dtype=np.int64, count=len(hits))
        if counts.sum() == 0:
            continue
        row = np.repeat(np.arange(sl.start, sl.stop), counts)
        idx = np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=int(counts.sum()))
        d = pts[idx] - center[row]
        s = dot(d, u[row]) / dot(u[row], u[row])
        t = dot(d, v[row]) / dot(v[row], v[row])
        inside = s * s + t * t <= 1.0
        if splats.clip_lines is not None:
            lines = splats.clip_lines[row].astype(np.float64)
            value = lines[:, :, 0] * s[:, None] + lines[:, :, 1] * t[:, None] + lines[:, :, 2]
            inside &= (value >= -clip_tolerance).all(axis=1)
        h = np.abs(dot(d, normal[row]))
        np.minimum.at(best, idx[inside], h[inside])
    return best
