"""Stage 5: relaxation (after [WK04]'s global relaxation, as Botsch 2004 sec. 3 uses it).

Each step: redundant splats (all their samples covered by others) are
dropped, every sample goes to the covering splat it is most central in
(smallest ``s^2 + t^2``), and each splat is re-fitted to its samples
(re-centred; its old plane is kept where the new one breaks the tolerance or
fits no surface). Every step keeps every sample covered.
"""

from __future__ import annotations

import numpy as np

from ..common import dot, for_blocks
from ..neighbors import kdtree
from .csr import segments
from .fit import Splats, fit_splats, member_planes
from .samples import Samples

#: Splats per relaxation query: a sample is assigned among its nearest splat centers.
RELAX_NEIGHBOURS = 8


def relax_step(samples: Samples, splats: Splats, work: float, rng) -> Splats:
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
    centroid, normal, err = member_planes(samples, ptr, idx)
    # where the new least-squares plane breaks the tolerance (or there is none)
    # keep the old plane (it covers these samples), centred at their projected centroid
    bad = err > work
    if bad.any():
        old_c = splats.center[alive[bad]]
        old_n = splats.normal[alive[bad]]
        centroid[bad] = centroid[bad] - dot(centroid[bad] - old_c, old_n)[:, None] * old_n
        normal[bad] = old_n
    return fit_splats(samples, ptr, idx, centroid, normal)


def _owners(splats: Splats, n: int) -> np.ndarray:
    """A splat covering each sample (one whose members hold it)."""
    owner = np.full(n, -1, dtype=np.int64)
    owner[splats.idx] = segments(splats.ptr)
    return owner


def _covering_pairs(samples: Samples, splats: Splats, work: float) -> tuple[np.ndarray, np.ndarray]:
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
    tree = kdtree(splats.center)
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

    for_blocks(block, n)
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
