"""The automatic viewing direction: the candidate view that shows the most of a model.

A view is scored by its viewpoint entropy (Vazquez, Feixas, Sbert & Heidrich 2001, eq. 1):

    H(d) = - sum_i (A_i / A_t) log2(A_i / A_t)

over the projected areas ``A_i`` of the visible faces, with the background as one more term
``A_0`` and ``A_t`` the area of the whole image. Views that show many faces at balanced sizes score
high; a view straight onto one large face (a CAD part seen face-on: one grey silhouette) scores low.
Splats have no faces: a face here is an orientation class, the splats whose (unoriented) normals are
nearest one of :data:`NORMAL_BINS` directions spread over a hemisphere, so a flat face is one class
and a curved surface several. Areas are measured as Vazquez et al. do, with an item buffer: the
model's samples are projected orthographically onto a :data:`RESOLUTION`-pixel square holding its
bounding sphere, each pixel keeps its nearest sample (a z-buffer, by ``np.minimum.at``), and a
class's area is the number of pixels it keeps; uncovered pixels are the background.

Candidates are :data:`CANDIDATES` directions spread evenly (a Fibonacci lattice) over the hemisphere
above the model (about its up axis), plus the default direction. Models that already look right
keep their view: the default is replaced only where it looks at one face head-on (the largest
orientation class covers more than :data:`FACE_ON_SHARE` of the model's visible area) and the best
candidate scores more than :data:`KEEP_DEFAULT` bits above it.

Samples: :data:`SAMPLES` splat centers and normals at most (a regular subsample), stratified
triangle samples for a mesh, normals estimated from the nearest neighbours (PCA) for bare points
(a mesh's vertices alone, without faces, are sparse on a CAD part: pass the mesh).

A base module: NumPy, :mod:`surfsplat.cloud` and :mod:`surfsplat.camera` only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import direction_vector
from .cloud import SplatCloud
from .errors import InputError

#: Candidate directions on the upper hemisphere (besides the default).
CANDIDATES = 40
#: Highest candidate elevation above the horizon, degrees (straight down onto the top is left out:
#: its screen orientation about the up axis is arbitrary).
MAX_ELEVATION = 80.0
#: Item-buffer size, pixels per side (smaller for clouds too sparse to cover it without holes).
RESOLUTION = 96
#: Samples of the model scored per view (a regular subsample of larger clouds).
SAMPLES = 80_000
#: Samples per pixel of the item buffer's covered area wanted (fewer points: a coarser buffer).
SAMPLES_PER_PIXEL = 5.0
#: Orientation classes ("faces"): unoriented normal directions spread over a hemisphere.
NORMAL_BINS = 26
#: The default direction is kept when the best candidate's entropy exceeds its own by at most this
#: many bits.
KEEP_DEFAULT = 0.07
#: The default direction is replaced only where it is face-on: one orientation class covers more
#: than this fraction of the model's visible area (a box seen from the default direction shows its
#: largest face at 40-60%; a plate seen nearly head-on at 65% and more).
FACE_ON_SHARE = 0.6
#: Neighbours for the normals of bare points (PCA of the neighbourhood).
PCA_NEIGHBOURS = 10
#: Bare points used for PCA normals (brute-force neighbours: quadratic in this count).
PCA_SAMPLES = 4_000


@dataclass(frozen=True)
class ViewChoice:
    """The automatic view of a model.

    Attributes:
        direction: (3,) float64 unit vector from the model toward the eye, world.
        score: viewpoint entropy of ``direction``, bits.
        default_score: viewpoint entropy of the default direction, bits.
        best_score: the highest entropy over all candidates, bits.
        kept_default: True when the default direction was kept.
        default_face_share: the fraction of the model's visible area the largest orientation class
            covers in the default view.
        reason: one sentence for the user on the choice.
    """

    direction: np.ndarray
    score: float
    default_score: float
    best_score: float
    kept_default: bool
    default_face_share: float
    reason: str


def candidate_directions(up, count: int = CANDIDATES, max_elevation: float = MAX_ELEVATION) -> np.ndarray:
    """(count, 3) float64 unit directions evenly spread (Fibonacci lattice, equal area) over the band of
    the hemisphere about ``up`` from the horizon to ``max_elevation`` degrees."""
    up = _unit(direction_vector(up, "up"))
    right = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    right = _unit(right)
    front = np.cross(right, up)
    i = np.arange(count) + 0.5
    height = i / count * np.sin(np.radians(max_elevation))   # uniform in height: equal areas on the sphere
    azimuth = i * np.pi * (3.0 - np.sqrt(5.0))                 # the golden angle
    ring = np.sqrt(1.0 - height**2)
    return (ring * np.cos(azimuth))[:, None] * front + (ring * np.sin(azimuth))[:, None] * right + height[:, None] * up


def normal_bins(count: int = NORMAL_BINS) -> np.ndarray:
    """(count, 3) unit directions spread over the hemisphere z >= 0 (Fibonacci lattice): the
    orientation classes of unoriented normals."""
    i = np.arange(count) + 0.5
    z = i / count
    azimuth = i * np.pi * (3.0 - np.sqrt(5.0))
    ring = np.sqrt(1.0 - z**2)
    return np.column_stack([ring * np.cos(azimuth), ring * np.sin(azimuth), z])


def view_samples(model, samples: int = SAMPLES, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(positions, normals)``, (n, 3) float64 each, n <= ``samples``: the points a view is scored by.

    A SplatCloud with normals: a regular subsample of its splats (local coordinates). A mesh (an
    object with ``vertices`` and ``faces``): area-weighted samples of its triangles with the face
    normals. Bare points (a SplatCloud without normals, an (N, 3) array): a subsample of
    :data:`PCA_SAMPLES` with normals from the PCA of their nearest neighbours.
    """
    rng = np.random.default_rng(seed)
    faces = getattr(model, "faces", None)
    if faces is not None and len(faces):
        vertices = np.asarray(model.vertices, dtype=np.float64)
        tri = vertices[np.asarray(faces)]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = np.linalg.norm(cross, axis=1)
        if area.sum() > 0:
            # stratified in the cumulative area: every face gets its share of samples, less noise
            cumulative = np.cumsum(area)
            pick = np.searchsorted(cumulative, (np.arange(samples) + rng.random(samples)) / samples * cumulative[-1])
            pick = np.minimum(pick, len(tri) - 1)
            a, b = rng.random((2, samples))
            flip = a + b > 1.0
            a, b = np.where(flip, 1.0 - a, a), np.where(flip, 1.0 - b, b)
            t = tri[pick]
            positions = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
            return positions, cross[pick] / area[pick, None]
    if isinstance(model, SplatCloud):
        positions, normals = model.positions, model.normals
    else:
        positions = getattr(getattr(model, "points", None), "positions", None)
        normals = getattr(getattr(model, "points", None), "normals", None)
        if positions is None:
            positions = np.asarray(getattr(model, "vertices", model))
    positions = np.asarray(positions)
    if positions.ndim != 2 or positions.shape[1] != 3 or not len(positions):
        raise InputError(f"a view needs (N, 3) positions, got shape {positions.shape}")
    if normals is not None:
        step = -(-len(positions) // samples)
        p, n = positions[::step].astype(np.float64), np.asarray(normals[::step], dtype=np.float64)
        keep = np.isfinite(p).all(axis=1) & np.isfinite(n).all(axis=1)
        return p[keep], n[keep]
    p = positions[::-(-len(positions) // PCA_SAMPLES)].astype(np.float64)
    p = p[np.isfinite(p).all(axis=1)]
    return p, pca_normals(p)


def pca_normals(points: np.ndarray, k: int = PCA_NEIGHBOURS) -> np.ndarray:
    """(n, 3) unit normals of ``points`` (n, 3): the least-variance axis of each point's ``k`` nearest
    neighbours (brute force in blocks of rows: for a few thousand points)."""
    n = len(points)
    k = min(k, n)
    if k < 3:
        return np.tile([0.0, 0.0, 1.0], (n, 1))
    neighbours = np.empty((n, k), dtype=np.int64)
    block = max(1, 4_000_000 // n)
    for start in range(0, n, block):   # blocks of rows, vectorized within: memory O(block * n)
        d2 = ((points[start:start + block, None, :] - points[None, :, :]) ** 2).sum(axis=2)
        neighbours[start:start + block] = np.argpartition(d2, k - 1, axis=1)[:, :k]
    q = points[neighbours] - points[neighbours].mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", q, q))
    return vectors[:, :, 0]


def viewpoint_entropy(positions, normals, directions, up, resolution: int | None = None) -> np.ndarray:
    """(M,) viewpoint entropy, bits, of the samples seen from each of ``directions`` (M, 3): eq. 1 of
    Vazquez et al. 2001 over the shares :func:`view_areas` returns (the background one more term)."""
    share = view_areas(positions, normals, directions, up, resolution)
    logs = np.log2(np.where(share > 0, share, 1.0))
    return -(share * logs).sum(axis=1)


def view_areas(positions, normals, directions, up, resolution: int | None = None) -> np.ndarray:
    """(M, NORMAL_BINS + 1) fractions of the image each orientation class covers seen from each of
    ``directions`` (M, 3), the background last (rows sum to 1).

    Orthographic views along ``-direction`` of a square holding the samples' bounding sphere (its
    screen axes from ``up``), ``resolution`` pixels a side (None: :data:`RESOLUTION`, less for few
    samples); each pixel keeps its nearest sample (an item buffer); the classes are the samples'
    normal bins (see the module docstring).
    """
    p = np.asarray(positions, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    directions = np.atleast_2d(np.asarray(directions, dtype=np.float64))
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    up = _unit(direction_vector(up, "up"))
    if resolution is None:
        # a surface covers roughly half of its bounding sphere's square: enough samples per pixel there
        resolution = int(np.clip(np.sqrt(len(p) / SAMPLES_PER_PIXEL / 0.5), 8, RESOLUTION))
    q = p - 0.5 * (p.min(axis=0) + p.max(axis=0))
    radius = float(np.sqrt((q**2).sum(axis=1).max())) or 1.0
    bins = normal_bins()
    length = np.linalg.norm(n, axis=1, keepdims=True)
    unit = np.ascontiguousarray((n / np.where(length > 0, length, 1.0)).T)
    qt = np.ascontiguousarray(q.T)   # (3, n): dot products as three axpys (BLAS threads stall on a busy machine)

    def along(axis, rows=qt):
        return axis[0] * rows[0] + axis[1] * rows[1] + axis[2] * rows[2]

    classes = np.argmax(np.abs(np.stack([along(b, unit) for b in bins])), axis=0)
    total = resolution * resolution
    shares = np.empty((len(directions), len(bins) + 1))

    for j, d in enumerate(directions):   # one item buffer per candidate (vectorized over the samples)
        right = np.cross(up, d)
        if np.linalg.norm(right) < 1e-9:
            right = np.cross([1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0], d)
        right = _unit(right)
        screen_up = np.cross(d, right)
        scale = 0.5 * resolution / radius
        col = np.clip(((along(right) + radius) * scale).astype(np.int64), 0, resolution - 1)
        row = np.clip(((along(screen_up) + radius) * scale).astype(np.int64), 0, resolution - 1)
        pixel = row * resolution + col
        depth = -along(d)                                # distance behind the plane through the center
        nearest = np.full(total, np.inf)
        np.minimum.at(nearest, pixel, depth)             # the z-buffer
        owner = np.full(total, -1)
        front = np.flatnonzero(depth <= nearest[pixel])
        owner[pixel[front]] = front                      # one nearest sample per covered pixel
        front = owner[owner >= 0]
        shares[j, :-1] = np.bincount(classes[front], minlength=len(bins))
        shares[j, -1] = total - len(front)              # the background term
    return shares / total


def choose_direction(model, up, default, *, candidates: int = CANDIDATES, keep_default: float = KEEP_DEFAULT,
                     face_on_share: float = FACE_ON_SHARE) -> ViewChoice:
    """The automatic viewing direction of ``model`` (see the module docstring).

    Args:
        model: a SplatCloud (with normals: its splats; without: its points), a Hierarchy (its points),
            a mesh (``vertices``, ``faces``) or an (N, 3) array of points, model units.
        up: world up vector; candidates lie on the hemisphere above.
        default: world direction toward the eye kept unless a candidate shows clearly more.
        candidates: number of candidate directions besides the default.
        keep_default: bits of entropy the best candidate must gain over the default to replace it.
        face_on_share: the default is replaced only when one orientation class covers more than this
            fraction of the model's visible area in it (a face seen head-on).
    """
    default = _unit(direction_vector(default, "default direction"))
    positions, normals = view_samples(model)
    if not len(positions):
        raise InputError("a view needs at least one finite point")
    directions = np.vstack([default, candidate_directions(up, candidates)])
    shares = view_areas(positions, normals, directions, up)
    scores = -(shares * np.log2(np.where(shares > 0, shares, 1.0))).sum(axis=1)
    model_area = shares[0, :-1].sum()
    dominant = float(shares[0, :-1].max() / model_area) if model_area > 0 else 1.0
    best = int(np.argmax(scores))
    face_on = dominant > face_on_share
    kept = bool(not face_on or scores[best] <= scores[0] + keep_default)
    pick = 0 if kept else best
    if kept:
        why = (f"one face covers {dominant:.0%} of it" if face_on else
               f"no face covers more than {face_on_share:.0%} of it")
        reason = (f"the default view ({why}; viewpoint entropy {scores[0]:.2f} bits, the best other "
                  f"{scores[best]:.2f})")
    else:
        reason = (f"a view showing more than the default, where one face covers {dominant:.0%} of the model "
                  f"(viewpoint entropy {scores[best]:.2f} bits against {scores[0]:.2f})")
    return ViewChoice(directions[pick].copy(), float(scores[pick]), float(scores[0]), float(scores[best]), kept,
                      dominant, reason)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


__all__ = ["ViewChoice", "choose_direction", "viewpoint_entropy", "view_areas", "candidate_directions",
           "view_samples", "normal_bins", "pca_normals", "CANDIDATES", "RESOLUTION", "SAMPLES", "NORMAL_BINS",
           "KEEP_DEFAULT", "FACE_ON_SHARE"]
