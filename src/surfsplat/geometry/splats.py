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
* Cell-covering growth (:func:`cover_cells`, the default of
  :func:`surfsplat.geometry.preprocess` for ellipses). A global factor sized
  for the worst gap among a million points is paid by all of them: at 1.5 a
  point of the surface lies under ~19 splats. Instead, the bare ellipses
  (factor ``GAP_BASE`` = 1.0) are grown, each just enough to contain its own
  Voronoi cell, which leaves no hole by construction (the cells tile the
  surface). Measured on 1 M uniformly random points on a plane
  (``benchmarks/results/gap_radii.md``): no hole, about half the area and
  overlap of the factor 1.5, a quarter of the splats grown. At the open
  border of a surface the cells reach out of it: a splat is grown only to the
  cell vertices that samples surround, so borders stay within the factor
  1.5's (about the bare ellipses').
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
from .common import (BLOCK, block_covariance, block_offsets, check_indices, check_oriented_points, check_vectors,
                     columns, for_blocks, neighbour_offsets, parallel, row_norms)
from .neighbors import kdtree, knn_rows
from .normals import smallest_eigenvectors

#: Default cap of the ellipse axis ratio (major / minor).
MAX_ANISOTROPY = 4.0

#: Default factor on circle radii (see the module docstring: no holes on
#: uniformly random samples at 1 M points needed 1.19).
CIRCLE_COVERAGE = 1.25

#: Default factor on the circle radii of a smooth mesh's samples (``View.sample``: ``surface_splats``
#: of a mesh without sharp edges). Below the 1.19 that leaves no hole between 1 M uniformly random
#: samples without help: the few pixel-sized gaps that 1.1 leaves are closed by the renderer's
#: screen-space hole filling (``RenderOptions.fill_holes``, on by default), and a surface point lies
#: under ~19 splats instead of ~25 (``benchmarks/results/kernel_defaults.md``, ``ewa`` against the
#: mesh at 128, 512 and 1024 px: no hole pixel, PSNR +0.1 to +0.5 dB on the bunny, +0.3 to +1.2 dB
#: on the detailed surface).
SAMPLE_COVERAGE = 1.1

#: Default factor on the circle radii of the samples of a mesh with sharp edges (clip lines): its
#: occlusion edges (a pocket's rim over its floor) lose 0.1 to 0.5 dB at 1.1 (the CAD part at 128, 512
#: and 1024 px, ``benchmarks/results/kernel_defaults.md``), so it keeps ``CIRCLE_COVERAGE``.
CREASED_SAMPLE_COVERAGE = CIRCLE_COVERAGE

#: Default factor on ellipse semi-axes (no holes on uniformly random samples
#: at 1 M points needed 1.43).
ELLIPSE_COVERAGE = 1.5

#: Global factor on the ellipses before :func:`cover_cells` (``preprocess(coverage=None)``).
GAP_BASE = 1.0

#: :func:`cover_cells` grows a splat so that its farthest cell vertex lies this much inside
#: (relative to the semi-axes).
GAP_MARGIN = 0.02

#: Neighbours of :func:`cover_cells`' wider looks at the cells the k neighbours leave open or
#: bound too loosely, one look after the other for the cells still unresolved.
GAP_K = (12, 16, 24)

#: Cell vertices farther from the point than this times the distance to the look's farthest
#: neighbour are not trusted (the circle through them may hold points beyond the neighbours):
#: their cells are looked at again, wider; after the widest look they are the border of an open
#: surface. On 200k uniformly random points the vertices outside the bare ellipses lie within
#: 1.85 times the 8th-neighbour distance (~1.5 times the 12th one's).
GAP_REACH = 1.5

#: Cell vertices within this times the distance to the k-th neighbour are trusted without
#: :func:`cover_cells`' border test: the bare ellipse of a point on an open border reaches ~0.85
#: times that distance out of it already, the factor 1.5 ellipse ~1.3 times. On 200k uniformly
#: random points 15% of the vertices that grow a splat lie farther (34% beyond 1.0 times).
GAP_TRUSTED = 1.2

#: Shapes :func:`cover_cells` tries: the major semi-axis relative to the minor one, as a
#: fraction of the given ellipse's ratio (1: the same shape; smaller: rounder, down to a circle).
GAP_ROUNDING = (1.0, 0.75, 0.5, 0.25)

