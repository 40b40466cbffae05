"""Sampling a triangle mesh's surface: uniform random samples (:func:`sample_mesh`), and render-ready
splats of the surface at a density chosen for the screen (:func:`surface_splats`).

A mesh is a surface, not a point set: its vertices alone (today's default
rendering of a mesh file) leave the large triangles of CAD tessellations empty
and turn a triangle soup into crossed needles. :func:`surface_splats` welds
the mesh (:func:`surfsplat.io.surface.weld`), samples its surface uniformly
by area and evenly (:func:`stratified_barycentrics`), gives every sample the
mesh's shading normal (the file's normals, or crease-aware ones,
:func:`surfsplat.io.surface.shading_normals`, interpolated within the face, as
the ground-truth rasterizer interpolates them per pixel), its interpolated
vertex color, a circular splat sized by the sampling's own spacing
(:func:`spacing_radius`, :func:`face_coverage`: no neighbour search), and clip
lines at the mesh's sharp edges (Zwicker et al. 2004,
sec. 5; :func:`surfsplat.geometry.sharp.mesh_clip_lines`) and at its open
boundaries (the rim of a scan).

The density rule (:func:`samples_for_spacing`, :func:`view_spacing`): ``n =
area / spacing^2`` samples for a mean spacing ``spacing`` in model units, with
the spacing given on screen, :data:`DEFAULT_SPACING_PX` pixels, converted at
the mesh's center for a camera, capped at :data:`MAX_SAMPLES`. The default
and the cap are measured in ``benchmarks/mesh_sampling.py`` (PSNR against
``render_mesh`` and hole pixels at 512 and 1024 pixels for featuretype.ply,
bunny.ply and frag_115.ply; ``benchmarks/results/mesh_sampling.md``).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .. import progress
from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..io.atomic import memory_limit
from ..io.mesh import Mesh
from ..io.surface import AUTO, resolve_sharp_angle, shading_normals, weld, with_shading_normals
from .closed import flipped_normals, outward_flux
from .neighbors import kth_distance, spatial_order
from .preprocess import preprocess
from .sharp import check_sharp_angle, mesh_clip_lines, mesh_features
from .splats import CIRCLE_COVERAGE, CREASED_SAMPLE_COVERAGE, SAMPLE_COVERAGE, circular_splats

#: Default mean spacing of surface samples on screen, pixels. Measured (512 x 512, ewa, PSNR inside
#: the silhouette against render_mesh, ``benchmarks/results/mesh_sampling.md``): from 1 to 0.75 px
#: featuretype 34.2 -> 34.8 dB, bunny 41.1 -> 42.7, frag_115 36.3 -> 38.3 for 1.8x the samples;
#: 0.5 px adds 1.6, 1.0 and 2.1 dB more for 2.2x again (the bunny is on its plateau, 43.7 dB).
#: No hole pixels from 2 px to 0.5 px at 512 and 1024 px (one, frag_115 at 4 px and 1024).
DEFAULT_SPACING_PX = 0.75
#: Image side (pixels) that :func:`samples_for_pixels` converts the spacing at without a camera.
DEFAULT_IMAGE_SIZE = 512
#: Most samples :func:`surface_splats` draws by default (~100 bytes per splat; sampling, sizing and
#: clip lines take ~2-2.5 s per million samples on 2 cores, drawing 2 M splats 512 x 512 ~2-6 s on
#: llvmpipe). Reached at 1024 px for featuretype (0.93 px) and the bunny (0.88 px).
MAX_SAMPLES = 2_000_000
#: Neighbours that size the splats of sampled surfaces when :func:`surface_splats` is asked to size
#: them by their neighbours (``k``); by default they are sized by the sampling (:data:`SPACING_COVERAGE`).
SURFACE_K = 8
#: Radius of the splats of a stratified sampling of a surface, in mean spacings ``sqrt(A / n)``
#: (:func:`spacing_radius`), on faces whose longest side squared is less than :data:`SLIVER_ASPECT`
#: times twice their area. The largest gap measured between such samples (the distance from a point
#: of the surface to its nearest sample) is 1.7 and 1.9 spacings on bunny.ply and frag_115.ply (at
#: its open rim; 1e-6 of frag_115's surface is farther than 2.0 spacings, all of it there) and none
#: farther than 2.0 on featuretype.ply's well-shaped faces. Independent random samples would need
#: ~2.9 for the same area left uncovered, ``exp(-pi c^2)`` (a Poisson process); sized by their k-th
#: neighbours (1.25 h_8) their radii average 1.96 spacings.
SPACING_COVERAGE = 2.0
#: The radius on slivers (long thin faces of CAD tessellations), mean spacings: the square-root warp
#: spreads a sliver's samples less evenly; the largest gap measured on featuretype.ply is 2.25.
SLIVER_COVERAGE = 2.3
#: Longest side squared over twice the area (the side over the height on it) above which a face is a
#: sliver (an equilateral triangle: 1.15).
SLIVER_ASPECT = 8.0


#: Memory sampling holds per sample (float64 intermediates, the float32 cloud; with margin).
BYTES_PER_SAMPLE = 256


def _check_count(n, name: str) -> int:
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise InputError(f"{name}: n must be an integer, got {n!r}")
    if n < 1:
        raise InputError(f"{name}: n must be at least 1, got {n}")
    return int(n)


def _uniform_barycentrics(areas: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` independent uniform samples: faces by area, barycentrics by the square-root warp (Osada 2002)."""
    cdf = np.cumsum(areas)
    # side="right" never selects a zero-area face (its cdf step is empty)
    face = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    face = np.minimum(face, int(np.flatnonzero(areas > 0)[-1]))  # r * total may round up to total
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    return face, np.column_stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2])


