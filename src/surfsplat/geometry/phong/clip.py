"""Stage 6: clip lines where a splat reaches over a sharp edge (Botsch 2004, sec. 4; Zwicker 2004, sec. 5).

A clip line ``(a, b, c)`` in the splat's ``(s, t)`` is where the plane of the
face across the edge cuts the splat; the half-spaces come from the edge
samples on the splat's side (:attr:`.samples.Samples.halfspaces`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy.spatial import cKDTree

from ...cloud import NO_CLIP
from ..common import dot, first_of_runs, parallel
from ..sharp.lines import lines_from_halfspaces, pack_lines
from .csr import csr_take, segments
from .fit import Splats
from .samples import Samples

#: Clip lines: edge samples a splat takes half-spaces from (at most), the angle
#: by which a second line must differ from the first (a corner), the largest
#: shift (in splat radii) a line may get to keep the splat's samples, and the
#: cut (in splat radii) from which an edge that no line represents counts.
CLIP_SOURCES = 32
SECOND_LINE_ANGLE = 20.0
MAX_LINE_SHIFT = 0.25
MIN_CUT = 0.05


def clip_lines(samples: Samples, splats: Splats, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip lines of the splats from the half-spaces of nearby edge samples on their side (stage 6).

    Zwicker 2004 sec. 5 / Botsch 2004 sec. 4: the line is where the plane of
    the face across the edge cuts the splat. Candidate half-spaces: those of
    the samples within the splat's reach that have one (at most
    ``CLIP_SOURCES``, evenly spread), if their normal is within
    ``sharp_angle`` of the splat's and they lie near its plane; moved to the
    splat center (:func:`~surfsplat.geometry.sharp.lines.lines_from_halfspaces`).
    Kept: the crossing line that cuts the most (nearest to the center) and
    the one cutting the most of those whose direction differs from it by
    more than ``SECOND_LINE_ANGLE`` (a corner, or the other side of a narrow
    face). A line is then shifted just enough to keep every sample the splat
    covers (fitted planes are not exact), or dropped if that takes more than
    ``MAX_LINE_SHIFT`` (a reflex corner: two half-planes cannot describe
    that face). ``eps``: the tolerance, model units.

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
    cos_second = math.cos(math.radians(SECOND_LINE_ANGLE))
    block_size = 4096

    def block(start):
        sel = np.arange(start, min(start + block_size, count))
        found = _candidate_halfspaces(samples, splats, sel, tree, sources, radius, eps)
        if found is None:
            return
        row, cand, d = found
        line, crossing = lines_from_halfspaces(cand[:, :3], d, u[sel][row], v[sel][row])
        pair, used, ok = _strongest_two(line, crossing, row, len(sel), cos_second)
        chosen = used.copy()
        pair, used = _fit_lines_to_members(samples, splats, sel, pair, used)
        lost = _unrepresented(line, ok, row, pair, used, len(sel), cos_second)
        missing[sel] = lost | (chosen & ~used & (pair[:, :, 2] < 1.0)).any(axis=1)
        lines[sel] = pack_lines(pair, used)

    parallel(block, range(0, count, block_size))
    return lines, missing


def _candidate_halfspaces(samples: Samples, splats: Splats, sel: np.ndarray, tree: cKDTree, sources: np.ndarray,
                          radius: np.ndarray, eps: float):
    """The half-spaces a block of splats ``sel`` may take: ``(row, cand, d)``, or None if there are none.

    Edge samples (``sources``, in the k-d tree ``tree``) within a splat's
    reach, at most ``CLIP_SOURCES`` per splat (evenly spread), on the splat's
    side of the edge (normal within ``sharp_angle``) and near its plane
    (``2 eps + 0.05 radius``). ``row``: (P,) splat slot in ``sel``,
    ``cand``: (P, 4) the source's half-space, ``d``: (P,) its offset moved to
    the splat center (model units).
    """
    m = len(sel)
    hs = samples.halfspaces
    reach_max = float(samples.reach[sources].max())
    # candidate sources: edge samples within reach, at most CLIP_SOURCES per splat, evenly spread
    hits = tree.query_ball_point(splats.center[sel], radius[sel] + reach_max)
    sizes = np.fromiter((len(h) for h in hits), dtype=np.int64, count=m)
    if not sizes.sum():
        return None
    row = np.repeat(np.arange(m), sizes)
    src = sources[np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=int(sizes.sum()))]
    pos = np.arange(len(row)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    step = np.maximum(sizes / CLIP_SOURCES, 1.0)[row]
    spread = np.floor(pos / step) != np.floor((pos - 1) / step)
    row, src = row[spread], src[spread]
    normal = splats.normal[sel][row]
    p = splats.center[sel][row]
    same = dot(samples.nrm[src], normal) > samples.cos_sharp
    on_plane = np.abs(dot(samples.pts[src] - p, normal)) <= 2.0 * eps + 0.05 * radius[sel][row]
    near = np.linalg.norm(samples.pts[src] - p, axis=1) < radius[sel][row] + samples.reach[src]
    keep = same & on_plane & near
    row, src = np.repeat(row[keep], 2), np.repeat(src[keep], 2)
    plane = np.tile([0, 1], len(row) // 2)
    cand = hs[src, plane]
    present = np.abs(cand[:, :3]).sum(axis=1) > 0
    row, src, cand = row[present], src[present], cand[present]
    if not len(row):
        return None
    p = splats.center[sel][row]
    # the source's half-space n . (x - q) <= d, relative to this splat's center
    d = cand[:, 3] + dot(cand[:, :3], samples.pts[src] - p)
    return row, cand, d


def _strongest_two(line: np.ndarray, crossing: np.ndarray, row: np.ndarray, m: int, cos_second: float):
    """Per splat, the crossing line that cuts the most and the most cutting one of another direction.

    ``line``: (P, 3) candidate lines of the splats ``row`` (P,) in ``range(m)``.
    Returns ``(pair, used, ok)``: (m, 2, 3) lines, (m, 2) bool slots used,
    and the crossing candidates, per splat the most cutting first.
    """
    ok = np.flatnonzero(crossing)
    ok = ok[np.lexsort((line[ok, 2], row[ok]))]             # per splat, the most cutting first
    first = ok[first_of_runs(row[ok])]
    first_of = np.full(m, -1)
    first_of[row[first]] = first
    other = first_of[row[ok]]
    rest = ok[line[ok, 0] * line[other, 0] + line[ok, 1] * line[other, 1] < cos_second]
    second = rest[first_of_runs(row[rest])]
    pair = np.zeros((m, 2, 3))
    used = np.zeros((m, 2), dtype=bool)
    pair[row[first], 0] = line[first]
    used[row[first], 0] = True
    pair[row[second], 1] = line[second]
    used[row[second], 1] = True
    return pair, used, ok


def _unrepresented(line: np.ndarray, ok: np.ndarray, row: np.ndarray, pair: np.ndarray, used: np.ndarray, m: int,
                   cos_second: float) -> np.ndarray:
    """(m,) bool: splats with an edge that cuts more than ``MIN_CUT`` of them and that no kept line represents."""
    deep = ok[line[ok, 2] < 1.0 - MIN_CUT]
    unmatched = np.ones(len(deep), dtype=bool)
    for slot in range(2):
        same_dir = line[deep, 0] * pair[row[deep], slot, 0] + line[deep, 1] * pair[row[deep], slot, 1]
        unmatched &= ~(used[row[deep], slot] & (same_dir >= cos_second))
    lost = np.zeros(m, dtype=bool)
    lost[row[deep[unmatched]]] = True
    return lost


def _fit_lines_to_members(samples: Samples, splats: Splats, sel: np.ndarray, pair: np.ndarray,
                          keep: np.ndarray):
    """Shift each line so that all samples the splat covers are kept; drop it if that is far."""
    ptr, idx = csr_take(splats.ptr, splats.idx, sel)
    seg = segments(ptr)
    rel = samples.pts[idx] - splats.center[sel][seg]
    s = dot(rel, splats.u_hat[sel][seg]) / splats.a[sel][seg]
    t = dot(rel, splats.v_hat[sel][seg]) / splats.b[sel][seg]
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