#: Points per chunk of :func:`cover_cells`' wider looks ((K^2 / 2, chunk) float32 temporaries).
_GAP_CHUNK = 1024

#: Neighbours (the nearest) that :func:`_cell_vertices` tests every circumcircle against first; the
#: others only test the circles none of these lies in.
_VERTEX_FIRST = 4

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


def cover_cells(positions, indices, u, v, *, margin: float = GAP_MARGIN, wide: tuple[int, ...] = GAP_K,
                reach: float = GAP_REACH, exclude=None, tree=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grow each splat just enough to cover its Voronoi cell: no hole, and little overlap.

    The Voronoi cells of the samples tile the surface, so splats that contain their cells
    leave no hole (the argument of Pajarola 2003, sec. 3.4, with the cell in place of the
    neighbours; :mod:`surfsplat.geometry.cells` does the same for scan lines). A cell is
    convex and so is an ellipse: the ellipse contains the cell iff it contains the cell's
    vertices, the circumcenters of the point's Delaunay triangles. Per point ``i`` and pair
    ``(j, k)`` of its neighbours, projected into ``i``'s tangent plane (the plane of ``u``,
    ``v``), the circumcenter ``c`` of ``(i, j, k)`` is a vertex of ``i``'s cell among its
    neighbours when no other neighbour lies strictly inside the circumcircle. Where a vertex
    lies outside the ellipse, the ellipse is grown (never shrunk: it keeps containing the
    given one) so that its farthest vertex lies ``margin`` inside, keeping the axis directions:
    of the shapes whose axis ratio is the given one times ``GAP_ROUNDING`` (at least 1), the
    one of least area (a cell across a thin ellipse asks for a rounder splat, not a larger
    needle).

    The k nearest neighbours bound a cell too loosely next to large empty circles (the cell
    among the neighbours contains the true cell, so this errs on the safe side, but its far
    vertices cost area) and not at all where they all lie on one side. Cells with a vertex
    outside the ellipse and farther than ``reach`` times the farthest neighbour's distance
    (where the circle may hold unseen points), and cells the neighbours leave open, are
    therefore traced again among ``wide[0]`` neighbours, and those still unresolved among
    ``wide[1]``, ...; what is left after the widest look is the border of an open surface.
    There, and at every look, the cell of a border point reaches out of the surface, unbounded
    or up to circumcenters of border triples: splats grown to them bulge out of the border. A
    vertex farther than ``GAP_TRUSTED`` times the k-th neighbour distance is therefore trusted
    only where samples surround it: where its triangle is acute (the circumcenter lies inside)
    or its own 8 nearest samples leave no angular gap of pi or more around it (it lies in their
    convex hull: the angle criterion of boundary detection, Gumhold, Wang & MacLeod 2001,
    applied from the vertex); an interior gap's empty circle is surrounded by samples, a vertex
    beyond an open border has them on one side only. Untrusted vertices outside the ellipse send
    the cell to the wider look, and after the widest one they are dropped. Most cells are shown
    to lie inside their ellipse by a cheaper test first (:func:`_inside`). Collinear and
    coincident triples have no circumcenter and are skipped.

    Args:
        positions: (N, 3) float array, model units.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).
        u, v: (N, 3) float orthogonal splat semi-axes (model units), nonzero, ``|u| >= |v|``.
        margin: relative depth of the farthest vertex inside the grown ellipse (>= 0).
        wide: neighbours of the wider looks (an integer or integers >= 2, those <= k ignored;
            clamped to N - 1).
        reach: the trust radius (> 0), in units of the look's farthest neighbour distance (the widest
            look's for the border cells left after it).
        exclude: optional (N,) bool: splats left as they are (outliers about to be dropped
            or resized); they still bound the others' cells.
        tree: the k-d tree of ``positions`` (from :func:`~surfsplat.geometry.neighbors.kdtree`),
            if built already.

    Returns:
        ``(u, v, factors)``: the (N, 3) float32 axes and the (N, 2) float32 factors they were
        scaled by (on ``u`` and on ``v``; both >= 1, both 1 where the ellipse contained its
        cell already).
    """
    if not margin >= 0:
        raise InputError(f"margin must be >= 0, got {margin}")
    if not reach > 0:
        raise InputError(f"reach must be > 0, got {reach!r}")
    wide = (wide,) if isinstance(wide, (int, np.integer)) else tuple(wide)
    if not all(isinstance(w, (int, np.integer)) and not isinstance(w, bool) and w >= 2 for w in wide):
        raise InputError(f"wide must be integers >= 2, got {wide!r}")
    pts = check_vectors(positions, "positions")
    n = len(pts)
    idx = check_indices(indices, n)
    u = check_vectors(u, "u", n)
    v = check_vectors(v, "v", n)
    a, b = row_norms(u), row_norms(v)
    if not (np.isfinite(a).all() and np.isfinite(b).all() and (a > 0).all() and (b > 0).all()):
        raise InputError("cover_cells: the splat axes u and v must be finite and nonzero")
    skip = np.zeros(n, dtype=bool) if exclude is None else np.asarray(exclude, dtype=bool)
    if skip.shape != (n,):
        raise InputError(f"exclude must have shape ({n},), got {skip.shape}")
    factors = np.ones((n, 2), dtype=np.float32)
    k = idx.shape[1]
    if k < 2:
        return u.copy(), v.copy(), factors
    cols = columns(pts)
    # the shapes tried: major semi-axis a * rho (never below the minor one), minor b
    rho = np.maximum(np.asarray(GAP_ROUNDING, dtype=np.float32)[:, None], (b / a)[None, :])
    frame = (u / a[:, None], v / b[:, None], a, b, rho)
    need = np.zeros((len(GAP_ROUNDING), n), dtype=np.float32)  # squared metric of the farthest vertex
    reach2 = np.float32(reach * reach)
    trusted2 = np.float32(GAP_TRUSTED * GAP_TRUSTED)
    limit = np.float32((1.0 + margin) ** -2)  # a cell within this metric needs no growth
    unresolved = np.zeros(n, dtype=bool)
    is_open = np.zeros(n, dtype=bool)   # open among the neighbours of the latest look

    def trace(d, rows, bound_dist, own_dist):
        """The need of the cells of ``rows`` (offsets ``d``, k-th neighbour distance ``own_dist``);
        marks the ones left unresolved."""
        inside, open_ = _inside(d, rows, frame, limit)
        need[:, rows] = 0.0
        sel = np.flatnonzero(~inside & ~open_)
        bounds = reach2 * bound_dist[sel] ** 2, trusted2 * own_dist[sel] ** 2
        need[:, rows[sel]], far = _cell_vertices([o[:, sel] for o in d], rows[sel], frame, *bounds, pts, tree)
        unresolved[rows] = open_
        unresolved[rows[sel]] = far
        is_open[rows] = open_

    def first(at):
        d = neighbour_offsets(cols, at, idx[at])
        dist = np.sqrt((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).max(axis=0))
        trace(d, at, dist, dist)

    tree = kdtree(pts) if tree is None else tree
    # the excluded splats keep their axes: their cells are not traced (they still bound the others')
    live = np.flatnonzero(~skip)
    parallel(first, [live[s:s + BLOCK] for s in range(0, len(live), BLOCK)])
    rows = np.flatnonzero(unresolved & ~skip)
    kw = k
    wide_dist = np.zeros((0, k), dtype=np.float32)
    wide_idx = np.zeros((0, k), dtype=np.int64)
    for kw in sorted(min(int(w), n - 1) for w in wide if w > k):
        if not len(rows):
            break
        # cells the neighbours leave open or bound too loosely: a wider look
        wide_dist, wide_idx = knn_rows(tree, rows, kw)

        def again(start):
            part = slice(start, start + _GAP_CHUNK)
            sel, nb = rows[part], wide_idx[part]
            trace(neighbour_offsets(cols, sel, nb), sel, wide_dist[part, -1], wide_dist[part, k - 1])

        parallel(again, range(0, len(rows), _GAP_CHUNK))
        keep = unresolved[rows]
        rows, wide_dist, wide_idx = rows[keep], wide_dist[keep], wide_idx[keep]
    if len(rows) and kw > k:
        # still open or loose with the widest look: the border of an open surface, whose cells reach
        # out of it; grown only to the trusted vertices. The loose ones were so grown by that look
        # already (the same neighbours, the same bounds); the open ones are traced here, in chunks.
        sel = np.flatnonzero(is_open[rows])
        rows, wide_dist, wide_idx = rows[sel], wide_dist[sel], wide_idx[sel]

        def border(start):
            part = slice(start, start + _GAP_CHUNK)
            at, dist = rows[part], wide_dist[part]
            need[:, at] = _cell_vertices(neighbour_offsets(cols, at, wide_idx[part]), at, frame,
                                         reach2 * dist[:, -1] ** 2, trusted2 * dist[:, k - 1] ** 2, pts, tree)[0]

        parallel(border, range(0, len(rows), _GAP_CHUNK))
    # per shape: the scale that reaches the farthest vertex and keeps the given ellipse inside
    scale = np.maximum(np.sqrt(need) * np.float32(1.0 + margin), np.maximum(1.0 / rho, np.float32(1.0)))
    best = np.argmin(scale * scale * rho, axis=0)  # area relative to the given ellipse's
    pick = np.arange(n)
    factors[:, 1] = scale[best, pick]
    factors[:, 0] = np.maximum(factors[:, 1] * rho[best, pick], np.float32(1.0))  # >= 1 after rounding too
    factors[skip] = 1.0
    return u * factors[:, :1], v * factors[:, 1:], factors


def _in_plane(d, rows, ua, va) -> tuple[np.ndarray, np.ndarray]:
    """The (K, M) coordinates of neighbour offsets ``d`` in the tangent frames (unit axes ``ua``,
    ``va``) of their points ``rows``."""
    x = d[0] * ua[rows, 0] + d[1] * ua[rows, 1] + d[2] * ua[rows, 2]
    y = d[0] * va[rows, 0] + d[1] * va[rows, 1] + d[2] * va[rows, 2]
    return x, y


def _cell_vertices(d, rows, frame, bound, plain, pts, tree):
    """The farthest vertex of some points' Voronoi cells among their neighbours (see :func:`cover_cells`).

    d: three (K, M) float32 neighbour offsets (model units); rows: (M,) the points; frame: the
    cloud's unit axes, semi-axis lengths and the (S, N) shapes tried; bound: (M,) the largest
    squared distance of a trusted vertex; plain: (M,) the squared distance within which a vertex
    is trusted without the border test; pts, tree: the (N, 3) positions and their k-d tree. A
    vertex between ``plain`` and ``bound`` is trusted only if its triangle is acute (it lies in
    the triangle) or its own nearest samples enclose it (:func:`_witnessed`). Returns
    ``(need, far)``: (S, M) float32 squared ellipse metric of the farthest trusted vertex in each
    shape (0 if none), and (M,) bool: an untrusted vertex lies outside the ellipse.
    """
    ua, va, a, b, rho = frame
    k = d[0].shape[0]
    x, y = _in_plane(d, rows, ua, va)   # in i's own ellipse frame (the splat's tangent plane)
    q = x * x + y * y
    jj, kk = np.triu_indices(k, 1)
    xj, xk, yj, yk, qj, qk = x[jj], x[kk], y[jj], y[kk], q[jj], q[kk]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # circumcenter of (0, P_j, P_k): the Voronoi vertex of the three samples
        det2 = 2.0 * (xj * yk - xk * yj)
        cx = (yk * qj - yj * qk) / det2
        cy = (xj * qk - xk * qj) / det2
        # only vertices near or outside the ellipse matter, in any of the rounder shapes too
        # (their scale keeps the given ellipse inside); NaN: no circumcenter
        # (candidates in point order: each point's vertices form one run, for the maxima below)
        col, pair = np.nonzero(((cx / a[rows]) ** 2 + (cy / b[rows]) ** 2 > np.float32(0.9)).T)
    cx, cy = cx[pair, col], cy[pair, col]
    # the triangle's angle at the point and at P_j, P_k: obtuse where the dot products are negative
    flat = pair * len(rows) + col
    pj = xj.ravel()[flat] * xk.ravel()[flat] + yj.ravel()[flat] * yk.ravel()[flat]
    obtuse = (pj < 0) | (qj.ravel()[flat] < pj) | (qk.ravel()[flat] < pj)
    with np.errstate(invalid="ignore", over="ignore"):
        r2 = cx * cx + cy * cy
        # a vertex of the cell: no neighbour strictly inside the circle, |P_l - c|^2 < |c|^2; most
        # candidates (~99% on noisy scans at K = 24) have one of the nearest neighbours inside, so
        # those are tested first and only the survivors against the rest (the same test, in two parts)
        # the neighbours point by point, (M, K): a candidate's gather reads contiguous rows (~2x faster)
        xt, yt, qt = (np.ascontiguousarray(t.T) for t in (x, y, q))
        first = slice(None, _VERTEX_FIRST)
        vertex = _empty_circles(xt[:, first], yt[:, first], qt[:, first], col, cx, cy, r2)
        if k > _VERTEX_FIRST:
            live = np.flatnonzero(vertex)
            rest = slice(_VERTEX_FIRST, None)
            vertex[live] = _empty_circles(xt[:, rest], yt[:, rest], qt[:, rest], col[live], cx[live], cy[live],
                                          r2[live])
        near = r2 <= bound[col]
    i = rows[col]
    keep = vertex & near
    # beyond an open border: a far vertex is trusted only where samples surround it; an acute
    # triangle's circumcenter lies inside it, an obtuse one's beyond its longest side
    sel = np.flatnonzero(keep & (r2 > plain[col]) & obtuse)
    keep[sel] = _witnessed(pts, tree, frame, i[sel], cx[sel], cy[sel])
    far = np.zeros(len(rows), dtype=bool)
    with np.errstate(over="ignore"):
        ey2 = (cy / b[i]) ** 2
        far[col[vertex & ~keep & ((cx / a[i]) ** 2 + ey2 > 1.0)]] = True
    col, i, cx, ey2 = col[keep], i[keep], cx[keep], ey2[keep]
    need = np.zeros((len(rho), len(rows)), dtype=np.float32)
    if len(col):
        # the largest value per point: a maximum over each point's run (exact, like maximum.at)
        start = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
        for s in range(len(rho)):
            need[s, col[start]] = np.maximum.reduceat((cx / (a[i] * rho[s, i])) ** 2 + ey2, start)
    return need, far


def _empty_circles(x, y, q, col, cx, cy, r2) -> np.ndarray:
    """(P,) bool: none of the neighbours ``(x, y)`` (M, K; ``q = x^2 + y^2``) of the points ``col`` (P,)
    lies strictly inside the circle through the point (the origin) centred at ``(cx, cy)`` (P,),
    ``r2 = cx^2 + cy^2``."""
    xs, ys = x[col], y[col]
    return ~((q[col] - 2.0 * (xs * cx[:, None] + ys * cy[:, None])) < (np.float32(-1e-4) * r2)[:, None]).any(axis=1)


def _enclosed(x, y, cx, cy):
    """Whether the vertices ``(cx, cy)`` (V,) lie in the convex hull of the origin and the points
    ``(x, y)`` (K, V): the directions from the vertex to them leave no angular gap of pi or more.

    The empty circle of a Voronoi vertex inside a sampled surface is surrounded by samples; one
    beyond an open border has samples on one side only (the criterion of boundary detection by
    the largest angular gap, Gumhold, Wang & MacLeod 2001, applied from the vertex).
    """
    with np.errstate(invalid="ignore"):
        ang = np.sort(np.concatenate([np.arctan2(y - cy, x - cx), np.arctan2(-cy, -cx)[None]]), axis=0)
        gap = np.maximum(np.diff(ang, axis=0).max(axis=0), ang[0] + np.float32(2.0 * np.pi) - ang[-1])
        return gap < np.float32(np.pi * (1.0 + 1e-4))  # on a hull edge counts as inside; NaN fails


def _witnessed(pts, tree, frame, i, cx, cy, k=8):
    """Whether the cell vertices ``(cx, cy)`` (V,) in the frames of the points ``i`` (V,) lie in the
    convex hull of their own ``k`` nearest samples (:func:`_enclosed`, seen in ``i``'s tangent plane;
    ``pts``: the (N, 3) positions, ``tree``: their k-d tree)."""
    ua, va = frame[:2]
    if not len(i):
        return np.zeros(0, dtype=bool)
    at = pts[i] + cx[:, None] * ua[i] + cy[:, None] * va[i]
    _, nb = tree.query(at, k=min(k, len(pts)))  # called from parallel blocks already
    nb = nb.reshape(len(i), -1).T
    rel = pts[nb] - pts[i]
    x = np.einsum("kvc,vc->kv", rel, ua[i])
    y = np.einsum("kvc,vc->kv", rel, va[i])
    return _enclosed(x, y, cx, cy)


def _inside(d, rows, frame, limit):
    """Which Voronoi cells among the neighbours lie surely inside their ellipse, and which are open.

    d: three (K, M) float32 neighbour offsets; rows: (M,) the points; frame: as in
    :func:`_cell_vertices`; limit: the largest squared ellipse metric accepted. In coordinates
    where the ellipse is the unit circle the cell is the intersection of the half-planes
    ``D_j . X <= 1`` (``D_j = n_j / h_j``, the bisector ``p . o_j <= |o_j|^2 / 2`` with
    ``p = (a X, b Y)``): it lies inside the unit circle iff the convex hull of the dual points
    ``D_j`` contains it (polarity). With the ``D_j`` sorted by angle, the hull contains every
    triangle ``(0, D_m, D_m+1)`` and ``(0, D_m, D_m+2)`` spanning less than pi, and such a
    triangle covers the unit circle in its angle when the line through its two points is at least
    1 from the origin, i.e. when the two boundary lines meet within the circle. So: the cell is
    surely inside when every angle between adjacent ``D_j`` is covered that way, at the cost of
    2 K line intersections instead of K (K - 1) / 2 circumcenters; redundant neighbours make
    the test fail, not err. A gap of pi or more between adjacent ``D_j`` leaves the cell open (all
    neighbours on one side). Returns two (M,) bool arrays ``(inside, open)``.
    """
    ua, va, a, b = frame[:4]
    x, y = _in_plane(d, rows, ua, va)
    k, m = x.shape
    # one (4, K + 2, M) array: the neighbours sorted by angle and, wrapped around, the first two again,
    # so that "the next" and "the one after" are slices, not rolled copies
    raw = np.empty((4, k, m), dtype=np.float32)
    ang, nx, ny, h = raw
    np.multiply(x, a[rows], out=nx)
    np.multiply(y, b[rows], out=ny)
    np.multiply(np.float32(0.5), x * x + y * y, out=h)
    np.arctan2(ny, nx, out=ang)
    ang[~(h > 0)] = np.nan                       # a coincident point bounds nothing
    order = np.argsort(ang.T, axis=1)            # (M, K); insertion sort for K <= 16: ties keep their order
    flat = np.ascontiguousarray((order * m + np.arange(m)[:, None]).T)   # (K, M) positions in a (K, M) array
    table = np.empty((4, k + 2, m), dtype=np.float32)
    for c in range(4):
        np.take(raw[c].reshape(-1), flat, out=table[c, :k])
    table[:, k:] = table[:, :2]
    ang, nx, ny, h = table[0, :k], table[1, :k], table[2, :k], table[3, :k]
    two_pi = np.float32(2.0 * np.pi)
    half_turn = np.float32(np.pi * 0.999)
    ok = {}
    for step in (1, 2):
        ang1, nx1, ny1, h1 = table[0, step:step + k], table[1, step:step + k], table[2, step:step + k], \
            table[3, step:step + k]
        span = ang1 - ang
        span[span < 0] += two_pi  # wrapped around; NaN (coincident points) fails both tests
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            det = nx * ny1 - nx1 * ny
            cx = (h * ny1 - h1 * ny) / det
            cy = (nx * h1 - nx1 * h) / det
            ok[step] = (cx * cx + cy * cy <= limit) & (span < half_turn)
        if step == 1:
            open_ = ~(span < half_turn).all(axis=0)
    # the angle from D_m to D_m+1 is covered by its own edge or by the edges from D_m-1 or D_m to two on
    covered = ok[1] | ok[2] | np.roll(ok[2], 1, axis=0)
    return covered.all(axis=0) & ~open_, open_
