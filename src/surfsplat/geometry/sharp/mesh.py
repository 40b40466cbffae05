"""Clip lines for samples of a triangle mesh: exact planes of the faces across its sharp edges.

Zwicker et al. 2004, section 5: the clip line of a splat is the intersection
of its plane with the plane of the face on the other side of a sharp edge
(dihedral angle above the threshold). Which side is kept: the side of the
splat's own face. For a splat on face A next to face B, the line is A's plane
intersected with B's plane; the kept side is the side of B's plane where A
lies. At a convex edge that is the inside of B's plane, at a concave edge the
outside, so the part of the splat that pokes out of the solid (convex) or
through face B (concave) is cut. Used by
:func:`surfsplat.geometry.sampling.sample_mesh` and
:func:`surfsplat.geometry.sampling.surface_splats`.

Open boundaries (edges of only one face: the rim of a scan, a hole in it) are
treated the same way on request (``boundaries=True``): the plane across them is
the plane through the edge perpendicular to its face, moved out by
:data:`BOUNDARY_MARGIN` of the splat's radius, so a splat next to the boundary
is cut there instead of reaching past the surface's outline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ...cloud import NO_CLIP
from ...io.surface import DEGENERATE_AREA, boundary_edges, face_adjacency, weld_map
from ..common import dot, first_of_runs
from .lines import check_sharp_angle, lines_from_halfspaces

#: Open boundaries cut splats this fraction of their radius outside the boundary edge. Measured
#: on frag_115.ply (scan, 1,493 boundary edges; 512 and 1024 px, 1 and 0.75 px spacing): cutting
#: exactly at the edge left up to 7 hole pixels in 1-3 px wide slivers of its jagged rim; 0.1 up
#: to 2, 0.15 and 0.25 none; leaks past the rim grow with the margin (1024 px, 1 px spacing:
#: 412, 476, 518, 614 pixels; 2,609 without boundary lines).
BOUNDARY_MARGIN = 0.25
#: Edge points per edge-sample query: candidates of the nearest edges.
_EDGE_CANDIDATES = 24


@dataclass
class MeshFeatures:
    """The sharp edges (and, on request, open boundary edges) of a triangle mesh and the planes on either side.

    Attributes:
        vertices: (V', 3) float64 positions after merging duplicates.
        faces: (F, 3) int64 faces on the merged vertices (same order as the mesh's).
        normals: (F + B, 3) float64 unit face normals (zero for degenerate faces), then
            the normals of the B virtual planes at the open boundary edges (through
            the edge, perpendicular to its face, pointing out of the surface).
        offsets: (F + B,) float64 ``normals . x`` on each face's (virtual) plane.
        patch: (F + B,) int64 label of the smooth patch (faces connected across
            edges that are not sharp) each face belongs to; a label of its own for
            each virtual plane.
        edges: (E, 2) int64 merged vertex ids of the sharp edges (then the boundary edges).
        edge_faces: (E, 2) int64 the two faces at each edge (a face and its virtual
            plane ``F + b`` at a boundary edge).
        angles: (E,) float64 dihedral angles between those faces' normals, degrees
            (90 at boundary edges).
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


def mesh_features(mesh, sharp_angle: float | None, *, boundaries: bool = False) -> MeshFeatures:
    """Find the edges of ``mesh`` whose dihedral angle exceeds ``sharp_angle`` degrees.

    Duplicated vertices (CAD meshes split them along creases so that each face
    keeps its own normal; triangle soups) are merged first
    (:func:`surfsplat.io.surface.weld_map`, within 1e-6 of the bounding-box
    diagonal), so that the faces on either side of a crease become
    neighbours. Edge adjacency: manifold edges shared by exactly two faces
    (:func:`surfsplat.io.surface.face_adjacency`); the angle is the one
    between the faces' normals as wound (consistently wound meshes: 0 for
    coplanar faces). Zero-area faces take part in no sharp edge.

    Args:
        mesh: a :class:`surfsplat.io.Mesh` (validated).
        sharp_angle: degrees in (0, 180), or None (no sharp edges; only
            boundaries, when asked for).
        boundaries: also list the open boundary edges (used by one face only),
            each with a virtual plane through it, perpendicular to its face.

    Returns:
        :class:`MeshFeatures`.
    """
    if sharp_angle is not None:
        sharp_angle = check_sharp_angle(sharp_angle)
    verts = mesh.vertices.astype(np.float64)
    ids = weld_map(verts)
    first = np.zeros(int(ids.max()) + 1, dtype=np.int64)
    first[ids[::-1]] = np.arange(len(ids))[::-1]                       # first vertex of each group
    merged = verts[first]
    faces = ids[mesh.faces]
    adjacency, _, shared = face_adjacency(faces, len(merged))
    a, b, c = merged[faces[:, 0]], merged[faces[:, 1]], merged[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    length = np.linalg.norm(cross, axis=1)
    diagonal = max(float(np.linalg.norm(merged.max(axis=0) - merged.min(axis=0))), 1e-300)
    proper = length > DEGENERATE_AREA * diagonal * diagonal  # twice the area, relative to the model's size
    normals = np.where(proper[:, None], cross / np.where(proper, length, 1.0)[:, None], 0.0)
    offsets = np.einsum("ij,ij->i", normals, a)

    f1, f2 = adjacency[:, 0], adjacency[:, 1]
    cos = np.clip(np.einsum("ij,ij->i", normals[f1], normals[f2]), -1.0, 1.0)
    angles = np.degrees(np.arccos(cos))
    usable = proper[f1] & proper[f2]
    sharp = usable & (angles > sharp_angle) if sharp_angle is not None else np.zeros(len(f1), dtype=bool)
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
    features = MeshFeatures(merged, faces, normals, offsets, patch.astype(np.int64), shared,
                            np.stack([f1, f2], axis=1), angles, keep_sign)
    return _with_boundaries(features, centroid, proper) if boundaries else features


def _with_boundaries(feat: MeshFeatures, centroid: np.ndarray, proper: np.ndarray) -> MeshFeatures:
    """``feat`` with the open boundary edges of its (proper) faces appended, each with a virtual plane
    through the edge, perpendicular to its face, its outer side cut (see :class:`MeshFeatures`)."""
    face, _, edges = boundary_edges(feat.faces, len(feat.vertices))
    keep = proper[face]
    face, edges = face[keep], edges[keep]
    n_faces, count = len(feat.faces), len(face)
    if count == 0:
        return feat
    p0, p1 = feat.vertices[edges[:, 0]], feat.vertices[edges[:, 1]]
    along = p1 - p0
    normal = np.cross(along, feat.normals[face])                        # in the face's plane, across the edge
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    outward = np.einsum("ij,ij->i", normal, p0 - centroid[face]) >= 0
    normal = np.where(outward[:, None], normal, -normal)
    offset = np.einsum("ij,ij->i", normal, p0)
    virtual = n_faces + np.arange(count)
    return MeshFeatures(
        feat.vertices, feat.faces, np.concatenate([feat.normals, normal]), np.concatenate([feat.offsets, offset]),
        np.concatenate([feat.patch, feat.patch.max() + 1 + np.arange(count)]),
        np.concatenate([feat.edges, edges]), np.concatenate([feat.edge_faces, np.stack([face, virtual], axis=1)]),
        np.concatenate([feat.angles, np.full(count, 90.0)]),
        np.concatenate([feat.keep_sign, np.ones((count, 2))]))


def _edge_points(vertices: np.ndarray, edges: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along each edge, both ends included, at most ``spacing`` apart: (P, 3) points, (P,) edge ids."""
    p0, p1 = vertices[edges[:, 0]], vertices[edges[:, 1]]
    count = np.ceil(np.linalg.norm(p1 - p0, axis=1) / spacing).astype(np.int64) + 1
    edge = np.repeat(np.arange(len(edges)), count)
    start = np.cumsum(count) - count
    step = np.arange(int(count.sum())) - start[edge]
    t = step / (count[edge] - 1.0)
    return p0[edge] + t[:, None] * (p1 - p0)[edge], edge


def mesh_clip_lines(mesh, face, positions, u, v, sharp_angle: float | None, *,
                    features: MeshFeatures | None = None, boundaries: bool = False,
                    order: np.ndarray | None = None, bary: np.ndarray | None = None) -> np.ndarray:
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
        u, v: (N, 3) float scaled splat axes in the face planes, model units.
        sharp_angle: degrees in (0, 180), or None (no sharp edges: boundaries only).
        features: precomputed :func:`mesh_features` of the mesh (optional).
        boundaries: also cut splats at the mesh's open boundary edges (the
            plane through the edge, perpendicular to its face; see the module
            docstring), so they do not reach past the surface's outline.
        order: optional (N,) permutation that puts the splats in a spatially
            coherent order (:func:`surfsplat.geometry.neighbors.spatial_order`):
            the search for nearby edges visits them in it (about half the time
            for 2 M random samples); the lines are the same.
        bary: optional (N, 3) barycentrics of the splat centers in their faces:
            then a splat whose smooth patch is planar and whose center lies
            farther from its own face's sides than its largest semi-axis is
            left out of the search (the lines are the same: in a plane, the
            path to any edge of the patch leaves the face through a side,
            :func:`_far_from_edges`).

    Returns:
        (N, 2, 3) float32 clip lines in normalized ``(s, t)``; ``(0, 0, 1)``
        for unused slots.
    """
    feat = features if features is not None else mesh_features(mesh, sharp_angle, boundaries=boundaries)
    pts = np.asarray(positions, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    face = np.asarray(face, dtype=np.int64)
    n = len(pts)
    lines = np.broadcast_to(NO_CLIP, (n, 2, 3)).astype(np.float32)
    if n == 0 or len(feat.edges) == 0:
        return lines
    radius = np.sqrt(np.maximum(np.einsum("ij,ij->i", u, u), np.einsum("ij,ij->i", v, v)))
    if bary is not None:
        near = np.flatnonzero(~_far_from_edges(feat, face, np.asarray(bary, dtype=np.float64), radius))
        sub_order = None
        if order is not None:   # the given order restricted to the splats searched
            rank = np.full(n, -1)
            rank[near] = np.arange(len(near))
            sub_order = rank[np.asarray(order)]
            sub_order = sub_order[sub_order >= 0]
        pairs = _splat_edge_pairs(feat, pts[near], radius[near], sub_order) if len(near) else None
        if pairs is not None:
            pairs = near[pairs[0]], pairs[1]
    else:
        pairs = _splat_edge_pairs(feat, pts, radius, order)
    if pairs is None:
        return lines
    row, e = pairs
    p = pts[row]
    # exact distance from the splat center to each edge segment
    a0, a1 = feat.vertices[feat.edges[e, 0]], feat.vertices[feat.edges[e, 1]]
    seg = a1 - a0
    t = np.clip(dot(p - a0, seg) / np.maximum(dot(seg, seg), 1e-300), 0.0, 1.0)
    seg_dist = np.linalg.norm(a0 + t[:, None] * seg - p, axis=1)
    own_side, other, normal, offset = _across(feat, face[row], e, p)
    boundary = other >= len(feat.faces)                     # virtual planes of open boundary edges
    offset = offset + np.where(boundary, BOUNDARY_MARGIN * radius[row], 0.0)
    cand, crossing = lines_from_halfspaces(normal, offset, u[row], v[row])
    valid = np.flatnonzero(own_side & (seg_dist < radius[row]) & crossing)
    # first line: the nearest edge; second: the nearest one across to another patch
    order = valid[np.lexsort((seg_dist[valid], row[valid]))]
    first = order[first_of_runs(row[order])]
    first_of = np.full(n, -1)
    first_of[row[first]] = first
    other_patch = feat.patch[other]
    rest = order[other_patch[order] != other_patch[first_of[row[order]]]]
    second = rest[first_of_runs(row[rest])]
    # Two lines keep the intersection of two half-planes: right where the splat's face has a
    # convex corner there (each edge on the kept side of the other's plane), wrong at a reflex
    # one (the floor around a block standing on it), which would punch a hole: one line there.
    mid = 0.5 * (a0 + a1)                                                   # edge midpoints
    one = first_of[row[second]]
    slack = 1e-6 * radius[row[second]]

    def kept(i, j):  # is the midpoint of pair i's edge on the kept side of pair j's plane?
        return offset[j] - dot(normal[j], mid[i] - p[j]) >= -slack

    second = second[kept(one, second) & kept(second, one)]
    lines[row[first], 0] = cand[first]
    lines[row[second], 1] = cand[second]
    return lines


def _far_from_edges(feat: MeshFeatures, face: np.ndarray, bary: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """(N,) bool: splats no sharp or boundary edge of their own patch can cut (see :func:`mesh_clip_lines`).

    A point inside a triangle lies ``bary_i * h_i`` from the line of side ``i`` (``h_i`` the
    triangle's height over that side), and the nearest point of the triangle's boundary is on
    the nearest of those lines. Where the face's smooth patch is planar, every edge of the
    patch lies in that plane, and the segment from the center to its nearest point leaves the
    face through a side: the edge is at least that far. A splat whose radius falls short of it
    (with a relative margin of 1e-4 for float32 centers) gets no clip line; splats in curved
    patches are always searched.
    """
    n_faces = len(feat.faces)
    normals = feat.normals[:n_faces]
    patch = feat.patch[:n_faces]
    # a patch is planar when all its faces share the normal of one of them (connected: one plane)
    first = np.full(patch.max() + 1, -1)
    first[patch[::-1]] = np.arange(n_faces)[::-1]
    bent = np.einsum("ij,ij->i", normals, normals[first[patch]]) < 1.0 - 1e-9
    planar = np.ones(len(first), dtype=bool)
    planar[patch[bent]] = False
    corners = feat.vertices[feat.faces]                                      # (F, 3, 3)
    sides = np.linalg.norm(corners[:, [2, 0, 1]] - corners[:, [1, 2, 0]], axis=2)   # side i: opposite corner i
    area2 = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        heights = np.where(sides > 0, area2[:, None] / sides, 0.0)           # (F, 3)
    inside = (bary * heights[face]).min(axis=1)
    return planar[patch[face]] & (inside > radius * (1.0 + 1e-4))


def _splat_edge_pairs(feat: MeshFeatures, pts: np.ndarray, radius: np.ndarray, order: np.ndarray | None = None):
    """Candidate (splat, sharp edge) pairs ``(row, e)``: edges with a point near the splat; None if none.

    ``pts`` (N, 3) float64 splat centers and ``radius`` (N,) their largest
    semi-axes, model units. The candidates come from a k-d tree over points
    spaced half the median radius along the sharp edges; each pair is listed
    once, sorted by splat. ``order``: a spatially coherent order of the splats to query them in, or None.
    """
    n = len(pts)
    spacing = 0.5 * float(np.median(radius))
    # cap the edge points at ~4 per splat (pathological meshes where every edge is sharp)
    total = float(np.linalg.norm(np.diff(feat.vertices[feat.edges], axis=1)[:, 0], axis=1).sum())
    spacing = max(spacing, total / (4.0 * n + 1000.0), 1e-12)
    epts, eid = _edge_points(feat.vertices, feat.edges, spacing)
    tree = cKDTree(epts)
    # every point of an edge is within spacing / 2 of one of its edge points
    reach = radius + 0.5 * spacing
    bound = float(reach.max())
    if order is None:
        near, _ = tree.query(pts, k=1, distance_upper_bound=bound, workers=-1)
        rows = np.flatnonzero(near < reach)
    else:
        near, _ = tree.query(pts[order], k=1, distance_upper_bound=bound, workers=-1)
        hit = np.zeros(n, dtype=bool)
        hit[order] = near < reach[order]
        rows = np.flatnonzero(hit)
    if len(rows) == 0:
        return None
    k = min(_EDGE_CANDIDATES, len(epts))
    _, hit = tree.query(pts[rows], k=k, distance_upper_bound=float(reach[rows].max()), workers=-1)
    hit = hit.reshape(len(rows), k)
    # (splat, edge) pairs: one per distinct edge among each splat's candidate edge points
    found = hit < len(epts)
    key = np.unique(np.repeat(rows, k)[found.ravel()] * len(feat.edges) + eid[hit[found]])
    return key // len(feat.edges), key % len(feat.edges)


def _across(feat: MeshFeatures, own_face: np.ndarray, e: np.ndarray, p: np.ndarray):
    """The plane across sharp edge ``e`` from each splat (on ``own_face``, centered at ``p``, model units).

    Returns ``(own_side, other, normal, offset)``: (M,) bool whether either
    face of the edge lies in the splat's own smooth patch (else the edge
    belongs to another part of the model), (M,) the other face, and its plane
    as the half-space ``normal . (x - p) <= offset`` that holds the splat's
    own face (``sign * (d - n . x) >= 0`` with the edge's ``keep_sign``).
    """
    # which side of the edge the splat is on: the face in the splat's own patch
    own_patch = feat.patch[own_face]
    g1, g2 = feat.edge_faces[e, 0], feat.edge_faces[e, 1]
    in1, in2 = feat.patch[g1] == own_patch, feat.patch[g2] == own_patch
    nf = feat.normals[own_face]
    own_is_1 = in1 & (~in2 | (dot(nf, feat.normals[g1]) >= dot(nf, feat.normals[g2])))
    other = np.where(own_is_1, g2, g1)
    sign = np.where(own_is_1, feat.keep_sign[e, 0], feat.keep_sign[e, 1])
    # the other face's plane as the half-space sign * (d - n . x) >= 0, relative to the splat center
    normal = sign[:, None] * feat.normals[other]
    offset = sign * (feat.offsets[other] - dot(feat.normals[other], p))
    return in1 | in2, other, normal, offset