#: The plastic number: ``1 / PLASTIC`` and ``1 / PLASTIC**2`` step the R2 sequence (Roberts 2018), the
#: two-dimensional Kronecker sequence of lowest dispersion known.
PLASTIC = 1.32471795724474602596


def stratified_barycentrics(areas: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` stratified samples of a surface of faces of ``areas``: ``(face, barycentrics)``.

    Uniform by area like independent samples (every sample is, on its own, uniform on the
    surface), but spread evenly instead of clumped:

    * faces: the ``n`` numbers ``(i + r_i) / n`` (one per stratum of the area's cumulative sum,
      ``r_i`` uniform in [0, 1)) pick the faces, so a face of area ``a`` gets ``n a / A`` samples
      give or take less than 2 (whole strata and at most two partial ones; independent samples
      miss by about ``sqrt(n a / A)``), sorted by face;
    * within a face, its ``m`` samples are the R2 sequence ``(o + j / g, o' + j / g^2) mod 1``,
      ``j = 0 .. m - 1`` (Roberts 2018; ``g`` the plastic number), rotated by a random offset
      ``(o, o')`` per face (Cranley-Patterson rotation: each point uniform on the unit square),
      mapped to the triangle by the square-root warp (Osada et al. 2002), which keeps area.

    Measured (``benchmarks/results/preprocess_real.md``): the largest distance from a point of the
    surface to its nearest sample is 1.7 (bunny.ply), 1.9 (frag_115.ply) and 2.25
    (featuretype.ply, slivers) times the mean spacing ``sqrt(A / n)``, against 2.2 for
    independent samples, and the area farther than 1.4 spacings 10x smaller.

    Args:
        areas: (F,) float64 face areas; their sum > 0.
        n: number of samples.
        rng: the random generator.

    Returns:
        ``face`` (n,) int64 face indices, ascending; ``bary`` (n, 3) float64 barycentrics.
    """
    cdf = np.cumsum(areas)
    face = np.searchsorted(cdf, (np.arange(n) + rng.random(n)) * (cdf[-1] / n), side="right")
    face = np.minimum(face, int(np.flatnonzero(areas > 0)[-1]))
    j = np.arange(n) - np.searchsorted(face, face, side="left")   # index of the sample within its face
    offset = rng.random((len(areas), 2))
    r1 = np.sqrt(np.remainder(offset[face, 0] + j * (1.0 / PLASTIC), 1.0))
    r2 = np.remainder(offset[face, 1] + j * (1.0 / PLASTIC ** 2), 1.0)
    return face, np.column_stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2])


def _interpolated(bary: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """(n, d) ``sum_k bary[:, k] values[at][:, k]``: the barycentric interpolation of per-corner ``values``
    ((V, d) gathered by the (n, 3) indices ``at``, or (F, 3, d) by the (n,) faces ``at``), summed in
    corner order (the sums ``einsum("nk,nkd->nd")`` forms, without its (n, 3, d) gather)."""
    out = None
    for k in range(3):
        corner = np.take(values[:, k], at, axis=0) if values.ndim == 3 else np.take(values, at[:, k], axis=0)
        term = bary[:, k:k + 1] * corner
        out = term if out is None else np.add(out, term, out=out)
    assert out is not None
    return out


def _samples(mesh: Mesh, n: int, seed: int, smooth_normals: bool, crease_angle: float | None,
             name: str, stratified: bool = False) -> tuple[SplatCloud, np.ndarray, np.ndarray]:
    """``n`` samples uniform by area on ``mesh`` (validated), the face and barycentrics of each: see
    :func:`sample_mesh`; ``stratified``: :func:`stratified_barycentrics` instead of independent samples."""
    areas = mesh.face_areas()
    total = float(areas.sum())
    if not np.isfinite(total) or total <= 0:
        raise InputError(f"{name}: mesh has zero total area ({len(mesh.faces)} degenerate faces)")

    rng = np.random.default_rng(seed)
    if stratified:
        face, bary = stratified_barycentrics(areas, n, rng)
    else:
        face, bary = _uniform_barycentrics(areas, n, rng)

    corners = mesh.faces[face]  # (n, 3) vertex indices
    vertices = mesh.vertices.astype(np.float64)
    positions = _interpolated(bary, vertices, corners)

    normals = mesh.face_normals()[face].astype(np.float64)
    if mesh.has_normals or smooth_normals:
        smooth = _interpolated(bary, shading_normals(mesh, crease_angle).astype(np.float64), face)
        flip = np.einsum("nd,nd->n", normals, smooth) < 0
        normals[flip] *= -1.0
        if smooth_normals:
            length = np.linalg.norm(smooth, axis=1, keepdims=True)
            # opposite corner normals can cancel: keep the face normal there
            normals = np.where(length > 1e-6, smooth / np.maximum(length, 1e-30), normals)

    colors = None
    if mesh.vertex_colors is not None:
        colors = _interpolated(bary, mesh.vertex_colors.astype(np.float64), corners)

    cloud = SplatCloud(positions=positions.astype(np.float32), normals=normals.astype(np.float32),
                       colors=None if colors is None else colors.astype(np.float32), origin=mesh.origin)
    return cloud, face, bary


def sample_mesh(mesh: Mesh, n: int, *, seed: int = 0, sharp_angle: float | None = None, k: int = 8,
                shape: str = "circle", coverage: float | None = None, smooth_normals: bool = False) -> SplatCloud:
    """Sample ``n`` points uniformly by area on the surface of ``mesh``.

    Each sample picks a face with probability proportional to its area, then a
    uniform point in it: barycentrics ``(1 - sqrt(r1), sqrt(r1) (1 - r2),
    sqrt(r1) r2)`` for uniform ``r1, r2`` (Osada et al. 2002).

    Args:
        mesh: the surface; faces (F, 3), vertices (V, 3) model space.
        n: number of samples, >= 1.
        seed: seed of ``numpy.random.default_rng``; equal seeds give equal
            samples.
        sharp_angle: None (default: points and normals only), or a dihedral
            angle in degrees, in (0, 180): then every sample also gets its
            splat, and splats that reach over an edge sharper than this get
            clip lines from the faces there (see below).
        smooth_normals: give each sample the normalized barycentric interpolation
            of the mesh's corner normals (the normals a smooth-shaded rendering
            of the mesh uses, :func:`surfsplat.io.surface.shading_normals`: the
            stored ones, or where the mesh stores none crease-aware ones at
            ``sharp_angle``, smooth everywhere when it is None) instead of its
            face's normal.
        k, shape, coverage: splat sizes when ``sharp_angle`` is given, as in
            :func:`surfsplat.geometry.preprocess.preprocess` with the normals
            kept: ``k`` neighbours; ``shape`` ``"circle"`` (default:
            radius ``coverage * h_k``, Guennebaud 2003 eq. 7, the distance
            to the k-th neighbour) or ``"ellipse"``; ``coverage`` default
            1.25 for circles, 1.5 for ellipses, the factors measured to leave
            no holes between uniformly random samples (see
            :mod:`surfsplat.geometry.splats`). The axes lie in the plane
            normal to the sample's normal (the face's plane without
            ``smooth_normals``). Sizes adapt to the random gaps, which a global
            radius ``sqrt(area / n)`` times a constant cannot do without
            splats ~2x larger everywhere.

    Returns:
        SplatCloud with positions (n, 3) float32 model space; normals (n, 3)
        float32 unit: the face's geometric normal (right-hand rule on its
        vertex order), flipped where it disagrees (negative dot product) with
        the barycentric interpolation of the mesh's stored normals, when the
        mesh has them (or that interpolation itself with ``smooth_normals``);
        colors (n, 3) float32 interpolated from the vertex colors, when the
        mesh has them. No splat axes (u, v are None); with ``sharp_angle``,
        the splats (u, v in model units) and ``clip_lines`` (n, 2, 3).

    Raises:
        InputError: ``n`` < 1 or not an integer, an invalid mesh, or a mesh
            whose total area is zero.
    """
    n = _check_count(n, "sample_mesh")
    limit = memory_limit()
    if n * BYTES_PER_SAMPLE > limit:
        raise InputError(f"sample_mesh: {n:,} samples need about {n * BYTES_PER_SAMPLE / 2**20:,.0f} MiB, more than "
                         f"the {limit / 2**20:,.0f} MiB of memory available")
    if sharp_angle is not None:
        sharp_angle = check_sharp_angle(sharp_angle, "sample_mesh: sharp_angle")
    mesh = mesh.validated("sample_mesh: mesh")
    cloud, face, _ = _samples(mesh, n, seed, smooth_normals, sharp_angle, "sample_mesh")
    if sharp_angle is None:
        return cloud
    return _splats_with_clip_lines(mesh, cloud, face, sharp_angle, k, shape, coverage, "sample_mesh")


def _circles(cloud: SplatCloud, k: int, name: str, order: np.ndarray | None = None,
             coverage: float = SAMPLE_COVERAGE) -> SplatCloud:
    """Circular splats of radius ``coverage * h_k`` in the planes normal to the samples' normals
    (Guennebaud 2003 eq. 7, :func:`surfsplat.geometry.splats.circular_splats`), ``k`` clamped to n - 1.

    Samples of a surface need none of the rules for raw scans that :func:`preprocess` applies
    (duplicates, outliers, scan lines, size bounds): every sample is kept, one splat per sample.
    ``order``: the samples' :func:`~surfsplat.geometry.neighbors.spatial_order`, if computed already.
    """
    n = len(cloud)
    if n < 2:
        raise InputError(f"{name}: needs at least 2 samples to size the splats, got {n}")
    # only h_k, the k-th distance, sizes a circle (the row maximum of knn's distances)
    h_k = kth_distance(cloud.positions, min(int(k), n - 1), order=order)
    u, v = circular_splats(cloud.normals, h_k[:, None], coverage=coverage)
    return cloud.replace(u=u, v=v).validated(name)


def spacing_radius(area: float, n: int, coverage: float = SPACING_COVERAGE) -> float:
    """The splat radius of ``n`` samples spread evenly over a surface of ``area`` (squared model units).

    ``coverage * sqrt(area / n)`` model units: ``sqrt(area / n)`` is the mean spacing (one sample
    per square of that side). For independent uniform samples (a Poisson process of density
    ``n / area``) the fraction of the surface farther than this radius from every sample is
    ``exp(-pi coverage^2)``; stratified samples (:func:`stratified_barycentrics`) have (next to)
    none for ``coverage`` >= 2.0 on well-shaped faces, 2.3 on slivers (:data:`SPACING_COVERAGE`,
    :data:`SLIVER_COVERAGE`, measured).
    """
    return float(coverage) * math.sqrt(float(area) / int(n))


def face_coverage(mesh: Mesh) -> np.ndarray:
    """(F,) float64 splat radius of each face's samples in mean spacings: :data:`SPACING_COVERAGE`, or
    :data:`SLIVER_COVERAGE` where the face's longest side squared exceeds :data:`SLIVER_ASPECT` times
    twice its area (zero-area faces, never sampled, count as slivers)."""
    corners = mesh.vertices.astype(np.float64)[mesh.faces]
    longest = (np.diff(corners[:, [0, 1, 2, 0]], axis=1) ** 2).sum(axis=2).max(axis=1)
    sliver = ~(longest < SLIVER_ASPECT * 2.0 * mesh.face_areas())
    return np.where(sliver, SLIVER_COVERAGE, SPACING_COVERAGE)


def _spaced_circles(cloud: SplatCloud, radius, name: str) -> SplatCloud:
    """Circles of ``radius`` (model units: a number, or (N,) per sample) in the planes normal to the
    samples' (unit) normals."""
    r = np.asarray(radius, dtype=np.float32)
    if not (np.isfinite(r).all() and (r > 0).all()):
        raise InputError(f"{name}: a splat radius from the sample spacing is not a positive number")
    u, v = circular_splats(cloud.normals, np.broadcast_to(r, (len(cloud),))[:, None], coverage=1.0)
    return cloud.replace(u=u, v=v)


def _splats_with_clip_lines(mesh: Mesh, cloud: SplatCloud, face: np.ndarray, sharp_angle: float | None, k: int | None,
                            shape: str | None, coverage: float | None, name: str,
                            boundaries: bool = False, radius: np.ndarray | None = None,
                            bary: np.ndarray | None = None) -> SplatCloud:
    """Splats (normals kept, sized by the k-neighbourhoods: :func:`preprocess` with ``shape`` and
    ``coverage``, or plain circles, :func:`_circles`, when ``shape`` is None) with clip lines at the
    edges sharper than ``sharp_angle`` and, with ``boundaries``, at the open boundary edges (None
    without a sharp angle when there is no boundary either). ``radius``: (N,) circles of these radii
    instead (from :func:`spacing_radius`, model units; samples in face order, no neighbour search)."""
    n = len(cloud)
    # one spatial order of the samples for the neighbour search and the search for nearby edges
    order = spatial_order(cloud.positions) if shape is None and radius is None and n >= 2 else None
    if radius is not None:
        with progress.stage("splat sizes from the sample spacing", n):
            splats = _spaced_circles(cloud, radius, name)
    elif shape is None:
        assert k is not None
        # a mesh with sharp edges keeps the larger circles at its occlusion edges (splats.py)
        splats = _circles(cloud, k, name, order, SAMPLE_COVERAGE if sharp_angle is None else CREASED_SAMPLE_COVERAGE)
    else:
        # samples of a surface: no duplicates to merge or outliers to drop (one splat per sample)
        splats = preprocess(cloud, k=k, shape=shape, coverage=coverage, source=name, outliers="keep",
                            merge_duplicates=False)
    if len(splats) != n:  # samples of a valid mesh are finite, their normals unit
        raise InputError(f"{name}: preprocessing dropped {n - len(splats)} samples")
    if sharp_angle is None and not boundaries:
        return splats
    features = mesh_features(mesh, sharp_angle, boundaries=boundaries)
    if sharp_angle is None and len(features.edges) == 0:
        return splats
    with progress.stage("clip lines at sharp edges", n):
        lines = mesh_clip_lines(mesh, face, splats.positions, splats.u, splats.v, sharp_angle, features=features,
                                order=order, bary=bary)
    return splats.replace(clip_lines=lines)


# -- the density rule ---------------------------------------------------------------------------


def _check_positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def samples_for_spacing(mesh: Mesh, spacing: float, *, max_samples: int = MAX_SAMPLES) -> int:
    """The sample count for a mean spacing of ``spacing`` model units on ``mesh``'s surface.

    ``ceil(area / spacing^2)`` (one sample per ``spacing x spacing`` square of
    the mesh's total area, squared model units), at least 1 and at most
    ``max_samples``.

    Raises:
        InputError: spacing not a positive number, max_samples < 1, or an
            invalid mesh.
    """
    spacing = _check_positive(spacing, "samples_for_spacing: spacing")
    max_samples = _check_count(max_samples, "samples_for_spacing: max_samples")
    area = float(mesh.validated("samples_for_spacing: mesh").face_areas().sum())
    wanted = area / (spacing * spacing)
    if not math.isfinite(wanted):
        return max_samples
    return int(min(max(math.ceil(wanted), 1), max_samples))


def view_spacing(mesh: Mesh, camera: Camera, pixels: float = DEFAULT_SPACING_PX) -> float:
    """Model units that ``pixels`` pixels span at the center of ``mesh``'s bounding box, seen by ``camera``.

    ``pixels * distance / focal_px``, with ``distance`` the center's depth
    along the view axis (model units; at least 1e-6 of the bounding-box
    diagonal) and ``focal_px`` the camera's focal length in pixels. Surfaces
    nearer to the eye than the center get proportionally more pixels. A mesh
    wholly behind the eye (every corner of its box) is not in the view: the
    distance is the eye's to the center, so that it is sampled as if seen.
    """
    pixels = _check_positive(pixels, "view_spacing: pixels")
    lo, hi = (np.asarray(b, dtype=np.float64) for b in mesh.validated("view_spacing: mesh").bounds())
    center = 0.5 * (lo + hi)
    view = np.asarray(camera.view_matrix, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    if ((corners @ view[:3, :3].T + view[:3, 3])[:, 2] >= 0).all():   # camera space looks along -z
        depth = float(np.linalg.norm(np.asarray(camera.eye, dtype=np.float64) - center))
    else:
        depth = -float((view[:3, :3] @ center + view[:3, 3])[2])
    depth = max(depth, 1e-6 * (float(np.linalg.norm(hi - lo)) or 1.0))
    return pixels * depth / camera.focal_px


def samples_for_pixels(mesh: Mesh, pixels: float = DEFAULT_SPACING_PX, *, camera: Camera | None = None,
                       image_size: int = DEFAULT_IMAGE_SIZE, max_samples: int = MAX_SAMPLES) -> int:
    """The sample count that spaces samples ``pixels`` pixels apart on screen (the default density rule).

    With a ``camera``: the spacing in model units is :func:`view_spacing`
    (``pixels`` at the depth of the mesh's center). Without one (no view
    known yet, e.g. for a file to be viewed later): the mesh's bounding-box
    diagonal is taken to span ``image_size`` pixels, spacing ``pixels *
    diagonal / image_size`` model units (the automatic framing fills 90% of
    the image with the model's projection, which is at most the diagonal, so
    this is close: featuretype.ply, bunny.ply and frag_115.ply get 0.98,
    0.62 and 0.70 times the samples of their automatic 512-pixel view, see
    ``benchmarks/results/mesh_sampling.md``). The count is
    :func:`samples_for_spacing` of that spacing, capped at ``max_samples``
    (:data:`MAX_SAMPLES`).
    """
    if camera is not None:
        spacing = view_spacing(mesh, camera, pixels)
    else:
        pixels = _check_positive(pixels, "samples_for_pixels: pixels")
        size = _check_count(image_size, "samples_for_pixels: image_size")
        lo, hi = (np.asarray(b, dtype=np.float64) for b in mesh.validated("samples_for_pixels: mesh").bounds())
        spacing = pixels * (float(np.linalg.norm(hi - lo)) or 1.0) / size
    return samples_for_spacing(mesh, spacing, max_samples=max_samples)


# -- render-ready splats of a surface ---------------------------------------------------------------


def surface_splats(mesh: Mesh, n: int | None = None, *, sharp_angle: float | str | None = AUTO, seed: int = 0,
                   pixels: float = DEFAULT_SPACING_PX, camera: Camera | None = None,
                   image_size: int = DEFAULT_IMAGE_SIZE, k: int | None = None,
                   max_samples: int = MAX_SAMPLES, boundaries: bool = True,
                   facing_eye=None) -> SplatCloud:
    """Render-ready splats of a triangle mesh's surface (what a mesh file renders as).

    Steps: weld the mesh (:func:`surfsplat.io.surface.weld`: a triangle soup or
    a crease-split CAD mesh becomes a connected surface); draw ``n`` samples
    uniformly by area (:func:`sample_mesh`); give each the interpolated shading
    normal of its face's corners (the file's normals, or crease-aware normals
    at ``sharp_angle``: smooth within curved parts, split at sharp edges, as
    ``render_mesh`` shades the mesh), the interpolated vertex color, a circular
    splat in the plane normal to it of radius :data:`SPACING_COVERAGE` = 2.0
    mean spacings ``sqrt(area / n)``, 2.3 on slivers (:func:`spacing_radius`,
    :func:`face_coverage`: the sampling knows its density, so no neighbour
    search), times ``SAMPLE_COVERAGE / CIRCLE_COVERAGE`` = 0.88 on a mesh
    without sharp edges (:data:`~surfsplat.geometry.splats.SAMPLE_COVERAGE`:
    with the renderer's hole filling, no holes on screen), and clip lines where it
    reaches over an edge sharper than ``sharp_angle``: the line where the
    splat's plane meets the plane of the face across the edge (Zwicker et al.
    2004, sec. 5; :func:`surfsplat.geometry.sharp.mesh_clip_lines`); likewise
    at the open boundary edges of the surface (the rim of a scan), with the
    plane through the edge perpendicular to its face, so that splats do not
    reach past the surface's outline.

    Args:
        mesh: the surface (validated; model units).
        n: number of samples; None (default): :func:`samples_for_pixels` with
            ``pixels``, ``camera``/``image_size`` and ``max_samples``.
        sharp_angle: dihedral angle in degrees (0, 180) above which an edge is
            sharp (crease normals, clip lines); ``"auto"`` (default):
            :func:`surfsplat.io.surface.auto_sharp_angle`, 30 degrees for a mesh
            with creases, None for one without; None: no sharp edges.
        seed: random seed; equal arguments give equal splats.
        pixels: mean sample spacing on screen, pixels (default
            :data:`DEFAULT_SPACING_PX`), when ``n`` is None.
        camera: the view the spacing is measured in; None (default): the
            bounding-box diagonal spans ``image_size`` pixels (see
            :func:`samples_for_pixels`).
        k: None (default): splats sized by the sampling, as above; an integer:
            independent uniform samples (:func:`sample_mesh`) each sized by its
            ``k``-th nearest sample, radius 1.25 ``h_k`` (Guennebaud 2003 eq. 7;
            the former default with ``k`` = :data:`SURFACE_K`, 8).
        max_samples: the cap on the count when ``n`` is None.
        boundaries: clip splats at open boundary edges (default True).
        facing_eye: None (default), or a position (model units, the mesh's frame) from which a
            closed mesh is seen with back faces culled: the ``n`` samples are drawn as without it,
            given outward normals (:func:`~surfsplat.geometry.closed.outward_splats`' rule over
            all of them), and only those whose normal does not face away from it are kept and sized
            (the others are splats the renderer culls: :func:`facing_samples`). The kept splats
            equal the corresponding ones of the whole sampling.

    Returns:
        A validated SplatCloud of ``n`` splats: positions, unit normals, u and
        v (model units), colors where the mesh has vertex colors, and
        clip_lines (N, 2, 3) when there is a sharp angle or (with
        ``boundaries``) the mesh has open boundary edges, else None.

    Raises:
        InputError: an invalid mesh (no faces, non-finite vertices, zero
            area), count (at least 2), spacing or angle.
    """
    welded = weld(mesh)
    angle = resolve_sharp_angle(welded, sharp_angle, "surface_splats: sharp_angle")
    if n is None:
        n = samples_for_pixels(welded, pixels, camera=camera, image_size=image_size, max_samples=max_samples)
    n = _check_count(n, "surface_splats")
    shaded = with_shading_normals(welded, angle)  # crease normals computed once, for samples and splats
    if k is not None and (isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 1):
        raise InputError(f"surface_splats: k must be None or a positive integer, got {k!r}")
    with progress.stage("sampling the surface", n):
        cloud, face, bary = _samples(shaded, n, seed, True, angle, "surface_splats", stratified=k is None)
    radius = None
    if k is None:
        # a smooth mesh's splats shrink as its k-neighbour circles did (1.1 instead of 1.25 h_k, splats.py)
        shrink = (SAMPLE_COVERAGE if angle is None else CREASED_SAMPLE_COVERAGE) / CIRCLE_COVERAGE
        radius = spacing_radius(float(shaded.face_areas().sum()), n, shrink) * face_coverage(shaded)[face]
    flip = False
    if facing_eye is not None:
        keep, flip = facing_samples(cloud, facing_eye)
        cloud, face, bary = cloud.subset(keep), face[keep], bary[keep]
        radius = None if radius is None else radius[keep]
        progress.message(f"{len(cloud):,} of them face the eye (the others are culled)")
    splats = _splats_with_clip_lines(shaded, cloud, face, angle, k, None, None, "surface_splats",
                                     boundaries=boundaries, radius=radius, bary=bary)
    return flipped_normals(splats) if flip else splats


#: Samples :func:`facing_samples` keeps facing away by up to this cosine times their distance to the
#: eye: the shaders cull a splat facing away by any amount, after float32 rounding.
FACING_TOLERANCE = 1e-4


def facing_samples(samples: SplatCloud, eye) -> tuple[np.ndarray, bool]:
    """``(keep, flip)``: (N,) bool, the samples of a closed surface whose normal, turned outward, does
    not face away from ``eye`` (model units, the samples' frame) by more than
    :data:`FACING_TOLERANCE`; and whether the normals point inward (the sign of the flux of
    :func:`~surfsplat.geometry.closed.outward_splats`, over all the samples). Only the kept ones can
    be drawn where back faces are culled (``splat_vertex.glsl``: a circle's plane normal is its
    normal)."""
    p = samples.positions.astype(np.float64)
    nrm = samples.normals.astype(np.float64)
    flip = outward_flux(p, nrm) < 0
    to_eye = np.asarray(eye, dtype=np.float64) - p
    facing = np.einsum("nd,nd->n", nrm, to_eye) * (-1.0 if flip else 1.0)
    return facing >= -FACING_TOLERANCE * np.sqrt(np.einsum("nd,nd->n", to_eye, to_eye)), bool(flip)
