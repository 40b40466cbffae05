"""Phong splat generation (Botsch, Spernat & Kobbelt 2004, section 3).

From dense samples with normals to far fewer elliptical splats with linear
normal fields that cover every sample within an error tolerance ``eps``: a
sample ``p_i`` is covered by splat ``S_j`` when it lies in the elliptical
cylinder of the splat offset by ``+-eps`` along its plane normal (Botsch 2004,
sec. 3, after eq. 1), i.e. its projection into the plane is inside the
ellipse and its distance from the plane is at most ``eps``.

Stages (each reported through :func:`surfsplat.progress.stage`), in the
spirit of Wu & Kobbelt 2004 ([WK04], the generator Botsch 2004 uses):

1. samples: validation, spatial (Morton) order, a k-d tree; PCA normals
   oriented by the MST (Hoppe 1992) when the cloud has none; with
   ``sharp_angle``, the half-spaces of the faces across sharp edges (from the
   samples' own clip lines, or :func:`~surfsplat.geometry.sharp.detect_sharp_features`).
2. candidates: a splat per seed sample, grown over its nearest neighbours in
   rings of increasing size (x 1.25 each) while the least-squares plane of the
   grown set keeps every member within ``eps`` (the splat's covered set
   ``P_j``). The neighbours are ranked by an anisotropic distance that follows
   the local principal curvatures ([WK04]: ellipses aligned to the principal
   directions): from the covariance of the neighbours' normals, so that
   candidates stretch along the flat direction, up to ``MAX_ANISOTROPY``.
   Seeds: a random subset of about ``SEED_FACTOR`` candidates per splat (a
   pilot of ``PILOT_SEEDS`` seeds measures the typical splat size and the
   neighbourhood sizes needed: candidates that outgrow the one enough for
   half of them grow again over a larger one), then every sample no
   candidate covered.
3. greedy cover: candidates that cover the most not-yet-covered samples
   are picked, vectorized in rounds: each round takes every candidate whose
   gain (with a random tie-break) is the largest among all candidates sharing
   an uncovered sample with it, exactly like the sequential greedy locally.
4. fit (vectorized over splats): least-squares plane (centroid and smallest
   eigenvector of the covariance of ``P_j``), tangent axes along the principal
   directions (Botsch 2004, sec. 3: eigenvectors of the two smaller
   eigenvalues of ``sum n_i n_i^T``, projected into the plane; the point
   covariance's axes where that is isotropic, e.g. on a plane), the
   smallest enclosing ellipse with these axes (a 1-D convex minimisation
   over the axis ratio, bounded by ``MAX_ANISOTROPY``), grown by a surface
   margin (``SURFACE_MARGIN``: the enclosing ellipses cover the samples but
   not the surface between them), the splat's orientation from the sum of
   its samples' normals, and the linear normal field of eq. 3-4.
5. relaxation (``relax`` iterations, after [WK04]'s global relaxation):
   redundant splats (all their samples covered by others) are dropped, every
   sample goes to the covering splat it is most central in (smallest
   ``s^2 + t^2``), and each splat is re-fitted to its samples (re-centred;
   its old plane is kept where the new one breaks the tolerance or fits no
   surface). Every step keeps every sample covered.
6. with ``sharp_angle``: clip lines where a splat reaches over a sharp edge
   (Botsch 2004, sec. 4, ``(a, b, c)`` in ``(s, t)``) from the half-spaces of
   the edge samples on the splat's side; splats that still claim samples of
   another face (a hole in the face, a third edge) are replaced by splats
   grown to at most two, then no, other faces (``REPAIR_FACES``); last, the
   surface margin of any splat that still does is reduced.

Normal field convention (:mod:`surfsplat.cloud`): ``n(s, t) = normals + s
alpha u_hat + t beta v_hat`` with ``(s, t)`` the splat's normalized
coordinates. ``u x v`` is the splat's plane normal, ``normals`` the fitted
center normal (which generally differs from it, Botsch 2004 sec. 3).
"""

from __future__ import annotations

import itertools
import math
import numbers
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .. import progress as report
from ..cloud import NO_CLIP, SplatCloud
from ..errors import InputError
from .neighbors import _LEAFSIZE, knn, spatial_order
from .normals import _for_blocks, _parallel, estimate_normals, orient_normals, smallest_eigenvectors
from .sharp import _lines_from_halfspaces, _pack_lines, check_sharp_angle, detect_sharp_features
from .splats import MAX_ANISOTROPY, tangent_frame

#: Default cap of the neighbourhood a candidate splat grows over (the most
#: samples one splat can cover). The neighbourhood actually queried is sized
#: by the pilot, usually far smaller.
MAX_NEIGHBOURS = 1024

#: Candidate seeds per expected splat in the first round (the greedy cover
#: picks among about this many candidates per sample).
SEED_FACTOR = 16.0

#: Seeds of the pilot run that sizes the neighbourhoods and the seed count.
PILOT_SEEDS = 1000

#: Growth factor of the neighbour rings a candidate grows over.
RING_GROWTH = 1.25

#: Neighbours whose normals give a seed's curvature anisotropy (growth metric),
#: and the largest axis ratio of that metric.
METRIC_NEIGHBOURS = 16
GROWTH_ANISOTROPY = MAX_ANISOTROPY

#: Neighbours of the PCA normal estimation (as :func:`surfsplat.geometry.preprocess`).
NORMAL_NEIGHBOURS = 8

#: Surface margin: the smallest enclosing ellipse covers the samples, not the
#: surface between them (neighbouring splats' ellipses meet at samples and
#: leave holes). Each splat's axes grow by ``margin`` (default
#: ``SURFACE_MARGIN``) times the mean distance of its samples to their
#: ``GAP_NEIGHBOURS``-th nearest sample. Measured on 50 k uniformly random
#: samples of the unit sphere (exact normals, relax 2; fraction of 400 k random
#: surface points in no ellipse, median growth of the axes), for eps 1e-4 /
#: 1e-3 / 1e-2 (~5 / ~26 / ~220 samples per splat): margin 0: 63 % / 7.7 % /
#: 0.4 % holes; 0.5: 2.7 % / 0.1 % / 2e-5 (axes +161 % / +31 % / +10 %);
#: 0.75: 9e-4 / 5e-5 / 0 (+241 % / +46 % / +14 %).
SURFACE_MARGIN = 0.75
GAP_NEIGHBOURS = 8

#: Samples whose normal is more than ~75 degrees from the splat's plane normal
#: (``|n_i . n| < 0.25``) are left out of the normal-field fit: their
#: homogeneous coordinates (Botsch 2004, fig. 1) would be huge outliers.
MIN_NORMAL_COS = 0.25

#: The normal covariance is "isotropic" (no principal direction: planes,
#: spheres) when its two smaller eigenvalues differ by less than this fraction
#: of their sum; the point covariance's axes are used there.
ISOTROPIC_GAP = 0.2

#: Golden-section iterations of the ellipse's axis ratio (interval x 0.618 each).
RATIO_ITERATIONS = 28

#: Splats per relaxation query: a sample is assigned among its nearest splat centers.
RELAX_NEIGHBOURS = 8

#: Count mode: the largest default neighbourhood (few splats for many samples).
MAX_COUNT_NEIGHBOURS = 4096

#: Count mode: relative tolerance of the splat count, and search iterations.
COUNT_TOLERANCE = 0.03
COUNT_ITERATIONS = 14

#: Count mode on large inputs: first search on a random subsample of this size.
COUNT_SUBSAMPLE = 200_000

#: With ``sharp_angle``: a candidate stops growing before it reaches samples
#: of more than ``OTHER_FACES`` faces across sharp edges (two clip lines can
#: cut two off). Splats that still claim samples of another face after
#: clipping, or reach over an edge no line represents (a hole inside the
#: ellipse, a third edge), are replaced, round i, by candidates that reach at
#: most ``REPAIR_FACES[i]`` other faces. Measured on the CAD part (60 k
#: samples, two sample sets): (2, 0) gives ~5 % more splats than (1, 0) and
#: 0.3-0.7 dB better Phong shading on its curved faces; (0, 0) ~15 % more
#: splats than (2, 0) for about the same shading.
OTHER_FACES = 2
REPAIR_ROUNDS = 2
REPAIR_FACES = (2, 0)

#: Clip lines: edge samples a splat takes half-spaces from (at most), the angle
#: by which a second line must differ from the first (a corner), the largest
#: shift (in splat radii) a line may get to keep the splat's samples, and the
#: cut (in splat radii) from which an edge that no line represents counts.
CLIP_SOURCES = 32
SECOND_LINE_ANGLE = 20.0
MAX_LINE_SHIFT = 0.25
MIN_CUT = 0.05

#: Relative tightening of the tolerance and absolute slack (in float32 ulps of
#: the coordinates) so that the float32 output still covers every sample.
_EPS_MARGIN = 1e-4
_ULPS = 8.0 * 2.0 ** -24

#: A least-squares plane more than 45 degrees from the samples' normals (the
#: seed's while growing) fits no surface (e.g. a few samples along one arc).
_MIN_PLANE_COS = math.cos(math.radians(45.0))

#: Re-fitted planes (relaxation) more than 20 degrees from their samples' mean
#: normal are not taken (samples along an arc): the old plane is kept.
_MIN_MEAN_COS = math.cos(math.radians(20.0))

#: Relative margin on the ellipse axes (float32 rounding of the farthest sample).
_ELLIPSE_MARGIN = 1e-5

#: Entries (seeds x neighbours) per growth block.
_BLOCK_ENTRIES = 1 << 18


# -- public API -------------------------------------------------------------------------------------


@dataclass
class PhongResult:
    """Phong splats and how they were made (:func:`phong_fit`).

    Attributes:
        splats: the :class:`SplatCloud` of Phong splats (see :func:`phong_splats`).
        error: the tolerance used, model units (found by the search in count mode).
        samples: number of (valid) input samples.
        member_ptr, member_idx: CSR of the samples each splat was fitted to
            (its covered set ``P_j``): splat ``j`` covers the samples
            ``member_idx[member_ptr[j]:member_ptr[j + 1]]``, row indices of
            the validated input (``cloud.validated()``; the input's own rows
            when none was dropped). Every sample appears at least once.
    """

    splats: SplatCloud
    error: float
    samples: int
    member_ptr: np.ndarray
    member_idx: np.ndarray


