"""Stage 3: greedy cover of the samples by candidates (Botsch 2004, sec. 3 / [WK04]).

Seeds: a random subset of about ``SEED_FACTOR`` candidates per expected splat,
then every sample no candidate covered; the candidates that cover the most
not-yet-covered samples are picked, vectorized in rounds (see
:func:`_greedy_cover`).
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from .candidates import PILOT_SEEDS, grow_twice, pilot
from .csr import concat_csr, csr_take
from .samples import Samples

#: Candidate seeds per expected splat in the first round (the greedy cover
#: picks among about this many candidates per sample).
SEED_FACTOR = 16.0


def cover(samples: Samples, pool: np.ndarray, covered: np.ndarray, k_cap: int, work: float, rng, faces: int,
          stage) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stages 2-3: candidates and greedy cover of the samples ``pool``; marks them in ``covered``.

    Seeds: ``SEED_FACTOR`` per expected splat at random, then every sample
    left uncovered; candidates keep their members within ``work`` (model
    units) of their plane and reach at most ``faces`` other faces; ``stage``
    reports progress (:func:`surfsplat.progress.stage` or :func:`silent`).
    Returns the picked candidates: members CSR ``(ptr, idx)``, centroids
    (model units) and unit plane normals.
    """
    with stage("pilot", min(len(pool), PILOT_SEEDS), "seeds"):
        k_first, k, mean_size = pilot(samples, pool, work, k_cap, rng, faces)
    seed_count = int(min(len(pool), SEED_FACTOR * len(pool) / max(mean_size, 1.0)))
    seeds = np.sort(rng.choice(pool, size=seed_count, replace=False)) if seed_count < len(pool) else pool
    parts = []
    round_no = 0
    while len(seeds):
        round_no += 1
        with stage(f"candidates, round {round_no} ({k_first}, then {k} neighbours)", len(seeds), "seeds"):
            cand = grow_twice(samples, seeds, k_first, k, work, faces)
        with stage("greedy cover", len(seeds), "candidates"):
            pick = _greedy_cover(cand.ptr, cand.idx, covered, rng)
        ptr, idx = csr_take(cand.ptr, cand.idx, pick)
        parts.append((ptr, idx, cand.centroid[pick], cand.normal[pick]))
        seeds = pool[~covered[pool]]
    ptr, idx = concat_csr([p[0] for p in parts], [p[1] for p in parts])
    return ptr, idx, np.concatenate([p[2] for p in parts]), np.concatenate([p[3] for p in parts])


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
        covered[csr_take(ptr, idx, pick)[1]] = True
    return np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.int64)


@contextmanager
def silent(*_args, **_kwargs):
    """A stand-in for :func:`surfsplat.progress.stage` that reports nothing."""
    yield
