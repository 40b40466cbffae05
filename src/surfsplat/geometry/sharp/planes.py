"""Planar groups of a neighbourhood (steps 2-4 of :func:`~surfsplat.geometry.sharp.points.detect_sharp_features`).

Zwicker et al. 2004, section 5 intersects "the tangent planes of adjacent
reconstruction kernels on either side of a feature"; here the tangent plane
of each side is fitted to the points of that side. A neighbourhood is split
into up to three planar groups (greedy, like RANSAC with deterministic
hypotheses: the planes through the neighbours with their normals), a
least-squares plane is fitted to each, planes within the sharp angle are
merged, and the planes left (more than the angle apart) are the faces on
either side of an edge or corner. Vectorized over blocks of B neighbourhoods
of K1 points each (the point itself first).
"""

from __future__ import annotations

import numpy as np

from ..normals import smallest_eigenvectors

#: A fitted plane needs at least this many points and a spread of
#: ``lambda_mid / lambda_max`` above ``_MIN_SPREAD`` (not collinear).
_MIN_GROUP = 4
_MIN_SPREAD = 1e-3

#: A plane is dropped when another group has this fraction (and at least 2)
#: of its points on either side of it, farther than ``_STRADDLE_TOL`` inlier
#: tolerances (a curved face bulges a little past the plane fitted to it).
_STRADDLE = 0.1
_STRADDLE_TOL = 5.0

#: A point belongs to a plane when it lies within this fraction of the
#: neighbourhood radius of it (raw-point path).
_INLIER = 0.01

#: A feature needs this fraction of the neighbourhood's points within
#: ``_COVER_TOL`` inlier tolerances of its planes: faces at a crease are planar up
#: to it, a surface curved at the neighbourhood's scale fits planes only in strips.
#: Measured on cylinders (radius 1, 2, 4, 10 neighbourhood radii) at the CAD test's
#: density: false lines on the curved side for 2 % and 0 % of its points at radius 1
#: and 2 (99 % and 88 % without this test), none above; of the splats crossing the
#: cap/side rim, 17, 49, 75 and 96 % get their line.
_COVERED = 0.9
_COVER_TOL = 3.0

#: An own face is exactly planar when the RMS distance of its points to their plane is below
#: this fraction of the inlier tolerance.
_PLANAR = 0.1

#: Floor of the trimming tolerance of the final plane fits, fraction of the neighbourhood radius.
_TRIM = 1e-4


def _fit(x: np.ndarray, member: np.ndarray):
    """Least-squares planes of G groups of points.

    ``x``: (B, K1, 3) float64 points; ``member``: (B, K1, G) bool.
    Returns (normal (B, G, 3) unit, offset (B, G) with ``normal . x = offset``
    on the plane, centroid (B, G, 3), active (B, G): at least ``_MIN_GROUP``
    points, not collinear).
    """
    w = member.astype(np.float64)
    count = w.sum(axis=1)                                           # (B, G)
    safe = np.maximum(count, 1.0)
    wt = np.ascontiguousarray(w.transpose(0, 2, 1))                 # (B, G, K1)
    centroid = np.matmul(wt, x) / safe[..., None]                   # (B, G, 3)
    # second moments of all groups at once: (B, G, 3, K1) @ (B, 1, K1, 3); offsets are relative
    # to the point (small), so the one-pass covariance loses nothing in float64
    second = np.matmul(x.transpose(0, 2, 1)[:, None] * wt[:, :, None, :], x[:, None]) / safe[..., None, None]
    c = second - centroid[..., :, None] * centroid[..., None, :]
    normal = smallest_eigenvectors(*(c[..., i, j].ravel() for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))))
    normal = normal.astype(np.float64).reshape(centroid.shape)
    # not collinear: lambda_mid / lambda_max ~ I2 / trace^2 above _MIN_SPREAD
    trace = c[..., 0, 0] + c[..., 1, 1] + c[..., 2, 2]
    i2 = (c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] ** 2 + c[..., 0, 0] * c[..., 2, 2] - c[..., 0, 2] ** 2
          + c[..., 1, 1] * c[..., 2, 2] - c[..., 1, 2] ** 2)
    active = (count >= _MIN_GROUP) & (i2 > _MIN_SPREAD * trace * trace)
    offset = (normal * centroid).sum(axis=2)
    return normal, offset, centroid, active


