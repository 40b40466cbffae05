"""Uniform random sampling of a triangle mesh's surface into splat centers (and, on request,
splats with clip lines at the mesh's sharp edges)."""

from __future__ import annotations

import numbers
from dataclasses import replace

import numpy as np

from .. import progress
from ..cloud import SplatCloud
from ..errors import InputError
from ..io.mesh import Mesh, area_weighted_normals
from .preprocess import preprocess
from .sharp import check_sharp_angle, mesh_clip_lines


def sample_mesh(mesh: Mesh, n: int, *, seed: int = 0, sharp_angle: float | None = None, k: int = 8,
                shape: str = "circle", coverage: float | None = None, smooth_normals: bool = False) -> SplatCloud:
    """Sample ``n`` points uniformly by area on the surface of ``mesh``.

    Each sample picks a face with probability proportional to its area, then a
    uniform point in it: barycentrics ``(1 - sqrt(r1), sqrt(r1) (1 - r2),
    sqrt(r1) r2)`` for uniform ``r1, r2`` (Osada et al. 2002).

    Args:
        mesh: the surface; faces (F, 3), vertices (V, 3) model space.
        n: number of samples, >= 1.
        seed: seed of ``numpy.random.default_rng``; equal seeds give equal
            samples.
        sharp_angle: None (default: points and normals only), or a dihedral
            angle in degrees, in (0, 180): then every sample also gets its
            splat, and splats that reach over an edge sharper than this get
            clip lines from the faces there (see below).
        smooth_normals: give each sample the normalized barycentric interpolation
            of the vertex normals (the normals a Phong-shaded rendering of the
            mesh uses; area-weighted face normals where the mesh stores none)
            instead of its face's normal.
        k, shape, coverage: splat sizes when ``sharp_angle`` is given, as in
            :func:`surfsplat.geometry.preprocess.preprocess` with the face
            normals kept: ``k`` neighbours; ``shape`` ``"circle"`` (default:
            radius ``coverage * h_k``, Guennebaud 2003 eq. 7, the distance
            to the k-th neighbour) or ``"ellipse"``; ``coverage`` default
            1.25 for circles, 1.5 for ellipses, the factors measured to leave
            no holes between uniformly random samples (see
            :mod:`surfsplat.geometry.splats`). The axes lie in the face's
            plane. Sizes adapt to the random gaps, which a global radius
            ``sqrt(area / n)`` times a constant cannot do without splats ~2x
            larger everywhere.

    Returns:
        SplatCloud with positions (n, 3) float32 model space; normals (n, 3)
        float32 unit: the face's geometric normal (right-hand rule on its
        vertex order), flipped where it disagrees (negative dot product) with
        the barycentric interpolation of the mesh's vertex normals, when the
        mesh has them (or that interpolation itself with ``smooth_normals``);
        colors (n, 3) float32 interpolated from the vertex colors, when the
        mesh has them. No splat axes (u, v are None); with ``sharp_angle``,
        the splats (u, v in model units) and ``clip_lines`` (n, 2, 3).

    Raises:
        InputError: ``n`` < 1 or not an integer, an invalid mesh, or a mesh
            whose total area is zero.
    """
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise InputError(f"sample_mesh: n must be an integer, got {n!r}")
    if n < 1:
        raise InputError(f"sample_mesh: n must be at least 1, got {n}")
    if sharp_angle is not None:
        sharp_angle = check_sharp_angle(sharp_angle, "sample_mesh: sharp_angle")
    mesh = mesh.validated("sample_mesh: mesh")
    if smooth_normals and mesh.vertex_normals is None:
        mesh = replace(mesh, vertex_normals=area_weighted_normals(mesh.vertices, mesh.faces))
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
        if smooth_normals:
            length = np.linalg.norm(smooth, axis=1, keepdims=True)
            # opposite vertex normals can cancel: keep the face normal there
            normals = np.where(length > 1e-6, smooth / np.maximum(length, 1e-30), normals)

    colors = None
    if mesh.vertex_colors is not None:
        colors = np.einsum("nk,nkd->nd", bary, mesh.vertex_colors.astype(np.float64)[corners])

    cloud = SplatCloud(positions=positions.astype(np.float32), normals=normals.astype(np.float32),
                       colors=None if colors is None else colors.astype(np.float32))
    if sharp_angle is None:
        return cloud
    # splats with the face normals kept (axes in the face planes), sized by the k-neighbourhoods
    splats = preprocess(cloud, k=k, shape=shape, coverage=coverage, source="sample_mesh")
    if len(splats) != n:  # cannot happen: samples of a valid mesh are finite, their normals unit
        raise InputError(f"sample_mesh: preprocessing dropped {n - len(splats)} samples")
    with progress.stage("clip lines at sharp edges", n):
        lines = mesh_clip_lines(mesh, face, splats.positions, splats.u, splats.v, sharp_angle)
    return splats.replace(clip_lines=lines)
