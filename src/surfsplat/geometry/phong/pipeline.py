"""Stages 2-6 for one tolerance: candidates, greedy cover, fit, relaxation, clip lines."""

from __future__ import annotations

import numpy as np

from ... import progress as report
from ...cloud import NO_CLIP
from .candidates import OTHER_FACES
from .clip import clip_lines
from .cover import cover, silent
from .fit import Splats, fit_splats
from .relax import relax_step
from .samples import Samples
from .sharp_edges import REPAIR_FACES, REPAIR_ROUNDS, repair, shrink_margins

#: Relative tightening of the tolerance so that the float32 output still
#: covers every sample (with the samples' float32 slack, see :func:`_effective`).
_EPS_MARGIN = 1e-4


def generate(samples: Samples, eps: float, k_cap: int, relax: int, rng, quiet: bool = False) -> Splats:
    """Stages 2-6 for the tolerance ``eps`` (model units): the fitted :class:`~.fit.Splats`.

    ``k_cap``: the most neighbours a candidate grows over; ``relax``:
    relaxation iterations; ``rng``: the random generator of the seeds and
    ties; ``quiet``: report no stages.
    """
    n = len(samples.pts)
    work = _effective(samples, eps)
    if n == 1:
        ptr = np.array([0, 1], dtype=np.int64)
        idx = np.zeros(1, dtype=np.int64)
        splats = fit_splats(samples, ptr, idx, samples.pts.copy(), samples.nrm.copy())
        if samples.cos_sharp is not None:
            splats.lines = np.broadcast_to(NO_CLIP, (1, 2, 3)).astype(np.float32)
            splats.missing = np.zeros(1, dtype=bool)
        return splats
    stage = report.stage if not quiet else silent
    covered = np.zeros(n, dtype=bool)
    ptr, idx, centroid, normal = cover(samples, np.arange(n), covered, k_cap, work, rng, OTHER_FACES, stage)
    with stage("fit splats", len(centroid), "splats"):
        splats = fit_splats(samples, ptr, idx, centroid, normal)
    for i in range(relax):
        with stage(f"relaxation {i + 1}", n):
            splats = relax_step(samples, splats, work, rng)
    if samples.cos_sharp is not None:
        with stage("clip lines", len(splats.center), "splats"):
            splats.lines, splats.missing = clip_lines(samples, splats, eps)
        for i in range(REPAIR_ROUNDS):
            with stage(f"splats across sharp edges, round {i + 1}", len(splats.center), "splats"):
                splats, replaced = repair(samples, splats, k_cap, eps, work, rng, REPAIR_FACES[i])
            if not replaced:
                break
        with stage("surface margins at sharp edges", len(splats.center), "splats"):
            shrink_margins(samples, splats, eps, work)
    return splats


def _effective(samples: Samples, eps: float) -> float:
    """The tolerance the construction works with: a hair below eps (float32 output)."""
    return eps - min(0.5 * eps, max(_EPS_MARGIN * eps, samples.slack))