def _members(label: np.ndarray) -> np.ndarray:
    """(B, K1, 3) bool one-hot of labels 0..2 (label 3 = left out)."""
    return label[..., None] == np.arange(3)


def _agree(label: np.ndarray, nn: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(B, 3) +-1 that turns each plane's normal toward the sum of its points' normals."""
    total = np.matmul(_members(label).transpose(0, 2, 1).astype(np.float64), nn)     # (B, 3, 3)
    return np.where((total * normal).sum(axis=2) < 0, -1.0, 1.0)


def _assign(x, normal, offset, active, tol):
    """Label of the nearest active plane within ``tol`` (B,) of each point, 3 where none is."""
    dist = np.abs(np.matmul(x, normal.transpose(0, 2, 1)) - offset[:, None, :])
    dist = np.where(active[:, None, :], dist, np.inf)
    nearest = np.argmin(dist, axis=2)
    return np.where(np.take_along_axis(dist, nearest[..., None], axis=2)[..., 0] < tol[:, None], nearest, 3)


def _refine_groups(x, label, normal, offset, active, tol):
    """Step 3 of :func:`group_planes`: (label, trimmed) after least squares,
    reassignment, a group for coplanar left-over points, and trimming."""
    for _ in range(2):
        label = _assign(x, normal, offset, active, tol)
        normal, offset, _, active = _fit(x, _members(label))
    # points left over (e.g. a corner's third face, when a stray point of another face kept
    # the greedy step from seeing that the rest is one plane): a group of their own if coplanar
    left = label == 3
    ln, lo, _, lok = _fit(x, left[..., None])
    flat = np.where(left, np.abs(np.matmul(x, ln[:, 0, :, None])[..., 0] - lo[:, :1]), 0.0).max(axis=1) < tol
    free = np.argmin(active, axis=1)
    new_group = lok[:, 0] & flat & ~active.all(axis=1)
    if new_group.any():
        label = np.where(left & new_group[:, None], free[:, None], label)
        normal, offset, _, active = _fit(x, _members(label))
        label = _assign(x, normal, offset, active, tol)
        normal, offset, _, active = _fit(x, _members(label))
    # trim: points of another face within the tolerance of a plane (near the edge) tilt it
    # slightly; refit each plane to the points within 4x the median residual of its trimmed
    # points (exact samples: only its own face's points; noisy ones: ~3 sigma), floored at
    # 1e-4 of the radius; three rounds, as a tilted plane's residuals start large
    trimmed = label
    floor = _TRIM * tol[:, None] / _INLIER
    for _ in range(3):
        residual = np.abs((x * np.take_along_axis(normal, np.minimum(label, 2)[..., None], 1)).sum(axis=2)
                          - np.take_along_axis(offset, np.minimum(label, 2), 1))
        medians = []
        for g in range(3):
            mine = trimmed == g
            ranked = np.sort(np.where(mine, residual, np.inf), axis=1)
            middle = np.maximum(mine.sum(axis=1) - 1, 0) // 2
            medians.append(np.where(mine.any(axis=1), np.take_along_axis(ranked, middle[:, None], 1)[:, 0], 0.0))
        limit = np.maximum(4.0 * np.stack(medians, axis=1), floor)                 # (B, 3)
        trimmed = np.where((label < 3) & (residual <= np.take_along_axis(limit, np.minimum(label, 2), 1)), label, 3)
        normal, offset, _, active = _fit(x, _members(trimmed))
    return label, trimmed


def group_planes(x: np.ndarray, nn: np.ndarray, cos_sharp: float, oriented: bool):
    """Steps 2-4 of :func:`~.points.detect_sharp_features` for a block of B candidate points.

    ``x``: (B, K1, 3) float64 offsets from the point (slot 0 = the point),
    model units; ``nn``: (B, K1, 3) float64 unit normals (sign-aligned unless
    ``oriented``); ``cos_sharp``: cosine of the sharp angle.
    Returns (own normal (B, 3), planes (B, 2, 4) half-spaces ``n . x <= d``
    relative to the point (model units), feature (B,) bool, refined (B,) bool:
    where the own normal is the own plane's).
    """
    tol = _INLIER * np.sqrt((x * x).sum(axis=2).max(axis=1))          # (B,)
    label = _greedy_groups(x, nn, tol)
    label, trimmed, normal, active = _least_squares_groups(x, label, tol)
    label, trimmed = _merge_faces(nn, label, trimmed, normal, active, cos_sharp, oriented)
    normal, offset, centroid, active = _fit(x, _members(trimmed))
    flip = _agree(label, nn, normal)
    normal *= flip[..., None]
    offset *= flip
    signed = np.matmul(x, normal.transpose(0, 2, 1)) - offset[:, None, :]      # (B, K1, plane)
    active &= ~_straddled(label, signed, active, tol)
    return _own_face(x, nn, trimmed, normal, offset, centroid, active, signed, tol)


def _greedy_groups(x: np.ndarray, nn: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """Step 2: (B, K1) labels 0..2 of up to three planar groups, 3 = on none (greedy, RANSAC-like).

    Hypotheses: the plane through each neighbour h with its normal; the one
    with the most remaining points within ``tol`` (B,) takes them, after one
    least-squares refinement; the rest becomes a group at once when it all
    fits one plane.
    """
    b_count, k1 = x.shape[:2]
    # inliers[b, h, k]: point k lies on the plane through neighbour h with its normal
    along = np.matmul(nn, x.transpose(0, 2, 1))
    along -= (nn * x).sum(axis=2)[..., None]
    inliers = np.abs(along) < tol[:, None, None]
    del along
    label = np.full((b_count, k1), 3)
    remaining = np.ones((b_count, k1), dtype=bool)
    for g in range(3):
        # the rest at once when it all fits one plane
        normal, offset, _, active = _fit(x, remaining[..., None])
        off_plane = np.abs(np.matmul(x, normal[:, 0, :, None])[..., 0] - offset[:, :1])
        coplanar = active[:, 0] & (np.where(remaining, off_plane, 0.0).max(axis=1) < tol)
        score = np.matmul(inliers, remaining[..., None].astype(np.float32))[..., 0] if g < 2 else None
        if score is not None:
            best = np.argmax(score, axis=1)
            take = np.take_along_axis(inliers, best[:, None, None], axis=1)[:, 0] & remaining
            # one least-squares refinement of the hypothesis: its plane through its inliers
            hn, ho, _, hok = _fit(x, take[..., None])
            near = np.abs(np.matmul(x, hn[:, 0, :, None])[..., 0] - ho[:, :1]) < tol[:, None]
            take = np.where(hok[:, :1], near & remaining, take)
        else:
            take = np.zeros_like(remaining)
        take = np.where(coplanar[:, None], remaining, take)
        take &= (take.sum(axis=1) >= _MIN_GROUP)[:, None]
        label[take] = g
        remaining &= ~take
    return label


def _least_squares_groups(x: np.ndarray, label: np.ndarray, tol: np.ndarray):
    """Step 3: least squares, reassignment to the nearest plane within the tolerance.

    A second pass starts from the trimmed (exact) planes of the first where
    points were left on no plane. Returns (label, trimmed, normal (B, 3, 3),
    active (B, 3)) of the trimmed groups' planes.
    """
    normal, offset, centroid, active = _fit(x, _members(label))
    label, trimmed = _refine_groups(x, label, normal, offset, active, tol)
    normal, offset, centroid, active = _fit(x, _members(trimmed))
    again = np.flatnonzero((label == 3).any(axis=1))
    if len(again):
        label[again], trimmed[again] = _refine_groups(x[again], label[again], normal[again], offset[again],
                                                      active[again], tol[again])
        fitted = _fit(x[again], _members(trimmed[again]))
        for whole, part in zip((normal, offset, centroid, active), fitted):
            whole[again] = part
    return label, trimmed, normal, active


def _merge_faces(nn: np.ndarray, label: np.ndarray, trimmed: np.ndarray, normal: np.ndarray, active: np.ndarray,
                 cos_sharp: float, oriented: bool):
    """Planes within the sharp angle are one face: (label, trimmed) with such groups merged.

    Each plane is oriented like its points' normals first. Done on every row,
    so that rows do not depend on their block.
    """
    flip = _agree(label, nn, normal)
    oriented_normal = normal * flip[..., None]
    root = np.broadcast_to(np.arange(4), (len(label), 4)).copy()
    for ga, gb in ((0, 1), (0, 2), (1, 2)):
        cos = np.einsum("bj,bj->b", oriented_normal[:, ga], oriented_normal[:, gb])
        close = active[:, ga] & active[:, gb] & ((cos if oriented else np.abs(cos)) > cos_sharp)
        hi = np.maximum(root[:, ga], root[:, gb])
        lo = np.minimum(root[:, ga], root[:, gb])
        root = np.where(close[:, None] & (root == hi[:, None]), lo[:, None], root)
    return np.take_along_axis(root, label, axis=1), np.take_along_axis(root, trimmed, axis=1)


def _straddled(label: np.ndarray, signed: np.ndarray, active: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """(B, 3) bool: planes that another group's points straddle are no face of this neighbourhood.

    E.g. one through a handful of points along another edge, near a corner: a
    face's points lie on one side of every other face's plane. ``signed``:
    (B, K1, 3) signed distances of the points from the planes.
    """
    members = _members(label)
    beyond = np.abs(signed) > _STRADDLE_TOL * tol[:, None, None]
    mt = members.transpose(0, 2, 1).astype(np.float32)                         # (B, group, K1)
    above = np.matmul(mt, (beyond & (signed > 0)).astype(np.float32)).transpose(0, 2, 1)   # (B, plane, group)
    below = np.matmul(mt, (beyond & (signed < 0)).astype(np.float32)).transpose(0, 2, 1)
    size = members.sum(axis=1).astype(np.float64)[:, None, :]                   # (B, 1, group)
    least = np.maximum(2.0, _STRADDLE * size)
    return ((above >= least) & (below >= least) & active[:, None, :]).any(axis=2)   # (B, plane)


def _own_face(x, nn, trimmed, normal, offset, centroid, active, signed, tol):
    """Step 4: the point's own group (the plane nearest to it) and the half-spaces of the others.

    Returns (own normal (B, 3), planes (B, 2, 4), feature (B,), refined (B,)):
    see :func:`group_planes`.
    """
    b_count = len(x)
    own = np.argmin(np.where(active, np.abs(offset), np.inf), axis=1)
    b = np.arange(b_count)
    # (the point must lie on it: near a corner its own face may be a sliver that fitted no plane)
    own_ok = active[b, own] & (np.abs(offset[b, own]) < tol)
    others = active & (np.arange(3) != own[:, None]) & own_ok[:, None]
    own_centroid = centroid[b, own]
    # the half-space of each other plane that holds the own group: sign * (d - n . x) >= 0
    sign = np.where(offset - (normal * own_centroid[:, None, :]).sum(axis=2) >= 0, 1.0, -1.0)
    halfspace = np.concatenate([normal * sign[..., None], (offset * sign)[..., None]], axis=2)   # (B, 3, 4)
    order = np.argsort(~others, axis=1, kind="stable")[:, :2]           # the (up to two) others first
    # Faces meeting at a feature are planar right up to it: (almost) every point lies on one of
    # the planes. A surface curved at the neighbourhood's scale (a hole of a few splat radii)
    # fits three planes only in strips, with many points on none: no feature there.
    gap = np.where(active[:, None, :], np.abs(signed), np.inf).min(axis=2)          # (B, K1)
    covered = (gap < _COVER_TOL * tol[:, None]).mean(axis=1) >= _COVERED
    used = np.take_along_axis(others, order, axis=1) & covered[:, None]
    planes = np.where(used[..., None], np.take_along_axis(halfspace, order[..., None], axis=1),
                      np.array([0.0, 0.0, 0.0, 1.0]))
    feature = used[:, 0]
    # the own plane also replaces the normal where no other plane could be fitted (the other
    # faces are slivers of a few points near a corner) but the own face is exactly planar:
    # residuals of its points far below the tolerance (a curved surface fills it)
    mine = trimmed == own[:, None]
    off = (x * normal[b, own][:, None, :]).sum(axis=2) - offset[b, own][:, None]
    rms = np.sqrt(np.where(mine, off * off, 0.0).sum(axis=1) / np.maximum(mine.sum(axis=1), 1))
    planar = own_ok & (mine.sum(axis=1) >= 2 * _MIN_GROUP) & (rms < _PLANAR * tol)
    refined = feature | planar
    own_n = np.where(refined[:, None], normal[b, own], nn[:, 0])
    return own_n, planes, feature, refined
