"""Tangent frames of normals (Duff et al. 2017): the splat axes of circular splats, the frames of
LOD node splats. A base module: io, geometry and hierarchy all use it."""

from __future__ import annotations

import numpy as np

from .errors import InputError


def tangent_frame64(unit_normals) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangents ``(t1, t2)`` with ``t1 x t2 = n`` for (N, 3) unit normals, float64.

    The branch-free construction of Duff et al. 2017 ("Building an orthonormal basis,
    revisited", JCGT 6(1)): continuous except where n_z changes sign, exact at n = +-z.
    The normals are used as given (not renormalized, not checked).
    """
    n = np.asarray(unit_normals, dtype=np.float64)
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    s = np.where(nz >= 0, 1.0, -1.0)
    a = -1.0 / (s + nz)
    b = nx * ny * a
    t1 = np.stack([1.0 + s * nx * nx * a, s * b, -s * nx], axis=1)
    t2 = np.stack([b, s + ny * ny * a, -ny], axis=1)
    return t1, t2


def tangent_frame(normals) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangent vectors for each normal (:func:`tangent_frame64`, computed in float64).

    Args:
        normals: (N, 3) float array of nonzero normals (renormalized here).

    Returns:
        ``(t1, t2)``: two (N, 3) float32 unit vectors with t1, t2, n mutually
        orthogonal and ``t1 x t2 = n`` (right-handed).
    """
    nrm = np.asarray(normals, dtype=np.float64)
    if nrm.ndim != 2 or nrm.shape[1] != 3:
        raise InputError(f"normals must have shape (N, 3), got {nrm.shape}")
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    if not (length > 0).all() or not np.isfinite(length).all():
        raise InputError("tangent_frame: normals must be finite and nonzero")
    t1, t2 = tangent_frame64(nrm / length)
    return t1.astype(np.float32), t2.astype(np.float32)
