"""Stage 6, continued: splats that still reach over a sharp edge after clipping.

Splats that still claim samples of another face (a hole inside the face, a
third edge: nothing two clip lines can cut off) are replaced by splats grown
to at most ``REPAIR_FACES[i]`` other faces (:func:`repair`); last, the
surface margin of any splat that still does is reduced
(:func:`shrink_margins`).
"""

from __future__ import annotations

import numpy as np

from ..common import dot, parallel
from .clip import clip_lines
from .cover import cover, silent
from .fit import Splats, fit_splats
from .samples import Samples

#: Splats that still claim samples of another face after clipping, or reach
#: over an edge no line represents (a hole inside the ellipse, a third edge),
#: are replaced, round i, by candidates that reach at most ``REPAIR_FACES[i]``
#: other faces (:data:`~.candidates.OTHER_FACES` in the first cover).
#: Measured on the CAD part (60 k samples, two sample sets): (2, 0) gives ~5 %
#: more splats than (1, 0) and 0.3-0.7 dB better Phong shading on its curved
#: faces; (0, 0) ~15 % more splats than (2, 0) for about the same shading.
REPAIR_ROUNDS = 2
REPAIR_FACES = (2, 0)


def repair(samples: Samples, splats: Splats, k_cap: int, eps: float, work: float, rng, faces: int):
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
    ptr, idx, centroid, normal = cover(samples, pool, covered, k_cap, work, rng, faces, silent)
    new = fit_splats(samples, ptr, idx, centroid, normal)
    new.lines, new.missing = clip_lines(samples, new, eps)
    return kept.concat(new), True


def shrink_margins(samples: Samples, splats: Splats, eps: float, work: float) -> None:
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
        splats.lines[rows], splats.missing[rows] = clip_lines(samples, splats.take(rows), eps)


def _leaking(samples: Samples, splats: Splats, work: float) -> np.ndarray:
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
        other = dot(samples.nrm[idx], splats.normal[row]) <= samples.cos_sharp
        row, idx = row[other], idx[other]
        rel = samples.pts[idx] - splats.center[row]
        s = dot(rel, splats.u_hat[row]) / splats.a[row]
        t = dot(rel, splats.v_hat[row]) / splats.b[row]
        claimed = (s * s + t * t <= 1.0) & (np.abs(dot(rel, splats.normal[row])) <= work)
        if splats.lines is not None:
            lines = splats.lines[row].astype(np.float64)
            value = lines[:, :, 0] * s[:, None] + lines[:, :, 1] * t[:, None] + lines[:, :, 2]
            claimed &= value.min(axis=1) >= 1e-3
        out[row[claimed]] = True

    parallel(block, range(0, count, chunk))
    if splats.missing is not None:
        out |= splats.missing
    return out
