"""Sharp features: where the clip lines of splats come from.

Zwicker et al. 2004, section 5 (figure 4): a sharp edge is represented by
*clip lines* in the tangent planes of the splats next to it, "computed by
intersecting the tangent planes of adjacent reconstruction kernels on either
side of a feature". We store a clip line as Botsch et al. 2004, section 4
do: ``(a, b, c)`` in the splat's normalized coordinates ``(s, t)`` (the point
``p + s u + t v``, see :mod:`surfsplat.cloud`), the point kept where
``a s + b t + c >= 0``. Up to two lines per splat: one at an edge, two at a
corner (Zwicker 2004, figure 5).

Both sources below reduce to the same algebra. The plane on the other side of
the feature is a half-space ``n . x <= d`` (``n`` unit) that contains the
splat's own side; on the splat ``x = p + s u + t v`` it reads

    ``(d - n . p) - s (n . u) - t (n . v) >= 0``,

so ``(a, b, c) = (-n . u, -n . v, d - n . p)``, scaled by ``1 / |(a, b)|``
(then ``c`` is the signed distance of the splat center from the line in
``(s, t)`` units). A line is only stored where it crosses the splat
(``|c| < 1``): one farther out cuts nothing, and one that would cut the
whole splat (the center far on the wrong side) would punch a hole.
Which side is kept: the side of the splat's own face. For a splat on face
A next to face B, the line is A's plane intersected with B's plane; the kept
side is the side of B's plane where A lies. At a convex edge that is the
inside of B's plane, at a concave edge the outside, so the part of the splat
that pokes out of the solid (convex) or through face B (concave) is cut.

* :func:`mesh_clip_lines`: samples of a triangle mesh, with exact planes of
  the mesh's faces across edges whose dihedral angle exceeds the threshold
  (used by :func:`surfsplat.geometry.sampling.sample_mesh`).
* :func:`detect_sharp_features` and :func:`feature_clip_lines`: raw points.
  Where a neighbourhood's normals spread, it is split into up to three
  planar groups (hypotheses: the planes through the neighbours with their
  normals), a least-squares plane is fitted to each, and planes more than the
  threshold apart are the faces on either side of an edge or corner
  (used by :func:`surfsplat.geometry.preprocess.preprocess`).
"""

from __future__ import annotations

import argparse
import math
import numbers
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..cloud import NO_CLIP
from ..errors import InputError
from .normals import _check_indices, _check_vectors, _for_blocks, _parallel, smallest_eigenvectors

#: Neighbours per point for feature detection on raw points (the point itself
#: excluded). It should reach the other side of a feature wherever a splat
#: crosses it: ellipse splats' major axes are ~1.8x the 8-neighbour radius
#: (median on random samples), 32 neighbours reach ~2x. Larger splats take
#: the planes of the feature points nearest to them (:func:`feature_clip_lines`).
SHARP_NEIGHBOURS = 32

#: Edge points per edge-sample query (mesh path): candidates of the nearest edges.
_EDGE_CANDIDATES = 24

#: A fitted plane needs at least this many points and a spread of
#: ``lambda_mid / lambda_max`` above ``_MIN_SPREAD`` (not collinear).
_MIN_GROUP = 4
_MIN_SPREAD = 1e-3

#: A plane is dropped when another group has this fraction (and at least 2)
#: of its points on either side of it, farther than ``_STRADDLE_TOL`` inlier
#: tolerances (a curved face bulges a little past the plane fitted to it).
_STRADDLE = 0.1
_STRADDLE_TOL = 5.0

#: A point belongs to a plane when it lies within this fraction of the
#: neighbourhood radius of it (raw-point path).
_INLIER = 0.01

#: A feature needs this fraction of the neighbourhood's points within
#: ``_COVER_TOL`` inlier tolerances of its planes: faces at a crease are planar up
#: to it, a surface curved at the neighbourhood's scale fits planes only in strips.
#: Measured on cylinders (radius 1, 2, 4, 10 neighbourhood radii) at the CAD test's
#: density: false lines on the curved side for 2 % and 0 % of its points at radius 1
#: and 2 (99 % and 88 % without this test), none above; of the splats crossing the
#: cap/side rim, 17, 49, 75 and 96 % get their line.
_COVERED = 0.9
_COVER_TOL = 3.0

#: An own face is exactly planar when the RMS distance of its points to their plane is below
#: this fraction of the inlier tolerance.
_PLANAR = 0.1

#: Floor of the trimming tolerance of the final plane fits, fraction of the neighbourhood radius.
_TRIM = 1e-4

#: Nearest feature points whose planes a splat may take (raw-point path).
_SOURCES = 32

#: Points per k-d tree query call (bounded temporaries).
_QUERY_CHUNK = 65536