def phong_splats(cloud: SplatCloud, error: float | None = None, *, count: int | None = None,
                 k: int | None = None, sharp_angle: float | None = None, relax: int = 2,
                 margin: float = SURFACE_MARGIN, progress: bool | None = None,
                 source: str = "input") -> SplatCloud:
    """Phong splats (Botsch, Spernat & Kobbelt 2004, sec. 3) that cover every sample within ``error``.

    Args:
        cloud: dense samples: a :class:`SplatCloud` (or an (N, 3) array of
            positions), with normals (oriented consistently) or without
            (then estimated by PCA over 8 neighbours and oriented by the MST,
            as :func:`~surfsplat.geometry.preprocess.preprocess` does). Colors
            are averaged per splat. Invalid rows are dropped with a warning.
        error: the tolerance ``eps`` in model units, > 0: every sample lies in
            some splat's ellipse (projected into its plane) within ``eps`` of
            its plane (the elliptical cylinder offset by ``+-eps``).
        count: instead of ``error``: the number of splats wanted, 1 to N.
            The tolerance is searched (secant/bisection on ``log eps`` over the
            whole pipeline) until the count is within ``COUNT_TOLERANCE`` (3 %);
            if no tolerance gets within 5 % (e.g. flat regions whose splats are
            capped by ``k``), the closest result is returned with a warning.
        k: the most neighbours (samples) a candidate splat grows over, >= 1:
            caps the samples per splat, and time and memory. Default (None):
            ``MAX_NEIGHBOURS`` (1024); in count mode up to
            ``MAX_COUNT_NEIGHBOURS`` (4096) where few splats need more.
        sharp_angle: None, or a dihedral angle in degrees in (0, 180): splats
            do not grow across edges sharper than this (a sample joins a splat
            only if its normal is within the angle of the seed's), and splats
            reaching over such an edge get clip lines ``(a, b, c)`` (Botsch
            2004, sec. 4). The edges come from the samples' own clip lines
            when the cloud has them (e.g. ``sample_mesh(..., sharp_angle=)``),
            else from :func:`~surfsplat.geometry.sharp.detect_sharp_features`.
            Splats that two lines cannot keep off other faces (a hole in the
            face, a third edge) are replaced by smaller ones, and their
            surface margin is reduced.
        relax: relaxation iterations (>= 0, default 2): redundant splats
            dropped, samples re-assigned to the covering splat they are most
            central in, splats re-fitted to them (coverage kept).
        margin: factor (>= 0, default 0.75) on the mean distance of a splat's
            samples to their 8th nearest sample, added to both semi-axes so
            that the surface between the samples is covered too, not only the
            samples (see ``SURFACE_MARGIN``); 0 gives the paper's bare smallest
            enclosing ellipses.
        progress: None (default) reports stages on stderr when
            :func:`surfsplat.progress.enable` is on; True or False forces it
            on or off for this call.
        source: name of the input in messages and warnings.

    Returns:
        A :class:`SplatCloud` (float32) with one row per splat: ``positions``
        the ellipse centers (the covered samples' centroid, on their
        least-squares plane); ``u``, ``v`` the scaled semi-axes spanning that
        plane (``u x v`` along the plane normal; ``u`` along the direction of
        largest normal variation); ``normals`` the unit center normal of the
        fitted linear normal field and ``normal_field`` ``(alpha, beta)`` so
        that ``normals + s alpha u_hat + t beta v_hat`` is the fitted normal at
        ``(s, t)`` (Botsch 2004, eq. 2-4, up to scale); ``colors`` the mean of
        the covered samples' colors (None without input colors); with
        ``sharp_angle``, ``clip_lines`` (N, 2, 3).

    Raises:
        InputError: neither or both of ``error`` and ``count``, a tolerance
            that is not a positive finite number, a count outside 1..N,
            bad ``k``, ``relax``, ``margin`` or ``sharp_angle``, or no valid
            samples.
    """
    return phong_fit(cloud, error, count=count, k=k, sharp_angle=sharp_angle, relax=relax, margin=margin,
                     progress=progress, source=source).splats


