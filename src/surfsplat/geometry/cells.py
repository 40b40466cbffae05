"""Splats where the k nearest neighbours do not span the surface: scan lines (Voronoi-cell ellipses).

Pajarola's covering ellipse (:mod:`.splats`) takes the shape of the k nearest neighbours. On
airborne-LiDAR scan lines, points are several times denser along a line than across: all k
nearest neighbours lie on the point's own line. Measured on a synthetic 5:1 scan (40 lines,
:func:`surfsplat.scenes_faulty.scan_lines`), the old construction gave PCA normals lying *in* the
plane (median ``|n_z|`` 0.014: the smallest eigenvector of a line of points is any direction
across it) and needles along the line (axis ratio at the cap of 4, minor semi-axis 1.6 point
spacings for a line gap of 5 spacings): standing splats, holes between the lines.

For such a point (a *linear* neighbourhood: ``lambda_2 < lambda_1 / max_anisotropy^2``, i.e. the
one where Pajarola's axis ratio hits its cap) this module uses a larger neighbourhood of
``K = 2 k`` points (``4 k`` where those still lie on a line), which reaches the adjacent lines:

1. the tangent plane: PCA of the K neighbours (Hoppe et al. 1992, sec. 3.2), unless normals
   are given;
2. the point's Voronoi cell in that plane, among the K projected neighbours: the cells tile
   the surface, so splats that contain their cells leave no hole (the same argument as the
   covering ellipses of Pajarola 2003, sec. 3.4, with the cell in place of the neighbours).
   The cell is traced by ``RAYS`` rays from the point, each stopped at the nearest bisector
   ``{x : x . o_j = |o_j|^2 / 2}`` of a neighbour offset ``o_j``, plus the exact vertex where two
   consecutive rays hit different bisectors (their intersection). Directions where no
   neighbour bounds the cell (a genuine line of points: a wire, a trunk) are cut at the
   distance to the k-th nearest neighbour;
3. the ellipse takes the shape of the cell's second moments (``sqrt(lambda_1 / lambda_2)``,
   capped at ``max_anisotropy``), is scaled so that every cell vertex lies inside (Pajarola's
   ``f = max sqrt(x^2/a'^2 + y^2/b'^2)`` over the vertices), then by ``coverage``. On a 5:1
   lattice of spacing d the bare ellipse is 3.2 d across the line and 0.8 d along it: the
   across-line axis comes from the real across-line spacing;
4. new neighbour rows for the orientation graph: the k neighbours nearest in that ellipse's
   metric (they include the adjacent lines, so the lines' normals are oriented together).

Circles (``shape="circle"``): the radius is the distance to the farthest cell vertex times
``coverage`` (Guennebaud 2003 eq. 7's ``h_k`` over the cell instead of the k neighbours).
"""

from __future__ import annotations

import numpy as np

from ..frames import tangent_frame
from .common import BLOCK, columns, neighbour_offsets, parallel
from .neighbors import knn_rows
from .normals import smallest_eigenvectors

#: Neighbours of a linear neighbourhood's second look: K = k * f for f in LINEAR_K_FACTORS, the
#: larger only where the smaller still lies on a line. 16 neighbours (k = 8) reach the adjacent
#: lines of scan lines up to ~6 times denser along than across, 32 up to ~10 times.
LINEAR_K_FACTORS = (2, 4)

#: Rays that trace a Voronoi cell (every 22.5 degrees); the vertices between them are exact.
RAYS = 16

#: Points sampled by :func:`linear_share`, and the share of linear ones above which
#: preprocessing queries 2k neighbours for every point in one go.
PREDICT_SAMPLE = 2048
PREDICT_SHARE = 0.5

#: Points per block of the cell kernel: (K, B) float32 temporaries of ~0.5 MB.
CELL_BLOCK = BLOCK // 4

_ANGLES = 2.0 * np.pi * np.arange(RAYS) / RAYS
_COS = np.cos(_ANGLES).astype(np.float32)
_SIN = np.sin(_ANGLES).astype(np.float32)


