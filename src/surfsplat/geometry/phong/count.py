"""Count mode (``phong_splats(count=N)``, CLI ``--count``): the tolerance whose pipeline gives N splats."""

from __future__ import annotations

import math
import warnings

import numpy as np

from ... import progress as report
from .candidates import grow
from .pipeline import generate
from .samples import Samples

#: Count mode: relative tolerance of the splat count, and search iterations.
COUNT_TOLERANCE = 0.03
COUNT_ITERATIONS = 14

#: Count mode on large inputs: first search on a random subsample of this size.
COUNT_SUBSAMPLE = 200_000


def search_count(samples: Samples, target: int, k_cap: int, relax: int, source: str):
    """The tolerance whose pipeline gives ``target`` splats (within COUNT_TOLERANCE): (eps, splats)."""
    n = len(samples.pts)
    lo, hi = _extent_bounds(samples)
    if n == 1:
        return hi, generate(samples, hi, k_cap, relax, np.random.default_rng(0), quiet=True)
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


def _extent_bounds(samples: Samples) -> tuple[float, float]:
    """Bounds of the tolerance search, model units: 1e-9 and 1 times the samples' bounding-box diagonal."""
    lo_c, hi_c = samples.pts.min(axis=0), samples.pts.max(axis=0)
    diagonal = float(np.linalg.norm(hi_c - lo_c)) or 1.0
    return diagonal * 1e-9, diagonal


def _initial_guess(samples: Samples, target: int, k_cap: int) -> float:
    """A tolerance whose pilot candidates have about the size ``target`` splats need."""
    n = len(samples.pts)
    want = 2.0 * n / target            # samples per candidate; a cover overlaps ~2x
    lo, hi = _extent_bounds(samples)
    eps = hi * 1e-4
    rng = np.random.default_rng(2)
    for _ in range(12):
        seeds = np.sort(rng.choice(n, size=min(n, 256), replace=False))
        cap = max(1, min(k_cap, n - 1))
        size = float(grow(samples, seeds, min(cap, max(16, int(4 * want))), eps).sizes.mean())
        if abs(math.log(max(size, 1.0) / want)) < 0.2:
            break
        # candidate area ~ eps on curved surfaces
        eps = float(np.clip(eps * want / max(size, 1.0), lo, hi))
    return eps


def _secant(samples: Samples, target: int, eps: float, lo: float, hi: float, k_cap: int, relax: int,
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
        splats = generate(samples, eps, k_cap, relax, np.random.default_rng(0), quiet=True)
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
