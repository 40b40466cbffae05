"""Sharp features of raw points: detection (planes on either side) and clip lines from them.

Where a neighbourhood's normals spread, it is split into up to three planar
groups (:mod:`.planes`), a least-squares plane is fitted to each, and planes
more than the threshold apart are the faces on either side of an edge or
corner (Zwicker et al. 2004, section 5). Used by
:func:`surfsplat.geometry.preprocess.preprocess` (and by the Phong splat
generator, for samples without clip lines).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...cloud import NO_CLIP
from ...errors import InputError
from ..common import check_oriented_points, check_vectors, columns, dot, first_of_runs, for_blocks, parallel
from ..neighbors import QUERY_CHUNK, kdtree
from .lines import check_sharp_angle, lines_from_halfspaces
from .planes import group_planes

#: Neighbours per point for feature detection on raw points (the point itself
#: excluded). It should reach the other side of a feature wherever a splat
#: crosses it: ellipse splats' major axes are ~1.8x the 8-neighbour radius
#: (median on random samples), 32 neighbours reach ~2x. Larger splats take
#: the planes of the feature points nearest to them (:func:`feature_clip_lines`).
SHARP_NEIGHBOURS = 32

#: Nearest feature points whose planes a splat may take.
_SOURCES = 32

#: Points per block of the raw-point detection (rows of (B, k + 1, 3) arrays).
_BLOCK = 4096


@dataclass
class SharpFeatures:
    """Sharp features detected in a point cloud (:func:`detect_sharp_features`).

    Attributes:
        normals: (N, 3) float32 unit normals: the least-squares plane of the
            point's own face at feature points (when refined), else the input.
        planes: (N, 2, 4) float64 ``(n, d)``: the planes of the other faces in
            the neighbourhood as half-spaces ``n . (x - p) <= d`` relative to
            the point ``p``, containing the point's own face; ``(0, 0, 0, 1)``
            where unused. :func:`feature_clip_lines` turns them into clip lines
            once the splat axes are known.
        feature: (N,) bool, points whose neighbourhood holds two or three
            planes more than ``sharp_angle`` apart (at least one plane stored).
        candidates: number of points that the normal-spread pre-test sent to
            the plane analysis.
        reach: (N,) float32 radius of each candidate's neighbourhood, model
            units (0 elsewhere): its planes are faces within this distance.
        sharp_angle: the threshold used, degrees.
        oriented: whether the normals were taken as consistently oriented.
    """

    normals: np.ndarray
    planes: np.ndarray
    feature: np.ndarray
    candidates: int
    reach: np.ndarray
    sharp_angle: float
    oriented: bool


def detect_sharp_features(positions, normals, indices, sharp_angle: float, *, neighbours: int = SHARP_NEIGHBOURS,
                          oriented: bool = True, refine_normals: bool = True) -> SharpFeatures:
    """Sharp edges and corners of a point cloud, from normal discontinuities in each neighbourhood.

    Clip lines come from "intersecting the tangent planes of adjacent
    reconstruction kernels on either side of a feature" (Zwicker 2004,
    section 5). Here the tangent plane of each side is fitted to the points
    of that side, over the point and its ``neighbours`` (32) nearest points:

    1. Where to look. Seeds (all points, over the small neighbourhoods
       ``indices`` of the normal estimation): a neighbour's normal is more
       than ``sharp_angle / 4`` from the point's own; normals turn across a
       feature within a band about one such neighbourhood wide, so every
       feature has seeds, and smooth surfaces few. The wide neighbourhoods
       are then queried only for points within 1.25x a seed's
       wide-neighbourhood radius of it (where theirs may hold the seed).
       Pre-test on them: a neighbour's normal deviates from their normalized
       mean by more than ``sharp_angle / 3``. If two faces' normals differ by
       more than the angle, the mean lies between them and is at least half
       the angle from one of them (a third: margin for normals blended across
       the feature). Only these candidates go on.
    2. Split the neighbourhood into up to three planar groups (greedy, like
       RANSAC with deterministic hypotheses): every neighbour's normal gives
       a hypothesis, the plane through that neighbour; the hypothesis with
       the most remaining points within ``_INLIER`` (1 %) of the
       neighbourhood radius takes them as a group; repeated on the rest (the
       rest becomes the last group at once when all of it fits one plane).
       PCA normals are blended across a feature (they average both faces),
       but those of points a neighbourhood away from it are exact, and so
       are the planes through them.
    3. Least-squares plane per group (PCA of its points), points moved to the
       nearest plane within the tolerance (others are left out), refitted
       twice. Groups of fewer than 4 points (any 3 are coplanar) or nearly
       collinear ones fit no plane;
       planes within ``sharp_angle`` of each other are merged.
    4. Where two or three planes remain, the point's own group is the plane
       nearest to it: its normal becomes the point's normal
       (``refine_normals``; the PCA normal is wrong there; also where no
       other plane could be fitted but the own face is exactly planar, RMS
       residual below 0.1 % of the radius, e.g. next to a corner whose other
       faces are slivers of a few points). Each other plane
       is stored as the half-space on the side of the own group's centroid:
       its intersection with the splat's plane is the clip line (points near,
       not on, the feature get it too, whenever their neighbourhood holds
       the other side).

    Vectorized over blocks of points (a thread per core); no per-point
    Python loop. Assumes samples with noise well below 1 % of the
    neighbourhood radius (scans of CAD parts, mesh samples).

    Args:
        positions: (N, 3) float, model units.
        normals: (N, 3) float unit normals (e.g. PCA over 8 neighbours, oriented).
        indices: (N, k) int small neighbourhoods (e.g. the k = 8 of the
            normal estimation, from :func:`~surfsplat.geometry.neighbors.knn`),
            for the seeds.
        sharp_angle: degrees in (0, 180): planes more than this apart are
            separate faces.
        neighbours: size of the wide neighbourhoods (default ``SHARP_NEIGHBOURS``
            = 32); their radius should reach the splats' extent.
        oriented: the normals are consistently oriented; else they are axes
            (compared after flipping each to the point's own normal, so
            normals more than 90 degrees apart read as 180 minus their angle).
        refine_normals: replace the normals of feature points by their own
            plane's normal (off for normals that came with the data).

    Returns:
        :class:`SharpFeatures`.
    """
    sharp_angle = check_sharp_angle(sharp_angle)
    pts, nrm, idx = check_oriented_points(positions, normals, indices)
    n = len(pts)
    neighbours = int(neighbours)
    if neighbours < 1:
        raise InputError(f"detect_sharp_features: neighbours must be >= 1, got {neighbours}")
    out_normals = nrm.copy()
    planes = np.zeros((n, 2, 4))
    planes[:, :, 3] = 1.0
    feature = np.zeros(n, dtype=bool)
    reach = np.zeros(n, dtype=np.float32)
    result = SharpFeatures(out_normals, planes, feature, 0, reach, sharp_angle, oriented)
    cols = columns(nrm)
    seeds = _seeds(cols, idx, sharp_angle, oriented)
    kq = min(neighbours, n - 1)
    if len(seeds) == 0 or kq < 2:
        return result
    full = _wide_neighbourhoods(pts, seeds, kq, reach)
    rows = np.flatnonzero(_pretest(cols, full, sharp_angle, oriented))      # into full
    result.candidates = int(len(rows))
    cos_sharp = math.cos(math.radians(sharp_angle))

    def block(start):
        sel = rows[start:start + _BLOCK]
        nb = full[sel]
        point = nb[:, 0]
        x = pts[nb].astype(np.float64) - pts[point].astype(np.float64)[:, None, :]   # offsets, (B, K1, 3)
        nn = nrm[nb].astype(np.float64)
        if not oriented:
            nn *= np.where((nn * nn[:, :1]).sum(axis=2) < 0, -1.0, 1.0)[..., None]
        own_n, pl, feat, refined = group_planes(x, nn, cos_sharp, oriented)
        if refine_normals:
            out_normals[point[refined]] = own_n[refined]
        planes[point] = pl
        feature[point] = feat

    parallel(block, range(0, len(rows), _BLOCK))
    return result


def _seeds(cols: list[np.ndarray], idx: np.ndarray, sharp_angle: float, oriented: bool) -> np.ndarray:
    """Step 1a: the seed points (ids), over the small neighbourhoods ``idx``.

    A neighbour's normal (``cols``: the normals' columns) more than a quarter
    of ``sharp_angle`` (degrees) from the point's own. Normals turn across a
    feature within a band about one such neighbourhood wide, so every feature
    has seeds.
    """
    n = len(idx)
    seed = np.zeros(n, dtype=bool)
    cos_seed = math.cos(math.radians(sharp_angle / 4.0))

    def seed_test(sl):
        it = np.ascontiguousarray(idx[sl].T)                           # neighbour slot first: (k, B)
        dots = cols[0][it] * cols[0][sl] + cols[1][it] * cols[1][sl] + cols[2][it] * cols[2][sl]
        seed[sl] = (dots if oriented else np.abs(dots)).min(axis=0) < cos_seed

    for_blocks(seed_test, n)
    return np.flatnonzero(seed)


def _wide_neighbourhoods(pts: np.ndarray, seeds: np.ndarray, kq: int, reach: np.ndarray) -> np.ndarray:
    """Step 1b: (R, kq + 1) intp wide neighbourhoods (the point itself first) where one may hold a seed.

    Only the points within 1.25x a seed's own wide-neighbourhood radius of it
    (similar density nearby). Writes each such point's neighbourhood radius
    (model units) into ``reach``.
    """
    points = pts.astype(np.float64)
    tree = kdtree(points)
    seed_radius = np.empty(len(seeds))
    for start in range(0, len(seeds), QUERY_CHUNK):
        chunk = seeds[start:start + QUERY_CHUNK]
        seed_radius[start:start + len(chunk)] = tree.query(points[chunk], k=[kq + 1], workers=-1)[0][:, 0]
    near, which = cKDTree(points[seeds]).query(points, k=1, distance_upper_bound=1.25 * seed_radius.max(),
                                               workers=-1)
    found = which < len(seeds)
    region = np.flatnonzero(found & (near < 1.25 * seed_radius[np.where(found, which, 0)]))
    full = np.empty((len(region), kq + 1), dtype=np.intp)               # the point itself first
    for start in range(0, len(region), QUERY_CHUNK):
        rows = region[start:start + QUERY_CHUNK]
        dist, nb = tree.query(points[rows], k=kq + 1, workers=-1)
        # the point itself is usually first; coincident duplicates may precede it or push
        # it out: drop it where it is, else the farthest result
        is_self = nb == rows[:, None]
        is_self[~is_self.any(axis=1), -1] = True
        full[start:start + len(rows), 0] = rows
        full[start:start + len(rows), 1:] = nb[~is_self].reshape(len(rows), kq)
        reach[rows] = dist[:, -1]
    return full


def _pretest(cols: list[np.ndarray], full: np.ndarray, sharp_angle: float, oriented: bool) -> np.ndarray:
    """Step 1c: (R,) bool, the wide neighbourhoods ``full`` that go on to the plane analysis.

    A normal more than a third of ``sharp_angle`` (degrees) from their mean:
    two faces more than the angle apart put one at least half of it away.
    """
    cos_pre = math.cos(math.radians(sharp_angle / 3.0))
    candidate = np.zeros(len(full), dtype=bool)

    def pretest(sl):
        it = np.ascontiguousarray(full[sl].T)                          # (K1, B)
        g = [col[it] for col in cols]
        if not oriented:
            flip = np.where(g[0] * g[0][0] + g[1] * g[1][0] + g[2] * g[2][0] < 0, -1.0, 1.0).astype(np.float32)
            g = [gc * flip for gc in g]
        mean = [gc.sum(axis=0) for gc in g]
        length = np.maximum(np.sqrt(mean[0] ** 2 + mean[1] ** 2 + mean[2] ** 2), 1e-30)
        dots = g[0] * mean[0] + g[1] * mean[1] + g[2] * mean[2]
        candidate[sl] = dots.min(axis=0) < cos_pre * length

    for_blocks(pretest, len(full))
    return candidate


def feature_clip_lines(features: SharpFeatures, positions, u, v) -> np.ndarray:
    """Clip lines ``(a, b, c)`` of splats from the feature planes of :func:`detect_sharp_features`.

    A splat's candidate planes are those of the feature points nearest to it
    (``_SOURCES`` = 32 of them, itself first when it is one, found with a k-d
    tree over the feature points) on the same side of the feature (normal
    within ``sharp_angle`` of the splat's), each moved to the splat's center:
    a splat larger than its neighbourhood still gets the feature that points
    closer to it found. Kept, in order of distance: the first candidate whose
    line crosses the splat, and the first after it whose plane differs from
    the first's by more than ``sharp_angle`` (a corner's second face).

    Args:
        features: the :class:`SharpFeatures` of these points.
        positions: (N, 3) float splat centers, model units.
        u, v: (N, 3) float scaled tangent axes of the splats, model units
            (in the planes of ``features.normals``).

    Returns:
        (N, 2, 3) float32 clip lines in normalized ``(s, t)``, kept where
        ``a s + b t + c >= 0``; ``(0, 0, 1)`` where unused. Used lines come first.
    """
    pts = check_vectors(positions, "positions")
    n = len(pts)
    u = check_vectors(u, "u", n).astype(np.float64)
    v = check_vectors(v, "v", n).astype(np.float64)
    planes = np.asarray(features.planes, dtype=np.float64)
    if planes.shape != (n, 2, 4) or len(features.normals) != n:
        raise InputError(f"feature_clip_lines: features of {len(planes)} points for {n} splats")
    lines = np.broadcast_to(NO_CLIP, (n, 2, 3)).astype(np.float32)
    sources = np.flatnonzero(features.feature)
    if len(sources) == 0:
        return lines
    radius = np.sqrt(np.maximum(np.einsum("ij,ij->i", u, u), np.einsum("ij,ij->i", v, v)))
    reach = np.asarray(features.reach, dtype=np.float64)
    # a source's planes are faces within its neighbourhood radius of it
    bound = float(radius.max() + reach[sources].max())
    tree = cKDTree(pts[sources].astype(np.float64))
    nearest, _ = tree.query(pts, k=1, distance_upper_bound=bound, workers=-1)
    rows = np.flatnonzero(nearest < radius + reach[sources].max())
    nrm = np.asarray(features.normals, dtype=np.float64)
    cos_sharp = math.cos(math.radians(features.sharp_angle))
    oriented = features.oriented
    k = min(_SOURCES, len(sources))

    def block(start):
        sel = rows[start:start + _BLOCK]
        m = len(sel)
        p = pts[sel].astype(np.float64)
        dist, hit = tree.query(p, k=k, distance_upper_bound=float(radius[sel].max() + reach[sources].max()))
        dist, hit = dist.reshape(m, k), hit.reshape(m, k)
        found = hit < len(sources)
        src = sources[np.where(found, hit, 0)]                              # (m, k) feature points
        same = (nrm[src] * nrm[sel][:, None, :]).sum(axis=2)
        same = (same if oriented else np.abs(same)) > cos_sharp
        usable = found & same & (dist < radius[sel][:, None] + reach[src])
        # candidate planes of the usable sources, in order of row, then distance, then slot
        row, slot = np.nonzero(usable)
        j = src[row, slot]
        row, j, plane = np.repeat(row, 2), np.repeat(j, 2), np.tile([0, 1], len(row))
        cand = planes[j, plane]                                             # (P, 4)
        present = np.abs(cand[:, :3]).sum(axis=1) > 0
        row, j, cand = row[present], j[present], cand[present]
        # move the source's half-space n . (x - q) <= d to this splat's center p
        cand_n = cand[:, :3]
        cand_d = cand[:, 3] + dot(cand_n, pts[j].astype(np.float64) - p[row])
        line, crossing = lines_from_halfspaces(cand_n, cand_d, u[sel][row], v[sel][row])
        ok = np.flatnonzero(crossing)
        first = ok[first_of_runs(row[ok])]
        first_of = np.full(m, -1)
        first_of[row[first]] = first
        rest = ok[dot(cand_n[ok], cand_n[first_of[row[ok]]]) < cos_sharp]
        second = rest[first_of_runs(row[rest])]
        out = np.broadcast_to(NO_CLIP, (m, 2, 3)).astype(np.float32)
        out[row[first], 0] = line[first]
        out[row[second], 1] = line[second]
        lines[sel] = out

    parallel(block, range(0, len(rows), _BLOCK))
    return lines