#: Points per block of the raw-point detection (rows of (B, k + 1, 3) arrays).
_BLOCK = 4096


def check_sharp_angle(value, name: str = "sharp_angle") -> float:
    """``value`` as a float in degrees, or InputError naming ``name``.

    A sharp-feature threshold is a dihedral angle (between two faces'
    normals) strictly between 0 and 180 degrees.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be an angle in degrees, got {value!r}")
    angle = float(value)
    if not (0.0 < angle < 180.0):  # also rejects NaN
        raise InputError(f"{name} must be an angle in degrees strictly between 0 and 180, got {value!r}")
    return angle


def sharp_angle_argument(text: str) -> float:
    """argparse ``type=`` for ``--sharp-angle DEG``: a clear usage error (exit status 2) when bad."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not (0.0 < value < 180.0):
        raise argparse.ArgumentTypeError(f"must be an angle in degrees strictly between 0 and 180 (the dihedral "
                                         f"angle above which an edge is sharp), got {text!r}")
    return value


# -- half-spaces -> clip lines ---------------------------------------------------------------------


def _lines_from_halfspaces(n: np.ndarray, c: np.ndarray, u: np.ndarray, v: np.ndarray):
    """Clip lines of half-spaces ``n . (x - p) <= c`` on splats ``p + s u + t v``.

    ``n``: (..., 3) float64 unit normals (zero = no plane); ``c``: (...,)
    float64 offsets relative to the splat center; ``u``, ``v``: (..., 3)
    float64 scaled axes broadcastable to ``n``. Returns ``(lines, crossing)``:
    (..., 3) float64 normalized ``(a, b, c)`` (``|(a, b)| = 1``) and a bool
    mask of the lines that cross the splat without cutting it all.
    """
    a = -(n[..., 0] * u[..., 0] + n[..., 1] * u[..., 1] + n[..., 2] * u[..., 2])
    b = -(n[..., 0] * v[..., 0] + n[..., 1] * v[..., 1] + n[..., 2] * v[..., 2])
    norm = np.hypot(a, b)
    # |(a, b)| = |n projected onto the splat plane| * radius: ~0 for a plane
    # parallel to the splat, whose "line" is undefined
    scale = np.sqrt((u * u).sum(axis=-1) + (v * v).sum(axis=-1))
    usable = norm > 1e-4 * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(usable, 1.0 / norm, 0.0)
    lines = np.stack([a * inv, b * inv, c * inv], axis=-1)
    crossing = usable & (lines[..., 2] < 1.0) & (lines[..., 2] > -1.0)
    return lines, crossing


