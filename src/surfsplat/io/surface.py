"""Meshes as connected surfaces: welding, edge adjacency, dihedral angles and crease-aware normals.

A file's triangles are not always connected where the surface is: STL stores
every triangle with its own three vertices (a *triangle soup*), and CAD
exporters split vertices along creases so that each side keeps its own normal.
:func:`weld` merges coincident vertices (within a tolerance relative to the
model's size) so that neighbouring faces share their vertices again;
:func:`face_adjacency` then finds the faces on either side of every edge, and
:func:`dihedral_angles` the angle between their normals.

Crease-aware normals (:func:`crease_normals`) are the classic "auto smooth" of
modelling tools: around each vertex, the faces are split into *fans* of faces
that are connected across edges whose dihedral angle is at most the sharp
angle; every corner gets the mean normal of its fan, weighted by the faces'
angles at the vertex (Thuermer & Wuethrich 1998). Curved parts (small angles
between neighbouring facets) are shaded smoothly, sharp edges stay sharp, and
a mesh without sharp edges gets one angle-weighted normal per vertex. (The
bunny's ground truth, which used area-weighted vertex normals, changed by
that: PSNR 44 dB between the two at 512 x 512, 19% of its pixels by more than
1/255, 2.5% by more than 4/255; ``benchmarks/results/mesh_sampling.md``.)
:func:`shading_normals` picks a mesh's normals per corner: the stored ones
where the file has normals, crease-aware ones otherwise. The ground-truth
rasterizer (``surfsplat.rendering.mesh``) and surface sampling
(``surfsplat.geometry.sampling``) both shade with them.

The default sharp angle is chosen per mesh (:func:`auto_sharp_angle`, the
``"auto"`` that ``render_mesh`` and surface sampling default to):
:data:`DEFAULT_SHARP_ANGLE` (30 degrees, the default of modelling tools' auto
smooth) for a mesh with creases, None (smooth everywhere) for one without. A
mesh has creases when at least half of its edge length sharper than 20 degrees
is sharper than 40 degrees (:data:`CREASE_BAND`): CAD parts put their facets
either almost flat (curved surfaces) or at design angles, scans have a
continuous tail of noise angles. Measured on the development data
(``benchmarks/results/mesh_sampling.md``): the CAD part featuretype.ply has
dihedral angles of 0-15 degrees between the facets of its curved surfaces
(hole, rounds), none from 15 to 45, and 45 (chamfer) and 90 degrees at its
edges: 100% of the length above 20 degrees is above 40. The bunny has 15%,
the frag_115 scan 8%: at 30 degrees their crease normals would split at
isolated noise spikes (2.6% of the bunny's corners; speckles along the ear's
rim in the ground truth, 37 dB against the smooth one), so they stay smooth.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InputError
from .mesh import Mesh

#: Welding tolerance relative to the diagonal of the mesh's bounding box: vertices closer
#: than ``WELD_TOLERANCE * diagonal`` are merged (1e-6: far below any feature of a
#: tessellation, far above float32 rounding of the coordinates, 6e-8 of their magnitude, unless
#: the model lies more than ~10 of its sizes away from the origin).
WELD_TOLERANCE = 1e-6
#: Dihedral angle (degrees, between the normals of two faces sharing an edge) above which
#: an edge is sharp by default: crease normals split there, and sampled splats get clip lines.
DEFAULT_SHARP_ANGLE = 30.0
#: Dihedral angles (degrees) of the band around the default sharp angle: a mesh has creases
#: when the edge length above the band is at least the edge length inside it.
CREASE_BAND = (20.0, 40.0)
#: The sharp-angle argument that asks for :func:`auto_sharp_angle`.
AUTO = "auto"
#: Stored normals of merged vertices that differ by more than this (degrees) are kept per corner.
NORMAL_AGREEMENT = 1.0
#: Faces with twice their area below this fraction of the squared bounding-box diagonal are degenerate.
DEGENERATE_AREA = 1e-12


def _diagonal(vertices: np.ndarray) -> float:
    """The bounding-box diagonal of (V, 3) vertices, model units (1 for an empty or single point)."""
    if len(vertices) == 0:
        return 1.0
    v = np.asarray(vertices, dtype=np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) or 1.0


def weld_map(vertices: np.ndarray, tolerance: float | None = None) -> np.ndarray:
    """The welded vertex id of each vertex: (V,) int64 in ``[0, V')``, ids in order of first appearance.

    Vertices closer than ``tolerance`` (model units; default
    :data:`WELD_TOLERANCE` times the bounding-box diagonal) get the same id,
    as do chains of them (connected components of the "closer than" graph).
    Exact duplicates are found by sorting; the rest with a k-d tree.
    """
    v = np.asarray(vertices, dtype=np.float64)
    n = len(v)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    tol = WELD_TOLERANCE * _diagonal(v) if tolerance is None else float(tolerance)
    if not np.isfinite(tol) or tol < 0:
        raise InputError(f"weld: tolerance must be a finite number >= 0, got {tolerance!r}")
    _, first, exact = np.unique(v, axis=0, return_index=True, return_inverse=True)
    exact = exact.reshape(-1)
    label = exact
    if tol > 0 and len(first) > 1:
        pairs = cKDTree(v[first]).query_pairs(tol, output_type="ndarray")
        if len(pairs):
            m = len(first)
            graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
            _, component = connected_components(graph, directed=False)
            label = component[exact]
    # renumber by first appearance, so a mesh without duplicates keeps its vertex order
    _, first_of_label, inverse = np.unique(label, return_index=True, return_inverse=True)
    order = np.argsort(first_of_label, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[inverse.reshape(-1)].astype(np.int64)


def weld(mesh: Mesh, tolerance: float | None = None, *, source: str = "weld: mesh") -> Mesh:
    """Merge coincident vertices so that faces meeting there share them: a connected surface.

    Args:
        mesh: the mesh (validated here).
        tolerance: merge distance in model units; None (default):
            :data:`WELD_TOLERANCE` (1e-6) times the diagonal of the vertices'
            bounding box. 0 merges exact duplicates only.
        source: the mesh's name (its file) in messages.

    Returns:
        A new :class:`Mesh` (the input is returned unchanged when nothing
        merges): each group of merged vertices becomes its first vertex
        (position kept exactly), faces re-indexed, faces whose corners
        collapsed onto fewer than three vertices removed. ``merged_vertices``
        and ``collapsed_faces`` count the changes (added to the input's counts).
        Colors are averaged over each group. Stored vertex normals are averaged
        (renormalized) when the normals of every group agree within
        :data:`NORMAL_AGREEMENT` degrees; otherwise (the file split vertices at
        a crease to give each side its normal) they are kept exactly, per face
        corner (``corner_normals``), and ``vertex_normals`` is None. Stored
        corner normals follow their faces.

    Raises:
        InputError: an invalid mesh or tolerance, or one whose every face collapses.
    """
    mesh = mesh.validated(source)
    ids = weld_map(mesh.vertices, tolerance)
    n_new = int(ids.max()) + 1 if len(ids) else 0
    if n_new == len(mesh.vertices):
        return _wound_consistently(mesh)
    first = np.full(n_new, len(ids), dtype=np.int64)
    np.minimum.at(first, ids, np.arange(len(ids)))
    faces = ids[mesh.faces]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    if not keep.any():   # a few far-off vertices make the diagonal, and so the tolerance, huge
        lo, hi = mesh.bounds()
        raise InputError(f"{source}: welding merges vertices within "
                         f"{WELD_TOLERANCE if tolerance is None else tolerance:.3g}"
                         f"{' of the bounding-box diagonal' if tolerance is None else ''} and collapses every face; "
                         f"the model's bounds (min {np.array2string(lo, precision=4)} max "
                         f"{np.array2string(hi, precision=4)}) are far larger than its faces: remove the stray "
                         "far-off vertices", element="face")
    colors = None if mesh.vertex_colors is None else _group_mean(mesh.vertex_colors, ids, n_new)
    vertex_normals, corner_normals = None, mesh.corner_normals
    if mesh.vertex_normals is not None and corner_normals is None:
        mean = _group_mean(mesh.vertex_normals, ids, n_new)
        length = np.linalg.norm(mean, axis=1, keepdims=True)
        unit = mean / np.maximum(length, 1e-30)
        stored = mesh.vertex_normals.astype(np.float64)
        cos = np.einsum("ij,ij->i", stored, unit[ids]) / np.maximum(np.linalg.norm(stored, axis=1), 1e-30)
        if np.all(cos >= np.cos(np.radians(NORMAL_AGREEMENT))):
            vertex_normals = unit
        else:
            corner_normals = mesh.vertex_normals[mesh.faces]
    if corner_normals is not None:
        corner_normals = corner_normals[keep]
    return _wound_consistently(Mesh(mesh.vertices[first], faces[keep], vertex_normals, colors, corner_normals,
                                    merged_vertices=mesh.merged_vertices + len(ids) - n_new,
                                    collapsed_faces=mesh.collapsed_faces + int((~keep).sum()), origin=mesh.origin))


def consistent_winding(faces: np.ndarray) -> bool:
    """Whether the faces (F, 3) of a welded mesh are wound consistently: no directed edge is used
    twice (two faces sharing an edge traverse it in opposite directions) and no edge has more than
    two faces. Faces with a repeated corner take no part."""
    f = np.asarray(faces, dtype=np.int64)
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    n = int(f.max(initial=0)) + 1
    directed = np.sort(a * n + b)
    if np.any(directed[1:] == directed[:-1]):
        return False
    undirected = np.unique(np.minimum(a, b) * n + np.maximum(a, b), return_counts=True)[1]
    return bool(undirected.max(initial=0) <= 2)


def _wound_consistently(mesh: Mesh) -> Mesh:
    """``mesh`` with the faces of each connected part turned to agree with their neighbours
    (``trimesh.repair.fix_winding``) when they do not: a triangle soup of random winding otherwise
    gives averaged vertex normals that cancel and samples lit from the wrong side (dark dots)."""
    if consistent_winding(mesh.faces):
        return mesh
    import trimesh   # deferred (0.7 s): a mesh wound inconsistently is rare

    fixed = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    trimesh.repair.fix_winding(fixed)
    faces = np.asarray(fixed.faces, dtype=np.int64)
    flipped = np.any(faces != mesh.faces, axis=1)
    corner_normals = mesh.corner_normals
    if corner_normals is not None and flipped.any():
        corner_normals = corner_normals.copy()
        corner_normals[flipped] = corner_normals[flipped][:, ::-1]
    return replace(mesh, faces=faces, corner_normals=corner_normals)


def _group_mean(values: np.ndarray, ids: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) float64 mean of the (V, 3) ``values`` over each id group."""
    count = np.bincount(ids, minlength=n).astype(np.float64)
    out = np.empty((n, values.shape[1]), dtype=np.float64)
    for axis in range(values.shape[1]):
        out[:, axis] = np.bincount(ids, weights=values[:, axis].astype(np.float64), minlength=n)
    return out / np.maximum(count, 1.0)[:, None]


def face_adjacency(faces: np.ndarray, n_vertices: int | None = None):
    """The manifold edges of a triangle list and the two faces at each.

    Args:
        faces: (F, 3) int vertex indices (welded, for a connected surface).
            Faces with a repeated index take part in no edge.
        n_vertices: number of vertices (default ``faces.max() + 1``).

    Returns:
        ``(pairs, slots, edges)``: (E, 2) int64 the two faces sharing each
        edge that exactly two faces use (boundary edges, with one face, and
        non-manifold ones, with three or more, are left out); (E, 2) int64
        the edge's slot k in each face (the edge from corner k to corner
        k + 1 mod 3); (E, 2) int64 the edge's vertices, smaller id first.
    """
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    order, _, start, count, lo, hi = _sorted_edges(f, n_vertices)
    two = start[count == 2]
    e1, e2 = order[two], order[two + 1]
    pairs = np.stack([e1 // 3, e2 // 3], axis=1)
    slots = np.stack([e1 % 3, e2 % 3], axis=1)
    edges = np.stack([lo[e1], hi[e1]], axis=1)
    return pairs, slots, edges


def boundary_edges(faces: np.ndarray, n_vertices: int | None = None):
    """The open boundary edges of a triangle list: edges that exactly one face uses.

    Args:
        faces: (F, 3) int vertex indices (welded). Faces with a repeated index
            take part in no edge.
        n_vertices: number of vertices (default ``faces.max() + 1``).

    Returns:
        ``(face, slot, edges)``: (B,) int64 the face of each boundary edge,
        (B,) int64 its slot in that face (from corner k to k + 1 mod 3), and
        (B, 2) int64 its vertices, smaller id first.
    """
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    order, _, start, count, lo, hi = _sorted_edges(f, n_vertices)
    one = order[start[count == 1]]
    return one // 3, one % 3, np.stack([lo[one], hi[one]], axis=1)


def _sorted_edges(f: np.ndarray, n_vertices: int | None):
    """The face edges (slot k of face i at 3 i + k) of proper faces sorted by their undirected key:
    ``(order, sorted keys, run starts, run lengths, lo, hi)``."""
    n = int(n_vertices) if n_vertices is not None else (int(f.max()) + 1 if f.size else 0)
    proper = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    a = f.reshape(-1)                       # corner k of face i at 3 i + k
    b = f[:, [1, 2, 0]].reshape(-1)         # the next corner: edge slot k runs from corner k to k + 1
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * max(n, 1) + hi
    valid = np.flatnonzero(np.repeat(proper, 3))
    order = valid[np.argsort(key[valid], kind="stable")]
    sorted_key = key[order]
    start = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]]) if len(order) else np.zeros(0, np.int64)
    count = np.diff(np.r_[start, len(order)])
    return order, sorted_key, start, count, lo, hi


def face_normals_and_areas(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(cross, unit, proper)``: (F, 3) float64 face cross products (twice the area times the
    unit normal), (F, 3) float64 unit normals (zero for degenerate faces) and (F,) bool
    non-degenerate (twice the area above :data:`DEGENERATE_AREA` times the squared diagonal)."""
    v = mesh.vertices.astype(np.float64)
    f = mesh.faces
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(cross, axis=1)
    proper = length > DEGENERATE_AREA * _diagonal(v) ** 2
    unit = np.where(proper[:, None], cross / np.where(proper, length, 1.0)[:, None], 0.0)
    return cross, unit, proper


def dihedral_angles(mesh: Mesh, *, welded: bool = False):
    """Dihedral angles of a mesh's manifold edges, in degrees.

    The angle between the normals of the two faces sharing the edge, as
    wound: 0 for coplanar faces, 90 at the edge of a cube; faces wound
    inconsistently across the edge meet at ~180 degrees. Edges at a
    degenerate (zero-area) face get NaN.

    Args:
        mesh: the mesh; welded first (:func:`weld_map`, default tolerance)
            unless ``welded`` says it is already.

    Returns:
        ``(angles, lengths)``: (E,) float64 degrees and (E,) float64 edge
        lengths (model units), one per manifold edge of the welded mesh.
    """
    mesh = mesh.validated("dihedral_angles: mesh")
    faces = mesh.faces if welded else weld_map(mesh.vertices)[mesh.faces]
    pairs, _, edges = face_adjacency(faces, len(mesh.vertices))
    _, unit, proper = face_normals_and_areas(mesh)
    cos = np.clip(np.einsum("ij,ij->i", unit[pairs[:, 0]], unit[pairs[:, 1]]), -1.0, 1.0)
    angles = np.where(proper[pairs[:, 0]] & proper[pairs[:, 1]], np.degrees(np.arccos(cos)), np.nan)
    return angles, _edge_lengths(mesh, faces, edges)


def _edge_lengths(mesh: Mesh, faces: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(E,) lengths of ``edges`` given as welded ids: measured between representatives of the ids."""
    v = mesh.vertices.astype(np.float64)
    rep = np.zeros(int(faces.max()) + 1 if faces.size else 0, dtype=np.int64)
    rep[faces.reshape(-1)] = mesh.faces.reshape(-1)
    return np.linalg.norm(v[rep[edges[:, 1]]] - v[rep[edges[:, 0]]], axis=1)


def crease_normals(mesh: Mesh, sharp_angle: float | None = DEFAULT_SHARP_ANGLE, *, welded: bool = False) -> np.ndarray:
    """Crease-aware normals per face corner ("auto smooth" at ``sharp_angle`` degrees).

    Around each vertex the faces form fans: faces connected across edges
    whose dihedral angle (:func:`dihedral_angles`) is at most ``sharp_angle``.
    Each corner gets its fan's mean face normal, weighted by the faces'
    interior angles at the vertex (Thuermer & Wuethrich 1998: independent of
    how a surface is cut into triangles, which matters for the long thin
    triangles of CAD tessellations; on a cylinder tessellated as split quads
    area weights tilt the normals by ~2 degrees). Smooth parts share one
    normal per vertex and shade continuously; across an edge sharper than
    ``sharp_angle`` the corners belong to different fans and keep their own
    sides' normals. Boundary and non-manifold edges (not two faces) and edges
    at a degenerate face split fans too. Corners whose fan sums to zero
    (degenerate faces) get the weighted normal of all faces at the vertex, or
    zero.

    Args:
        mesh: the mesh. Its vertices are welded first (:func:`weld_map`,
            default tolerance; the result is aligned with the input's faces)
            unless ``welded`` is True.
        sharp_angle: degrees in (0, 180), or None: no edge is sharp (smooth
            normals everywhere: one angle-weighted normal per vertex).

    Returns:
        (F, 3, 3) float32: unit normal of corner k of face i at ``[i, k]``.
    """
    if sharp_angle is not None:
        sharp_angle = check_angle(sharp_angle, "crease_normals: sharp_angle")
    mesh = mesh.validated("crease_normals: mesh")
    n_faces = len(mesh.faces)
    ids = np.arange(len(mesh.vertices)) if welded else weld_map(mesh.vertices)
    faces = ids[mesh.faces]
    n_vertices = int(ids.max()) + 1
    _, unit, proper = face_normals_and_areas(mesh)
    pairs, slots, _ = face_adjacency(faces, n_vertices)
    f1, f2 = pairs[:, 0], pairs[:, 1]
    smooth = proper[f1] & proper[f2]
    if sharp_angle is not None:
        cos = np.einsum("ij,ij->i", unit[f1], unit[f2])
        smooth &= cos >= np.cos(np.radians(sharp_angle))
    f1, f2, s1, s2 = f1[smooth], f2[smooth], slots[smooth, 0], slots[smooth, 1]
    # the edge runs from corner s to s + 1 in each face; the same vertex is at the same end
    # when both faces run along it the same way (inconsistent winding), else at opposite ends
    same = faces[f1, s1] == faces[f2, s2]
    c1a, c1b = 3 * f1 + s1, 3 * f1 + (s1 + 1) % 3
    c2a = 3 * f2 + np.where(same, s2, (s2 + 1) % 3)
    c2b = 3 * f2 + np.where(same, (s2 + 1) % 3, s2)
    rows = np.concatenate([c1a, c1b])
    cols = np.concatenate([c2a, c2b])
    corners = 3 * n_faces
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(corners, corners))
    _, fan = connected_components(graph, directed=False)
    weighted = (corner_angles(mesh)[:, :, None] * unit[:, None, :]).reshape(-1, 3)  # (3F, 3)
    normals = _vertex_sum(fan, weighted, int(fan.max()) + 1)[fan]
    length = np.linalg.norm(normals, axis=1)
    good = length > 1e-9
    out = np.zeros((corners, 3), dtype=np.float64)
    out[good] = normals[good] / length[good, None]
    if not good.all():
        vertex = _vertex_sum(faces.reshape(-1), weighted, n_vertices)[faces.reshape(-1)[~good]]
        vlen = np.linalg.norm(vertex, axis=1, keepdims=True)
        out[~good] = np.where(vlen > 1e-9, vertex / np.maximum(vlen, 1e-300), 0.0)
    return out.reshape(n_faces, 3, 3).astype(np.float32)


def corner_angles(mesh: Mesh) -> np.ndarray:
    """(F, 3) float64 interior angle of each face at each corner, radians (0 for degenerate faces'
    coincident corners; the three sum to pi)."""
    v = mesh.vertices.astype(np.float64)[mesh.faces]            # (F, 3, 3)
    e1 = np.roll(v, -1, axis=1) - v                              # to the next corner
    e2 = np.roll(v, 1, axis=1) - v                               # to the previous corner
    sine = np.linalg.norm(np.cross(e1, e2), axis=2)
    cosine = np.einsum("fkd,fkd->fk", e1, e2)
    return np.arctan2(sine, cosine)


def _vertex_sum(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) float64 sums of the (M, 3) ``values`` onto ``index``."""
    out = np.empty((n, 3), dtype=np.float64)
    for axis in range(3):
        out[:, axis] = np.bincount(index, weights=values[:, axis], minlength=n)
    return out


def auto_sharp_angle(mesh: Mesh) -> float | None:
    """The default sharp angle of a mesh: :data:`DEFAULT_SHARP_ANGLE` if it has creases, else None.

    A mesh has creases when the total length of its edges with a dihedral
    angle above ``CREASE_BAND[1]`` (40 degrees) is at least that of the edges
    between ``CREASE_BAND[0]`` and ``CREASE_BAND[1]`` (20 to 40 degrees), and
    positive (see the module docstring for the measurements behind the rule).
    Angles as :func:`dihedral_angles` (welded, edges at degenerate faces
    ignored).
    """
    angles, lengths = dihedral_angles(mesh)
    lo, hi = CREASE_BAND
    with np.errstate(invalid="ignore"):
        band = float(lengths[(angles > lo) & (angles <= hi)].sum())
        sharp = float(lengths[angles > hi].sum())
    return DEFAULT_SHARP_ANGLE if sharp > 0 and sharp >= band else None


def resolve_sharp_angle(mesh: Mesh, sharp_angle, name: str = "sharp_angle") -> float | None:
    """A sharp-angle argument as degrees or None: ``"auto"`` -> :func:`auto_sharp_angle`,
    None -> None (no sharp edges), a number -> checked to lie in (0, 180) (InputError naming ``name``)."""
    if isinstance(sharp_angle, str):
        if sharp_angle != AUTO:
            raise InputError(f"{name} must be an angle in degrees, None or {AUTO!r}, got {sharp_angle!r}")
        return auto_sharp_angle(mesh)
    if sharp_angle is None:
        return None
    return check_angle(sharp_angle, name)


def shading_normals(mesh: Mesh, sharp_angle: float | str | None = AUTO) -> np.ndarray:
    """The normals a mesh is shaded with, per face corner: (F, 3, 3) float32 unit vectors.

    The file's normals where it stores them (``corner_normals``, else
    ``vertex_normals`` at each face's corners); otherwise
    :func:`crease_normals` at ``sharp_angle`` degrees (``"auto"``, the
    default: :func:`auto_sharp_angle`; None: smooth everywhere), computed on
    the welded vertices. Used by the ground-truth
    rasterizer and by surface sampling, so that both shade alike.
    """
    if mesh.corner_normals is not None:
        return mesh.corner_normals
    if mesh.vertex_normals is not None:
        return mesh.vertex_normals[mesh.faces]
    return crease_normals(mesh, resolve_sharp_angle(mesh, sharp_angle))


def with_shading_normals(mesh: Mesh, sharp_angle: float | str | None = AUTO) -> Mesh:
    """``mesh`` with :func:`shading_normals` stored as its ``corner_normals`` (itself if it stores normals)."""
    if mesh.has_normals:
        return mesh
    return replace(mesh, corner_normals=shading_normals(mesh, sharp_angle))


def check_angle(value, name: str) -> float:
    """``value`` as a float in degrees strictly between 0 and 180, or InputError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be an angle in degrees, got {value!r}")
    angle = float(value)
    if not (0.0 < angle < 180.0):  # also rejects NaN
        raise InputError(f"{name} must be an angle in degrees strictly between 0 and 180, got {value!r}")
    return angle