def _cell_polygon(x: np.ndarray, y: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary of each point's Voronoi cell among its neighbours, in its tangent plane.

    x, y: (K, B) float32 neighbour offsets in the tangent frame (model units); bound: (B,)
    float32 cut of the cell's radius. Returns (2 RAYS, B) float32 vertex coordinates of the
    polygon in counter-clockwise order: ray hits alternating with cell vertices.

    The ray in direction ``e`` meets the bisector of the offset ``o_j`` at the distance
    ``|o_j|^2 / (2 o_j . e)`` (where ``o_j . e > 0``): the nearest bisector is the one with the
    largest ``w_j = 2 o_j . e / |o_j|^2``.
    """
    k, b = x.shape
    q = x * x + y * y
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(q > 0, 2.0 / q, 0.0).astype(np.float32)  # coincident projections bound nothing
    xs, ys = x * scale, y * scale
    cols = np.arange(b)
    who = np.empty((RAYS, b), dtype=np.intp)
    best = np.empty((RAYS, b), dtype=np.float32)
    w = np.empty_like(xs)
    tmp = np.empty_like(xs)
    for m in range(RAYS):
        np.multiply(xs, _COS[m], out=w)
        np.multiply(ys, _SIN[m], out=tmp)
        w += tmp
        who[m] = np.argmax(w, axis=0)  # the nearest bisector along the ray
        best[m] = w[who[m], cols]
    with np.errstate(divide="ignore"):
        hit = np.where(best > 0, 1.0 / best, np.inf).astype(np.float32)
    open_ = ~(hit <= bound)
    hit = np.where(open_, bound, hit)
    rx = hit * _COS[:, None]
    ry = hit * _SIN[:, None]
    # vertex between ray m and ray m + 1: the intersection of their two bisectors
    a, c = who, np.roll(who, -1, axis=0)
    xa, ya, qa = x[a, cols], y[a, cols], q[a, cols]
    xc, yc, qc = x[c, cols], y[c, cols], q[c, cols]
    det = xa * yc - xc * ya
    with np.errstate(divide="ignore", invalid="ignore"):
        vx = (qa * yc - qc * ya) / (2.0 * det)
        vy = (xa * qc - xc * qa) / (2.0 * det)
    ok = ~open_ & ~np.roll(open_, -1, axis=0) & (a != c) & np.isfinite(vx) & np.isfinite(vy)
    ok &= vx * vx + vy * vy <= bound * bound
    vx = np.where(ok, vx, rx)
    vy = np.where(ok, vy, ry)
    px = np.empty((2 * RAYS, b), dtype=np.float32)
    py = np.empty((2 * RAYS, b), dtype=np.float32)
    px[0::2], px[1::2] = rx, vx
    py[0::2], py[1::2] = ry, vy
    return px, py


def _cell_ellipses(x, y, bound, coverage: float, max_anisotropy: float, k: int):
    """Covering ellipses of the Voronoi cells, for one block (see the module docstring).

    Returns ``(c, s, major, minor, radius, nearest)``: (B,) direction cosine and sine of the
    major axis in the tangent frame, (B,) float32 semi-axes and circle radius (model units,
    ``coverage`` included) and (k, B) positions (into the K neighbours) of the k neighbours
    nearest in the ellipse's metric.
    """
    px, py = _cell_polygon(x, y, bound)
    px64, py64 = px.astype(np.float64), py.astype(np.float64)
    x1, y1 = np.roll(px64, -1, axis=0), np.roll(py64, -1, axis=0)
    cross = px64 * y1 - x1 * py64
    # second moments of the polygon about the point (Green's theorem)
    ixx = (cross * (px64 * px64 + px64 * x1 + x1 * x1)).sum(axis=0) / 12.0
    iyy = (cross * (py64 * py64 + py64 * y1 + y1 * y1)).sum(axis=0) / 12.0
    ixy = (cross * (px64 * y1 + 2.0 * px64 * py64 + 2.0 * x1 * y1 + x1 * py64)).sum(axis=0) / 24.0
    half = 0.5 * (ixx - iyy)
    disc = np.sqrt(half * half + ixy * ixy)
    mid = 0.5 * (ixx + iyy)
    lam1, lam2 = mid + disc, mid - disc
    theta = 0.5 * np.arctan2(2.0 * ixy, ixx - iyy)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lam2 > 0, np.sqrt(lam1 / lam2), max_anisotropy)
    ratio = np.clip(np.nan_to_num(ratio, nan=1.0), 1.0, max_anisotropy).astype(np.float32)
    c = np.cos(theta).astype(np.float32)
    s = np.sin(theta).astype(np.float32)
    # Pajarola 2003 sec. 3.4 covering rule over the cell's vertices
    ex = (px * c + py * s) / ratio
    ey = py * c - px * s
    f = np.sqrt((ex * ex + ey * ey).max(axis=0)) * np.float32(1.0 + 1e-5)
    radius = np.sqrt((px * px + py * py).max(axis=0)) * np.float32(coverage)
    minor = f * np.float32(coverage)
    major = minor * ratio
    # the k neighbours nearest in the ellipse's metric (for the orientation graph)
    nx = (x * c + y * s) / ratio
    ny = y * c - x * s
    metric = nx * nx + ny * ny
    nearest = np.argpartition(metric, k - 1, axis=0)[:k] if k < len(x) else np.broadcast_to(
        np.arange(len(x))[:, None], x.shape)
    return c, s, major, minor, radius, nearest


def linear_share(tree, pts: np.ndarray, k: int, max_anisotropy: float, sample: int = PREDICT_SAMPLE,
                 seed: int = 0) -> float:
    """Share of linear k-neighbourhoods (see the module docstring) among ``sample`` random points.

    ``tree``: the k-d tree of ``pts`` ((N, 3), model units). Where most neighbourhoods are
    linear (scan lines), :func:`surfsplat.geometry.preprocess` queries 2k neighbours for all
    points at once instead of k, then 2k again for the linear ones (~0.8 s less per million).
    """
    n = tree.n
    rows = np.sort(np.random.default_rng(seed).choice(n, size=min(n, sample), replace=False))
    _, idx = knn_rows(tree, rows, min(k, n - 1))
    d = [(col[idx] - col[rows, None]).T.astype(np.float32) for col in (pts[:, 0], pts[:, 1], pts[:, 2])]
    m = np.float32(idx.shape[1] + 1)
    mean = [o.sum(axis=0) / m for o in d]
    cov = [(np.einsum("ij,ij->j", d[a], d[b]) / m - mean[a] * mean[b]).astype(np.float64)
           for a, b in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
    lam = smallest_eigenvectors(*cov, with_eigenvalues=True)[1]
    return float((lam[:, 1] * (max_anisotropy * max_anisotropy) < lam[:, 0]).mean())


def linear_splats(tree, pts: np.ndarray, rows: np.ndarray, k: int, bound: np.ndarray, normals: np.ndarray | None,
                  *, shape: str, coverage: float, max_anisotropy: float, neighbours=None):
    """Normals, splat axes and neighbour rows for the points ``rows`` from their Voronoi cells.

    See the module docstring. Args: ``tree`` the k-d tree of ``pts`` ((N, 3) float32, model
    units, as :func:`~surfsplat.geometry.neighbors.knn` returns it); ``rows`` (R,) int
    indices of the linear points; ``k`` the neighbours of the ordinary rows; ``bound`` (R,)
    float32 cut of the cells' radius (model units: the distance to the k-th neighbour);
    ``normals`` (R, 3) given normals of those points, or None to estimate them by PCA of the
    K neighbours; ``shape`` ``"ellipse"`` or ``"circle"``; ``coverage``, ``max_anisotropy``
    as in :func:`~surfsplat.geometry.splats.elliptical_splats`; ``neighbours``: optional
    ``(dist, idx)``, the (N, 2k) nearest neighbours of all points if known (skips a query).

    Returns:
        ``(normals, eigenvalues, u, v, idx, dist)``: (R, 3) float32 unit normals (unoriented
        when estimated), (R, 3) float64 covariance eigenvalues of the K-neighbourhoods
        (descending, model units squared), (R, 3) float32 axes (model units), and (R, k) int64
        neighbour indices and float32 distances (ascending), the k neighbours nearest in the
        ellipse's metric.
    """
    r = len(rows)
    out = (np.empty((r, 3), dtype=np.float32), np.empty((r, 3), dtype=np.float64), np.empty((r, 3), dtype=np.float32),
           np.empty((r, 3), dtype=np.float32), np.empty((r, k), dtype=np.int64), np.empty((r, k), dtype=np.float32))
    todo = np.arange(r)
    for factor in LINEAR_K_FACTORS:
        big = min(factor * k, tree.n - 1)
        known = neighbours if neighbours is not None and neighbours[0].shape[1] == big else None
        part = _cells(tree, pts, rows[todo], k, big, bound[todo], None if normals is None else normals[todo],
                      shape, coverage, max_anisotropy, known)
        for o, p in zip(out, part):
            o[todo] = p
        if big == tree.n - 1:
            break
        lam = part[1]
        todo = todo[lam[:, 1] * (max_anisotropy * max_anisotropy) < lam[:, 0]]  # still on a line
        if not len(todo):
            break
    return out


def _cells(tree, pts, rows, k, big, bound, normals, shape, coverage, max_anisotropy, known=None):
    """:func:`linear_splats` with ``big`` neighbours for all ``rows`` (``known``: (dist, idx) of all points)."""
    if known is None:
        dist_k, idx_k = knn_rows(tree, rows, big)
        where = None
    else:
        (dist_k, idx_k), where = known, rows
    r = len(rows)
    out_n = np.empty((r, 3), dtype=np.float32)
    out_l = np.empty((r, 3), dtype=np.float64)
    out_u = np.empty((r, 3), dtype=np.float32)
    out_v = np.empty((r, 3), dtype=np.float32)
    out_i = np.empty((r, k), dtype=np.int64)
    out_d = np.empty((r, k), dtype=np.float32)
    cols = columns(pts)

    def block(sl):
        at = sl if where is None else where[sl]
        nb, nd = idx_k[at], dist_k[at]
        d = neighbour_offsets(cols, rows[sl], nb)   # (K, B) each
        m = np.float32(big + 1)
        mean = [o.sum(axis=0) / m for o in d]
        cov = [(np.einsum("ij,ij->j", d[a], d[b]) / m - mean[a] * mean[b]).astype(np.float64)
               for a, b in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
        nrm, lam = smallest_eigenvectors(*cov, with_eigenvalues=True)
        if normals is not None:
            nrm = normals[sl]
        t1, t2 = tangent_frame(nrm)
        x = d[0] * t1[:, 0] + d[1] * t1[:, 1] + d[2] * t1[:, 2]
        y = d[0] * t2[:, 0] + d[1] * t2[:, 1] + d[2] * t2[:, 2]
        c, s, major, minor, radius, nearest = _cell_ellipses(x, y, bound[sl], coverage, max_anisotropy, k)
        if shape == "circle":
            u, v = t1 * radius[:, None], t2 * radius[:, None]
        else:
            cc, ss = c[:, None], s[:, None]
            u = (t1 * cc + t2 * ss) * major[:, None]
            v = (t2 * cc - t1 * ss) * minor[:, None]
        near = nearest.T
        sel_d = np.take_along_axis(nd, near, axis=1)
        order = np.argsort(sel_d, axis=1)
        out_n[sl], out_l[sl], out_u[sl], out_v[sl] = nrm, lam, u, v
        out_i[sl] = np.take_along_axis(np.take_along_axis(nb, near, axis=1), order, axis=1)
        out_d[sl] = np.take_along_axis(sel_d, order, axis=1)

    parallel(block, [slice(s, min(s + CELL_BLOCK, r)) for s in range(0, r, CELL_BLOCK)])
    return out_n, out_l, out_u, out_v, out_i, out_d
