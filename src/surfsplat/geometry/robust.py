"""Robust splats from raw points: duplicates, outliers, non-planar neighbourhoods, size bounds.

Real raw points (photogrammetric scans, airborne LiDAR) break the assumption behind the
k-neighbour constructions of :mod:`.splats` (Guennebaud 2003 eq. 7; Pajarola 2003 sec. 3.4):
a clean surface sampled densely everywhere. :func:`surfsplat.geometry.preprocess` applies these
rules, in this order, all vectorized (``h_i``: the distance from point i to its k-th neighbour,
the local spacing):

1. **Duplicates** (:func:`exact_duplicates`, :func:`near_duplicates`, :func:`merge_points`):
   points at exactly the same position, and points closer than ``DUPLICATE_FRACTION`` (1e-5)
   times the median ``h`` are merged, transitively, into the first of them in input order.
   1e-5 of the spacing is float32 rounding for a cloud of a million points; uniformly random
   samples hold a pair that close with probability ~4e-4 per million points. Colors of a
   merged group are averaged; given normals are averaged after turning them to the first
   one's side, then normalized.
2. **Outliers**: points without a surface neighbourhood of their own.
   *Isolated clusters* (:func:`isolated_clusters`): cut the kNN edges ``i -> j`` longer than
   ``CUT_FACTOR`` (3) times ``h_j`` (much longer than the spacing at the far end), longer than
   ``GLOBAL_CUT`` (10) times the median ``h``, or longer than ``PAIR_CUT`` (4) times the larger
   of both ends' 2nd-neighbour distances (a tight floater's own spacing); the connected
   components of at most k points are isolated: every member's k-neighbourhood reaches out of
   it. *Stray points* (:func:`stray_points`): ``h_i`` more than 3 times the median ``h_j`` of
   its neighbours, or more than 10 times the median ``h`` (a point floating above a surface,
   or in a sparse cloud of strays). Measured: no point of a million uniformly random samples
   of a plane, of 200k samples of a cube, of frag_115.ply, bunny.ply or simple.las is either
   (the largest ``h_i`` over its neighbours' median was 2.5; the longest edge over ``h_j`` 3.05).
   ``outliers="drop"`` (default) removes them, ``"cap"`` gives them small round splats
   (:func:`outlier_radius`), ``"keep"`` treats them like the other points.
3. **Scan lines** (:func:`linear`, :mod:`.cells`): neighbourhoods along a line get their
   tangent plane from a larger neighbourhood and splats covering their Voronoi cells.
4. **Non-planar neighbourhoods** (:func:`volumetric`; raw points only: given normals say there
   is a surface): where the covariance eigenvalues have ``lambda_3 > VOLUME_RATIO *
   lambda_2`` (0.25: the spread off the fitted plane is more than half the smaller spread in
   it; vegetation, noise), the splat is a small circle (:func:`round_radius`) instead of a
   huge flat ellipse. Measured with k = 8: 80 % of the points of a uniformly random volume
   are classified so, 0.15 % of bunny.ply's vertices, 0.03 % of frag_115.ply's, 12 % of
   simple.las's, 1.3 % of a sampled cube's (next to its edges; excluded where ``sharp_angle``
   finds the edges).
5. **Size bound** (:func:`bound_sizes`): the major semi-axis of every splat is at most
   ``LOCAL_CAP`` (4) times the median of its k neighbours' own major semi-axes, and at most
   ``GLOBAL_CAP`` (4) times the median over the cloud; a splat above its bound shrinks
   uniformly (shape kept). On a million uniformly random samples of a plane (a torus) the
   largest ratios were 3.56 (3.67) to the neighbours' median and 3.85 (2.98) to the global one:
   the bound leaves clean samples alone. It limits legitimate density variation to 16:1 in
   area (a region sampled 4 times coarser than the median gets smaller splats than it needs).

The counts go to :class:`PreprocessReport` and through :func:`surfsplat.progress.message`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..cloud import SplatCloud
from ..errors import InputError
from .common import for_blocks, neighbour_median, row_norms

#: Points closer than this times the median k-th-neighbour distance are duplicates.
DUPLICATE_FRACTION = 1e-5

#: A kNN edge i -> j longer than this times j's own k-th-neighbour distance is cut ...
CUT_FACTOR = 3.0

#: ... and so is one longer than this times the median k-th-neighbour distance of the cloud ...
GLOBAL_CUT = 10.0

#: ... and one longer than this times the larger of its two ends' distances to their 2nd neighbour
#: (the own spacing of a small tight cluster, whose links to anything else are long).
PAIR_CUT = 4.0

#: ``lambda_3 / lambda_2`` above which a neighbourhood is not a surface.
VOLUME_RATIO = 0.25

#: Radius of a non-planar point's round splat: this times the median neighbour distance (times coverage).
ROUND_FRACTION = 0.5

#: A splat's major semi-axis is at most this times the median of its neighbours' ...
LOCAL_CAP = 4.0

#: ... and at most this times the ``GLOBAL_QUANTILE`` quantile (the median) over the cloud.
GLOBAL_CAP = 4.0
GLOBAL_QUANTILE = 0.5

#: What ``preprocess(outliers=...)`` does with the outliers (isolated clusters, stray points).
OutlierAction = Literal["drop", "cap", "keep"]
OUTLIER_ACTIONS = get_args(OutlierAction)


@dataclass(frozen=True)
class PreprocessReport:
    """What :func:`surfsplat.geometry.preprocess` found and changed (all counts are points).

    Attributes:
        input_points: valid points given (invalid rows are dropped before, with a warning).
        output_points: splats returned.
        duplicates: points merged into another one (``exact_duplicates`` of them at exactly
            the same position, the rest closer than ``duplicate_tolerance``).
        exact_duplicates: see above.
        duplicate_tolerance: the distance below which points were merged, model units.
        outliers: points without a surface neighbourhood of their own: the points of
            ``outlier_clusters`` isolated clusters and ``strays`` stray points.
        outlier_clusters: see above.
        strays: see above.
        outlier_action: ``"drop"``, ``"cap"`` or ``"keep"``: what was done with them.
        linear: points whose k neighbours lay on a line (scan lines), sized from their
            Voronoi cells (:mod:`surfsplat.geometry.cells`).
        volumetric: points with non-planar neighbourhoods, given small round splats.
        capped: splats shrunk by the local or global size bound.
        spacing: median distance to the k-th neighbour, model units.
        size_bound: the global bound on the major semi-axis, model units (0 if not computed).
        kept: (output_points,) int64: for each output splat, the row of the input it comes
            from (the first of a duplicate group), counted after invalid rows were dropped.
    """

    input_points: int
    output_points: int
    duplicates: int = 0
    exact_duplicates: int = 0
    duplicate_tolerance: float = 0.0
    outliers: int = 0
    outlier_clusters: int = 0
    strays: int = 0
    outlier_action: OutlierAction = "drop"
    linear: int = 0
    volumetric: int = 0
    capped: int = 0
    spacing: float = 0.0
    size_bound: float = 0.0
    kept: np.ndarray | None = field(default=None, repr=False)


def check_outliers(outliers: str) -> str:
    """``outliers`` if it is one of :data:`OUTLIER_ACTIONS`; InputError otherwise."""
    if outliers not in OUTLIER_ACTIONS:
        raise InputError(f"outliers must be one of {OUTLIER_ACTIONS}, got {outliers!r}")
    return outliers


# -- duplicates ---------------------------------------------------------------------------------------


def exact_duplicates(positions: np.ndarray) -> np.ndarray | None:
    """Groups of points at exactly the same position.

    Args:
        positions: (N, 3) float32 positions (model units).

    Returns:
        None if all positions differ, else (N,) int64 ``rep``: the index of the first point
        (in input order) at the same position as each point (``rep[i] == i`` for the kept ones).
        Found by sorting a 64-bit hash of the coordinates' bits and comparing neighbours in
        that order (~0.1 s per million points).
    """
    # + 0.0 turns -0.0 into +0.0: equal positions, and now equal bits for the hash
    pos = np.ascontiguousarray(positions, dtype=np.float32) + np.float32(0.0)
    bits = pos.view(np.uint32).astype(np.uint64)
    key = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
    key ^= bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
    key ^= bits[:, 2] * np.uint64(0x165667B19E3779F9)
    order = np.argsort(key, kind="stable")  # stable: equal keys in input order
    ks = key[order]
    same = ks[1:] == ks[:-1]
    if not same.any():
        return None
    cand = np.flatnonzero(same)
    same[cand] = (pos[order[cand]] == pos[order[cand + 1]]).all(axis=1)
    if not same.any():
        return None
    # runs of equal positions in the sorted order; the run's first entry is its smallest index
    start = np.flatnonzero(np.r_[True, ~same])
    run = np.cumsum(np.r_[True, ~same]) - 1
    rep = np.empty(len(pos), dtype=np.int64)
    rep[order] = order[start[run]]
    return rep


def near_duplicates(dist: np.ndarray, idx: np.ndarray, tolerance: float) -> np.ndarray | None:
    """Groups of points closer than ``tolerance`` (model units), transitively, from the kNN graph.

    Args:
        dist, idx: (N, k) kNN distances (float32, model units) and indices (:func:`knn`).
        tolerance: merge distance, model units.

    Returns:
        None if no kNN edge is that short, else (N,) int64 ``rep``: the smallest index of each
        point's group (``rep[i] == i`` for the kept ones).
    """
    short = dist <= tolerance
    if not short.any():
        return None
    n = len(dist)
    a = np.nonzero(short)[0]
    b = idx[short]
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    return first[label]


def merge_points(cloud: SplatCloud, rep: np.ndarray) -> SplatCloud:
    """The cloud with every point merged into ``rep[i]`` (see :func:`exact_duplicates`).

    Positions, splat axes, normal fields, clip lines and attributes are the representative's
    (the group's first point in input order: a class cannot be averaged); colors are
    the group's mean; normals the normalized sum of the group's normals, each turned to the
    representative's side (the representative's own where they cancel). Input order is kept.
    """
    keep = np.flatnonzero(rep == np.arange(len(rep)))
    slot = np.full(len(rep), -1, dtype=np.int64)
    slot[keep] = np.arange(len(keep))
    group = slot[rep]
    out = cloud.subset(keep)
    changes = {}
    count = np.bincount(group, minlength=len(keep)).astype(np.float64)
    if cloud.colors is not None:
        changes["colors"] = np.stack([np.bincount(group, weights=cloud.colors[:, c], minlength=len(keep)) / count
                                      for c in range(3)], axis=1).astype(np.float32)
    if cloud.normals is not None:
        own = cloud.normals[rep]
        nrm = np.where((np.einsum("ij,ij->i", cloud.normals, own) < 0)[:, None], -cloud.normals, cloud.normals)
        total = np.stack([np.bincount(group, weights=nrm[:, c], minlength=len(keep)) for c in range(3)], axis=1)
        length = np.linalg.norm(total, axis=1, keepdims=True)
        changes["normals"] = np.where(length > 1e-6, total / np.maximum(length, 1e-30), out.normals).astype(np.float32)
    return out.replace(**changes) if changes else out


# -- isolated clusters ----------------------------------------------------------------------------------


def isolated_clusters(dist: np.ndarray, idx: np.ndarray, max_size: int | None = None,
                      cut: float = CUT_FACTOR, global_cut: float = GLOBAL_CUT) -> tuple[np.ndarray, int]:
    """Points in isolated clusters: small components of the kNN graph without its long edges.

    The edge ``i -> idx[i, j]`` is cut when ``dist[i, j] > cut * h[idx[i, j]]``, ``h`` the
    distance from a point to its k-th neighbour, when ``dist[i, j] > global_cut * median(h)``,
    or when it is longer than ``PAIR_CUT`` times the larger of its ends' distances to their
    2nd neighbour. A connected component (edges undirected) of at most ``max_size`` points
    (default k) is isolated. Every point of such a component has a cut edge (at most k - 1 of
    its k neighbours are inside), so only the points with a cut edge are examined.

    Args:
        dist, idx: (N, k) kNN distances (float32, model units, ascending) and indices.
        max_size: largest isolated component (default k).
        cut: the edge-length factor relative to the far end's spacing.
        global_cut: the edge-length factor relative to the median spacing.

    Returns:
        ``(mask, clusters)``: (N,) bool, True for the points of isolated components, and their number.
    """
    h = dist[:, -1]
    return _isolated(dist, idx, h, float(np.median(h)), k_max=max_size, cut=cut, global_cut=global_cut)


def _isolated(dist, idx, h, median_h, k_max=None, cut=CUT_FACTOR, global_cut=GLOBAL_CUT, suspect=None):
    """:func:`isolated_clusters` with the spacings ``h`` and their median given (and, optionally,
    ``suspect``: the (N,) bool rows with a cut edge)."""
    n, k = dist.shape
    max_size = k if k_max is None else int(k_max)
    limit = np.float32(global_cut * median_h)

    near = dist[:, min(1, k - 1)]

    def cut_edges(rows):
        d, nb = dist[rows], idx[rows]
        out = (d > np.float32(cut) * np.take(h, nb)) | (d > limit)
        out |= d > np.float32(PAIR_CUT) * np.maximum(near[rows][:, None], np.take(near, nb))
        return out

    if suspect is None:
        suspect = np.empty(n, dtype=bool)

        def block(sl):
            suspect[sl] = cut_edges(sl).any(axis=1)

        for_blocks(block, n)
    mask = np.zeros(n, dtype=bool)
    if not suspect.any():
        return mask, 0
    rows = np.flatnonzero(suspect)
    slot = np.full(n, -1, dtype=np.int64)
    slot[rows] = np.arange(len(rows))
    # kept edges out of the suspects ...
    kept = ~cut_edges(rows)
    a = np.repeat(rows, k).reshape(-1, k)[kept]
    b = idx[rows][kept]
    inside = suspect[b]
    graph = coo_matrix((np.ones(int(inside.sum()), dtype=np.int8), (slot[a[inside]], slot[b[inside]])),
                       shape=(len(rows), len(rows)))
    count, label = connected_components(graph, directed=False)
    leaky = np.zeros(count, dtype=bool)
    leaky[label[slot[a[~inside]]]] = True  # joined to a point that is not a suspect
    # ... and kept edges into them from the other points (their edges are all kept)
    into = []

    def into_block(sl):
        hit = np.take(suspect, idx[sl])
        hit[suspect[sl]] = False
        if hit.any():
            into.append(idx[sl][hit])

    for_blocks(into_block, n)
    if into:
        leaky[label[slot[np.concatenate(into)]]] = True
    size = np.bincount(label, minlength=count)
    isolated = ~leaky & (size <= max_size)
    mask[rows] = isolated[label]
    return mask, int(isolated.sum())


def stray_points(dist: np.ndarray, idx: np.ndarray, cut: float = CUT_FACTOR,
                 global_cut: float = GLOBAL_CUT) -> np.ndarray:
    """Points far from any surface: their own spacing is much larger than their neighbours'.

    ``h_i > cut * median_j h_j`` (over the k neighbours j; the lower median for even k: at
    least half of them are ``cut`` times denser) or ``h_i > global_cut * median(h)``,
    ``h`` the distance to the k-th neighbour: the same two scales as the edge cuts of
    :func:`isolated_clusters`. A stray point floating above a surface has the surface's points
    as neighbours, at a distance much larger than their own spacing; a sparse network of
    strays has a spacing much larger than the cloud's. On a million uniformly random samples
    of a plane the largest ``h_i / median_j h_j`` was 2.5.

    Args:
        dist, idx: (N, k) kNN distances (float32, model units, ascending) and indices.

    Returns:
        (N,) bool mask.
    """
    h = dist[:, -1]
    return _stray(idx, h, float(np.median(h)), cut, global_cut)


def _stray(idx, h, median_h, cut=CUT_FACTOR, global_cut=GLOBAL_CUT):
    """:func:`stray_points` with the spacings ``h`` and their median given."""
    denser = np.count_nonzero(np.take(h, idx) * np.float32(cut) < h[:, None], axis=1)
    return (denser >= (idx.shape[1] + 1) // 2) | (h > np.float32(global_cut * median_h))


def outlier_points(dist: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """Both kinds of outliers at once: ``(isolated, clusters, stray)`` as :func:`isolated_clusters`
    and :func:`stray_points` return them, stray points in isolated clusters left out of ``stray``.

    One blocked, threaded pass gathers the neighbours' spacings for both tests.
    """
    n, k = dist.shape
    h = dist[:, -1]
    median_h = float(np.median(h))
    limit = np.float32(GLOBAL_CUT * median_h)
    half = (k + 1) // 2
    near = dist[:, min(1, k - 1)]
    suspect = np.empty(n, dtype=bool)
    stray = np.empty(n, dtype=bool)

    def block(sl):
        hn = np.take(h, idx[sl])
        d = dist[sl]
        cut_edge = (d > np.float32(CUT_FACTOR) * hn) | (d > limit)
        cut_edge |= d > np.float32(PAIR_CUT) * np.maximum(near[sl][:, None], np.take(near, idx[sl]))
        suspect[sl] = cut_edge.any(axis=1)
        # h_i > cut * (lower) median of the h_j: at least half the neighbours are that much denser
        denser = np.count_nonzero(hn * np.float32(CUT_FACTOR) < h[sl][:, None], axis=1)
        stray[sl] = (denser >= half) | (h[sl] > limit)

    for_blocks(block, n)
    isolated, clusters = _isolated(dist, idx, h, median_h, suspect=suspect)
    return isolated, clusters, stray & ~isolated


def outlier_radius(minor: np.ndarray, idx: np.ndarray, outlier: np.ndarray) -> np.ndarray:
    """Radius of the round splats that ``outliers="cap"`` gives isolated points (model units).

    The median minor semi-axis of the point's neighbours outside isolated clusters (the size
    of one sample of the surface next to it); the median over the cloud where all are isolated.

    Args:
        minor: (N,) float32 minor semi-axes of all splats, model units.
        idx: (N, k) neighbour indices.
        outlier: (N,) bool mask of isolated points.

    Returns:
        (M,) float32 radii of the M isolated points, in order.
    """
    rows = np.flatnonzero(outlier)
    near = idx[rows]
    vals = np.where(outlier[near], np.nan, minor[near])
    fallback = float(np.median(minor[~outlier])) if (~outlier).any() else float(np.median(minor))
    with np.errstate(invalid="ignore"):
        counts = (~np.isnan(vals)).sum(axis=1)
        med = np.nanmedian(np.where(counts[:, None] > 0, vals, fallback), axis=1)
    return med.astype(np.float32)


# -- neighbourhood shapes ---------------------------------------------------------------------------------


def linear(eigenvalues: np.ndarray, max_anisotropy: float) -> np.ndarray:
    """(N,) bool: neighbourhoods along a line, ``lambda_2 < lambda_1 / max_anisotropy^2``.

    ``eigenvalues``: (N, 3) descending covariance eigenvalues. That is where Pajarola's axis
    ratio ``sqrt(lambda_1 / lambda_2)`` would exceed ``max_anisotropy`` (see :mod:`.cells`).
    """
    lam = eigenvalues
    return lam[:, 1] * (max_anisotropy * max_anisotropy) < lam[:, 0]


def volumetric(eigenvalues: np.ndarray) -> np.ndarray:
    """(N,) bool: non-planar neighbourhoods, ``lambda_3 > VOLUME_RATIO * lambda_2`` (and lambda_2 > 0)."""
    lam = eigenvalues
    return (lam[:, 2] > VOLUME_RATIO * lam[:, 1]) & (lam[:, 1] > 0)


def round_radius(dist: np.ndarray, coverage: float, limit: float) -> np.ndarray:
    """(N,) float32 radius of the round splats of non-planar points, model units.

    ``min(coverage * ROUND_FRACTION * d_med, limit)``: ``d_med`` the row median of ``dist``
    ((N, k) neighbour distances, model units), ``limit`` the size of one sample of the
    surface (preprocess passes the median minor semi-axis of the planar splats): a point that
    is not on a surface needs no splat larger than a sample's, however sparse its neighbours.
    """
    med = np.median(dist, axis=1) if dist.shape[1] > 1 else dist[:, 0]
    return np.minimum(np.float32(coverage * ROUND_FRACTION) * med, np.float32(limit)).astype(np.float32)


# -- the size bound ---------------------------------------------------------------------------------------


def bound_sizes(u: np.ndarray, v: np.ndarray, idx: np.ndarray, *, exclude: np.ndarray | None = None
                ) -> tuple[int, float]:
    """Shrink, in place, the splats above the local and global size bound (see the module docstring).

    Args:
        u, v: (N, 3) float32 splat axes (model units); scaled in place.
        idx: (N, k) neighbour indices.
        exclude: (N,) bool, points that neither get a bound nor count in the global quantile
            (isolated clusters, handled by the ``outliers`` action).

    Returns:
        ``(capped, bound)``: how many splats shrank, and the global bound (model units).
    """
    size = np.maximum(row_norms(u), row_norms(v))
    ok = np.ones(len(size), dtype=bool) if exclude is None else ~exclude
    if not ok.any():
        return 0, 0.0
    bound = float(GLOBAL_CAP * np.quantile(size[ok], GLOBAL_QUANTILE))
    local = np.float32(LOCAL_CAP) * neighbour_median(size, idx)
    cap = np.minimum(local, np.float32(bound))
    over = ok & (size > cap) & (cap > 0)
    if over.any():
        scale = (cap[over] / size[over])[:, None]
        u[over] *= scale
        v[over] *= scale
    return int(over.sum()), bound
