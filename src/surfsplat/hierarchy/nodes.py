"""Per-node math of the point-octree: covariances, ellipses, normal fields, cones (pure functions).

Pajarola, Sainz & Guidotti 2003, sections 3.3 and 3.4, vectorized over
nodes (leading axis). Everything here is float64 unless stated otherwise.

* The *generic homogeneous covariance* of a point set is
  ``M_bar = sum_i p'_i p'_i^T`` with ``p'_i = (p_i - o, 1)`` (EQ 2), a
  symmetric 4x4 matrix stored as its 10 unique entries in the order
  :data:`COVARIANCE_ENTRIES`. ``o`` is a fixed origin (the hierarchy uses the
  center of the cloud's bounds; it only improves float64 precision for clouds
  far from the model origin: EQ 2 holds for any translation). M_bar of a
  union of sets is the sum of theirs (EQ 4).
* The covariance about any center ``c`` is the upper-left 3x3 of
  ``T M_bar T^T`` with T the translation by ``-c`` (EQ 2; EQ 1 without the
  factor 1/n).
* The tangent-plane ellipse: the covariance projected into the plane of the
  node's normal (EQ 3, with an orthonormal tangent frame instead of the
  paper's ``R_y = (0, -n_z, n_y)``, which degenerates for n = x), its
  eigen-decomposition in closed form (EQ 5, EQ 6) giving the axis directions
  and the axis ratio ``sqrt(lambda1 / lambda2)`` (semi-axes are proportional
  to the square roots of the eigenvalues: the paper's ``a' = lambda1`` is a
  slip), capped by a maximum anisotropy.
"""

from __future__ import annotations

import numpy as np

from ..frames import tangent_frame64

#: (row, column) of the 10 unique entries of the symmetric 4x4 ``M_bar``,
#: index 3 being the homogeneous coordinate (1): xx xy xz x yy yz y zz z n.
COVARIANCE_ENTRIES = ((0, 0), (0, 1), (0, 2), (0, 3), (1, 1), (1, 2), (1, 3), (2, 2), (2, 3), (3, 3))

#: Column of the point count (the (3, 3) entry) and of the coordinate sums in the packed M_bar.
COUNT = 9
SUMS = (3, 6, 8)

#: Largest |alpha|, |beta| of a fitted normal field (the normal tilts at most
#: atan(8) ~ 83 degrees at the rim of the ellipse).
MAX_NORMAL_SLOPE = 8.0

#: Normals "cancel" where their average is shorter than this.
CANCEL = 1e-6


