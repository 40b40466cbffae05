"""Closed surfaces: whether a mesh bounds a solid, and splats of it with outward normals.

A closed, consistently wound surface is seen only from outside, so its back side is never visible.
Culling the splats whose normal faces away from the eye (Botsch et al. 2004, sec. 4.1; Guennebaud &
Paulin 2003, sec. 6) is the default only for a closed mesh's samples drawn by a technique whose
footprints reach past the disks (:func:`automatic_culling`): the splats stand for the surface only
together, and a back-facing splat is the only one covering some pixels of the front wherever its
front-facing neighbours leave them open, which no test of the splat alone can tell.
Measured at 512 x 512, before edge coverage and hole filling were on by default (default views, every
pixel a hole the unculled picture covers):

- the bunny, flat splats sampled from its mesh: 80 pixels of the silhouette band, 75 of them
  inside the mesh's silhouette. Front splats near a silhouette are seen nearly edge-on and cover
  slivers; the gaps between them are filled by splats just past the silhouette (facing -0.004 to
  -0.07, the median pixel) and, at the ears' thin tips, by the far side's splats (facing down to
  -0.83) while their neighbours' normals within their radius turn by 39 degrees at most: no normal
  cone of the surface a splat stands for bounds which of them may be needed;
- a sphere of 10,000 Phong splats (``phong_splats`` of 100,000 samples): 13 (ewa) and 32 (phong)
  pixels inside its disk, most of them far from the silhouette (the surface facing the eye at
  0.2-0.87): the fit covers each sample along the splat's normal, and along a slanted ray the
  front layer leaves cracks 1-6 pixels wide (no front disk within 1.003-1.16 of its radius) that
  the far side (facing -0.2 to -0.57) fills unculled;
- a CAD part (``featuretype.ply``) sampled with smooth (vertex-interpolated) normals: 3,669 pixels,
  whole faces whose splats' planes follow the normals averaged over a 90 degree edge and so face
  away from an eye the faces themselves face.

Culled, the bunny's silhouette band matched the mesh better (its PSNR at 1024 x 1024, 4 x 4
supersampling, rose from 20.5 to 22.3 dB, benchmarks/edge_quality.py: the splats pushed past the
silhouette by a flat disk went with the holes) and a frame took 0.6-0.8 of the time. With edge coverage
and the hole filling (both default now), ``ewa`` and ``perspective`` leave none of these holes on the
meshes' samples (their prefiltered fringe reaches the silhouette pixels): :func:`automatic_culling`.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..cloud import SplatCloud
from ..io.mesh import Mesh
from ..io.surface import boundary_edges, consistent_winding, weld

#: Longest hole (one loop of open boundary edges) of a closed mesh, in bounding-box diagonals: the
#: scanned bunny's five holes at its base (0.12-0.45) pass; the opening of a vase, a bowl or a scan
#: fragment's outline (1.5 and more) does not.
MAX_HOLE = 0.5


def is_closed_surface(mesh: Mesh, max_hole: float = MAX_HOLE) -> bool:
    """Whether ``mesh`` (welded first, :func:`surfsplat.io.surface.weld`) is a closed surface:
    consistently wound, manifold, and none of its holes (loops of open boundary edges) longer than
    ``max_hole`` bounding-box diagonals. A sheet, a scan fragment, a bowl, a triangle soup or a mesh
    of mixed winding is not."""
    welded = weld(mesh)
    faces = welded.faces
    if len(faces) < 4 or not consistent_winding(faces):
        return False
    v = welded.vertices.astype(np.float64)
    edges = boundary_edges(faces, len(v))[2]
    if len(edges) == 0:
        return True
    n = len(v)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    loop = connected_components(graph, directed=False)[1][edges[:, 0]]
    length = np.bincount(loop, weights=np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1))
    return bool(length.max() <= max_hole * np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def outward_splats(splats: SplatCloud) -> SplatCloud:
    """The splats of a closed, consistently oriented surface with normals pointing out of the solid.

    The flux of the position field through a closed surface is three times the enclosed volume
    (divergence theorem), so the mean of ``(p - c) . n`` over samples uniform by area has the sign
    of the orientation: negative, every normal is flipped (the sampled mesh was wound inward, like
    the Stanford bunny), with the slopes of a linear normal field."""
    flux = outward_flux(splats.positions.astype(np.float64), splats.normals.astype(np.float64))
    return splats if flux >= 0 else flipped_normals(splats)


def outward_flux(positions: np.ndarray, normals: np.ndarray) -> float:
    """The mean of ``(p - c) . n`` over samples (``c`` their mean; model units): positive where the
    normals of samples uniform by area on a closed surface point out of the solid (see
    :func:`outward_splats`)."""
    return float(np.einsum("nd,nd->n", positions - positions.mean(axis=0), normals).mean())


def flipped_normals(splats: SplatCloud) -> SplatCloud:
    """``splats`` with every normal turned around, with the slopes of a linear normal field."""
    field = None if splats.normal_field is None else -splats.normal_field   # Botsch 2004, eq. 2: n + s a u + t b v
    return splats.replace(normals=-splats.normals, normal_field=field)


#: Points the orientation test of a cloud projects (a strided sample beyond).
ORIENTATION_SAMPLE = 50_000
#: Cells per side of the coarse depth buffers of that test.
ORIENTATION_GRID = 40
#: Share of the splats seen first, over all test directions, that must face the viewer (or all
#: face away) for a cloud to count as closed and oriented: the bunny sampled to 1M points scores
#: 0.990-0.994 (given or estimated normals; silhouettes and the coarse cells miss some), with the
#: normals of 1% of its surface turned 0.982-0.985, of 2% 0.971-0.973.
ORIENTATION_SHARE = 0.98


def _test_directions() -> np.ndarray:
    """The 26 unit directions to the faces, edges and corners of a cube."""
    d = np.stack(np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], indexing="ij"), -1).reshape(-1, 3)
    d = d[np.any(d != 0.0, axis=1)]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def closed_orientation(cloud: SplatCloud) -> int:
    """+1 when ``cloud`` samples closed surfaces with outward normals, -1 with inward normals, 0
    when it does not look closed and consistently oriented (or has no normals).

    Looking at the cloud from far away along 26 directions (cube faces, edges and corners), the
    splats seen first (in each cell of a coarse orthographic depth buffer,
    :data:`ORIENTATION_GRID` cells per side) face the viewer on a closed, outward-oriented
    surface, whatever the direction; an open sheet or a scan fragment seen from behind, a bowl
    seen into, or a surface with unoriented normals show the back of some of theirs. +1 when at
    least :data:`ORIENTATION_SHARE` of them face the viewer (grazing ones, ``|n . d| < 0.1``,
    count both ways: silhouettes, noise), -1 when as many face away. A strided sample of
    :data:`ORIENTATION_SAMPLE` points is tested (about 50 ms); fewer than 100 points: 0."""
    if cloud.normals is None or len(cloud.positions) < 100:
        return 0
    step = max(1, -(-len(cloud.positions) // ORIENTATION_SAMPLE))
    p = cloud.positions[::step].astype(np.float64)
    n = cloud.normals[::step].astype(np.float64)
    p -= p.mean(axis=0)
    extent = float(np.abs(p).max())
    if not np.isfinite(extent) or extent == 0.0:
        return 0
    cells = ORIENTATION_GRID
    front = back = total = 0
    for d in _test_directions():
        a = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])   # a frame across d
        a /= np.linalg.norm(a)
        b = np.cross(d, a)
        i = np.clip(((p @ a / extent + 1.0) * (0.5 * cells)).astype(np.int64), 0, cells - 1)
        j = np.clip(((p @ b / extent + 1.0) * (0.5 * cells)).astype(np.int64), 0, cells - 1)
        key = i * cells + j
        depth = p @ d                        # larger: nearer to a viewer far away along d
        nearest = np.full(cells * cells, -np.inf)
        np.maximum.at(nearest, key, depth)
        seen = depth >= nearest[key]
        cos = n[seen] @ d
        front += int(np.count_nonzero(cos > -0.1))
        back += int(np.count_nonzero(cos < 0.1))
        total += int(np.count_nonzero(seen))
    if front >= ORIENTATION_SHARE * total:
        return 1
    return -1 if back >= ORIENTATION_SHARE * total else 0


def eye_outside(bounds: tuple[np.ndarray, np.ndarray], eye) -> bool:
    """Whether ``eye`` lies outside the axis-aligned box ``bounds`` (lo, hi), so outside every closed
    surface in it: only then is back-face culling of a closed surface safe."""
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    e = np.asarray(eye, dtype=np.float64)
    return bool(np.any(e < lo) or np.any(e > hi))


def automatic_culling(outward: bool, bounds: tuple[np.ndarray, np.ndarray], eye, *, sampled_mesh: bool = False,
                      fringe: bool = True) -> bool:
    """Whether back faces are culled where the options leave it automatic
    (``VisibilityOptions.cull_backfaces=None``): for the splats sampled from a closed mesh
    (``sampled_mesh``, oriented outward: ``outward``) seen from outside their ``bounds``
    (:func:`eye_outside`) by a technique whose footprints reach beyond the splats' disks (``fringe``:
    ``ewa``, ``perspective``), else never.

    A closed surface seen from outside hides its back side. Splats sampled from the mesh carry its
    faces' normals (clip lines at the sharp edges), so the few pixels of the front that only a
    back-facing splat covers lie on the silhouette, where the front's prefiltered fringe and edge
    coverage cover them: measured at 512 x 512 (the bunny and the CAD part, six orbit views each,
    against the 4 x 4 mesh, ``ewa`` with edge coverage), culling leaves no hole inside the mesh's
    silhouette and is 0.3-1.2 dB better over the image (the back side no longer widens the outlines
    or dots the rims of pockets). Techniques drawing only inside their disks (``phong``, ``blend``,
    ``flat``) lose pixels of thin tips there (32 of the bunny's ears at 256 x 256) and stay
    two-sided. A point cloud is never culled automatically, closed or not: its normals need not
    follow the geometry (a CAD part with smooth normals loses whole thin faces, 241 pixels inside
    its silhouette at 256 x 256) and a fitted front layer may leave cracks only the far side covers
    (Phong splats of a sphere: 3 pixels of its rim with ``phong``, ``blend`` and ``flat``); see the
    module docstring. ``cull_backfaces=True`` culls on request."""
    return bool(sampled_mesh and fringe and outward and eye_outside(bounds, eye))
