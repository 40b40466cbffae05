"""Splat axes from the neighbour graph: circles (Guennebaud 2003) and ellipses (Pajarola 2003).

A splat is the ellipse ``p + s u + t v`` with ``s^2 + t^2 <= 1`` (see
:mod:`surfsplat.cloud`). ``u`` and ``v`` are orthogonal to the normal and to
each other, and ``(u, v, n)`` is right-handed (``u x v`` points along ``n``).

Design choices (documented defaults):

* Coverage factors. The bare constructions reach exactly to the farthest
  neighbour: the circle of radius h_k (Guennebaud 2003, eq. 7) and the
  smallest ellipse of the covariance shape containing all k neighbours
  (Pajarola 2003, sec. 3.4). That covers regular and jittered samplings
  (a factor of 0.5 resp. ~0.85 would do), but not uniformly random (Poisson)
  samples such as points sampled from a mesh: there, rare large empty
  regions between samples stay uncovered. Measured on 1 M Poisson points on a
  plane (k = 8, a grid of 4 M query points), the factor needed for no hole
  was 1.16 / 1.19 (two seeds) for circles and 1.40 / 1.43 for ellipses; at
  factor 1.0, 2e-5 (circles) and 3e-4 (ellipses) of the area were holes.
  Ellipses need more because their shape follows random fluctuations of the
  neighbourhood. Defaults: ``CIRCLE_COVERAGE = 1.25`` and
  ``ELLIPSE_COVERAGE = 1.5``; pass ``coverage=1.0`` for the bare papers'
  constructions (enough for scans and other near-regular samplings).
* ``max_anisotropy`` (default 4.0) caps the ellipse axis ratio
  ``sqrt(lambda1 / lambda2)``: nearly collinear neighbourhoods would otherwise
  give needle-thin splats that leave gaps between scan lines.
* Degenerate neighbourhoods (all neighbours projecting onto the point:
  coincident or stacked along the normal) give circles of radius equal to the
  largest 3D neighbour distance; where even that is 0 (k coincident
  duplicates) the radius is :func:`fallback_radius`, the median over the
  cloud of the positive largest-neighbour distances (1.0 if there is none).
  Axes are therefore always finite and positive.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..frames import tangent_frame
from .common import (block_covariance, block_offsets, check_indices, check_oriented_points, check_vectors, columns,
                     for_blocks)
from .normals import smallest_eigenvectors

#: Default cap of the ellipse axis ratio (major / minor).
MAX_ANISOTROPY = 4.0

#: Default factor on circle radii (see the module docstring: no holes on
#: uniformly random samples at 1 M points needed 1.19).
CIRCLE_COVERAGE = 1.25

#: Default factor on ellipse semi-axes (no holes on uniformly random samples
#: at 1 M points needed 1.43).
ELLIPSE_COVERAGE = 1.5

#: Relative growth of the Pajarola factor f so that the farthest neighbour,
#: which lies exactly on the ellipse, stays inside after float32 rounding.
_ROUNDING_MARGIN = 1e-5


def fallback_radius(distances) -> float:
    """Radius for splats whose neighbours all coincide with them, model units.

    The median over the cloud of the positive per-point maximum neighbour
    distance; 1.0 when every point coincides with all its neighbours.

    Args:
        distances: (N, k) float neighbour distances (e.g. from :func:`knn`).
    """
    dmax = _row_max(np.asarray(distances))
    positive = dmax[dmax > 0]
    return float(np.median(positive)) if len(positive) else 1.0


def _check_distances(distances, n: int) -> np.ndarray:
    """(n, k) finite non-negative neighbour distances as float32; InputError otherwise."""
    d = np.asarray(distances, dtype=np.float32)
    if d.ndim != 2 or d.shape[0] != n or d.shape[1] < 1:
        raise InputError(f"distances must have shape ({n}, k) with k >= 1, got {d.shape}")
    if not np.isfinite(d).all() or (d < 0).any():
        raise InputError("distances must be finite and non-negative")
    return d


def circular_splats(normals, distances, *, coverage: float = CIRCLE_COVERAGE) -> tuple[np.ndarray, np.ndarray]:
    """Circular splats of radius ``coverage * h_k``.

    ``h_k`` is the maximum distance from point k to its neighbours
    (Guennebaud & Paulin 2003, eq. 7: ``V_k^r = diag(h_k^2, h_k^2)``).
    Points whose neighbours all coincide with them get
    :func:`fallback_radius`.

    Args:
        normals: (N, 3) float array of nonzero normals.
        distances: (N, k) float neighbour distances, model units (e.g. from :func:`knn`).
        coverage: factor on the radius (> 0); default ``CIRCLE_COVERAGE``
            (1.25, see the module docstring), 1.0 for the bare eq. 7 radius.

    Returns:
        ``(u, v)``: (N, 3) float32 tangent axes, both of length the radius
        (model units), orthogonal to the normal, ``u x v`` along the normal.
    """
    if not coverage > 0:
        raise InputError(f"coverage must be > 0, got {coverage}")
    nrm = check_vectors(normals, "normals")
    dist = _check_distances(distances, len(nrm))
    radius = _row_max(dist)  # Guennebaud 2003, eq. 7: h_k
    radius = np.where(radius > 0, radius, np.float32(fallback_radius(dist))) * np.float32(coverage)
    t1, t2 = tangent_frame(nrm)
    return t1 * radius[:, None], t2 * radius[:, None]


def _block_ellipses(d, nrm, dist, coverage, max_anisotropy, fallback):
    """Ellipse axes for one block.

    d: three (k, B) float32 neighbour offsets ``p_j - p_i`` (x, y, z);
    nrm: (B, 3) normals; dist: (B, k) float32 neighbour distances;
    fallback: callable giving the global fallback radius (evaluated only if needed).
    Returns (u, v), two (B, 3) float32 arrays.
    """
    k = d[0].shape[0]
    t1, t2 = tangent_frame(nrm)
    # project the neighbourhood into the tangent plane of the point
    # (Pajarola 2003, sec. 3.4, with the splat center p_i as origin)
    x = d[0] * t1[:, 0]
    x += d[1] * t1[:, 1]
    x += d[2] * t1[:, 2]
    y = d[0] * t2[:, 0]
    y += d[1] * t2[:, 1]
    y += d[2] * t2[:, 2]
    # 2x2 covariance of the k neighbours and the point itself (at the origin);
    # one-pass form, fine since the offsets are relative to the point
    m = np.float32(k + 1)
    mx = x.sum(axis=0) / m
    my = y.sum(axis=0) / m
    cxx = (np.einsum("ij,ij->j", x, x) / m - mx * mx).astype(np.float64)
    cxy = (np.einsum("ij,ij->j", x, y) / m - mx * my).astype(np.float64)
    cyy = (np.einsum("ij,ij->j", y, y) / m - my * my).astype(np.float64)
    # closed-form eigen-decomposition of the 2x2 covariance (Pajarola 2003, EQ 5 and EQ 6)
    half = 0.5 * (cxx - cyy)
    disc = np.sqrt(half * half + cxy * cxy)
    mid = 0.5 * (cxx + cyy)
    lam1 = mid + disc
    lam2 = np.maximum(mid - disc, 0.0)
    theta = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)  # direction of the major axis in (t1, t2)
    c = np.cos(theta).astype(np.float32)
    s = np.sin(theta).astype(np.float32)
    # axis ratio a'/b' = sqrt(lambda1 / lambda2), capped at max_anisotropy
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lam2 > 0, np.sqrt(lam1 / lam2), max_anisotropy)
    ratio = np.clip(np.nan_to_num(ratio, nan=1.0), 1.0, max_anisotropy).astype(np.float32)
    # neighbours in the ellipse frame with b' = 1, a' = ratio. Pajarola 2003,
    # sec. 3.4: f^2 = max over the neighbours of x^2/a'^2 + y^2/b'^2
    ex = x * c
    ex += y * s
    ex *= 1.0 / ratio
    ey = y * c
    ey -= x * s
    ex *= ex
    ey *= ey
    ex += ey
    f = np.sqrt(ex.max(axis=0)) * np.float32(1.0 + _ROUNDING_MARGIN)
    minor = f * np.float32(coverage)
    major = minor * ratio
    cc, ss = c[:, None], s[:, None]
    u = (t1 * cc + t2 * ss) * major[:, None]
    v = (t2 * cc - t1 * ss) * minor[:, None]
    degenerate = ~(f > 0) | ~np.isfinite(f)
    if degenerate.any():
        # all neighbours project onto the point: circle through the farthest one
        radius = dist[degenerate].max(axis=1)
        radius = np.where(radius > 0, radius, np.float32(fallback())) * np.float32(coverage)
        u[degenerate] = t1[degenerate] * radius[:, None]
        v[degenerate] = t2[degenerate] * radius[:, None]
    return u, v


def _row_max(dist: np.ndarray) -> np.ndarray:
    """(N,) largest of the k distances per row (fast for small k)."""
    out = dist[:, 0].copy()
    for j in range(1, dist.shape[1]):
        np.maximum(out, dist[:, j], out=out)
    return out


def check_ellipse_options(coverage: float, max_anisotropy: float) -> None:
    """InputError unless ``coverage`` (factor on the semi-axes) > 0 and ``max_anisotropy`` (axis ratio) >= 1."""
    if not coverage > 0:
        raise InputError(f"coverage must be > 0, got {coverage}")
    if not max_anisotropy >= 1:
        raise InputError(f"max_anisotropy must be >= 1, got {max_anisotropy}")


def elliptical_splats(positions, normals, indices, distances, *, coverage: float = ELLIPSE_COVERAGE,
                      max_anisotropy: float = MAX_ANISOTROPY) -> tuple[np.ndarray, np.ndarray]:
    """Elliptical splats that enclose each point's k-neighbourhood in its tangent plane.

    Pajarola, Sainz & Guidotti 2003, end of section 3.4 (applied to the
    input points instead of octree nodes): the neighbourhood is projected into
    the tangent plane of the splat; the eigenvectors of its 2x2 covariance
    (EQ 5, EQ 6, closed form) give the axis directions and
    ``sqrt(lambda1 / lambda2)`` the axis ratio (capped at ``max_anisotropy``);
    the axes are then scaled by ``f = max_j sqrt(x_j^2/a'^2 + y_j^2/b'^2)``
    so that every neighbour lies inside (on the boundary for the farthest),
    then by ``coverage``.
    The ellipse is centered at the point itself (the splat center), not at
    the neighbourhood mean. Degenerate neighbourhoods fall back to circles
    (see the module docstring).

    Args:
        positions: (N, 3) float array, model units.
        normals: (N, 3) float array of nonzero normals (the tangent planes).
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).
        distances: (N, k) float neighbour distances, model units (for the
            degenerate fallback).
        coverage: factor on both semi-axes (> 0); default ``ELLIPSE_COVERAGE``
            (1.5, see the module docstring), 1.0 for the bare bounding ellipse.
        max_anisotropy: cap of the major/minor ratio (>= 1).

    Returns:
        ``(u, v)``: (N, 3) float32 scaled axes, model units: ``u`` the major
        semi-axis, ``v`` the minor one; ``u . n = v . n = u . v = 0`` and
        ``u x v`` along ``n``.
    """
    check_ellipse_options(coverage, max_anisotropy)
    pts, nrm, idx = check_oriented_points(positions, normals, indices)
    n = len(pts)
    dist = _check_distances(distances, n)
    if dist.shape != idx.shape:
        raise InputError(f"distances {dist.shape} and indices {idx.shape} must have the same shape")
    cols = columns(pts)
    u = np.empty((n, 3), dtype=np.float32)
    v = np.empty((n, 3), dtype=np.float32)

    def block(sl):
        u[sl], v[sl] = _block_ellipses(block_offsets(cols, idx, sl), nrm[sl], dist[sl],
                                       coverage, max_anisotropy, lambda: fallback_radius(dist))

    for_blocks(block, n)
    return u, v


def normals_and_ellipses(positions, indices, distances, *, coverage: float = ELLIPSE_COVERAGE,
                         max_anisotropy: float = MAX_ANISOTROPY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """PCA normals and elliptical splats in one pass over the neighbourhoods.

    Same results as :func:`~surfsplat.geometry.normals.estimate_normals`
    followed by :func:`elliptical_splats`, but the neighbour offsets are
    gathered once (see :func:`pca_splats`). The normals are not oriented:
    after flipping some normals, negate ``v`` of the same splats to keep
    ``u x v`` along the normal.

    Args:
        positions: (N, 3) float array, model units.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).
        distances: (N, k) float neighbour distances, model units.
        coverage, max_anisotropy: as in :func:`elliptical_splats`.

    Returns:
        ``(normals, u, v)``: three (N, 3) float32 arrays.
    """
    nrm, _, u, v = pca_splats(positions, indices, distances, coverage=coverage, max_anisotropy=max_anisotropy)
    return nrm, u, v


def pca_splats(positions, indices, distances, *, shape: str = "ellipse", coverage: float | None = None,
               max_anisotropy: float = MAX_ANISOTROPY) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """PCA normals, covariance eigenvalues and splats in one pass over the neighbourhoods.

    The normal is the eigenvector of the smallest eigenvalue of the neighbourhood covariance
    (Hoppe et al. 1992, sec. 3.2); the splats are Pajarola's covering ellipses
    (:func:`elliptical_splats`) or Guennebaud's circles (:func:`circular_splats`). The
    offsets are gathered once (used by :func:`surfsplat.geometry.preprocess`).

    Args:
        positions: (N, 3) float array, model units.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).
        distances: (N, k) float neighbour distances, model units.
        shape: ``"ellipse"`` or ``"circle"``.
        coverage: factor on the axes; default ``ELLIPSE_COVERAGE`` or ``CIRCLE_COVERAGE``.
        max_anisotropy: as in :func:`elliptical_splats`.

    Returns:
        ``(normals, eigenvalues, u, v)``: (N, 3) float32 unit normals (not oriented), (N, 3)
        float64 covariance eigenvalues in descending order (model units squared), and (N, 3)
        float32 axes (model units).
    """
    if coverage is None:
        coverage = ELLIPSE_COVERAGE if shape == "ellipse" else CIRCLE_COVERAGE
    check_ellipse_options(coverage, max_anisotropy)
    if shape not in ("ellipse", "circle"):
        raise InputError(f"shape must be 'ellipse' or 'circle', got {shape!r}")
    pts = check_vectors(positions, "positions")
    n = len(pts)
    idx = check_indices(indices, n)
    dist = _check_distances(distances, n)
    cols = columns(pts)
    nrm = np.empty((n, 3), dtype=np.float32)
    lam = np.empty((n, 3), dtype=np.float64)
    u = np.empty((n, 3), dtype=np.float32)
    v = np.empty((n, 3), dtype=np.float32)

    def block(sl):
        d = block_offsets(cols, idx, sl)
        nrm[sl], lam[sl] = smallest_eigenvectors(*block_covariance(d), with_eigenvalues=True)
        if shape == "ellipse":
            u[sl], v[sl] = _block_ellipses(d, nrm[sl], dist[sl], coverage, max_anisotropy,
                                           lambda: fallback_radius(dist))
        else:
            radius = _row_max(dist[sl])  # Guennebaud 2003, eq. 7: h_k
            radius = np.where(radius > 0, radius, np.float32(fallback_radius(dist))) * np.float32(coverage)
            t1, t2 = tangent_frame(nrm[sl])
            u[sl], v[sl] = t1 * radius[:, None], t2 * radius[:, None]

    for_blocks(block, n)
    return nrm, lam, u, v
