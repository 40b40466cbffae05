"""Uniform random sampling of a triangle mesh's surface into splat centers."""

from __future__ import annotations

import numbers

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError
from ..io.mesh import Mesh


def sample_mesh(mesh: Mesh, n: int, *, seed: int = 0) -> SplatCloud:
    """Sample ``n`` points uniformly by area on the surface of ``mesh``.

    Each sample picks a face with probability proportional to its area, then a
    uniform point in it: barycentrics ``(1 - sqrt(r1), sqrt(r1) (1 - r2),
    sqrt(r1) r2)`` for uniform ``r1, r2`` (Osada et al. 2002).

    Args:
        mesh: the surface; faces (F, 3), vertices (V, 3) model space.
        n: number of samples, >= 1.
        seed: seed of ``numpy.random.default_rng``; equal seeds give equal
            samples.

    Returns:
        SplatCloud with positions (n, 3) float32 model space; normals (n, 3)
        float32 unit: the face's geometric normal (right-hand rule on its
        vertex order), flipped where it disagrees (negative dot product) with
        the barycentric interpolation of the mesh's vertex normals, when the
        mesh has them; colors (n, 3) float32 interpolated from the vertex
        colors, when the mesh has them. No splat axes (u, v are None).

    Raises:
        InputError: ``n`` < 1 or not an integer, an invalid mesh, or a mesh
            whose total area is zero.
    """
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise InputError(f"sample_mesh: n must be an integer, got {n!r}")
    if n < 1:
        raise InputError(f"sample_mesh: n must be at least 1, got {n}")
    mesh = mesh.validated("sample_mesh: mesh")
    areas = mesh.face_areas()
    total = float(areas.sum())
    if not np.isfinite(total) or total <= 0:
        raise InputError(f"sample_mesh: mesh has zero total area ({len(mesh.faces)} degenerate faces)")

    rng = np.random.default_rng(seed)
    cdf = np.cumsum(areas)
    # side="right" never selects a zero-area face (its cdf step is empty)
    face = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    face = np.minimum(face, int(np.flatnonzero(areas > 0)[-1]))  # r * total may round up to total
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    bary = np.column_stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2])  # (n, 3)

    corners = mesh.faces[face]  # (n, 3) vertex indices
    vertices = mesh.vertices.astype(np.float64)
    positions = np.einsum("nk,nkd->nd", bary, vertices[corners])

    normals = mesh.face_normals()[face].astype(np.float64)
    if mesh.vertex_normals is not None:
        smooth = np.einsum("nk,nkd->nd", bary, mesh.vertex_normals.astype(np.float64)[corners])
        flip = np.einsum("nd,nd->n", normals, smooth) < 0
        normals[flip] *= -1.0

    colors = None
    if mesh.vertex_colors is not None:
        colors = np.einsum("nk,nkd->nd", bary, mesh.vertex_colors.astype(np.float64)[corners])

    return SplatCloud(positions=positions.astype(np.float32), normals=normals.astype(np.float32),
                      colors=None if colors is None else colors.astype(np.float32))
