"""Hybrid drawing for LiDAR: surface splats where the scan is a surface, round points where it is not.

Airborne and terrestrial scans mix surfaces (ground, roofs, walls) with things that are not
surfaces at the sampling scale (vegetation, wires, noise). An oriented splat needs a tangent
plane; fitted to a tree crown it is a random flat disk that shows as a shard from most
directions. Potree and CloudCompare draw everything as screen-aligned points; here planar
neighbourhoods keep their surface splats and only the non-planar ones (the ``nonplanar``
attribute preprocessing sets, :func:`surfsplat.geometry.preprocess.preprocess`) become points.

How: the non-planar splats are turned, per frame, into disks facing the eye (normal along
``eye - p``, radius the splat's larger semi-axis, the size the ``points`` technique uses), and
the whole cloud is drawn by one technique in one frame. A disk facing the eye is what a round
screen-aligned point is (Schuetz 2016, sec. 3.4), up to the perspective of its outline, so both
kinds share one depth buffer, one visibility pass and one blend: occlusion between ground, roofs
and trees is the technique's own, with no second pass and no compositing. The renderer takes the
disk's plane from ``u``, ``v`` and shades with the stored normal (turned to the eye's side), so
only the axes change: the points keep their own normal for lighting (a normal toward the eye
would give every point the headlight's full diffuse and specular: bright dots), flat (no normal
field) and unclipped.
"""

from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..frames import tangent_frame


def facing_points(cloud: SplatCloud, points: np.ndarray, camera: Camera) -> SplatCloud:
    """``cloud`` with the splats where ``points`` ((N,) bool) is True made disks facing ``camera``'s eye.

    Each such splat keeps its center, colour and shading normal; its axes ``u``, ``v`` become an
    orthonormal pair across the direction to the eye scaled to ``r = max(|u|, |v|)`` (model units),
    its normal field zero and its clip lines none. Other rows are unchanged. Vectorized.
    """
    points = np.asarray(points, dtype=bool)
    if points.shape != (len(cloud),):
        raise InputError(f"hybrid: the point mask must have one entry per splat ({len(cloud)}), "
                         f"got shape {points.shape}")
    if not points.any():
        return cloud
    if cloud.u is None or cloud.v is None:
        raise InputError("hybrid: the cloud needs splat axes u, v (preprocess it first)")
    pos = cloud.positions[points].astype(np.float64)
    toward = np.asarray(camera.eye, dtype=np.float64) - pos
    length = np.linalg.norm(toward, axis=1, keepdims=True)
    # a point at the eye itself has no direction to it: face it along the view axis
    toward = np.where(length > 0, toward / np.where(length > 0, length, 1.0),
                      np.asarray(camera.view_matrix[2, :3], dtype=np.float64))  # -forward
    radius = np.maximum(np.linalg.norm(cloud.u[points], axis=1), np.linalg.norm(cloud.v[points], axis=1))
    t1, t2 = tangent_frame(toward)
    u, v = cloud.u.copy(), cloud.v.copy()
    u[points] = t1 * radius[:, None]
    v[points] = t2 * radius[:, None]
    changes = {"u": u, "v": v}
    if cloud.normal_field is not None:
        field = cloud.normal_field.copy()
        field[points] = 0.0
        changes["normal_field"] = field
    if cloud.clip_lines is not None:
        lines = cloud.clip_lines.copy()
        lines[points] = np.array([0.0, 0.0, 1.0], dtype=np.float32)   # c = 1 > 0: no clip (as node splats)
        changes["clip_lines"] = lines
    return cloud.replace(**changes)