def homogeneous_covariance(points, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Generic homogeneous covariance ``M_bar = sum p' p'^T`` of one point set (Pajarola 2003, EQ 2).

    Args:
        points: (N, 3) float array, model units.
        origin: the origin ``o`` of ``p' = (p - o, 1)``.

    Returns:
        (10,) float64 packed entries (see :data:`COVARIANCE_ENTRIES`).
    """
    p = np.asarray(points, dtype=np.float64) - np.asarray(origin, dtype=np.float64)
    h = np.concatenate([p, np.ones((len(p), 1))], axis=1)
    full = h.T @ h
    return np.array([full[i, j] for i, j in COVARIANCE_ENTRIES])


def unpack_covariance(packed) -> np.ndarray:
    """(..., 10) packed ``M_bar`` -> (..., 4, 4) symmetric matrices."""
    packed = np.asarray(packed, dtype=np.float64)
    out = np.empty(packed.shape[:-1] + (4, 4))
    for k, (i, j) in enumerate(COVARIANCE_ENTRIES):
        out[..., i, j] = out[..., j, i] = packed[..., k]
    return out


#: Entries of a symmetric 3x3 matrix stored as 6 columns: xx xy xz yy yz zz.
SYM_ENTRIES = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))

#: Column of each (i, j) in the 6-column symmetric storage.
_SYM = {(i, j): k for k, (i, j) in enumerate(SYM_ENTRIES)} | {(j, i): k for k, (i, j) in enumerate(SYM_ENTRIES)}

#: Columns of ``S = sum p p^T`` (6 entries, ``SYM_ENTRIES`` order) in the packed M_bar.
_SECOND = (0, 1, 2, 4, 5, 7)


def covariance_about(packed, center) -> np.ndarray:
    """Covariance sums ``sum (p - c)(p - c)^T`` about ``center`` from packed ``M_bar``, as 6 columns.

    Pajarola 2003, EQ 2: the upper-left 3x3 of ``T M_bar T^T``, T the
    translation by ``-c``; that is ``S - s c^T - c s^T + n c c^T`` with
    ``S = sum p p^T``, ``s = sum p``, ``n`` the count (all relative to the
    origin of M_bar). Not divided by n.

    Args:
        packed: (K, 10) packed M_bar.
        center: (K, 3) centers, relative to the origin of M_bar.

    Returns:
        (K, 6) float64 symmetric matrices as ``SYM_ENTRIES`` columns (see :func:`symmetric3`).
    """
    m, c = _columns(packed), _columns(center)
    s = m[list(SUMS)]
    n = m[COUNT]
    out = np.empty((6, m.shape[1]))
    for k, (i, j) in enumerate(SYM_ENTRIES):
        out[k] = m[_SECOND[k]] - s[i] * c[j] - c[i] * s[j] + n * c[i] * c[j]
    return out.T


def symmetric3(sym6) -> np.ndarray:
    """(K, 6) symmetric matrices (``SYM_ENTRIES`` columns) -> (K, 3, 3)."""
    sym6 = np.asarray(sym6, dtype=np.float64)
    out = np.empty((len(sym6), 3, 3))
    for k, (i, j) in enumerate(SYM_ENTRIES):
        out[:, i, j] = out[:, j, i] = sym6[:, k]
    return out


def _columns(a) -> np.ndarray:
    """(K, n) -> contiguous (n, K) float64 (fast column access)."""
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).T)


def quadratic_form(sym6, a, b) -> np.ndarray:
    """(K,) ``a^T M b`` for (K, 6) symmetric matrices and (K, 3) vectors."""
    m, a, b = _columns(sym6), _columns(a), _columns(b)
    out = np.zeros(a.shape[1])
    for i in range(3):
        mb = m[_SYM[i, 0]] * b[0]
        mb += m[_SYM[i, 1]] * b[1]
        mb += m[_SYM[i, 2]] * b[2]
        mb *= a[i]
        out += mb
    return out


def average_normals(normal_sums, counts, covariance) -> np.ndarray:
    """Unit average normals; PCA normals where the normals cancel.

    Pajarola 2003, sec. 3.2: the representative normal is the average of the
    node's normals. Where ``|sum n| <= CANCEL * count`` (the two sides of a
    thin sheet, the root of a closed surface) the average has no reliable
    direction: the eigenvector of the smallest eigenvalue of the covariance
    (the least-squares plane normal) is used instead.

    Args:
        normal_sums: (K, 3) sums of the unit normals.
        counts: (K,) number of points.
        covariance: (K, 6) covariance sums (``SYM_ENTRIES``; used only for the fallback).

    Returns:
        (K, 3) float64 unit normals.
    """
    s = np.asarray(normal_sums, dtype=np.float64)
    length = np.linalg.norm(s, axis=1)
    cancel = ~(length > CANCEL * np.asarray(counts, dtype=np.float64))
    out = s / np.where(cancel, 1.0, length)[:, None]
    if cancel.any():
        out[cancel] = pca_normals(np.asarray(covariance)[cancel])
    return out


def pca_normals(covariance) -> np.ndarray:
    """(K, 3) unit eigenvectors of the smallest eigenvalue of (K, 6) symmetric matrices (``SYM_ENTRIES``)."""
    _, vectors = np.linalg.eigh(symmetric3(covariance))
    return vectors[:, :, 0]


def tangent_ellipses(covariance, normals, max_anisotropy: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Axis directions and axis ratio of the covariance ellipse in each node's tangent plane.

    Pajarola 2003, sec. 3.4: the covariance is expressed in the tangent frame
    of the normal (EQ 3) and its upper-left 2x2 block ``M^{x,y}`` (the points
    projected into the tangent plane) is decomposed in closed form (EQ 5,
    EQ 6). The semi-axes are proportional to ``sqrt(lambda1)`` and
    ``sqrt(lambda2)``; the ratio is capped at ``max_anisotropy`` and is 1
    where the projected covariance vanishes.

    Args:
        covariance: (K, 6) covariance sums about the node centers (``SYM_ENTRIES``).
        normals: (K, 3) unit normals.
        max_anisotropy: cap of major / minor (>= 1).

    Returns:
        ``(e1, e2, ratio)``: (K, 3) unit major and minor axis directions
        (``e1 x e2 = n``) and the (K,) ratio >= 1.
    """
    t1, t2 = tangent_frame64(normals)
    c = np.asarray(covariance, dtype=np.float64)
    cxx = quadratic_form(c, t1, t1)
    cxy = quadratic_form(c, t1, t2)
    cyy = quadratic_form(c, t2, t2)
    # closed-form eigen-decomposition of the 2x2 tangent covariance (EQ 5 and EQ 6)
    half = 0.5 * (cxx - cyy)
    disc = np.sqrt(half * half + cxy * cxy)
    mid = 0.5 * (cxx + cyy)
    lam1 = mid + disc
    lam2 = np.maximum(mid - disc, 0.0)
    theta = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    cos, sin = np.cos(theta)[:, None], np.sin(theta)[:, None]
    e1 = t1 * cos + t2 * sin
    e2 = t2 * cos - t1 * sin
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lam2 > 0, np.sqrt(lam1 / lam2), max_anisotropy)
    ratio = np.where(lam1 > 0, ratio, 1.0)
    ratio = np.clip(np.nan_to_num(ratio, nan=1.0), 1.0, max_anisotropy)
    return e1, e2, ratio


