"""Stage 2: candidate splats, grown per seed while the least-squares plane keeps the error bound.

Botsch 2004, sec. 3 (after Wu & Kobbelt 2004, [WK04]): a splat per seed
sample, grown over its nearest neighbours in rings of increasing size
(x ``RING_GROWTH`` each) while the least-squares plane of the grown set keeps
every member within ``eps`` (the splat's covered set ``P_j``). The neighbours
are ranked by an anisotropic distance that follows the local principal
curvatures ([WK04]: ellipses aligned to the principal directions): from the
covariance of the neighbours' normals, so that candidates stretch along the
flat direction, up to ``MAX_ANISOTROPY``. A pilot of ``PILOT_SEEDS`` seeds
measures the typical candidate size and the neighbourhood sizes needed:
candidates that outgrow the one enough for half of them grow again over a
larger one (:func:`grow_twice`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...frames import tangent_frame
from ..common import dot, parallel
from ..normals import smallest_eigenvectors
from ..splats import MAX_ANISOTROPY
from .csr import csr_positions, csr_take
from .fit import spans_plane
from .samples import Samples

#: Seeds of the pilot run that sizes the neighbourhoods and the seed count.
PILOT_SEEDS = 1000

#: Growth factor of the neighbour rings a candidate grows over.
RING_GROWTH = 1.25

#: Neighbours whose normals give a seed's curvature anisotropy (growth metric),
#: and the largest axis ratio of that metric.
METRIC_NEIGHBOURS = 16
GROWTH_ANISOTROPY = MAX_ANISOTROPY

#: With ``sharp_angle``: a candidate stops growing before it reaches samples
#: of more than ``OTHER_FACES`` faces across sharp edges (two clip lines can
#: cut two off; see also :data:`~.sharp_edges.REPAIR_FACES`).
OTHER_FACES = 2

#: A least-squares plane more than 45 degrees from the samples' normals (the
#: seed's while growing) fits no surface (e.g. a few samples along one arc).
_MIN_PLANE_COS = math.cos(math.radians(45.0))

#: Entries (seeds x neighbours) per growth block.
_BLOCK_ENTRIES = 1 << 18


@dataclass
class Candidates:
    """Candidate splats (internal): members CSR, plane, growth statistics."""

    ptr: np.ndarray       # (S + 1,) int64
    idx: np.ndarray       # (M,) int64 sample rows, seed first
    centroid: np.ndarray  # (S, 3) float64
    normal: np.ndarray    # (S, 3) float64 unit (sign arbitrary)
    rank: np.ndarray      # (S,) int64: neighbourhood size the members needed
    limited: np.ndarray   # (S,) bool: ran out of neighbours before the tolerance stopped it

    @property
    def sizes(self) -> np.ndarray:
        """(S,) int64 number of members of each candidate."""
        return np.diff(self.ptr)


def grow(samples: Samples, seeds: np.ndarray, k: int, eps: float, faces: int = OTHER_FACES) -> Candidates:
    """Grow a candidate splat at each seed over its k nearest neighbours (stage 2).

    A candidate keeps every member within ``eps`` (model units) of its
    least-squares plane (Botsch 2004, sec. 3). With ``sharp_angle``, it stops
    before samples of more than ``faces`` faces across sharp edges fall
    within its neighbourhood ring.
    """
    seeds = np.asarray(seeds, dtype=np.int64)
    block = max(16, _BLOCK_ENTRIES // (k + 2))
    starts = list(range(0, len(seeds), block))
    parts: dict[int, tuple] = {}

    def run(start):
        parts[start] = _grow_block(samples, seeds[start:start + block], k, eps, faces)

    parallel(run, starts)
    pieces = [parts[s] for s in starts]
    sizes = np.concatenate([p[0] for p in pieces])
    ptr = np.zeros(len(seeds) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ptr[1:])
    return Candidates(ptr, np.concatenate([p[1] for p in pieces]), np.concatenate([p[2] for p in pieces]),
                      np.concatenate([p[3] for p in pieces]), np.concatenate([p[4] for p in pieces]),
                      np.concatenate([p[5] for p in pieces]))


def _grow_block(samples: Samples, seeds: np.ndarray, k: int, eps: float, faces: int):
    """:func:`grow` for one block of seeds: (sizes, members, centroids, normals, ranks, limited)."""
    ids, off, order, count, walled = _ranked_neighbours(samples, seeds, k, faces)
    best, centroid, normal, failed = _grow_rings(off, count, samples.nrm[seeds], eps)
    keep = np.arange(ids.shape[1])[None, :] < best[:, None]
    members = ids[keep]
    rank = np.where(keep, order, 0).max(axis=1)
    limited = ~failed & (best >= count) & ~walled
    return best, members, centroid + samples.pts[seeds], normal, rank, limited


def _ranked_neighbours(samples: Samples, seeds: np.ndarray, k: int, faces: int):
    """The seeds' usable neighbours, nearest first by the anisotropic growth metric ([WK04]).

    Each seed's k nearest samples, without samples across sharp edges (normal
    beyond ``sharp_angle``) and, with ``sharp_angle``, cut before the nearest
    sample of face number ``faces + 1`` across them. Returns ``(ids, off,
    order, count, walled)``: (B, W) sample rows, seed first, and (B, W, 3)
    offsets from the seed (model units) in order of the metric, (B, W) their
    slots in the k-neighbourhood, (B,) how many are usable, and (B,) bool:
    cut by the faces rather than by the neighbourhood's size.
    """
    """:func:`grow` for one block of seeds: (sizes, members, centroids, normals, ranks, limited)."""
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
    return ids, off, order, count, walled


def _grow_rings(off: np.ndarray, count: np.ndarray, n0: np.ndarray, eps: float):
    """Grow each seed's candidate over its first 4, 5, 6, 8, ... ranked neighbours (:func:`_rings`).

    Botsch 2004, sec. 3: the least-squares plane (centroid, smallest
    eigenvector of the covariance) of the grown set must keep every member
    within ``eps`` (model units); the candidate stops at the first ring that
    breaks it. ``off``: (B, W, 3) offsets from the seed in rank order,
    ``count``: (B,) usable neighbours, ``n0``: (B, 3) seed normals. Returns
    ``(best, centroid, normal, failed)``: (B,) members taken, (B, 3)
    centroid offsets and unit plane normals, (B,) bool stopped by the
    tolerance.
    """
    b_count, width = off.shape[:2]
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
        fits = spans_plane(cov) & (np.abs(dot(nrm_fit, n0[act])) >= _MIN_PLANE_COS)
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
    return best, centroid, normal, failed


def _rings(limit: int) -> np.ndarray:
    """Ring sizes 4, 5, 6, 8, 10, ... (x RING_GROWTH) below ``limit``, then ``limit``."""
    sizes = []
    m = 4
    while m < limit:
        sizes.append(m)
        m = max(m + 1, int(math.ceil(m * RING_GROWTH)))
    sizes.append(limit)
    return np.asarray(sizes, dtype=np.int64)


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


def pilot(samples: Samples, pool: np.ndarray, eps: float, k_cap: int, rng,
          faces: int) -> tuple[int, int, float]:
    """Neighbourhood sizes and mean candidate size for ``eps`` (model units) from a few random seeds of ``pool``.

    Returns ``(k_first, k_full, mean size)``: ``k_first`` suffices for half
    the candidates (the rest, stretched along flat directions or bigger,
    grow again over ``k_full``, which suffices for 90 %).
    """
    n = len(samples.pts)
    cap = max(1, min(k_cap, n - 1))
    seeds = np.sort(rng.choice(pool, size=min(len(pool), PILOT_SEEDS), replace=False))
    k = min(cap, 64)
    while True:
        cand = grow(samples, seeds, k, eps, faces)
        if cand.limited.mean() <= 0.1 or k >= cap:
            break
        k = min(cap, 4 * k)
    need = np.quantile(cand.rank, [0.5, 0.9]) * 1.25 + 8
    k_first, k_full = (int(np.clip(x, min(cap, 16), cap)) for x in need)
    if cand.limited.mean() > 0.1:
        k_full = cap
    return k_first, k_full, float(cand.sizes.mean())


def grow_twice(samples: Samples, seeds: np.ndarray, k_first: int, k_full: int, eps: float,
               faces: int) -> Candidates:
    """:func:`grow` over ``k_first`` neighbours, again over ``k_full`` where that was too few.

    The k-d tree query dominates and grows faster than linearly with k: most
    candidates need a small neighbourhood, a few (stretched along a flat
    direction) a large one.
    """
    cand = grow(samples, seeds, k_first, eps, faces)
    redo = np.flatnonzero(cand.limited)
    if k_full <= k_first or not len(redo):
        return cand
    again = grow(samples, seeds[redo], k_full, eps, faces)
    sizes = cand.sizes
    sizes[redo] = again.sizes
    keep = np.ones(len(seeds), dtype=bool)
    keep[redo] = False
    ptr = np.zeros(len(seeds) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ptr[1:])
    idx = np.empty(ptr[-1], dtype=np.int64)
    old_ptr, old_idx = csr_take(cand.ptr, cand.idx, np.flatnonzero(keep))
    idx[csr_positions(ptr, np.flatnonzero(keep))] = old_idx
    idx[csr_positions(ptr, redo)] = again.idx
    for name in ("centroid", "normal", "rank", "limited"):
        getattr(cand, name)[redo] = getattr(again, name)
    return Candidates(ptr, idx, cand.centroid, cand.normal, cand.rank, cand.limited)