def _pack_lines(lines: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(N, 2, 3) float32: the kept ones of two candidate lines per row first, (0, 0, 1) elsewhere."""
    out = np.broadcast_to(NO_CLIP, lines.shape).astype(np.float32)
    out[keep] = lines[keep]
    swap = ~keep[:, 0] & keep[:, 1]
    out[swap] = out[swap][:, ::-1]
    return out


# -- meshes ----------------------------------------------------------------------------------------


@dataclass
class MeshFeatures:
    """The sharp edges of a triangle mesh and the planes on either side.

    Attributes:
        vertices: (V', 3) float64 positions after merging duplicates.
        faces: (F, 3) int64 faces on the merged vertices (same order as the mesh's).
        normals: (F, 3) float64 unit face normals (zero for degenerate faces).
        offsets: (F,) float64 ``normals . x`` on each face's plane.
        patch: (F,) int64 label of the smooth patch (faces connected across
            edges that are not sharp) each face belongs to.
        edges: (E, 2) int64 merged vertex ids of the sharp edges.
        edge_faces: (E, 2) int64 the two faces at each sharp edge.
        angles: (E,) float64 dihedral angles between those faces' normals, degrees.
        keep_sign: (E, 2) float64 +-1: for the splats on face ``edge_faces[e, i]``
            the kept side of the *other* face's plane is
            ``keep_sign[e, i] * (offset - normal . x) >= 0`` (+1 at convex edges).
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    patch: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    angles: np.ndarray
    keep_sign: np.ndarray


def mesh_features(mesh, sharp_angle: float) -> MeshFeatures:
    """Find the edges of ``mesh`` whose dihedral angle exceeds ``sharp_angle`` degrees.

    Duplicated vertices (CAD meshes split them along creases so that each face
    keeps its own normal) are merged first, at a tolerance of 1e-9 of the
    bounding-box diagonal, so that the faces on either side of a crease become
    neighbours. Edge adjacency (manifold edges shared by two faces) comes from
    ``trimesh``; the angle is the one between the faces' normals as wound
    (consistently wound meshes: 0 for coplanar faces). Zero-area faces take
    part in no sharp edge.

    Args:
        mesh: a :class:`surfsplat.io.Mesh` (validated).
        sharp_angle: degrees in (0, 180).

    Returns:
        :class:`MeshFeatures`.
    """
    import trimesh

    sharp_angle = check_sharp_angle(sharp_angle)
    verts = mesh.vertices.astype(np.float64)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    diagonal = max(float(np.linalg.norm(hi - lo)), 1e-300)
    tol = diagonal * 1e-9
    _, first, inverse = np.unique(np.round((verts - lo) / tol).astype(np.int64), axis=0,
                                  return_index=True, return_inverse=True)
    merged = verts[first]
    faces = inverse.reshape(-1)[mesh.faces]
    tri = trimesh.Trimesh(merged, faces, process=False, validate=False)
    adjacency = np.asarray(tri.face_adjacency, dtype=np.int64).reshape(-1, 2)
    shared = np.asarray(tri.face_adjacency_edges, dtype=np.int64).reshape(-1, 2)

    a, b, c = merged[faces[:, 0]], merged[faces[:, 1]], merged[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    length = np.linalg.norm(cross, axis=1)
    proper = length > 1e-12 * diagonal * diagonal  # twice the area, relative to the model's size
    normals = np.where(proper[:, None], cross / np.where(proper, length, 1.0)[:, None], 0.0)
    offsets = np.einsum("ij,ij->i", normals, a)

    f1, f2 = adjacency[:, 0], adjacency[:, 1]
    cos = np.clip(np.einsum("ij,ij->i", normals[f1], normals[f2]), -1.0, 1.0)
    angles = np.degrees(np.arccos(cos))
    usable = proper[f1] & proper[f2]
    sharp = usable & (angles > sharp_angle)
    # smooth patches: faces connected across the edges that are not sharp
    smooth = ~sharp
    graph = coo_matrix((np.ones(int(smooth.sum())), (f1[smooth], f2[smooth])), shape=(len(faces),) * 2)
    _, patch = connected_components(graph, directed=False)

    f1, f2, shared, angles = f1[sharp], f2[sharp], shared[sharp], angles[sharp]
    centroid = (a + b + c) / 3.0
    # kept side of the other face's plane: the side where the own face lies
    # (its centroid is off the shared edge, so strictly on one side)
    side1 = offsets[f2] - np.einsum("ij,ij->i", normals[f2], centroid[f1])  # own f1, other f2
    side2 = offsets[f1] - np.einsum("ij,ij->i", normals[f1], centroid[f2])  # own f2, other f1
    keep_sign = np.stack([np.where(side1 >= 0, 1.0, -1.0), np.where(side2 >= 0, 1.0, -1.0)], axis=1)
    return MeshFeatures(merged, faces, normals, offsets, patch.astype(np.int64), shared,
                        np.stack([f1, f2], axis=1), angles, keep_sign)


def _edge_points(vertices: np.ndarray, edges: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along each edge, both ends included, at most ``spacing`` apart: (P, 3) points, (P,) edge ids."""
    p0, p1 = vertices[edges[:, 0]], vertices[edges[:, 1]]
    count = np.ceil(np.linalg.norm(p1 - p0, axis=1) / spacing).astype(np.int64) + 1
    edge = np.repeat(np.arange(len(edges)), count)
    start = np.cumsum(count) - count
    step = np.arange(int(count.sum())) - start[edge]
    t = step / (count[edge] - 1.0)
    return p0[edge] + t[:, None] * (p1 - p0)[edge], edge


def mesh_clip_lines(mesh, face, positions, u, v, sharp_angle: float, *,
                    features: MeshFeatures | None = None) -> np.ndarray:
    """Exact clip lines for splats sampled on a mesh, from the faces across its sharp edges.

    Zwicker 2004, section 5: the line is the intersection of the splat's plane
    with the plane of the face on the other side of a sharp edge (dihedral
    angle above ``sharp_angle``), kept on the side of the splat's own face
    (see the module docstring: convex and concave edges alike). A splat gets
    a line from an edge when

    * the edge segment is within the splat's largest semi-axis of its center,
    * one of the edge's faces lies in the splat's own smooth patch (faces
      connected across edges that are not sharp), so edges of other parts
      of the model (the far side of a thin wall, the edges of a neighbouring
      face at a corner) are ignored; the other face gives the plane,
    * the line crosses the splat's ellipse.

    Of those, the nearest edge gives the first line and the nearest edge whose
    other face lies in a different patch the second (corners: two lines;
    a curved patch across the edge contributes one line, the nearest
    facet's plane). Two lines keep the intersection of two half-planes, which
    is the face only at a convex corner of it; at a reflex corner (the floor
    around the foot of a block standing on it), detected by an edge's
    midpoint lying on the cut side of the other edge's plane, only the first
    line is kept (two would cut a hole).

    Candidate edges come from a k-d tree over points spaced half the median
    splat radius along the sharp edges (vectorized, no per-splat loop).

    Args:
        mesh: the :class:`surfsplat.io.Mesh` the splats were sampled from.
        face: (N,) int face index of each splat's sample.
        positions: (N, 3) float splat centers (on their faces), model units.
        u, v: (N, 3) float scaled splat axes in the face planes.
        sharp_angle: degrees in (0, 180).
        features: precomputed :func:`mesh_features` of the mesh (optional).

    Returns:
        (N, 2, 3) float32 clip lines in normalized ``(s, t)``; ``(0, 0, 1)``
        for unused slots.
    """
    sharp_angle = check_sharp_angle(sharp_angle)
    feat = features if features is not None else mesh_features(mesh, sharp_angle)
    pts = np.asarray(positions, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    face = np.asarray(face, dtype=np.int64)
    n = len(pts)
    lines = np.broadcast_to(NO_CLIP, (n, 2, 3)).astype(np.float32)
    if n == 0 or len(feat.edges) == 0:
        return lines
    radius = np.sqrt(np.maximum(np.einsum("ij,ij->i", u, u), np.einsum("ij,ij->i", v, v)))
    spacing = 0.5 * float(np.median(radius))
    # cap the edge points at ~4 per splat (pathological meshes where every edge is sharp)
    total = float(np.linalg.norm(np.diff(feat.vertices[feat.edges], axis=1)[:, 0], axis=1).sum())
    spacing = max(spacing, total / (4.0 * n + 1000.0), 1e-12)
    epts, eid = _edge_points(feat.vertices, feat.edges, spacing)
    tree = cKDTree(epts)
    # every point of an edge is within spacing / 2 of one of its edge points
    reach = radius + 0.5 * spacing
    near, _ = tree.query(pts, k=1, distance_upper_bound=float(reach.max()), workers=-1)
    rows = np.flatnonzero(near < reach)
    if len(rows) == 0:
        return lines
    k = min(_EDGE_CANDIDATES, len(epts))
    _, hit = tree.query(pts[rows], k=k, distance_upper_bound=float(reach[rows].max()), workers=-1)
    hit = hit.reshape(len(rows), k)
    # (splat, edge) pairs: one per distinct edge among each splat's candidate edge points
    found = hit < len(epts)
    key = np.unique(np.repeat(rows, k)[found.ravel()] * len(feat.edges) + eid[hit[found]])
    row, e = key // len(feat.edges), key % len(feat.edges)
    p = pts[row]
    # exact distance from the splat center to each edge segment
    a0, a1 = feat.vertices[feat.edges[e, 0]], feat.vertices[feat.edges[e, 1]]
    seg = a1 - a0
    t = np.clip(_dot(p - a0, seg) / np.maximum(_dot(seg, seg), 1e-300), 0.0, 1.0)
    seg_dist = np.linalg.norm(a0 + t[:, None] * seg - p, axis=1)
    # which side of the edge the splat is on: the face in the splat's own patch
    own_face = face[row]
    own_patch = feat.patch[own_face]
    g1, g2 = feat.edge_faces[e, 0], feat.edge_faces[e, 1]
    in1, in2 = feat.patch[g1] == own_patch, feat.patch[g2] == own_patch
    nf = feat.normals[own_face]
    own_is_1 = in1 & (~in2 | (_dot(nf, feat.normals[g1]) >= _dot(nf, feat.normals[g2])))
    other = np.where(own_is_1, g2, g1)
    sign = np.where(own_is_1, feat.keep_sign[e, 0], feat.keep_sign[e, 1])
    # the other face's plane as the half-space sign * (d - n . x) >= 0, relative to the splat center
    normal = sign[:, None] * feat.normals[other]
    offset = sign * (feat.offsets[other] - _dot(feat.normals[other], p))
    cand, crossing = _lines_from_halfspaces(normal, offset, u[row], v[row])
    valid = np.flatnonzero((in1 | in2) & (seg_dist < radius[row]) & crossing)
    # first line: the nearest edge; second: the nearest one across to another patch
    order = valid[np.lexsort((seg_dist[valid], row[valid]))]
    first = order[_first_of_runs(row[order])]
    first_of = np.full(n, -1)
    first_of[row[first]] = first
    other_patch = feat.patch[other]
    rest = order[other_patch[order] != other_patch[first_of[row[order]]]]
    second = rest[_first_of_runs(row[rest])]
    # Two lines keep the intersection of two half-planes: right where the splat's face has a
    # convex corner there (each edge on the kept side of the other's plane), wrong at a reflex
    # one (the floor around a block standing on it), which would punch a hole: one line there.
    mid = 0.5 * (a0 + a1)                                                   # edge midpoints
    one = first_of[row[second]]
    slack = 1e-6 * radius[row[second]]

    def kept(i, j):  # is the midpoint of pair i's edge on the kept side of pair j's plane?
        return offset[j] - _dot(normal[j], mid[i] - p[j]) >= -slack

    second = second[kept(one, second) & kept(second, one)]
    lines[row[first], 0] = cand[first]
    lines[row[second], 1] = cand[second]
    return lines


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (M, 3) arrays."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _first_of_runs(keys: np.ndarray) -> np.ndarray:
    """Positions where a run of equal ``keys`` (sorted) starts."""
    return np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]]) if len(keys) else np.zeros(0, dtype=np.intp)


# -- raw points ------------------------------------------------------------------------------------


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
    pts = _check_vectors(positions, "positions")
    n = len(pts)
    nrm = _check_vectors(normals, "normals", n)
    idx = _check_indices(indices, n)
    neighbours = int(neighbours)
    if neighbours < 1:
        raise InputError(f"detect_sharp_features: neighbours must be >= 1, got {neighbours}")
    out_normals = nrm.copy()
    planes = np.zeros((n, 2, 4))
    planes[:, :, 3] = 1.0
    feature = np.zeros(n, dtype=bool)
    reach = np.zeros(n, dtype=np.float32)
    result = SharpFeatures(out_normals, planes, feature, 0, reach, sharp_angle, oriented)
    cols = [np.ascontiguousarray(nrm[:, c]) for c in range(3)]
    # 1a. seeds (all points, over the small neighbourhoods ``indices``): a neighbour's normal
    # more than a quarter of the angle from the point's own. Normals turn across a feature
    # within a band about one such neighbourhood wide, so every feature has seeds.
    seed = np.zeros(n, dtype=bool)
    cos_seed = math.cos(math.radians(sharp_angle / 4.0))

    def seed_test(sl):
        it = np.ascontiguousarray(idx[sl].T)                           # neighbour slot first: (k, B)
        dots = cols[0][it] * cols[0][sl] + cols[1][it] * cols[1][sl] + cols[2][it] * cols[2][sl]
        seed[sl] = (dots if oriented else np.abs(dots)).min(axis=0) < cos_seed

    _for_blocks(seed_test, n)
    seeds = np.flatnonzero(seed)
    kq = min(neighbours, n - 1)
    if len(seeds) == 0 or kq < 2:
        return result
    # 1b. the wide neighbourhoods, only where one may hold a seed: points within 1.25x a
    # seed's own wide-neighbourhood radius of it (similar density nearby)
    points = pts.astype(np.float64)
    tree = cKDTree(points, leafsize=16, balanced_tree=False)
    seed_radius = np.empty(len(seeds))
    for start in range(0, len(seeds), _QUERY_CHUNK):
        chunk = seeds[start:start + _QUERY_CHUNK]
        seed_radius[start:start + len(chunk)] = tree.query(points[chunk], k=[kq + 1], workers=-1)[0][:, 0]
    near, which = cKDTree(points[seeds]).query(points, k=1, distance_upper_bound=1.25 * seed_radius.max(),
                                               workers=-1)
    found = which < len(seeds)
    region = np.flatnonzero(found & (near < 1.25 * seed_radius[np.where(found, which, 0)]))
    full = np.empty((len(region), kq + 1), dtype=np.intp)               # the point itself first
    for start in range(0, len(region), _QUERY_CHUNK):
        rows = region[start:start + _QUERY_CHUNK]
        dist, nb = tree.query(points[rows], k=kq + 1, workers=-1)
        # the point itself is usually first; coincident duplicates may precede it or push
        # it out: drop it where it is, else the farthest result
        is_self = nb == rows[:, None]
        is_self[~is_self.any(axis=1), -1] = True
        full[start:start + len(rows), 0] = rows
        full[start:start + len(rows), 1:] = nb[~is_self].reshape(len(rows), kq)
        reach[rows] = dist[:, -1]
    # 1c. pre-test on the wide neighbourhoods: a normal more than a third of the angle from
    # their mean (two faces more than the angle apart put one at least half of it away)
    cos_pre = math.cos(math.radians(sharp_angle / 3.0))
    candidate = np.zeros(len(region), dtype=bool)

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

    _for_blocks(pretest, len(region))
    rows = np.flatnonzero(candidate)                                    # into region / full
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
        own_n, pl, feat, refined = _group_planes(x, nn, cos_sharp, oriented)
        if refine_normals:
            out_normals[point[refined]] = own_n[refined]
        planes[point] = pl
        feature[point] = feat

    _parallel(block, range(0, len(rows), _BLOCK))
    return result


def _fit(x: np.ndarray, member: np.ndarray):
    """Least-squares planes of G groups of points.

    ``x``: (B, K1, 3) float64 points; ``member``: (B, K1, G) bool.
    Returns (normal (B, G, 3) unit, offset (B, G) with ``normal . x = offset``
    on the plane, centroid (B, G, 3), active (B, G): at least ``_MIN_GROUP``
    points, not collinear).
    """
    w = member.astype(np.float64)
    count = w.sum(axis=1)                                           # (B, G)
    safe = np.maximum(count, 1.0)
    wt = np.ascontiguousarray(w.transpose(0, 2, 1))                 # (B, G, K1)
    centroid = np.matmul(wt, x) / safe[..., None]                   # (B, G, 3)
    # second moments of all groups at once: (B, G, 3, K1) @ (B, 1, K1, 3); offsets are relative
    # to the point (small), so the one-pass covariance loses nothing in float64
    second = np.matmul(x.transpose(0, 2, 1)[:, None] * wt[:, :, None, :], x[:, None]) / safe[..., None, None]
    c = second - centroid[..., :, None] * centroid[..., None, :]
    normal = smallest_eigenvectors(*(c[..., i, j].ravel() for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))))
    normal = normal.astype(np.float64).reshape(centroid.shape)
    # not collinear: lambda_mid / lambda_max ~ I2 / trace^2 above _MIN_SPREAD
    trace = c[..., 0, 0] + c[..., 1, 1] + c[..., 2, 2]
    i2 = (c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] ** 2 + c[..., 0, 0] * c[..., 2, 2] - c[..., 0, 2] ** 2
          + c[..., 1, 1] * c[..., 2, 2] - c[..., 1, 2] ** 2)
    active = (count >= _MIN_GROUP) & (i2 > _MIN_SPREAD * trace * trace)
    offset = (normal * centroid).sum(axis=2)
    return normal, offset, centroid, active


def _members(label: np.ndarray) -> np.ndarray:
    """(B, K1, 3) bool one-hot of labels 0..2 (label 3 = left out)."""
    return label[..., None] == np.arange(3)


def _agree(label: np.ndarray, nn: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(B, 3) +-1 that turns each plane's normal toward the sum of its points' normals."""
    total = np.matmul(_members(label).transpose(0, 2, 1).astype(np.float64), nn)     # (B, 3, 3)
    return np.where((total * normal).sum(axis=2) < 0, -1.0, 1.0)


def _assign(x, normal, offset, active, tol):
    """Label of the nearest active plane within ``tol`` (B,) of each point, 3 where none is."""
    dist = np.abs(np.matmul(x, normal.transpose(0, 2, 1)) - offset[:, None, :])
    dist = np.where(active[:, None, :], dist, np.inf)
    nearest = np.argmin(dist, axis=2)
    return np.where(np.take_along_axis(dist, nearest[..., None], axis=2)[..., 0] < tol[:, None], nearest, 3)


def _refine_groups(x, label, normal, offset, active, tol):
    """Step 3 of :func:`detect_sharp_features`: (label, trimmed) after least squares,
    reassignment, a group for coplanar left-over points, and trimming."""
    for _ in range(2):
        label = _assign(x, normal, offset, active, tol)
        normal, offset, _, active = _fit(x, _members(label))
    # points left over (e.g. a corner's third face, when a stray point of another face kept
    # the greedy step from seeing that the rest is one plane): a group of their own if coplanar
    left = label == 3
    ln, lo, _, lok = _fit(x, left[..., None])
    flat = np.where(left, np.abs(np.matmul(x, ln[:, 0, :, None])[..., 0] - lo[:, :1]), 0.0).max(axis=1) < tol
    free = np.argmin(active, axis=1)
    new_group = lok[:, 0] & flat & ~active.all(axis=1)
    if new_group.any():
        label = np.where(left & new_group[:, None], free[:, None], label)
        normal, offset, _, active = _fit(x, _members(label))
        label = _assign(x, normal, offset, active, tol)
        normal, offset, _, active = _fit(x, _members(label))
    # trim: points of another face within the tolerance of a plane (near the edge) tilt it
    # slightly; refit each plane to the points within 4x the median residual of its trimmed
    # points (exact samples: only its own face's points; noisy ones: ~3 sigma), floored at
    # 1e-4 of the radius; three rounds, as a tilted plane's residuals start large
    trimmed = label
    floor = _TRIM * tol[:, None] / _INLIER
    for _ in range(3):
        residual = np.abs((x * np.take_along_axis(normal, np.minimum(label, 2)[..., None], 1)).sum(axis=2)
                          - np.take_along_axis(offset, np.minimum(label, 2), 1))
        medians = []
        for g in range(3):
            mine = trimmed == g
            ranked = np.sort(np.where(mine, residual, np.inf), axis=1)
            middle = np.maximum(mine.sum(axis=1) - 1, 0) // 2
            medians.append(np.where(mine.any(axis=1), np.take_along_axis(ranked, middle[:, None], 1)[:, 0], 0.0))
        limit = np.maximum(4.0 * np.stack(medians, axis=1), floor)                 # (B, 3)
        trimmed = np.where((label < 3) & (residual <= np.take_along_axis(limit, np.minimum(label, 2), 1)), label, 3)
        normal, offset, _, active = _fit(x, _members(trimmed))
    return label, trimmed


def _group_planes(x: np.ndarray, nn: np.ndarray, cos_sharp: float, oriented: bool):
    """Steps 2-4 of :func:`detect_sharp_features` for a block of B candidate points.

    ``x``: (B, K1, 3) float64 offsets from the point (slot 0 = the point);
    ``nn``: (B, K1, 3) float64 unit normals (sign-aligned unless oriented).
    Returns (own normal (B, 3), planes (B, 2, 4), feature (B,) bool, refined (B,) bool:
    where the own normal is the own plane's).
    """
    b_count, k1 = x.shape[:2]
    tol = _INLIER * np.sqrt((x * x).sum(axis=2).max(axis=1))          # (B,)
    # 2. hypotheses: the plane through each neighbour h with its normal; inliers[b, h, k]
    along = np.matmul(nn, x.transpose(0, 2, 1))
    along -= (nn * x).sum(axis=2)[..., None]
    inliers = np.abs(along) < tol[:, None, None]
    del along
    label = np.full((b_count, k1), 3)
    remaining = np.ones((b_count, k1), dtype=bool)
    for g in range(3):
        # the rest at once when it all fits one plane
        normal, offset, _, active = _fit(x, remaining[..., None])
        off_plane = np.abs(np.matmul(x, normal[:, 0, :, None])[..., 0] - offset[:, :1])
        coplanar = active[:, 0] & (np.where(remaining, off_plane, 0.0).max(axis=1) < tol)
        score = np.matmul(inliers, remaining[..., None].astype(np.float32))[..., 0] if g < 2 else None
        if score is not None:
            best = np.argmax(score, axis=1)
            take = np.take_along_axis(inliers, best[:, None, None], axis=1)[:, 0] & remaining
            # one least-squares refinement of the hypothesis: its plane through its inliers
            hn, ho, _, hok = _fit(x, take[..., None])
            near = np.abs(np.matmul(x, hn[:, 0, :, None])[..., 0] - ho[:, :1]) < tol[:, None]
            take = np.where(hok[:, :1], near & remaining, take)
        else:
            take = np.zeros_like(remaining)
        take = np.where(coplanar[:, None], remaining, take)
        take &= (take.sum(axis=1) >= _MIN_GROUP)[:, None]
        label[take] = g
        remaining &= ~take
    # 3. least squares, reassignment to the nearest plane within the tolerance; a second pass
    # from the trimmed (exact) planes of the first where points were left on no plane
    normal, offset, centroid, active = _fit(x, _members(label))
    label, trimmed = _refine_groups(x, label, normal, offset, active, tol)
    normal, offset, centroid, active = _fit(x, _members(trimmed))
    again = np.flatnonzero((label == 3).any(axis=1))
    if len(again):
        label[again], trimmed[again] = _refine_groups(x[again], label[again], normal[again], offset[again],
                                                      active[again], tol[again])
        fitted = _fit(x[again], _members(trimmed[again]))
        for whole, part in zip((normal, offset, centroid, active), fitted):
            whole[again] = part
    # orient each plane like its points' normals
    flip = _agree(label, nn, normal)
    # planes within the angle are one face: merge, refit (every row, so rows do not depend on their block)
    oriented_normal = normal * flip[..., None]
    root = np.broadcast_to(np.arange(4), (b_count, 4)).copy()
    for ga, gb in ((0, 1), (0, 2), (1, 2)):
        dot = np.einsum("bj,bj->b", oriented_normal[:, ga], oriented_normal[:, gb])
        close = active[:, ga] & active[:, gb] & ((dot if oriented else np.abs(dot)) > cos_sharp)
        hi = np.maximum(root[:, ga], root[:, gb])
        lo = np.minimum(root[:, ga], root[:, gb])
        root = np.where(close[:, None] & (root == hi[:, None]), lo[:, None], root)
    label = np.take_along_axis(root, label, axis=1)
    trimmed = np.take_along_axis(root, trimmed, axis=1)
    normal, offset, centroid, active = _fit(x, _members(trimmed))
    flip = _agree(label, nn, normal)
    normal *= flip[..., None]
    offset *= flip
    # a plane that another group's points straddle is no face of this neighbourhood
    # (e.g. one through a handful of points along another edge, near a corner):
    # a face's points lie on one side of every other face's plane
    members = _members(label)
    signed = np.matmul(x, normal.transpose(0, 2, 1)) - offset[:, None, :]      # (B, K1, plane)
    beyond = np.abs(signed) > _STRADDLE_TOL * tol[:, None, None]
    mt = members.transpose(0, 2, 1).astype(np.float32)                         # (B, group, K1)
    above = np.matmul(mt, (beyond & (signed > 0)).astype(np.float32)).transpose(0, 2, 1)   # (B, plane, group)
    below = np.matmul(mt, (beyond & (signed < 0)).astype(np.float32)).transpose(0, 2, 1)
    size = members.sum(axis=1).astype(np.float64)[:, None, :]                   # (B, 1, group)
    least = np.maximum(2.0, _STRADDLE * size)
    straddled = ((above >= least) & (below >= least) & active[:, None, :]).any(axis=2)   # (B, plane)
    active &= ~straddled
    # 4. the point's own group: the plane nearest to the point (the origin)
    own = np.argmin(np.where(active, np.abs(offset), np.inf), axis=1)
    b = np.arange(b_count)
    # (the point must lie on it: near a corner its own face may be a sliver that fitted no plane)
    own_ok = active[b, own] & (np.abs(offset[b, own]) < tol)
    others = active & (np.arange(3) != own[:, None]) & own_ok[:, None]
    own_centroid = centroid[b, own]
    # the half-space of each other plane that holds the own group: sign * (d - n . x) >= 0
    sign = np.where(offset - (normal * own_centroid[:, None, :]).sum(axis=2) >= 0, 1.0, -1.0)
    halfspace = np.concatenate([normal * sign[..., None], (offset * sign)[..., None]], axis=2)   # (B, 3, 4)
    order = np.argsort(~others, axis=1, kind="stable")[:, :2]           # the (up to two) others first
    # Faces meeting at a feature are planar right up to it: (almost) every point lies on one of
    # the planes. A surface curved at the neighbourhood's scale (a hole of a few splat radii)
    # fits three planes only in strips, with many points on none: no feature there.
    gap = np.where(active[:, None, :], np.abs(signed), np.inf).min(axis=2)          # (B, K1)
    covered = (gap < _COVER_TOL * tol[:, None]).mean(axis=1) >= _COVERED
    used = np.take_along_axis(others, order, axis=1) & covered[:, None]
    planes = np.where(used[..., None], np.take_along_axis(halfspace, order[..., None], axis=1),
                      np.array([0.0, 0.0, 0.0, 1.0]))
    feature = used[:, 0]
    # the own plane also replaces the normal where no other plane could be fitted (the other
    # faces are slivers of a few points near a corner) but the own face is exactly planar:
    # residuals of its points far below the tolerance (a curved surface fills it)
    mine = trimmed == own[:, None]
    off = (x * normal[b, own][:, None, :]).sum(axis=2) - offset[b, own][:, None]
    rms = np.sqrt(np.where(mine, off * off, 0.0).sum(axis=1) / np.maximum(mine.sum(axis=1), 1))
    planar = own_ok & (mine.sum(axis=1) >= 2 * _MIN_GROUP) & (rms < _PLANAR * tol)
    refined = feature | planar
    own_n = np.where(refined[:, None], normal[b, own], nn[:, 0])
    return own_n, planes, feature, refined


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
    pts = _check_vectors(positions, "positions")
    n = len(pts)
    u = _check_vectors(u, "u", n).astype(np.float64)
    v = _check_vectors(v, "v", n).astype(np.float64)
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
        cand_d = cand[:, 3] + _dot(cand_n, pts[j].astype(np.float64) - p[row])
        line, crossing = _lines_from_halfspaces(cand_n, cand_d, u[sel][row], v[sel][row])
        ok = np.flatnonzero(crossing)
        first = ok[_first_of_runs(row[ok])]
        first_of = np.full(m, -1)
        first_of[row[first]] = first
        rest = ok[_dot(cand_n[ok], cand_n[first_of[row[ok]]]) < cos_sharp]
        second = rest[_first_of_runs(row[rest])]
        out = np.broadcast_to(NO_CLIP, (m, 2, 3)).astype(np.float32)
        out[row[first], 0] = line[first]
        out[row[second], 1] = line[second]
        lines[sel] = out

    _parallel(block, range(0, len(rows), _BLOCK))
    return lines
