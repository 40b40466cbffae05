"""Stage 1: the input samples (Botsch 2004, sec. 3: dense samples with normals), ready for the stages.

Validation, spatial (Morton) order, a k-d tree; PCA normals oriented by the
MST (Hoppe 1992) when the cloud has none; with ``sharp_angle``, the
half-spaces of the faces across sharp edges (from the samples' own clip
lines, or :func:`~surfsplat.geometry.sharp.detect_sharp_features`); the
sample spacing that sizes the surface margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ... import progress as report
from ...cloud import NO_CLIP, SplatCloud
from ...errors import InputError
from ..common import for_blocks
from ..neighbors import kdtree, knn, spatial_order
from ..preprocess import estimated_normals
from ..sharp import detect_sharp_features

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

#: Absolute slack (in float32 ulps of the coordinates) so that the float32
#: output still covers every sample.
_ULPS = 8.0 * 2.0 ** -24


@dataclass
class Samples:
    """The input samples, spatially sorted (internal); lengths in model units."""

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

    def subset(self, rows: np.ndarray) -> "Samples":
        """The samples ``rows`` (sorted ascending) as their own set (count-mode subsampling)."""
        pts = self.pts[rows]
        return Samples(pts, self.nrm[rows], None if self.colors is None else self.colors[rows],
                       self.perm[rows], kdtree(pts), self.cos_sharp,
                       None if self.halfspaces is None else self.halfspaces[rows],
                       None if self.reach is None else self.reach[rows], self.spacing, self.slack,
                       self.gap[rows], self.margin)


def prepare_samples(cloud: SplatCloud, sharp_angle: float | None, source: str) -> Samples:
    """Stage 1: validate, sort, estimate/orient normals, find sharp features.

    Args:
        cloud: the input samples (positions in model units; normals, colors,
            clip lines with ``u``/``v`` when it has them).
        sharp_angle: None, or the sharp-edge threshold in degrees (checked).
        source: name of the input in messages and warnings.

    Returns:
        :class:`Samples` in Morton order (``perm`` maps back to the
        validated input), with unit oriented normals, the sample spacing and
        the float32 slack in model units, and with ``sharp_angle`` the
        half-spaces of the faces across sharp edges.
    """
    cloud = cloud.validated(source)
    n = len(cloud)
    with report.stage("spatial sort and k-d tree", n):
        perm = spatial_order(cloud.positions)
        pts32 = np.take(cloud.positions, perm, axis=0)
        pts = pts32.astype(np.float64)
        tree = kdtree(pts)
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
        nrm = estimated_normals(pts32, idx, dist)
    colors = None if cloud.colors is None else np.take(cloud.colors, perm, axis=0)
    halfspaces = reach = None
    cos_sharp = None
    if sharp_angle is not None:
        cos_sharp = math.cos(math.radians(sharp_angle))
        nrm, halfspaces, reach = _sharp_halfspaces(cloud, perm, pts32, nrm, idx, sharp_angle, normals_given)
    nrm = np.asarray(nrm, dtype=np.float64)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    spacing = _spacing(tree, pts)
    slack = _ULPS * float(np.abs(pts).max()) if n else 0.0
    if dist is not None and dist.shape[1] == min(GAP_NEIGHBOURS, n - 1):
        gap = dist[:, -1].astype(np.float32)
    else:
        with report.stage("sample spacing", n):
            gap = _kth_distance(tree, pts, min(GAP_NEIGHBOURS, n - 1))
    return Samples(pts, nrm, colors, perm, tree, cos_sharp, halfspaces, reach, spacing, slack, gap)


def _sharp_halfspaces(cloud: SplatCloud, perm: np.ndarray, pts32: np.ndarray, nrm: np.ndarray,
                      idx: np.ndarray | None, sharp_angle: float, normals_given: bool):
    """The half-spaces of the faces across sharp edges, per sorted sample: ``(normals, halfspaces, reach)``.

    From the samples' own clip lines when the cloud has them (with ``u``,
    ``v``), else from :func:`~surfsplat.geometry.sharp.detect_sharp_features`
    over the 8-neighbourhoods ``idx`` (which re-fits estimated normals at the
    features). ``halfspaces``: (n, 2, 4) float64 ``n . (x - p) <= d``
    relative to the sample (zeros: none); ``reach``: (n,) float64, model
    units, how far from the sample they are valid.
    """
    n = len(perm)
    if cloud.clip_lines is not None and cloud.u is not None and cloud.v is not None:
        lines = np.take(cloud.clip_lines, perm, axis=0)
        u = np.take(cloud.u, perm, axis=0)
        v = np.take(cloud.v, perm, axis=0)
        halfspaces, reach = _halfspaces_from_lines(lines, u, v)
        return nrm, halfspaces, reach
    with report.stage("sharp features", n):
        features = detect_sharp_features(pts32, nrm, idx, sharp_angle, oriented=True,
                                         refine_normals=not normals_given)
    halfspaces = np.asarray(features.planes, dtype=np.float64)
    halfspaces[~features.feature] = 0.0
    reach = np.asarray(features.reach, dtype=np.float64)
    report.message(f"  {int(features.feature.sum()):,} samples at sharp features")
    return features.normals, halfspaces, reach


def _spacing(tree: cKDTree, pts: np.ndarray) -> float:
    """Typical sample spacing, model units: median nearest-neighbour distance of up to 4096 samples."""
    n = len(pts)
    probe = np.linspace(0, n - 1, min(n, 4096)).astype(np.int64)
    if n > 1:
        d, _ = tree.query(pts[probe], k=2)
        positive = d[:, 1][d[:, 1] > 0]
        spacing = float(np.median(positive)) if len(positive) else 1.0
    else:
        spacing = 1.0
    return spacing


def _kth_distance(tree: cKDTree, pts: np.ndarray, k: int) -> np.ndarray:
    """(n,) float32 distance of each point to its k-th nearest other point (0 when k = 0)."""
    out = np.zeros(len(pts), dtype=np.float32)
    if k < 1:
        return out

    def block(sl):
        d, _ = tree.query(pts[sl], k=k + 1)
        out[sl] = d.reshape(-1, k + 1)[:, -1]

    for_blocks(block, len(pts))
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