def phong_fit(cloud: SplatCloud, error: float | None = None, *, count: int | None = None,
              k: int | None = None, sharp_angle: float | None = None, relax: int = 2,
              margin: float = SURFACE_MARGIN, progress: bool | None = None,
              source: str = "input") -> PhongResult:
    """:func:`phong_splats` with the tolerance used and the samples each splat covers.

    Same arguments as :func:`phong_splats`; returns a :class:`PhongResult`.
    """
    if not isinstance(cloud, SplatCloud):
        cloud = SplatCloud(positions=cloud)
    error, count, k, relax, sharp_angle, margin = _check_arguments(error, count, k, relax, sharp_angle, margin)
    with report.enabled(progress):
        samples = _prepare(cloud, sharp_angle, source)
        samples.margin = margin
        n = len(samples.pts)
        if count is not None and count > n:
            raise InputError(f"{source}: count must be at most the number of samples ({n:,}), got {count:,}")
        if count is None:
            splats = _generate(samples, error, MAX_NEIGHBOURS if k is None else k, relax, np.random.default_rng(0))
        else:
            if k is None:
                # a cover overlaps ~2x, and anisotropic candidates use ~1/4 of their neighbourhood
                k = int(np.clip(8 * n // count, MAX_NEIGHBOURS, MAX_COUNT_NEIGHBOURS))
            error, splats = _search_count(samples, count, k, relax, source)
        out = _to_cloud(samples, splats)
        report.message(f"  {len(out):,} Phong splats for {n:,} samples (error {error:.4g}, "
                 f"{n / len(out):.1f} samples per splat)")
    # members in the order of the validated input
    member_idx = samples.perm[splats.idx]
    return PhongResult(out, float(error), n, splats.ptr.copy(), member_idx)


def phong_coverage(samples, splats: SplatCloud, *, clip_tolerance: float = 1e-4) -> np.ndarray:
    """Distance of each sample from the nearest splat plane whose ellipse contains it, model units.

    For checking a Phong splat cover: sample ``i`` is covered within ``eps``
    (Botsch 2004, sec. 3) when the result is ``<= eps``. A splat contains a
    sample when the sample's orthogonal projection into the splat's plane
    (``u x v``) has ``s^2 + t^2 <= 1`` and is on the kept side of its clip
    lines (``a s + b t + c >= -clip_tolerance``).

    Args:
        samples: (N, 3) positions or a :class:`SplatCloud`, model units.
        splats: splats with ``u`` and ``v``.
        clip_tolerance: slack of the clip-line test, in ``(s, t)`` units.

    Returns:
        (N,) float64: the smallest ``|distance from the plane|`` over the
        splats containing the sample, ``inf`` where none does. (Samples more
        than about one splat radius from a splat's plane are not tested
        against that splat.)
    """
    pts = np.asarray(samples.positions if isinstance(samples, SplatCloud) else samples, dtype=np.float64)
    if splats.u is None or splats.v is None:
        raise InputError("phong_coverage: the splats need axes u and v")
    center = splats.positions.astype(np.float64)
    u = splats.u.astype(np.float64)
    v = splats.v.astype(np.float64)
    normal = np.cross(u, v)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    radius = np.sqrt(np.maximum((u * u).sum(1), (v * v).sum(1)))
    best = np.full(len(pts), np.inf)
    if len(pts) == 0 or len(center) == 0:
        return best
    tree = cKDTree(pts, leafsize=_LEAFSIZE, balanced_tree=False)
    # a contained sample is within the splat's radius of its center along the
    # plane; the plane distance bound is unknown here, so search a bit wider
    reach = radius * 1.5 + 1e-12
    chunk = 4096
    for start in range(0, len(center), chunk):
        sl = slice(start, min(start + chunk, len(center)))
        hits = tree.query_ball_point(center[sl], reach[sl], workers=-1)
        counts = np.fromiter((len(h) for h in hits), dtype=np.int64, count=len(hits))
        if counts.sum() == 0:
            continue
        row = np.repeat(np.arange(sl.start, sl.stop), counts)
        idx = np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=int(counts.sum()))
        d = pts[idx] - center[row]
        s = _dot(d, u[row]) / _dot(u[row], u[row])
        t = _dot(d, v[row]) / _dot(v[row], v[row])
        inside = s * s + t * t <= 1.0
        if splats.clip_lines is not None:
            lines = splats.clip_lines[row].astype(np.float64)
            value = lines[:, :, 0] * s[:, None] + lines[:, :, 1] * t[:, None] + lines[:, :, 2]
            inside &= (value >= -clip_tolerance).all(axis=1)
        h = np.abs(_dot(d, normal[row]))
        np.minimum.at(best, idx[inside], h[inside])
    return best


# -- arguments, samples ------------------------------------------------------------------------------


def _check_arguments(error, count, k, relax, sharp_angle, margin):
    if (error is None) == (count is None):
        raise InputError("phong_splats: give exactly one of error (the tolerance eps, model units) "
                         "and count (the number of splats wanted)")
    if error is not None:
        if isinstance(error, bool) or not isinstance(error, numbers.Real) or not math.isfinite(error) or error <= 0:
            raise InputError(f"phong_splats: error must be a positive finite distance in model units, got {error!r}")
        error = float(error)
    if count is not None:
        if isinstance(count, bool) or not isinstance(count, numbers.Integral) or count < 1:
            raise InputError(f"phong_splats: count must be a positive integer, got {count!r}")
        count = int(count)
    if k is not None and (isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 1):
        raise InputError(f"phong_splats: k must be a positive integer (neighbours per splat), got {k!r}")
    if isinstance(relax, bool) or not isinstance(relax, numbers.Integral) or relax < 0:
        raise InputError(f"phong_splats: relax must be a non-negative integer (iterations), got {relax!r}")
    if sharp_angle is not None:
        sharp_angle = check_sharp_angle(sharp_angle, "phong_splats: sharp_angle")
    if isinstance(margin, bool) or not isinstance(margin, numbers.Real) or not (0 <= margin < math.inf):
        raise InputError(f"phong_splats: margin must be a non-negative finite factor, got {margin!r}")
    return error, count, None if k is None else int(k), int(relax), sharp_angle, float(margin)


@dataclass
class _Samples:
    """The input samples, spatially sorted (internal)."""

    pts: np.ndarray          # (n, 3) float64
    nrm: np.ndarray          # (n, 3) float64 unit, oriented
    colors: np.ndarray | None
    perm: np.ndarray         # sorted row -> validated input row
    tree: cKDTree
    cos_sharp: float | None
    halfspaces: np.ndarray | None   # (n, 2, 4) n . (x - p) <= d relative to the sample; zeros = none
    reach: np.ndarray | None        # (n,) how far from the sample its half-spaces are valid
    spacing: float           # typical distance to the nearest sample
    slack: float             # float32 resolution of the coordinates, model units
    gap: np.ndarray          # (n,) float32 distance to the 8th nearest sample (the surface margin's unit)
    margin: float = SURFACE_MARGIN

    def subset(self, rows: np.ndarray) -> "_Samples":
        """The samples ``rows`` (sorted ascending) as their own set (count-mode subsampling)."""
        pts = self.pts[rows]
        return _Samples(pts, self.nrm[rows], None if self.colors is None else self.colors[rows],
                        self.perm[rows], _tree(pts), self.cos_sharp,
                        None if self.halfspaces is None else self.halfspaces[rows],
                        None if self.reach is None else self.reach[rows], self.spacing, self.slack,
                        self.gap[rows], self.margin)


def _tree(pts: np.ndarray) -> cKDTree:
    return cKDTree(pts, leafsize=_LEAFSIZE, balanced_tree=False, compact_nodes=True)


def _prepare(cloud: SplatCloud, sharp_angle: float | None, source: str) -> _Samples:
    """Validate, sort, estimate/orient normals, find sharp features (stage 1)."""
    cloud = cloud.validated(source)
    n = len(cloud)
    with report.stage("spatial sort and k-d tree", n):
        perm = spatial_order(cloud.positions)
        pts32 = np.take(cloud.positions, perm, axis=0)
        pts = pts32.astype(np.float64)
        tree = _tree(pts)
    normals_given = cloud.normals is not None
    idx = dist = None
    if not normals_given or (sharp_angle is not None and cloud.clip_lines is None):
        if n < 3:
            raise InputError(f"{source}: estimating normals needs at least 3 samples, got {n}")
        kk = min(NORMAL_NEIGHBOURS, n - 1)
        with report.stage(f"{kk}-nearest neighbours", n):
            dist, idx = knn(pts32, kk, presorted=True)
    if normals_given:
        nrm = np.take(cloud.normals, perm, axis=0)
    else:
        with report.stage("normals (PCA)", n):
            nrm = estimate_normals(pts32, idx)
        with report.stage("orientation (MST)", n):
            nrm = orient_normals(pts32, nrm, idx, dist)
    colors = None if cloud.colors is None else np.take(cloud.colors, perm, axis=0)
    halfspaces = reach = None
    cos_sharp = None
    if sharp_angle is not None:
        cos_sharp = math.cos(math.radians(sharp_angle))
        if cloud.clip_lines is not None and cloud.u is not None and cloud.v is not None:
            lines = np.take(cloud.clip_lines, perm, axis=0)
            u = np.take(cloud.u, perm, axis=0)
            v = np.take(cloud.v, perm, axis=0)
            halfspaces, reach = _halfspaces_from_lines(lines, u, v)
        else:
            with report.stage("sharp features", n):
                features = detect_sharp_features(pts32, nrm, idx, sharp_angle, oriented=True,
                                                 refine_normals=not normals_given)
            nrm = features.normals
            halfspaces = np.asarray(features.planes, dtype=np.float64)
            halfspaces[~features.feature] = 0.0
            reach = np.asarray(features.reach, dtype=np.float64)
            report.message(f"  {int(features.feature.sum()):,} samples at sharp features")
    nrm = np.asarray(nrm, dtype=np.float64)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    # typical sample spacing: median nearest-neighbour distance of up to 4096 samples
    probe = np.linspace(0, n - 1, min(n, 4096)).astype(np.int64)
    if n > 1:
        d, _ = tree.query(pts[probe], k=2)
        positive = d[:, 1][d[:, 1] > 0]
        spacing = float(np.median(positive)) if len(positive) else 1.0
    else:
        spacing = 1.0
    slack = _ULPS * float(np.abs(pts).max()) if n else 0.0
    if dist is not None and dist.shape[1] == min(GAP_NEIGHBOURS, n - 1):
        gap = dist[:, -1].astype(np.float32)
    else:
        with report.stage("sample spacing", n):
            gap = _kth_distance(tree, pts, min(GAP_NEIGHBOURS, n - 1))
    return _Samples(pts, nrm, colors, perm, tree, cos_sharp, halfspaces, reach, spacing, slack, gap)


def _kth_distance(tree: cKDTree, pts: np.ndarray, k: int) -> np.ndarray:
    """(n,) float32 distance of each point to its k-th nearest other point (0 when k = 0)."""
    out = np.zeros(len(pts), dtype=np.float32)
    if k < 1:
        return out

    def block(sl):
        d, _ = tree.query(pts[sl], k=k + 1)
        out[sl] = d.reshape(-1, k + 1)[:, -1]

    _for_blocks(block, len(pts))
    return out


def _halfspaces_from_lines(lines: np.ndarray, u: np.ndarray, v: np.ndarray):
    """Half-spaces ``n . (x - p) <= d`` (n unit) of the samples' own clip lines, and their reach.

    A line ``a s + b t + c >= 0`` on the splat ``p + s u + t v`` reads
    ``g . (x - p) + c >= 0`` with ``g = a u / |u|^2 + b v / |v|^2``: the
    half-space through the line, orthogonal to the sample's plane.
    """
    u = u.astype(np.float64)
    v = v.astype(np.float64)
    lines = lines.astype(np.float64)
    uu = (u * u).sum(1)[:, None]
    vv = (v * v).sum(1)[:, None]
    g = lines[:, :, 0:1] * (u / uu)[:, None, :] + lines[:, :, 1:2] * (v / vv)[:, None, :]     # (n, 2, 3)
    length = np.linalg.norm(g, axis=2)
    used = (length > 0) & (np.abs(lines - NO_CLIP) > 0).any(axis=2)
    safe = np.where(used, length, 1.0)
    out = np.zeros(lines.shape[:2] + (4,))
    out[..., :3] = np.where(used[..., None], -g / safe[..., None], 0.0)
    out[..., 3] = np.where(used, lines[:, :, 2] / safe, 0.0)
    reach = np.sqrt(np.maximum(uu, vv))[:, 0]
    return out, reach


# -- stage 2: candidates -----------------------------------------------------------------------------


@dataclass
class _Candidates:
    """Candidate splats (internal): members CSR, plane, growth statistics."""

    ptr: np.ndarray       # (S + 1,) int64
    idx: np.ndarray       # (M,) int64 sample rows, seed first
    centroid: np.ndarray  # (S, 3) float64
    normal: np.ndarray    # (S, 3) float64 unit (sign arbitrary)
    rank: np.ndarray      # (S,) int64: neighbourhood size the members needed
    limited: np.ndarray   # (S,) bool: ran out of neighbours before the tolerance stopped it

    @property
    def sizes(self) -> np.ndarray:
        return np.diff(self.ptr)


def _rings(limit: int) -> np.ndarray:
    """Ring sizes 4, 5, 6, 8, 10, ... (x RING_GROWTH) below ``limit``, then ``limit``."""
    sizes = []
    m = 4
    while m < limit:
        sizes.append(m)
        m = max(m + 1, int(math.ceil(m * RING_GROWTH)))
    sizes.append(limit)
    return np.asarray(sizes, dtype=np.int64)


def _grow(samples: _Samples, seeds: np.ndarray, k: int, eps: float, faces: int = OTHER_FACES) -> _Candidates:
    """Grow a candidate splat at each seed over its k nearest neighbours (stage 2).

    With ``sharp_angle``, a candidate stops before samples of more than
    ``faces`` faces across sharp edges fall within its neighbourhood ring.
    """
    seeds = np.asarray(seeds, dtype=np.int64)
    block = max(16, _BLOCK_ENTRIES // (k + 2))
    starts = list(range(0, len(seeds), block))
    parts: dict[int, tuple] = {}

    def run(start):
        parts[start] = _grow_block(samples, seeds[start:start + block], k, eps, faces)

    _parallel(run, starts)
    pieces = [parts[s] for s in starts]
    sizes = np.concatenate([p[0] for p in pieces])
    ptr = np.zeros(len(seeds) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ptr[1:])
    return _Candidates(ptr, np.concatenate([p[1] for p in pieces]), np.concatenate([p[2] for p in pieces]),
                       np.concatenate([p[3] for p in pieces]), np.concatenate([p[4] for p in pieces]),
                       np.concatenate([p[5] for p in pieces]))


def _curvature_metric(nn: np.ndarray, valid: np.ndarray, t1: np.ndarray, t2: np.ndarray, sign: np.ndarray):
    """Anisotropy of the growth metric from the neighbours' normals ([WK04]: principal curvatures).

    The tangential parts of the (sign-aligned) normals vary along the
    principal directions by ``sigma_i ~ |kappa_i| r``; a plane stays within
    the tolerance over ``|kappa_i| x_i^2 ~ const``. Returns ``(w, c, s)``:
    the weight (>= 1, at most ``MAX_ANISOTROPY^2``) of the direction of
    largest normal variation ``c t1 + s t2``; the other direction has weight 1.
    """
    a = ((nn * t1[:, None, :]).sum(2) * sign)
    b = ((nn * t2[:, None, :]).sum(2) * sign)
    w = valid.astype(np.float64)
    cnt = np.maximum(w.sum(1), 1.0)
    ma, mb = (a * w).sum(1) / cnt, (b * w).sum(1) / cnt
    caa = (a * a * w).sum(1) / cnt - ma * ma
    cab = (a * b * w).sum(1) / cnt - ma * mb
    cbb = (b * b * w).sum(1) / cnt - mb * mb
    half = 0.5 * (caa - cbb)
    disc = np.sqrt(half * half + cab * cab)
    mid = 0.5 * (caa + cbb)
    lam1 = np.maximum(mid + disc, 0.0)
    lam2 = np.maximum(mid - disc, 0.0)
    theta = 0.5 * np.arctan2(2.0 * cab, caa - cbb)
    cap = GROWTH_ANISOTROPY ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lam2 > 0, np.sqrt(lam1 / lam2), np.where(lam1 > 0, cap, 1.0))
    return np.clip(np.nan_to_num(ratio, nan=1.0), 1.0, cap), np.cos(theta), np.sin(theta)


def _next_face(delta: np.ndarray, other: np.ndarray, nn: np.ndarray, cos_sharp: float, faces: int) -> np.ndarray:
    """(B,) ``delta`` of the nearest sample of face number ``faces + 1`` across sharp edges (inf: none).

    ``other`` marks the samples on the other side of a sharp edge from the
    seed; faces are told apart by normals more than ``sharp_angle`` apart.
    """
    rows = np.arange(len(delta))
    mask = other
    for _ in range(faces):
        d = np.where(mask, delta, np.inf)
        first = np.argmin(d, axis=1)
        n1 = nn[rows, first]
        mask = mask & (np.einsum("blk,bk->bl", nn, n1) <= cos_sharp)
    return np.where(mask, delta, np.inf).min(axis=1)


def _grow_block(samples: _Samples, seeds: np.ndarray, k: int, eps: float, faces: int):
    """:func:`_grow` for one block of seeds: (sizes, members, centroids, normals, ranks, limited)."""
    pts, nrm = samples.pts, samples.nrm
    b_count = len(seeds)
    dist, hits = samples.tree.query(pts[seeds], k=k + 1)
    dist = dist.reshape(b_count, k + 1)
    hits = hits.reshape(b_count, k + 1)
    ids = np.concatenate([seeds[:, None], hits], axis=1)                     # (B, L), column 0 the seed
    width = ids.shape[1]
    invalid = np.zeros(ids.shape, dtype=bool)
    invalid[:, 1:] = hits == seeds[:, None]                                  # the seed found again
    reach = dist[:, -1]                                                      # all samples within it are here
    p0 = pts[seeds]
    off = pts[ids]
    off -= p0[:, None, :]
    n0 = nrm[seeds]
    nn = nrm[ids]
    cosang = np.einsum("blk,bk->bl", nn, n0)
    other = None
    if samples.cos_sharp is not None:
        # splats do not grow across sharp edges: only samples on the seed's side
        other = ~invalid & (cosang <= samples.cos_sharp)
        invalid |= other
    t1, t2 = (t.astype(np.float64) for t in tangent_frame(n0))
    x = np.einsum("blk,bk->bl", off, t1)
    y = np.einsum("blk,bk->bl", off, t2)
    z = np.einsum("blk,bk->bl", off, n0)
    head = min(width, METRIC_NEIGHBOURS + 1)
    weight, c, s = _curvature_metric(nn[:, :head], ~invalid[:, :head], t1, t2,
                                     np.where(cosang[:, :head] < 0, -1.0, 1.0))
    along = x * c[:, None] + y * s[:, None]
    across = y * c[:, None] - x * s[:, None]
    # anisotropic distance >= the Euclidean one, so that every sample with
    # delta <= reach is among the k + 1 found: the valid prefix is complete
    delta = weight[:, None] * along * along + across * across + z * z
    beyond = delta > (reach * reach)[:, None]
    walled = np.zeros(b_count, dtype=bool)           # stopped by faces, not by the neighbourhood's size
    if other is not None:
        # at most two other faces within the splat: two clip lines can represent them
        limit = _next_face(delta, other & ~beyond, nn, samples.cos_sharp, faces)
        invalid |= delta >= limit[:, None]
        walled = np.isfinite(limit)
    delta[invalid | beyond] = np.inf
    count = np.isfinite(delta).sum(axis=1)                                   # >= 1 (the seed)
    # the valid samples first, in order of delta; the rest is never used
    width = int(count.max())
    order = np.argsort(delta, axis=1, kind="stable")[:, :width]
    ids = np.take_along_axis(ids, order, axis=1)
    off = np.take_along_axis(off, order[..., None], axis=1)
    # prefix moments of the offsets (relative to the seed: no cancellation)
    ox, oy, oz = off[..., 0], off[..., 1], off[..., 2]
    moments = [np.cumsum(m, axis=1) for m in (ox, oy, oz, ox * ox, ox * oy, ox * oz, oy * oy, oy * oz, oz * oz)]
    best = np.ones(b_count, dtype=np.int64)
    centroid = np.zeros((b_count, 3))
    normal = n0.copy()
    growing = count > 1
    failed = np.zeros(b_count, dtype=bool)
    for m in _rings(width):
        if not growing.any():
            break
        me = np.minimum(m, count)
        act = np.flatnonzero(growing & (me > best))
        if not len(act):
            continue
        mm = me[act]
        col = mm - 1
        sums = [mom[act, col] for mom in moments]
        inv = 1.0 / mm
        mean = np.stack(sums[:3], axis=1) * inv[:, None]
        cov = [sums[3] * inv - mean[:, 0] * mean[:, 0], sums[4] * inv - mean[:, 0] * mean[:, 1],
               sums[5] * inv - mean[:, 0] * mean[:, 2], sums[6] * inv - mean[:, 1] * mean[:, 1],
               sums[7] * inv - mean[:, 1] * mean[:, 2], sums[8] * inv - mean[:, 2] * mean[:, 2]]
        # Botsch 2004, sec. 3: least-squares plane (centroid, smallest eigenvector)
        nrm_fit = smallest_eigenvectors(*cov).astype(np.float64)
        nrm_fit /= np.linalg.norm(nrm_fit, axis=1, keepdims=True)
        # (nearly) collinear sets (e.g. samples along one arc) and planes far
        # from the seed's normal fit no surface: not taken, but the candidate
        # grows on; only a plane that breaks the tolerance stops it
        fits = _spread(cov) & (np.abs(_dot(nrm_fit, n0[act])) >= _MIN_PLANE_COS)
        span = int(mm.max())
        res = np.einsum("bjk,bk->bj", off[act, :span], nrm_fit) - (mean * nrm_fit).sum(1)[:, None]
        np.abs(res, out=res)
        res[np.arange(span)[None, :] >= mm[:, None]] = 0.0
        within = res.max(axis=1) <= eps
        ok = fits & within
        good = act[ok]
        best[good] = mm[ok]
        centroid[good] = mean[ok]
        normal[good] = nrm_fit[ok]
        growing[act[~within]] = False
        failed[act[~within]] = True
        growing[act[mm >= count[act]]] = False
    keep = np.arange(width)[None, :] < best[:, None]
    members = ids[keep]
    rank = np.where(keep, order, 0).max(axis=1)
    limited = ~failed & (best >= count) & ~walled
    return best, members, centroid + p0, normal, rank, limited


# -- stage 3: greedy cover ---------------------------------------------------------------------------


def _csr_take(ptr: np.ndarray, idx: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The member lists of ``rows`` as their own CSR ``(ptr, idx)``."""
    rows = np.asarray(rows, dtype=np.int64)
    out_ptr = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(ptr[rows + 1] - ptr[rows], out=out_ptr[1:])
    return out_ptr, idx[_csr_positions(ptr, rows)]


def _greedy_cover(ptr: np.ndarray, idx: np.ndarray, covered: np.ndarray, rng) -> np.ndarray:
    """Candidates picked by the greedy cover, in rounds (stage 3); marks their members in ``covered``.

    Greedy set cover [WK04]: take the candidate that covers the most samples
    not covered yet. Vectorized: in each round, every candidate whose key
    (gain, random tie-break) is the largest among the candidates containing
    each of its uncovered samples is taken, i.e. every candidate that the
    sequential greedy would take before any of its competitors. Competing
    candidates share no uncovered sample, so the round is order-independent.
    """
    s_count = len(ptr) - 1
    n = len(covered)
    cand = np.repeat(np.arange(s_count, dtype=np.int64), np.diff(ptr))
    mem = idx
    tie = rng.permutation(s_count).astype(np.int64)
    best = np.full(n, -1, dtype=np.int64)
    chosen = []
    while True:
        live = ~covered[mem]
        if not live.all():
            mem, cand = mem[live], cand[live]
        if not len(mem):
            break
        gain = np.bincount(cand, minlength=s_count)
        key = gain[cand] * s_count + tie[cand]
        best[mem] = -1
        np.maximum.at(best, mem, key)
        won = best[mem] == key
        wins = np.bincount(cand[won], minlength=s_count)
        pick = np.flatnonzero((wins == gain) & (gain > 0))
        chosen.append(pick)
        covered[_csr_take(ptr, idx, pick)[1]] = True
    return np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.int64)


def _pilot(samples: _Samples, pool: np.ndarray, eps: float, k_cap: int, rng,
           faces: int) -> tuple[int, int, float]:
    """Neighbourhood sizes and mean candidate size for ``eps`` from a few random seeds of ``pool``.

    Returns ``(k_first, k_full, mean size)``: ``k_first`` suffices for half
    the candidates (the rest, stretched along flat directions or bigger,
    grow again over ``k_full``, which suffices for 90 %).
    """
    n = len(samples.pts)
    cap = max(1, min(k_cap, n - 1))
    seeds = np.sort(rng.choice(pool, size=min(len(pool), PILOT_SEEDS), replace=False))
    k = min(cap, 64)
    while True:
        cand = _grow(samples, seeds, k, eps, faces)
        if cand.limited.mean() <= 0.1 or k >= cap:
            break
        k = min(cap, 4 * k)
    need = np.quantile(cand.rank, [0.5, 0.9]) * 1.25 + 8
    k_first, k_full = (int(np.clip(x, min(cap, 16), cap)) for x in need)
    if cand.limited.mean() > 0.1:
        k_full = cap
    return k_first, k_full, float(cand.sizes.mean())


def _grow_twice(samples: _Samples, seeds: np.ndarray, k_first: int, k_full: int, eps: float,
                faces: int) -> _Candidates:
    """:func:`_grow` over ``k_first`` neighbours, again over ``k_full`` where that was too few.

    The k-d tree query dominates and grows faster than linearly with k: most
    candidates need a small neighbourhood, a few (stretched along a flat
    direction) a large one.
    """
    cand = _grow(samples, seeds, k_first, eps, faces)
    redo = np.flatnonzero(cand.limited)
    if k_full <= k_first or not len(redo):
        return cand
    again = _grow(samples, seeds[redo], k_full, eps, faces)
    sizes = cand.sizes
    sizes[redo] = again.sizes
    keep = np.ones(len(seeds), dtype=bool)
    keep[redo] = False
    ptr = np.zeros(len(seeds) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ptr[1:])
    idx = np.empty(ptr[-1], dtype=np.int64)
    old_ptr, old_idx = _csr_take(cand.ptr, cand.idx, np.flatnonzero(keep))
    idx[_csr_positions(ptr, np.flatnonzero(keep))] = old_idx
    idx[_csr_positions(ptr, redo)] = again.idx
    for name in ("centroid", "normal", "rank", "limited"):
        getattr(cand, name)[redo] = getattr(again, name)
    return _Candidates(ptr, idx, cand.centroid, cand.normal, cand.rank, cand.limited)


def _csr_positions(ptr: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Positions in the member array of the members of ``rows``, row after row."""
    counts = ptr[rows + 1] - ptr[rows]
    start = np.zeros(len(rows), dtype=np.int64)
    np.cumsum(counts[:-1], out=start[1:])
    return np.arange(int(counts.sum()), dtype=np.int64) + np.repeat(ptr[rows] - start, counts)


def _cover(samples: _Samples, pool: np.ndarray, covered: np.ndarray, k_cap: int, work: float, rng, faces: int,
           stage) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stages 2-3: candidates and greedy cover of the samples ``pool``; marks them in ``covered``.

    Seeds: ``SEED_FACTOR`` per expected splat at random, then every sample
    left uncovered. Returns the picked candidates: members CSR ``(ptr, idx)``,
    centroids and plane normals.
    """
    with stage("pilot", min(len(pool), PILOT_SEEDS), "seeds"):
        k_first, k, mean_size = _pilot(samples, pool, work, k_cap, rng, faces)
    seed_count = int(min(len(pool), SEED_FACTOR * len(pool) / max(mean_size, 1.0)))
    seeds = np.sort(rng.choice(pool, size=seed_count, replace=False)) if seed_count < len(pool) else pool
    parts = []
    round_no = 0
    while len(seeds):
        round_no += 1
        with stage(f"candidates, round {round_no} ({k_first}, then {k} neighbours)", len(seeds), "seeds"):
            cand = _grow_twice(samples, seeds, k_first, k, work, faces)
        with stage("greedy cover", len(seeds), "candidates"):
            pick = _greedy_cover(cand.ptr, cand.idx, covered, rng)
        ptr, idx = _csr_take(cand.ptr, cand.idx, pick)
        parts.append((ptr, idx, cand.centroid[pick], cand.normal[pick]))
        seeds = pool[~covered[pool]]
    ptr, idx = _concat_csr([p[0] for p in parts], [p[1] for p in parts])
    return ptr, idx, np.concatenate([p[2] for p in parts]), np.concatenate([p[3] for p in parts])


# -- stage 4: fit -----------------------------------------------------------------------------------


@dataclass
class _Splats:
    """Fitted splats (internal), float64; members CSR into the sorted samples."""

    center: np.ndarray        # (J, 3) ellipse center (on the plane)
    normal: np.ndarray        # (J, 3) unit plane normal, oriented like the samples
    u_hat: np.ndarray         # (J, 3) unit axes, u_hat x v_hat = normal
    v_hat: np.ndarray
    a: np.ndarray             # (J,) semi-axes along u_hat, v_hat (with the surface margin)
    b: np.ndarray
    tight_a: np.ndarray       # (J,) the smallest enclosing ellipse's (cover bookkeeping)
    tight_b: np.ndarray
    center_normal: np.ndarray  # (J, 3) unit center normal of the field
    field: np.ndarray         # (J, 2) (alpha, beta) for the unit center normal
    colors: np.ndarray | None
    ptr: np.ndarray
    idx: np.ndarray
    lines: np.ndarray | None = None   # (J, 2, 3) float32 clip lines, with sharp_angle
    missing: np.ndarray | None = None  # (J,) bool: reaches over an edge without a line for it

    def take(self, rows: np.ndarray) -> "_Splats":
        """The splats ``rows``."""
        ptr, idx = _csr_take(self.ptr, self.idx, rows)
        pick = [None if x is None else x[rows] for x in (self.colors, self.lines, self.missing)]
        return _Splats(self.center[rows], self.normal[rows], self.u_hat[rows], self.v_hat[rows], self.a[rows],
                       self.b[rows], self.tight_a[rows], self.tight_b[rows], self.center_normal[rows],
                       self.field[rows], pick[0], ptr, idx, pick[1], pick[2])

    def resize(self, rows: np.ndarray, factor: float) -> None:
        """Keep ``factor`` of the (current) surface margin of the splats ``rows`` (in place).

        The normal field follows: ``alpha / a`` is the field's gradient along
        ``u_hat`` in model units, so alpha scales with the axis.
        """
        a = self.tight_a[rows] + factor * (self.a[rows] - self.tight_a[rows])
        b = self.tight_b[rows] + factor * (self.b[rows] - self.tight_b[rows])
        self.field[rows, 0] *= a / self.a[rows]
        self.field[rows, 1] *= b / self.b[rows]
        self.a[rows] = a
        self.b[rows] = b

    def concat(self, other: "_Splats") -> "_Splats":
        """These splats followed by ``other``'s."""
        ptr, idx = _concat_csr([self.ptr, other.ptr], [self.idx, other.idx])

        def cat(x, y):
            return None if x is None or y is None else np.concatenate([x, y])

        return _Splats(*(np.concatenate([getattr(self, f), getattr(other, f)]) for f in
                         ("center", "normal", "u_hat", "v_hat", "a", "b", "tight_a", "tight_b", "center_normal",
                          "field")),
                       cat(self.colors, other.colors), ptr, idx, cat(self.lines, other.lines),
                       cat(self.missing, other.missing))


def _segments(ptr: np.ndarray) -> np.ndarray:
    return np.repeat(np.arange(len(ptr) - 1, dtype=np.int64), np.diff(ptr))


def _segment_sum(values: np.ndarray, seg: np.ndarray, count: int) -> np.ndarray:
    """Per-segment sums of (M,) or (M, c) values."""
    if values.ndim == 1:
        return np.bincount(seg, weights=values, minlength=count)
    return np.stack([np.bincount(seg, weights=values[:, c], minlength=count) for c in range(values.shape[1])],
                    axis=1)


def _segment_outer(x: np.ndarray, seg: np.ndarray, count: int) -> np.ndarray:
    """(J, 3, 3) per-segment sums of ``x_i x_i^T``."""
    out = np.empty((count, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            out[:, i, j] = out[:, j, i] = np.bincount(seg, weights=x[:, i] * x[:, j], minlength=count)
    return out


def _principal_axes(aligned: np.ndarray, rel: np.ndarray, seg: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Unit ``u_hat`` in each splat's plane along the direction of largest normal variation.

    Botsch 2004, sec. 3: the eigenvectors of the two smaller eigenvalues of
    ``sum n_i n_i^T`` (here the middle one, the direction of maximum normal
    deviation = maximum curvature), projected into the plane. Where the two
    are about equal (planes, spheres) the major axis of the point covariance.
    """
    count = len(normal)
    lam, vec = np.linalg.eigh(_segment_outer(aligned, seg, count))
    axis = vec[:, :, 1]
    isotropic = lam[:, 1] - lam[:, 0] <= ISOTROPIC_GAP * (lam[:, 1] + lam[:, 0]) + 1e-12 * lam[:, 2]
    if isotropic.any():
        _, pvec = np.linalg.eigh(_segment_outer(rel, seg, count)[isotropic])
        axis[isotropic] = pvec[:, :, 2]
    axis = axis - _dot(axis, normal)[:, None] * normal
    length = np.linalg.norm(axis, axis=1)
    weak = length < 1e-6
    if weak.any():
        axis[weak] = tangent_frame(normal[weak])[0]
        length[weak] = np.linalg.norm(axis[weak], axis=1)
    return axis / length[:, None]


def _enclosing_ellipse(x: np.ndarray, y: np.ndarray, ptr: np.ndarray, seg: np.ndarray,
                       max_anisotropy: float = MAX_ANISOTROPY) -> tuple[np.ndarray, np.ndarray]:
    """Smallest ellipses with axes along x, y centred at 0 that enclose each segment's points.

    With fixed axes the area ``pi a b`` is, for the axis ratio ``rho = a / b``
    and ``b^2 = max_i (x_i^2 / rho^2 + y_i^2)``, proportional to
    ``g(r) = max_i (x_i^2 e^-r + y_i^2 e^r)`` with ``r = ln rho``: a maximum of
    convex functions, minimised by golden-section search over
    ``|r| <= ln max_anisotropy`` (vectorized over the segments).

    Returns ``(a, b)``: (J,) semi-axes along x and y (0 where all points are at 0).
    """
    xx, yy = x * x, y * y
    starts = ptr[:-1]

    def g(r):
        return np.maximum.reduceat(xx * np.exp(-r)[seg] + yy * np.exp(r)[seg], starts)

    bound = math.log(max_anisotropy)
    lo = np.full(len(starts), -bound)
    hi = np.full(len(starts), bound)
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - phi * (hi - lo), lo + phi * (hi - lo)
    fc, fd = g(c), g(d)
    for _ in range(RATIO_ITERATIONS):
        left = fc <= fd                          # the minimum is in [lo, d]
        hi = np.where(left, d, hi)
        lo = np.where(left, lo, c)
        new = np.where(left, hi - phi * (hi - lo), lo + phi * (hi - lo))
        fnew = g(new)
        c, d, fc, fd = (np.where(left, new, d), np.where(left, c, new),
                        np.where(left, fnew, fd), np.where(left, fc, fnew))
    r = np.where(fc <= fd, c, d)
    rho = np.exp(r)
    b = np.sqrt(np.maximum.reduceat(xx / (rho * rho)[seg] + yy, starts))
    return rho * b, b


def _solve_least_norm(g00, g01, g11, r0, r1):
    """Solutions of the symmetric PSD 2x2 systems ``[[g00, g01], [g01, g11]] x = r``.

    Least-norm (pseudo-inverse, Botsch 2004 after eq. 4 [GL89]) where a system
    is singular: a rank-1 matrix ``G = lambda e e^T`` (``lambda`` its trace)
    has ``G^+ = G / lambda^2``; a zero matrix gives 0.
    """
    det = g00 * g11 - g01 * g01
    trace = g00 + g11
    regular = det > 1e-9 * trace * trace
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.where(regular, 1.0 / np.where(regular, det, 1.0), 0.0)
        inv_t2 = np.where(trace > 0, 1.0 / np.where(trace > 0, trace * trace, 1.0), 0.0)
    x0 = np.where(regular, (g11 * r0 - g01 * r1) * inv_det, (g00 * r0 + g01 * r1) * inv_t2)
    x1 = np.where(regular, (g00 * r1 - g01 * r0) * inv_det, (g01 * r0 + g11 * r1) * inv_t2)
    return x0, x1


def _linear_field(s: np.ndarray, h: np.ndarray, w: np.ndarray, seg: np.ndarray, count: int):
    """Least-squares ``h_i ~ h_bar + slope s_i`` per splat: (h_bar, slope), least norm if singular.

    Botsch 2004, eq. 3 (and eq. 4 with ``t_i``, ``y_i``): the normal equations
    ``[[|P|, sum s], [sum s, sum s^2]] (h_bar, slope) = (sum h, sum h s)``,
    summed over the samples with weight ``w`` (0 = left out).
    """
    ws = w * s
    return _solve_least_norm(np.bincount(seg, weights=w, minlength=count),
                             np.bincount(seg, weights=ws, minlength=count),
                             np.bincount(seg, weights=ws * s, minlength=count),
                             np.bincount(seg, weights=w * h, minlength=count),
                             np.bincount(seg, weights=ws * h, minlength=count))


def _fit(samples: _Samples, ptr: np.ndarray, idx: np.ndarray, center: np.ndarray, normal: np.ndarray) -> _Splats:
    """Axes, ellipse, orientation, normal field and color of each splat on its plane (stage 4).

    ``center`` (J, 3) is a point of the plane (the members' centroid),
    ``normal`` (J, 3) its unit normal; ``ptr``, ``idx`` the members (>= 1 each).
    """
    count = len(ptr) - 1
    seg = _segments(ptr)
    rel = samples.pts[idx] - center[seg]
    nn = samples.nrm[idx]
    # orientation: the side of the samples' normals (sum; Botsch 2004 sec. 5:
    # only the splats need consistent orientation)
    flip = _dot(_segment_sum(nn, seg, count), normal) < 0
    normal = np.where(flip[:, None], -normal, normal)
    cos = _dot(nn, normal[seg])
    # the homogeneous normal representation cancels the samples' own signs
    aligned = nn * np.where(cos < 0, -1.0, 1.0)[:, None]
    cos = np.abs(cos)
    u_hat = _principal_axes(aligned, rel, seg, normal)
    v_hat = np.cross(normal, u_hat)
    x = _dot(rel, u_hat[seg])
    y = _dot(rel, v_hat[seg])
    tight_a, tight_b = _enclosing_ellipse(x, y, ptr, seg)
    # float32 rounding of the stored splat; a floor for single samples
    floor = 0.05 * samples.spacing
    tight_a = np.maximum(tight_a * (1.0 + _ELLIPSE_MARGIN) + samples.slack, floor)
    tight_b = np.maximum(tight_b * (1.0 + _ELLIPSE_MARGIN) + samples.slack, floor)
    # the surface between the samples: both semi-axes grow by the margin m
    # (for a circle exactly the points within m of it; see SURFACE_MARGIN)
    grow = samples.margin * _segment_sum(samples.gap[idx].astype(np.float64), seg, count) / np.diff(ptr)
    a = tight_a + grow
    b = tight_b + grow
    # Botsch 2004, eq. 3-4: (s_i, t_i) normalized coordinates, (x_i, y_i) the
    # normal on the offset tangent plane (fig. 1): n_i . u_hat / n_i . n
    s = x / a[seg]
    t = y / b[seg]
    usable = cos >= MIN_NORMAL_COS
    safe = np.where(usable, cos, 1.0)
    hx = _dot(aligned, u_hat[seg]) / safe
    hy = _dot(aligned, v_hat[seg]) / safe
    w = usable.astype(np.float64)
    xbar, alpha = _linear_field(s, hx, w, seg, count)
    ybar, beta = _linear_field(t, hy, w, seg, count)
    center_normal = normal + xbar[:, None] * u_hat + ybar[:, None] * v_hat
    length = np.linalg.norm(center_normal, axis=1)
    field = np.stack([alpha, beta], axis=1) / length[:, None]
    colors = None
    if samples.colors is not None:
        colors = _segment_sum(samples.colors[idx].astype(np.float64), seg, count) / np.diff(ptr)[:, None]
    return _Splats(center, normal, u_hat, v_hat, a, b, tight_a, tight_b, center_normal / length[:, None], field,
                   colors, ptr, idx)


def _planes(samples: _Samples, ptr: np.ndarray, idx: np.ndarray):
    """Least-squares planes of the member sets: (centroid, unit normal, max |distance|; inf: no plane)."""
    count = len(ptr) - 1
    seg = _segments(ptr)
    p = samples.pts[idx]
    centroid = _segment_sum(p, seg, count) / np.diff(ptr)[:, None]
    rel = p - centroid[seg]
    cov = [np.bincount(seg, weights=rel[:, i] * rel[:, j], minlength=count)
           for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
    normal = smallest_eigenvectors(*cov).astype(np.float64)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    err = np.maximum.reduceat(np.abs(_dot(rel, normal[seg])), ptr[:-1])
    # fewer than 3 samples or (nearly) collinear ones define no plane; one far
    # from the samples' normals fits no surface
    aligned = samples.nrm[idx] * np.where(_dot(samples.nrm[idx], normal[seg]) < 0, -1.0, 1.0)[:, None]
    mean = _segment_sum(aligned, seg, count)
    tilt = np.abs(_dot(mean, normal)) < _MIN_MEAN_COS * np.linalg.norm(mean, axis=1)
    err[~_spread(cov) | (np.diff(ptr) < 3) | tilt] = np.inf
    return centroid, normal, err


def _spread(cov) -> np.ndarray:
    """Covariances (six entries) of point sets that span a plane (``lambda_2 / lambda_1`` above ~1e-8)."""
    trace = cov[0] + cov[3] + cov[5]
    minors = cov[0] * cov[3] - cov[1] ** 2 + cov[0] * cov[5] - cov[2] ** 2 + cov[3] * cov[5] - cov[4] ** 2
    return minors > 1e-8 * trace * trace


# -- pipeline -------------------------------------------------------------------------------------------


def _effective(samples: _Samples, eps: float) -> float:
    """The tolerance the construction works with: a hair below eps (float32 output)."""
    return eps - min(0.5 * eps, max(_EPS_MARGIN * eps, samples.slack))


def _generate(samples: _Samples, eps: float, k_cap: int, relax: int, rng, quiet: bool = False) -> _Splats:
    """Stages 2-6 for one tolerance."""
    n = len(samples.pts)
    work = _effective(samples, eps)
    if n == 1:
        ptr = np.array([0, 1], dtype=np.int64)
        idx = np.zeros(1, dtype=np.int64)
        splats = _fit(samples, ptr, idx, samples.pts.copy(), samples.nrm.copy())
        if samples.cos_sharp is not None:
            splats.lines = np.broadcast_to(NO_CLIP, (1, 2, 3)).astype(np.float32)
            splats.missing = np.zeros(1, dtype=bool)
        return splats
    stage = report.stage if not quiet else _silent
    covered = np.zeros(n, dtype=bool)
    ptr, idx, centroid, normal = _cover(samples, np.arange(n), covered, k_cap, work, rng, OTHER_FACES, stage)
    with stage("fit splats", len(centroid), "splats"):
        splats = _fit(samples, ptr, idx, centroid, normal)
    for i in range(relax):
        with stage(f"relaxation {i + 1}", n):
            splats = _relax(samples, splats, work, rng)
    if samples.cos_sharp is not None:
        with stage("clip lines", len(splats.center), "splats"):
            splats.lines, splats.missing = _clip_lines(samples, splats, eps)
        for i in range(REPAIR_ROUNDS):
            with stage(f"splats across sharp edges, round {i + 1}", len(splats.center), "splats"):
                splats, replaced = _repair(samples, splats, k_cap, eps, work, rng, REPAIR_FACES[i])
            if not replaced:
                break
        with stage("surface margins at sharp edges", len(splats.center), "splats"):
            _shrink_margins(samples, splats, eps, work)
    return splats


def _shrink_margins(samples: _Samples, splats: _Splats, eps: float, work: float) -> None:
    """Where a splat still claims samples of another face, shrink its surface margin (in place).

    The margin (``SURFACE_MARGIN``) pushes an ellipse over nearby edges;
    clip lines cut most of that, but not a hole inside the face or a third
    face. Such splats get half, a quarter, then none of their margin, with
    their clip lines recomputed each time.
    """
    for factor in (0.5, 0.5, 0.0):
        rows = np.flatnonzero(_leaking(samples, splats, work))
        if not len(rows):
            return
        splats.resize(rows, factor)
        splats.lines[rows], splats.missing[rows] = _clip_lines(samples, splats.take(rows), eps)


def _leaking(samples: _Samples, splats: _Splats, work: float) -> np.ndarray:
    """(J,) bool: splats that claim samples of another face (normal beyond ``sharp_angle``).

    Claimed: inside the ellipse, within the tolerance of the plane and kept
    by the clip lines with a margin (samples right on an edge are either
    face's).
    """
    count = len(splats.center)
    radius = np.maximum(splats.a, splats.b)
    out = np.zeros(count, dtype=bool)
    chunk = 4096

    def block(start):
        sel = np.arange(start, min(start + chunk, count))
        hits = samples.tree.query_ball_point(splats.center[sel], radius[sel] + work)
        sizes = np.fromiter((len(h) for h in hits), dtype=np.int64, count=len(hits))
        if not sizes.sum():
            return
        row = np.repeat(sel, sizes)
        idx = np.concatenate([np.asarray(h, dtype=np.int64) for h in hits if len(h)])
        other = _dot(samples.nrm[idx], splats.normal[row]) <= samples.cos_sharp
        row, idx = row[other], idx[other]
        rel = samples.pts[idx] - splats.center[row]
        s = _dot(rel, splats.u_hat[row]) / splats.a[row]
        t = _dot(rel, splats.v_hat[row]) / splats.b[row]
        claimed = (s * s + t * t <= 1.0) & (np.abs(_dot(rel, splats.normal[row])) <= work)
        if splats.lines is not None:
            lines = splats.lines[row].astype(np.float64)
            value = lines[:, :, 0] * s[:, None] + lines[:, :, 1] * t[:, None] + lines[:, :, 2]
            claimed &= value.min(axis=1) >= 1e-3
        out[row[claimed]] = True

    _parallel(block, range(0, count, chunk))
    if splats.missing is not None:
        out |= splats.missing
    return out


def _repair(samples: _Samples, splats: _Splats, k_cap: int, eps: float, work: float, rng, faces: int):
    """Replace splats that claim samples of another face by ones that reach no other face.

    Returns ``(splats, replaced)``. The samples only the dropped splats
    covered seed candidates that stop growing before any sample across a
    sharp edge; the greedy cover picks among them; they get clip lines.
    """
    bad = _leaking(samples, splats, work)
    if not bad.any():
        return splats, False
    kept = splats.take(np.flatnonzero(~bad))
    covered = np.zeros(len(samples.pts), dtype=bool)
    covered[kept.idx] = True
    pool = np.flatnonzero(~covered)
    if not len(pool):
        return kept, True
    ptr, idx, centroid, normal = _cover(samples, pool, covered, k_cap, work, rng, faces, _silent)
    new = _fit(samples, ptr, idx, centroid, normal)
    new.lines, new.missing = _clip_lines(samples, new, eps)
    return kept.concat(new), True


@contextmanager
def _silent(*_args, **_kwargs):
    yield


def _concat_csr(ptrs, idxs):
    sizes = np.concatenate([np.diff(p) for p in ptrs])
    ptr = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ptr[1:])
    return ptr, np.concatenate(idxs)


# -- stage 5: relaxation ---------------------------------------------------------------------------


def _owners(splats: _Splats, n: int) -> np.ndarray:
    """A splat covering each sample (one whose members hold it)."""
    owner = np.full(n, -1, dtype=np.int64)
    owner[splats.idx] = _segments(splats.ptr)
    return owner


def _covering_pairs(samples: _Samples, splats: _Splats, work: float) -> tuple[np.ndarray, np.ndarray]:
    """Which splats cover each sample: ``(near, q)``, (n, k + 1) splat ids and ``s^2 + t^2`` (inf: not covered).

    Candidates are the ``RELAX_NEIGHBOURS`` nearest splat centers and the
    sample's owner (a splat whose members hold it, so every row has one
    finite entry). Covered: inside the ellipse, within ``work`` of the plane
    and, with ``sharp_angle``, on the splat's side of sharp edges.
    """
    pts = samples.pts
    n = len(pts)
    count = len(splats.center)
    owner = _owners(splats, n)
    tree = _tree(splats.center)
    k = min(RELAX_NEIGHBOURS, count)
    near = np.empty((n, k + 1), dtype=np.int64)
    q = np.empty((n, k + 1))

    def block(sl):
        _, hit = tree.query(pts[sl], k=k)
        own = owner[sl]
        ids = np.concatenate([hit.reshape(-1, k), own[:, None]], axis=1)
        rel = pts[sl][:, None, :] - splats.center[ids]
        h = np.abs(np.einsum("bkj,bkj->bk", rel, splats.normal[ids]))
        s = np.einsum("bkj,bkj->bk", rel, splats.u_hat[ids]) / splats.tight_a[ids]
        t = np.einsum("bkj,bkj->bk", rel, splats.v_hat[ids]) / splats.tight_b[ids]
        qq = s * s + t * t
        ok = (qq <= 1.0) & (h <= work)
        if samples.cos_sharp is not None:
            ok &= np.einsum("bkj,bj->bk", splats.normal[ids], samples.nrm[sl]) > samples.cos_sharp
        ok[:, :-1] &= ids[:, :-1] != own[:, None]      # listed once: in the last column,
        ok[:, -1] = True                               # which covers its members by construction
        near[sl] = ids
        q[sl] = np.where(ok, qq, np.inf)

    _for_blocks(block, n)
    return near, q


def _prune(near: np.ndarray, q: np.ndarray, count: int, rng) -> np.ndarray:
    """Splats to keep after dropping redundant ones: (count,) bool.

    A splat is redundant when every sample it covers is covered by another
    splat too. Redundant splats are dropped in rounds, the ones covering the
    fewest samples first: in a round, a splat goes only if it has the
    highest priority among the redundant splats covering each of its
    samples, so every sample loses at most one of its (>= 2) splats.
    """
    covers = np.isfinite(q)
    rows, cols = np.nonzero(covers)
    j = near[rows, cols]
    size = np.bincount(j, minlength=count)
    tie = rng.permutation(count).astype(np.int64)
    key = (int(size.max()) + 1 - size) * count + tie          # fewest samples first
    alive = np.ones(count, dtype=bool)
    mult = covers.sum(axis=1)
    best = np.full(len(near), -1, dtype=np.int64)
    while True:
        critical = np.zeros(count, dtype=bool)
        critical[j[mult[rows] == 1]] = True
        # only pairs of samples with a second splat and of splats that may go matter
        loose = ~critical[j]
        if not loose.any():
            break
        rows_l, j_l = rows[loose], j[loose]
        best[rows_l] = -1
        np.maximum.at(best, rows_l, key[j_l])
        won = best[rows_l] == key[j_l]
        wins = np.bincount(j_l[won], minlength=count)
        pairs = np.bincount(j_l, minlength=count)
        drop = np.flatnonzero((wins == pairs) & (pairs > 0) & alive)
        if not len(drop):
            break
        alive[drop] = False
        gone = ~alive[j]
        np.subtract.at(mult, rows[gone], 1)
        rows, j = rows[~gone], j[~gone]
    return alive


def _relax(samples: _Samples, splats: _Splats, work: float, rng) -> _Splats:
    """One relaxation step (stage 5); every sample stays covered.

    Redundant splats are dropped (:func:`_prune`), every sample goes to the
    covering splat it is most central in (smallest ``s^2 + t^2``), and each
    splat is re-fitted to its samples (re-centred, shrunk).
    """
    n = len(samples.pts)
    count = len(splats.center)
    near, q = _covering_pairs(samples, splats, work)
    alive = _prune(near, q, count, rng)
    q[~alive[near]] = np.inf
    pick = np.argmin(q, axis=1)
    new_owner = near[np.arange(n), pick]
    sizes = np.bincount(new_owner, minlength=count)
    alive = np.flatnonzero(sizes > 0)
    order = np.argsort(new_owner, kind="stable")
    ptr = np.zeros(len(alive) + 1, dtype=np.int64)
    np.cumsum(sizes[alive], out=ptr[1:])
    idx = order
    centroid, normal, err = _planes(samples, ptr, idx)
    # where the new least-squares plane breaks the tolerance (or there is none)
    # keep the old plane (it covers these samples), centred at their projected centroid
    bad = err > work
    if bad.any():
        old_c = splats.center[alive[bad]]
        old_n = splats.normal[alive[bad]]
        centroid[bad] = centroid[bad] - _dot(centroid[bad] - old_c, old_n)[:, None] * old_n
        normal[bad] = old_n
    return _fit(samples, ptr, idx, centroid, normal)


# -- count mode -----------------------------------------------------------------------------------------


def _search_count(samples: _Samples, target: int, k_cap: int, relax: int, source: str):
    """The tolerance whose pipeline gives ``target`` splats (within COUNT_TOLERANCE): (eps, splats)."""
    n = len(samples.pts)
    lo, hi = _extent_bounds(samples)
    if n == 1:
        return hi, _generate(samples, hi, k_cap, relax, np.random.default_rng(0), quiet=True)
    eps = _initial_guess(samples, target, k_cap)
    if n > COUNT_SUBSAMPLE and COUNT_SUBSAMPLE >= 16 * target:
        # coarse search on a random subsample: the count depends on the
        # geometry (area, curvature), hardly on the sampling density
        rng = np.random.default_rng(1)
        rows = np.sort(rng.choice(n, size=COUNT_SUBSAMPLE, replace=False))
        report.message(f"  count search on a random subsample of {COUNT_SUBSAMPLE:,} samples:")
        eps, _ = _secant(samples.subset(rows), target, eps, lo, hi, k_cap, relax, 0.05, 8)
        report.message(f"  count search on all {n:,} samples:")
    eps, splats = _secant(samples, target, eps, lo, hi, k_cap, relax, COUNT_TOLERANCE, COUNT_ITERATIONS)
    got = len(splats.center)
    if abs(got - target) > max(0.05 * target, 1):
        warnings.warn(f"{source}: asked for {target:,} splats, the closest count found is {got:,} "
                      f"(error {eps:.4g})", stacklevel=3)
    return eps, splats


def _extent_bounds(samples: _Samples) -> tuple[float, float]:
    lo_c, hi_c = samples.pts.min(axis=0), samples.pts.max(axis=0)
    diagonal = float(np.linalg.norm(hi_c - lo_c)) or 1.0
    return diagonal * 1e-9, diagonal


def _initial_guess(samples: _Samples, target: int, k_cap: int) -> float:
    """A tolerance whose pilot candidates have about the size ``target`` splats need."""
    n = len(samples.pts)
    want = 2.0 * n / target            # samples per candidate; a cover overlaps ~2x
    lo, hi = _extent_bounds(samples)
    eps = hi * 1e-4
    rng = np.random.default_rng(2)
    for _ in range(12):
        seeds = np.sort(rng.choice(n, size=min(n, 256), replace=False))
        cap = max(1, min(k_cap, n - 1))
        size = float(_grow(samples, seeds, min(cap, max(16, int(4 * want))), eps).sizes.mean())
        if abs(math.log(max(size, 1.0) / want)) < 0.2:
            break
        # candidate area ~ eps on curved surfaces
        eps = float(np.clip(eps * want / max(size, 1.0), lo, hi))
    return eps


def _secant(samples: _Samples, target: int, eps: float, lo: float, hi: float, k_cap: int, relax: int,
            tolerance: float, iterations: int):
    """Search ``eps`` for ``target`` splats: (eps, splats) of the closest count found.

    The count falls with ``eps`` (about as ``1 / eps`` on curved surfaces),
    with a few percent of noise (random seeds, greedy ties). Until the target
    is bracketed: steps along the log-log slope of the last two results
    (-1 at first); then regula falsi on ``(log eps, log count)`` between the
    bracket's ends, kept within its middle 80 % (a safeguarded bisection).
    """
    below = None            # (log eps, log count) with count > target
    above = None            # (log eps, log count) with count < target
    goal = math.log(target)
    history = []
    best = None
    for _ in range(iterations):
        splats = _generate(samples, eps, k_cap, relax, np.random.default_rng(0), quiet=True)
        got = len(splats.center)
        report.message(f"  error {eps:.5g}: {got:,} splats (target {target:,})")
        if best is None or abs(got - target) < abs(len(best[1].center) - target):
            best = (eps, splats)
        if abs(got - target) <= max(tolerance * target, 0.5):
            break
        point = (math.log(eps), math.log(got))
        if got > target and (below is None or point[0] > below[0]):
            below = point
        if got < target and (above is None or point[0] < above[0]):
            above = point
        history.append(point)
        if len(history) >= 3 and history[-1][1] == history[-2][1] == history[-3][1]:
            break            # saturated: e.g. splats capped by k on flat parts
        if below is not None and above is not None:
            if above[0] - below[0] < 1e-6:
                break
            frac = (below[1] - goal) / max(below[1] - above[1], 1e-12)
            proposal = below[0] + float(np.clip(frac, 0.1, 0.9)) * (above[0] - below[0])
        else:
            slope = -1.0
            if len(history) >= 2 and history[-1][0] != history[-2][0]:
                slope = float(np.clip((history[-1][1] - history[-2][1]) / (history[-1][0] - history[-2][0]),
                                      -3.0, -0.3))
            step = (goal - point[1]) / slope
            proposal = point[0] + math.copysign(max(abs(step), 0.05), step)
        eps = float(np.clip(math.exp(proposal), lo, hi))
    return best


# -- stage 6: clip lines -------------------------------------------------------------------------------


def _clip_lines(samples: _Samples, splats: _Splats, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip lines of the splats from the half-spaces of nearby edge samples on their side (stage 6).

    Zwicker 2004 sec. 5 / Botsch 2004 sec. 4: the line is where the plane of
    the face across the edge cuts the splat. Candidate half-spaces: those of
    the samples within the splat's reach that have one (at most
    ``CLIP_SOURCES``, evenly spread), if their normal is within
    ``sharp_angle`` of the splat's and they lie near its plane; moved to the
    splat center (:func:`~surfsplat.geometry.sharp._lines_from_halfspaces`).
    Kept: the crossing line that cuts the most (nearest to the center) and
    the one cutting the most of those whose direction differs from it by
    more than ``SECOND_LINE_ANGLE`` (a corner, or the other side of a narrow
    face). A line is then shifted just enough to keep every sample the splat
    covers (fitted planes are not exact), or dropped if that takes more than
    ``MAX_LINE_SHIFT`` (a reflex corner: two half-planes cannot describe
    that face).

    Returns ``(lines, missing)``: (J, 2, 3) float32 lines and (J,) bool for
    splats that reach over an edge that neither line represents (a third
    edge, a dropped line) by more than ``MIN_CUT``.
    """
    count = len(splats.center)
    lines = np.broadcast_to(NO_CLIP, (count, 2, 3)).astype(np.float32)
    missing = np.zeros(count, dtype=bool)
    hs = samples.halfspaces
    if hs is None or count == 0:
        return lines, missing
    has = (np.abs(hs[:, :, :3]).sum(axis=2) > 0).any(axis=1)
    sources = np.flatnonzero(has)
    if not len(sources):
        return lines, missing
    u = splats.u_hat * splats.a[:, None]
    v = splats.v_hat * splats.b[:, None]
    radius = np.maximum(splats.a, splats.b)
    tree = cKDTree(samples.pts[sources])
    reach_max = float(samples.reach[sources].max())
    cos_second = math.cos(math.radians(SECOND_LINE_ANGLE))
    block_size = 4096

    def block(start):
        sel = np.arange(start, min(start + block_size, count))
        m = len(sel)
        # candidate sources: edge samples within reach, at most CLIP_SOURCES per splat, evenly spread
        hits = tree.query_ball_point(splats.center[sel], radius[sel] + reach_max)
        sizes = np.fromiter((len(h) for h in hits), dtype=np.int64, count=m)
        if not sizes.sum():
            return
        row = np.repeat(np.arange(m), sizes)
        src = sources[np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=int(sizes.sum()))]
        pos = np.arange(len(row)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
        step = np.maximum(sizes / CLIP_SOURCES, 1.0)[row]
        spread = np.floor(pos / step) != np.floor((pos - 1) / step)
        row, src = row[spread], src[spread]
        normal = splats.normal[sel][row]
        p = splats.center[sel][row]
        same = _dot(samples.nrm[src], normal) > samples.cos_sharp
        on_plane = np.abs(_dot(samples.pts[src] - p, normal)) <= 2.0 * eps + 0.05 * radius[sel][row]
        near = np.linalg.norm(samples.pts[src] - p, axis=1) < radius[sel][row] + samples.reach[src]
        keep = same & on_plane & near
        row, src = np.repeat(row[keep], 2), np.repeat(src[keep], 2)
        plane = np.tile([0, 1], len(row) // 2)
        cand = hs[src, plane]
        present = np.abs(cand[:, :3]).sum(axis=1) > 0
        row, src, cand = row[present], src[present], cand[present]
        if not len(row):
            return
        p = splats.center[sel][row]
        # the source's half-space n . (x - q) <= d, relative to this splat's center
        d = cand[:, 3] + _dot(cand[:, :3], samples.pts[src] - p)
        line, crossing = _lines_from_halfspaces(cand[:, :3], d, u[sel][row], v[sel][row])
        ok = np.flatnonzero(crossing)
        ok = ok[np.lexsort((line[ok, 2], row[ok]))]             # per splat, the most cutting first
        first = ok[_first_of_runs(row[ok])]
        first_of = np.full(m, -1)
        first_of[row[first]] = first
        other = first_of[row[ok]]
        rest = ok[line[ok, 0] * line[other, 0] + line[ok, 1] * line[other, 1] < cos_second]
        second = rest[_first_of_runs(row[rest])]
        pair = np.zeros((m, 2, 3))
        used = np.zeros((m, 2), dtype=bool)
        pair[row[first], 0] = line[first]
        used[row[first], 0] = True
        pair[row[second], 1] = line[second]
        used[row[second], 1] = True
        chosen = used.copy()
        pair, used = _fit_lines_to_members(samples, splats, sel, pair, used)
        # edges that cut a part of the splat and that no kept line represents
        deep = ok[line[ok, 2] < 1.0 - MIN_CUT]
        unmatched = np.ones(len(deep), dtype=bool)
        for slot in range(2):
            same_dir = line[deep, 0] * pair[row[deep], slot, 0] + line[deep, 1] * pair[row[deep], slot, 1]
            unmatched &= ~(used[row[deep], slot] & (same_dir >= cos_second))
        lost = np.zeros(m, dtype=bool)
        lost[row[deep[unmatched]]] = True
        missing[sel] = lost | (chosen & ~used & (pair[:, :, 2] < 1.0)).any(axis=1)
        lines[sel] = _pack_lines(pair, used)

    _parallel(block, range(0, count, block_size))
    return lines, missing


def _fit_lines_to_members(samples: _Samples, splats: _Splats, sel: np.ndarray, pair: np.ndarray,
                          keep: np.ndarray):
    """Shift each line so that all samples the splat covers are kept; drop it if that is far."""
    ptr, idx = _csr_take(splats.ptr, splats.idx, sel)
    seg = _segments(ptr)
    rel = samples.pts[idx] - splats.center[sel][seg]
    s = _dot(rel, splats.u_hat[sel][seg]) / splats.a[sel][seg]
    t = _dot(rel, splats.v_hat[sel][seg]) / splats.b[sel][seg]
    for slot in range(2):
        value = pair[seg, slot, 0] * s + pair[seg, slot, 1] * t + pair[seg, slot, 2]
        worst = np.minimum.reduceat(value, ptr[:-1])
        shift = np.maximum(-worst, 0.0)
        shift = np.where(shift > 0, shift + 1e-6, 0.0)
        keep[:, slot] &= shift <= MAX_LINE_SHIFT
        pair[:, slot, 2] += np.where(keep[:, slot], shift, 0.0)
        # a line that no longer crosses the splat cuts nothing
        keep[:, slot] &= pair[:, slot, 2] < 1.0
    return pair, keep


# -- output --------------------------------------------------------------------------------------------


def _to_cloud(samples: _Samples, splats: _Splats) -> SplatCloud:
    u = splats.u_hat * splats.a[:, None]
    v = splats.v_hat * splats.b[:, None]
    return SplatCloud(positions=splats.center.astype(np.float32), normals=splats.center_normal.astype(np.float32),
                      colors=None if splats.colors is None else splats.colors.astype(np.float32),
                      u=u.astype(np.float32), v=v.astype(np.float32), normal_field=splats.field.astype(np.float32),
                      clip_lines=splats.lines)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (M, 3) arrays."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _first_of_runs(keys: np.ndarray) -> np.ndarray:
    """Positions where a run of equal ``keys`` (sorted) starts."""
    return np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]]) if len(keys) else np.zeros(0, dtype=np.intp)
