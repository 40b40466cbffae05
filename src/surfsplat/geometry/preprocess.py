"""Preprocessing: from points (optional normals, colors) to renderable splats.

Stages, each reported through :func:`surfsplat.progress.stage` (counts through
:func:`surfsplat.progress.message`, and in the :class:`PreprocessReport`):

1. duplicates merged (:mod:`.robust`: exactly coincident points, then points closer than
   1e-5 of the spacing, found from the kNN graph),
2. spatial sort (Morton order; internal only, the result keeps the input order),
3. k-nearest neighbours (:func:`knn`),
4. isolated clusters (:func:`~surfsplat.geometry.robust.isolated_clusters`: stray points and
   floaters; dropped, given small splats or kept as ``outliers`` says),
5. normals by PCA (:func:`estimate_normals`) when the cloud has none, and splat axes
   (:func:`elliptical_splats`, Pajarola 2003, or :func:`circular_splats`, Guennebaud 2003
   eq. 7) unless the cloud has ``u`` and ``v`` already,
6. scan lines: neighbourhoods along a line get the tangent plane of a larger neighbourhood and
   splats that cover their Voronoi cells (:mod:`.cells`),
7. consistent orientation (:func:`orient_normals`, Hoppe et al. 1992) when the normals were
   estimated here,
8. with ``sharp_angle``: sharp features (:func:`~surfsplat.geometry.sharp.detect_sharp_features`,
   Zwicker 2004 sec. 5): normals re-fitted to one side of the feature and the planes of the
   other side(s),
   then (default ``coverage=None``, ellipses) each bare ellipse grown to contain its Voronoi
   cell (:func:`~surfsplat.geometry.splats.cover_cells`),
9. non-planar neighbourhoods (vegetation, noise) get small round splats, and every splat is
   held under a local and a global size bound (:mod:`.robust`),
10. with ``sharp_angle``: clip lines where those planes cross the splats
    (:func:`~surfsplat.geometry.sharp.feature_clip_lines`).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from .. import progress
from ..cloud import SplatCloud
from ..errors import InputError
from ..frames import tangent_frame
from .cells import PREDICT_SHARE, linear_share, linear_splats
from .common import row_norms
from .neighbors import LEAFSIZE, as_points, kdtree, knn, spatial_order
from .normals import estimate_normals, neighbourhood_pca, orient_normals, orientation_signs
from .robust import (DUPLICATE_FRACTION, OutlierAction, PreprocessReport, bound_sizes, check_outliers,
                     exact_duplicates, linear, merge_points, near_duplicates, outlier_points, outlier_radius,
                     round_radius, volumetric)
from .sharp import check_sharp_angle, detect_sharp_features, feature_clip_lines
from .splats import (CIRCLE_COVERAGE, ELLIPSE_COVERAGE, GAP_BASE, MAX_ANISOTROPY, check_ellipse_options,
                     circular_splats, cover_cells, elliptical_splats, pca_splats)

SHAPES = ("ellipse", "circle")

#: Name of the per-point attribute ``preprocess(mark_nonplanar=True)`` adds (1: non-planar neighbourhood).
NONPLANAR = "nonplanar"

#: Rounds of near-duplicate merging (each needs a new kNN query; one is almost always enough).
_MERGE_ROUNDS = 3


def preprocess(cloud, *, k: int = 8, shape: str = "ellipse", orient: bool = True,
               coverage: float | None = None, max_anisotropy: float = MAX_ANISOTROPY,
               source: str = "input", sharp_angle: float | None = None, outliers: OutlierAction = "drop",
               merge_duplicates: bool = True, return_report: bool = False, mark_nonplanar: bool = False):
    """Turn a point cloud into renderable splats.

    Args:
        cloud: a :class:`SplatCloud` (or an (N, 3) array of positions).
            Existing normals, colors, ``u``/``v``, normal fields and clip lines
            are kept as they are; a cloud with ``u`` and ``v`` is not resized
            (none of the robust rules below apply to it).
        k: neighbours per point (>= 1). Clouds with at most k points use
            ``k = N - 1`` and warn.
        shape: ``"ellipse"`` (Pajarola 2003 covariance ellipses, default) or
            ``"circle"`` (Guennebaud 2003 eq. 7 radii).
        orient: orient estimated normals consistently (Hoppe et al. 1992).
            Given normals are never re-oriented.
        coverage: factor on all splat radii. Default (None): ellipses are
            Pajarola's bare ellipses, each grown just enough to contain its
            Voronoi cell (:func:`~surfsplat.geometry.splats.cover_cells`: no
            holes, about half the area of the factor 1.5 uniformly random samples
            need otherwise; ``benchmarks/results/gap_radii.md``), circles get
            1.25 (see :mod:`surfsplat.geometry.splats`). A number: that factor on
            every splat, nothing grown; 1.0 gives the papers' bare sizes, enough
            for near-regular samplings (scans). Scan-line, non-planar and
            sharp-feature splats get 1.5 (ellipses) or 1.25 (circles) by default.
        max_anisotropy: cap of the ellipse axis ratio (default 4.0).
        source: name of the input in messages and warnings.
        sharp_angle: None (default), or an angle in degrees in (0, 180):
            detect sharp edges and corners where the normals in a point's
            neighbourhood (its 32 nearest points) split into groups
            more than this apart, and give the splats there clip lines (see
            :func:`surfsplat.geometry.sharp.detect_sharp_features`). Estimated
            normals at feature points are re-fitted to the point's own side
            (PCA normals average the two faces). Normals that came with the
            cloud are kept as they are. A cloud that has clip lines already
            keeps them (this option is then ignored, with a warning).
        outliers: what to do with the points that have no surface neighbourhood
            of their own: isolated clusters (components of at most k points of
            the neighbour graph cut at edges much longer than the local or
            global spacing: floaters) and stray points (spacing 3 times their
            neighbours' or 10 times the cloud's median); see
            :mod:`surfsplat.geometry.robust`. ``"drop"`` (default: the best
            picture, measured in ``benchmarks/results/robust_splats.md``) removes
            them, ``"cap"`` keeps them as small round splats (one sample of the
            surface next to them), ``"keep"`` treats them like all other points
            (still under the size bound).
        merge_duplicates: merge points at the same position (exactly, or closer
            than 1e-5 times the median distance to the k-th neighbour) into the
            first of them, averaging colors and given normals (default True).
        return_report: also return a :class:`~surfsplat.geometry.robust.PreprocessReport`
            (the counts of duplicates, outliers, scan-line, non-planar and capped splats).
        mark_nonplanar: add the per-point attribute ``NONPLANAR`` ("nonplanar", uint8): 1 where
            the neighbourhood is not planar (:func:`~surfsplat.geometry.robust.volumetric`:
            vegetation, wires, noise; raw points only), 0 elsewhere. Nothing else changes.

    Returns:
        A validated :class:`SplatCloud` in the input order (invalid input rows
        dropped with a warning; merged duplicates and dropped outliers removed,
        the first of each duplicate group kept: ``report.kept`` maps the rows;
        ``attributes`` are the kept rows', a merged group's its first point's)
        with unit ``normals`` and splat axes ``u``, ``v`` (float32, model
        units). Neighbourhoods along scan lines get splats covering their
        Voronoi cells (:mod:`surfsplat.geometry.cells`), non-planar ones (raw
        points only) small round splats, and every splat's major semi-axis is
        at most 4 times its neighbours' median and 4 times the cloud's median
        (:mod:`surfsplat.geometry.robust`). If the cloud has ``u`` and
        ``v`` but no normals, the normals are ``u x v`` normalized. With
        ``sharp_angle``, ``clip_lines`` (N, 2, 3) float32 too (``(0, 0, 1)``
        where unused). With ``return_report``, ``(cloud, report)``.

    Raises:
        InputError: bad arguments, no valid points, or a single (distinct)
            point without splat axes (its size cannot be derived).
    """
    if not isinstance(cloud, SplatCloud):
        cloud = SplatCloud(positions=cloud)
    if shape not in SHAPES:
        raise InputError(f"shape must be one of {SHAPES}, got {shape!r}")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise InputError(f"k must be a positive integer, got {k!r}")
    gaps = coverage is None and shape == "ellipse"  # Voronoi-cell growth of bare ellipses
    if coverage is None:
        coverage = ELLIPSE_COVERAGE if shape == "ellipse" else CIRCLE_COVERAGE
    check_ellipse_options(coverage, max_anisotropy)
    base = GAP_BASE if gaps else coverage
    check_outliers(outliers)
    if sharp_angle is not None:
        sharp_angle = check_sharp_angle(sharp_angle)
    cloud = cloud.validated(source)
    n = len(cloud)
    if sharp_angle is not None and cloud.clip_lines is not None:
        warnings.warn(f"{source}: has clip lines already; sharp_angle ignored", stacklevel=2)
        sharp_angle = None
    need_normals = cloud.normals is None
    need_axes = cloud.u is None or cloud.v is None
    if not need_axes:
        if need_normals:
            cloud = cloud.replace(normals=np.cross(cloud.u, cloud.v)).validated(source)
        if sharp_angle is not None and n > 1:
            cloud = _add_clip_lines(cloud, sharp_angle).validated(source)
        report = PreprocessReport(n, len(cloud), outlier_action=outliers, kept=np.arange(len(cloud)))
        return (cloud, report) if return_report else cloud
    if n < 2:
        raise InputError(f"{source}: preprocessing needs at least 2 points to size the splats, got {n}")
    k = int(k)

    cloud, report, (perm, pts, dist, idx, tree, wide), k = _merged_neighbours(cloud, k, merge_duplicates, source,
                                                                              max_anisotropy)
    m = len(cloud)
    with progress.stage("outliers (isolated clusters, stray points)", m):
        isolated, clusters, stray = outlier_points(dist, idx)
        outlier = isolated | stray
    if outlier.any():
        verb = {"drop": "dropped", "cap": "given small splats", "keep": "kept"}[outliers]
        progress.message(f"  outliers ({verb}): {int(isolated.sum()):,} points in {clusters:,} isolated clusters, "
                         f"{int(stray.sum()):,} stray points")
    sharp = sharp_angle is not None
    if need_normals and not sharp:
        # one pass over the neighbourhoods for all three (shares the offset gathers)
        with progress.stage(f"normals (PCA) and splat {shape}s", m):
            normals, lam, u, v = pca_splats(pts, idx, dist, shape=shape, coverage=base,
                                            max_anisotropy=max_anisotropy)
    else:
        with progress.stage("normals (PCA)" if need_normals else "neighbourhood shapes (PCA)", m):
            normals, lam = neighbourhood_pca(pts, idx)
        if not need_normals:
            normals = np.take(cloud.normals, perm, axis=0)
        u = v = None
    special = outlier if outliers != "keep" else np.zeros(m, dtype=bool)  # "keep": ordinary points
    lin = linear(lam, max_anisotropy) & ~special
    rows = np.flatnonzero(lin)
    cells = None
    if len(rows):
        with progress.stage("scan lines: Voronoi-cell splats", len(rows)):
            cells = linear_splats(tree, pts, rows, k, dist[rows, -1], None if need_normals else normals[rows],
                                  shape=shape, coverage=coverage, max_anisotropy=max_anisotropy,
                                  neighbours=wide)
        progress.message(f"  {len(rows):,} neighbourhoods along scan lines, sized from their Voronoi cells")
        lam[rows] = cells[1]
        if need_normals:
            normals[rows] = cells[0]
        idx, dist = idx.copy(), dist.copy()
        idx[rows], dist[rows] = cells[4], cells[5]
        if u is not None:
            u[rows], v[rows] = cells[2], cells[3]
    cell_axes = None if cells is None else (cells[2], cells[3])
    if need_normals and orient:
        with progress.stage("orientation (MST)", m):
            sigma = orientation_signs(pts, normals, idx, dist, irregular=lin if len(rows) else None)
            normals *= sigma[:, None]
            if u is not None:
                v *= sigma[:, None]  # keep u x v along the normal
            elif cell_axes is not None:
                cell_axes = (cell_axes[0], cell_axes[1] * sigma[rows, None])
    features = None
    if u is None:
        u, v, features = _sized(pts, normals, idx, dist, rows, cell_axes, shape, base, max_anisotropy,
                                sharp_angle, oriented=orient or not need_normals, refine=need_normals)
        normals = features.normals if features is not None else normals
    # given normals say there is a surface (mesh samples, scanner normals): only raw points are judged
    vol = volumetric(lam) & ~special if need_normals else np.zeros(m, dtype=bool)
    if features is not None:  # two planes meeting at an edge are not a volume
        vol &= ~features.feature & ~features.feature[idx].any(axis=1)
    if gaps:
        # the non-planar splats are given round ones below: their cells need no tracing
        fixed = special | lin | vol
        if features is not None:
            # splats at sharp features get the global factor: their clip lines cut them, and their
            # cells, bounded by the other face's points projected onto their plane, end short of the edge
            fixed = fixed | features.feature
            u[features.feature] *= np.float32(ELLIPSE_COVERAGE / GAP_BASE)
            v[features.feature] *= np.float32(ELLIPSE_COVERAGE / GAP_BASE)
        with progress.stage("splat ellipses grown to their Voronoi cells", m):
            u, v, grown = cover_cells(pts, idx, u, v, exclude=fixed, tree=tree)
        progress.message(f"  {int((grown > 1).any(axis=1).sum()):,} splats grown to cover their Voronoi cells")
    if vol.any():
        surface = ~vol & ~special
        minor = row_norms(v[surface] if surface.any() else v)
        radius = round_radius(dist[vol], coverage, float(np.median(minor)))[:, None]
        t1, t2 = tangent_frame(normals[vol])
        u[vol], v[vol] = t1 * radius, t2 * radius
        progress.message(f"  {int(vol.sum()):,} non-planar neighbourhoods given small round splats")
    with progress.stage("splat size bound", m):
        capped, bound = bound_sizes(u, v, idx, exclude=special)
    if capped:
        progress.message(f"  {capped:,} splats shrunk to the local/global size bound")
    if outliers == "cap" and outlier.any():
        radius = outlier_radius(np.minimum(row_norms(u), row_norms(v)), idx, outlier)
        t1, t2 = tangent_frame(normals[outlier])
        u[outlier], v[outlier] = t1 * radius[:, None], t2 * radius[:, None]

    changes = {"u": _unsort(u, perm), "v": _unsort(v, perm)}
    if mark_nonplanar:
        flag = np.empty(m, dtype=np.uint8)
        flag[perm] = vol
        changes["attributes"] = {**(cloud.attributes or {}), NONPLANAR: flag}
    if need_normals:
        changes["normals"] = _unsort(normals, perm)
    if sharp:
        with progress.stage("clip lines", m):
            lines = feature_clip_lines(features, pts, u, v)
        out = np.empty_like(lines)
        out[perm] = lines
        changes["clip_lines"] = out
    result = cloud.replace(**changes)
    if outliers == "drop" and outlier.any():
        keep = np.ones(m, dtype=bool)
        keep[perm[outlier]] = False
        result = result.subset(keep)
        report = replace(report, kept=report.kept[keep])
    result = result.validated(source)
    report = replace(report, output_points=len(result), outliers=int(outlier.sum()), outlier_clusters=clusters,
                     strays=int(stray.sum()),
                     outlier_action=outliers, linear=len(rows), volumetric=int(vol.sum()), capped=capped,
                     size_bound=bound)
    return (result, report) if return_report else result


def _merged_neighbours(cloud: SplatCloud, k: int, merge: bool, source: str, max_anisotropy: float):
    """Merge duplicates (see :mod:`.robust`) and compute the kNN graph of what is left.

    Duplicates show in the kNN graph as edges no longer than the tolerance; groups of more
    than k + 1 coincident points may not be joined by it, so where a point has k coincident
    neighbours the exact duplicates are first merged by :func:`exact_duplicates` (a hash
    sort), then the graph is computed again. Clean clouds pay one check of the kNN distances.

    Returns ``(cloud, report, (perm, pts, dist, idx, tree, wide), k)``: the merged cloud, a
    first report (input points, duplicate counts, spacing, kept rows), the Morton order
    ``perm`` of the merged cloud, its sorted positions, their kNN distances and indices, k-d
    tree, and ``wide``: None, or the 2k nearest neighbours ``(dist, idx)`` where most
    neighbourhoods lie on lines (see :func:`~surfsplat.geometry.cells.linear_share`); and k
    clamped to the points left.
    """
    n = len(cloud)
    origin = np.arange(n, dtype=np.int64)
    exact = 0
    tolerance = 0.0
    warned = hashed = False
    for _ in range(_MERGE_ROUNDS):
        m = len(cloud)
        if m < 2:
            raise InputError(f"{source}: preprocessing needs at least 2 distinct points to size the splats, got {m}")
        if k > m - 1:
            if not warned:
                warnings.warn(f"{source}: only {m} points, using k = {m - 1} neighbours instead of {k}", stacklevel=3)
                warned = True
            k = m - 1
        with progress.stage("spatial sort", m):
            perm = spatial_order(cloud.positions)
            pts = np.take(cloud.positions, perm, axis=0)
        with progress.stage("k-d tree", m):
            tree = kdtree(as_points(pts))
            # scan lines: the neighbourhoods along a line need 2k neighbours (cells.py): one query
            lines = linear_share(tree, pts, k, max_anisotropy) > PREDICT_SHARE and m > 2 * k
        wide = None
        with progress.stage(f"{2 * k if lines else k}-nearest neighbours", m):
            if lines:
                wide = knn(pts, 2 * k, presorted=True, tree=tree)
                dist, idx = np.ascontiguousarray(wide[0][:, :k]), np.ascontiguousarray(wide[1][:, :k])
            else:
                dist, idx = knn(pts, k, presorted=True, tree=tree)
        spacing = float(np.median(dist[:, -1]))
        if not merge:
            break
        tolerance = DUPLICATE_FRACTION * spacing
        with progress.stage("duplicates", m):
            rep_sorted = near_duplicates(dist, idx, tolerance)
            if rep_sorted is None:
                break
            if not hashed and (dist[:, -1] == 0).any():
                rep = exact_duplicates(cloud.positions)  # k + 1 or more copies of a point: all at once
                hashed = True
            else:
                # the group's first point in input order represents it
                first = np.full(m, m, dtype=np.int64)
                np.minimum.at(first, rep_sorted, perm)
                rep = np.empty(m, dtype=np.int64)
                rep[perm] = first[rep_sorted]
            merged = rep != np.arange(m)
            exact += int((cloud.positions[merged] == cloud.positions[rep[merged]]).all(axis=1).sum())
            cloud = merge_points(cloud, rep)
            origin = origin[~merged]
    duplicates = n - len(cloud)
    if duplicates:
        progress.message(f"  {duplicates:,} duplicate points merged ({exact:,} at the same position, the others "
                         f"closer than {tolerance:.3g})")
    report = PreprocessReport(n, len(cloud), duplicates=duplicates, exact_duplicates=exact,
                              duplicate_tolerance=tolerance, spacing=spacing, kept=origin)
    return cloud, report, (perm, pts, dist, idx, tree, wide), k


def _sized(pts, normals, idx, dist, rows, cell_axes, shape, coverage, max_anisotropy, sharp_angle, oriented,
           refine):
    """Splat axes (and sharp features) when they were not computed with the normals.

    Sharp features re-fit ``normals`` where ``refine``; the rows ``rows`` take the (oriented)
    Voronoi-cell axes ``cell_axes = (u, v)`` unless their normal changed. Returns
    ``(u, v, features or None)``.
    """
    n = len(pts)
    features = None
    new_normals = normals
    if sharp_angle is not None:
        with progress.stage("sharp features", n):
            features = detect_sharp_features(pts, normals, idx, sharp_angle, oriented=oriented, refine_normals=refine)
        progress.message(f"  {int(features.feature.sum()):,} points at sharp features "
                         f"({features.candidates:,} examined)")
        new_normals = features.normals
    with progress.stage(f"splat {shape}s", n):
        if shape == "ellipse":
            u, v = elliptical_splats(pts, new_normals, idx, dist, coverage=coverage, max_anisotropy=max_anisotropy)
        else:
            u, v = circular_splats(new_normals, dist, coverage=coverage)
    if cell_axes is not None:
        same = (new_normals[rows] == normals[rows]).all(axis=1)
        u[rows[same]] = cell_axes[0][same]
        v[rows[same]] = cell_axes[1][same]
    return u, v, features


def estimated_normals(pts: np.ndarray, idx: np.ndarray, dist: np.ndarray, orient: bool = True) -> np.ndarray:
    """(N, 3) float32 unit PCA normals of points ``pts`` (model units) over their kNN ``idx``, as stages.

    Oriented consistently (Hoppe et al. 1992, MST) when ``orient``;
    ``dist``: the kNN distances (model units), which speed up the orientation.
    Each step is reported through :func:`surfsplat.progress.stage`.
    """
    n = len(pts)
    with progress.stage("normals (PCA)", n):
        normals = estimate_normals(pts, idx)
    if orient:
        with progress.stage("orientation (MST)", n):
            normals = orient_normals(pts, normals, idx, dist)
    return normals


def _unsort(arr: np.ndarray, perm: np.ndarray) -> np.ndarray:
    """(N, c) rows of ``arr`` (in the order ``perm``) back in the input order."""
    out = np.empty_like(arr)
    for c in range(arr.shape[1]):  # column scatters: ~2x faster than scattering 12-byte rows
        out[perm, c] = arr[:, c]
    return out


def _add_clip_lines(cloud: SplatCloud, sharp_angle: float) -> SplatCloud:
    """Clip lines for a cloud that has its splats (normals, u, v) already; normals unchanged."""
    n = len(cloud)
    with progress.stage("spatial sort", n):
        perm = spatial_order(cloud.positions)
        pts = np.take(cloud.positions, perm, axis=0)
    with progress.stage("8-nearest neighbours", n):
        _, idx = knn(pts, min(8, n - 1), presorted=True)
    with progress.stage("sharp features", n):
        features = detect_sharp_features(pts, np.take(cloud.normals, perm, axis=0), idx, sharp_angle,
                                         oriented=True, refine_normals=False)
        lines = feature_clip_lines(features, pts, np.take(cloud.u, perm, axis=0), np.take(cloud.v, perm, axis=0))
    out = np.empty_like(lines)
    out[perm] = lines
    return cloud.replace(clip_lines=out)


def neighbour_spacing(positions, k: int = 1, sample: int | None = None, seed: int = 0) -> dict:
    """Statistics of the distance from a point to its k-th nearest neighbour.

    For an ``info`` command: the sampling density of a cloud.

    Args:
        positions: (N, 3) float array (or a SplatCloud), model units, N >= k + 1.
        k: which neighbour (1 = nearest; the point itself excluded).
        sample: if given and smaller than N, only this many randomly chosen
            points are queried (the tree holds all points): a fast estimate
            for very large clouds.
        seed: random seed of the sample.

    Returns:
        dict with float ``min``, ``median``, ``mean``, ``max`` (model units)
        and int ``count`` (points queried) and ``zero`` (queried points with
        a coincident duplicate as k-th neighbour, distance 0).
    """
    if isinstance(positions, SplatCloud):
        positions = positions.positions
    points = as_points(positions)
    n = len(points)
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise InputError(f"neighbour_spacing: k must be a positive integer, got {k!r}")
    if n < k + 1:
        raise InputError(f"neighbour_spacing: need at least {k + 1} points, got {n}")
    if sample is not None and sample < n:
        query = np.sort(np.random.default_rng(seed).choice(n, size=int(sample), replace=False))
    else:
        query = np.arange(n)
    tree = cKDTree(points, leafsize=LEAFSIZE, balanced_tree=False, compact_nodes=False)
    dist, _ = tree.query(points[query], k=k + 1, workers=-1)
    # result 0 is the point itself (or a duplicate at distance 0): result k is
    # the k-th other point either way
    d = dist[:, k]
    return {
        "min": float(d.min()),
        "median": float(np.median(d)),
        "mean": float(d.mean()),
        "max": float(d.max()),
        "count": int(len(d)),
        "zero": int((d == 0).sum()),
    }