def ellipse_radius2(dx, dy, dz, e1, e2, inv_ratio):
    """Squared normalized radius ``(x / ratio)^2 + y^2`` of offsets in an ellipse frame.

    ``x = d . e1``, ``y = d . e2``: the offset ``d`` projected into the
    tangent plane (Pajarola 2003, sec. 3.4: ``f^2 = x^2/a'^2 + y^2/b'^2``
    with ``b' = 1``, ``a' = ratio``). Arrays broadcast; ``e1``, ``e2`` are
    sequences of three coordinate arrays. Computed in the dtype of the inputs.
    """
    x = dx * e1[0] + dy * e1[1] + dz * e1[2]
    y = dx * e2[0] + dy * e2[1] + dz * e2[2]
    x *= inv_ratio
    x *= x
    y *= y
    x += y
    return x


def disk_radius2(dx, dy, dz, ux, uy, uz, vx, vy, vz, e1, e2, inv_ratio):
    """Squared normalized radius (as :func:`ellipse_radius2`) bounding a whole disk ``d + s u + t v``.

    The disk projects into the ellipse frame as an ellipse with center
    ``c = (x_d, y_d)`` and axes the columns of ``A = [[x_u, x_v], [y_u, y_v]]``;
    its points lie within ``|c| + sigma_max(A)`` of the origin (the triangle
    inequality; exact for a disk centered on an axis). Pajarola 2003 (sec. 3.4,
    fig. 6 b) bounds the disks by their boxes ``d +- u +- v``, which is up to
    sqrt(2) larger. ``sigma_max^2 = (S + sqrt(S^2 - 4 det^2)) / 2`` with ``S`` the
    sum of squares of A's entries.
    """
    def frame(wx, wy, wz):
        return (wx * e1[0] + wy * e1[1] + wz * e1[2]) * inv_ratio, wx * e2[0] + wy * e2[1] + wz * e2[2]

    xd, yd = frame(dx, dy, dz)
    xu, yu = frame(ux, uy, uz)
    xv, yv = frame(vx, vy, vz)
    s = xu * xu + xv * xv + yu * yu + yv * yv
    det = xu * yv - xv * yu
    # S^2 - 4 det^2 factored, so large splats (model units ~1e10 and up) do not overflow float32
    gap = np.sqrt(np.maximum(s - 2.0 * np.abs(det), 0.0)) * np.sqrt(s + 2.0 * np.abs(det))
    sigma = np.sqrt(0.5 * (s + gap))
    r = np.sqrt(xd * xd + yd * yd) + sigma
    return r * r


def normal_field_fit(normal_moments, normal_sums, covariance, center, e1, e2, a, b) -> np.ndarray:
    """Linear normal field ``(alpha, beta)`` least-squares fitted to a node's normals.

    Botsch, Spernat & Kobbelt 2004, eq. 3-4, linearized: with the parameter
    ``s_i = (p_i - c) . e1 / a`` of each point and its normal's tangential
    component ``x_i = n_i . e1``, the slope is ``alpha = sum x_i s_i /
    sum s_i^2`` because ``sum s_i = 0`` for the mean center (the 2x2 systems
    decouple). Summed over points that is
    ``alpha = a (e1^T G_c e1) / (e1^T C e1)`` with
    ``G_c = sum n_i (p_i - c)^T = G - (sum n_i) c^T``, and the same for
    ``beta`` with ``e2`` and ``b``. On a sphere of radius R, alpha = a / R.
    Clamped to +-:data:`MAX_NORMAL_SLOPE`; 0 where the points do not spread
    along the axis.

    Args:
        normal_moments: (K, 9) ``G = sum n_i p_i^T`` row-major (p relative
            to the origin of M_bar).
        normal_sums: (K, 3) ``sum n_i``.
        covariance: (K, 6) covariance sums about ``center`` (``SYM_ENTRIES``).
        center: (K, 3) node centers (the means), relative to the same origin.
        e1, e2: (K, 3) unit ellipse axes; a, b: (K,) semi-axis lengths.

    Returns:
        (K, 2) float64 ``(alpha, beta)``.
    """
    g, nsum, c = _columns(normal_moments), _columns(normal_sums), _columns(center)
    scale = np.abs(covariance).max(axis=1)
    out = np.zeros((len(a), 2))
    for col, (e, length) in enumerate(((e1, a), (e2, b))):
        den = quadratic_form(covariance, e, e)
        e = _columns(e)
        num = np.zeros(len(length))
        for i in range(3):
            row = np.zeros(len(length))
            for j in range(3):
                # G_c = G - (sum n) c^T
                row += (g[3 * i + j] - nsum[i] * c[j]) * e[j]
            num += e[i] * row
        ok = den > 1e-12 * np.maximum(scale, 1e-300)
        slope = np.where(ok, length * num / np.where(ok, den, 1.0), 0.0)
        out[:, col] = np.clip(slope, -MAX_NORMAL_SLOPE, MAX_NORMAL_SLOPE)
    return out


def cone_angle(max_chord2) -> np.ndarray:
    """Normal-cone semi-angle from the largest squared chord ``|n_i - n_c|^2`` to the axis.

    For unit vectors ``|n_i - n_c| = 2 sin(theta_i / 2)``, accurate also for
    small angles (unlike ``acos`` of a dot product). Angles of 90 degrees or
    more become pi: the normals fit in no useful cone (Pajarola 2003,
    sec. 3.2; normal cones of Shirman & Abi-Ezzi 1993).
    """
    chord = np.sqrt(np.maximum(np.asarray(max_chord2, dtype=np.float64), 0.0))
    theta = 2.0 * np.arcsin(np.minimum(chord / 2.0, 1.0))
    return np.where(theta < 0.5 * np.pi, theta, np.pi)
