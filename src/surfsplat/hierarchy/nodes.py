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


# -- per-point attributes carried to the nodes ----------------------------------------


def range_sums(values, start, count) -> np.ndarray:
    """Sums of ``values`` ((N,) or (N, k)) over the index ranges ``[start, start + count)``, float64.

    Prefix sums: one cumulative sum, two gathers per range (ranges may nest or overlap).
    """
    v = np.asarray(values, dtype=np.float64)
    total = np.zeros((len(v) + 1,) + v.shape[1:])
    np.cumsum(v, axis=0, out=total[1:])
    start = np.asarray(start, dtype=np.int64)
    return total[start + np.asarray(count, dtype=np.int64)] - total[start]


def range_means(values, start, count) -> np.ndarray:
    """(M,) float64 mean of the finite ``values`` ((N,)) over each range ``[start, start + count)``.

    Non-finite values are left out of both sum and count; a range without a
    finite value gets NaN.
    """
    v = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(v)
    # prefix sums of the offsets from the overall mean: values far from zero (GPS times) keep their digits
    ref = float(v[finite].mean()) if finite.any() else 0.0
    sums = range_sums(np.where(finite, v - ref, 0.0), start, count)
    counts = range_sums(finite, start, count)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1.0) + ref, np.nan)


def _dense_codes(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(codes, distinct)``: int64 codes 0..K-1 in value order with ``distinct[codes] == values``.
    Integers of 1-2 bytes map to ``value - min`` directly (no sort)."""
    if values.dtype.kind in "biu" and values.dtype.itemsize <= 2 and len(values):
        lo, hi = int(values.min()), int(values.max())
        return values.astype(np.int64) - lo, np.arange(lo, hi + 1).astype(values.dtype)
    distinct, codes = np.unique(values, return_inverse=True)
    return codes.reshape(-1).astype(np.int64), distinct


def _runs(key: np.ndarray, count: np.ndarray | None, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """``(distinct keys in order, summed counts)`` of keys in ``[lo, hi)`` (each counts 1 without
    ``count``): a histogram where the key range is small, else a sort and run lengths."""
    if hi - lo <= 4 * len(key) + 1024:
        hist = np.bincount(key - lo, weights=count, minlength=hi - lo)
        present = np.flatnonzero(hist)
        return present + lo, hist[present].astype(np.int64)
    if count is None:
        key = np.sort(key)
        first = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
        return key[first], np.diff(np.append(first, len(key)))
    order = np.argsort(key, kind="stable")
    key = key[order]
    first = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
    return key[first], np.add.reduceat(count[order], first)


def node_majority(values, point_start, point_count, child_count, level_offsets) -> np.ndarray:
    """(M,) the most frequent of the integer ``values`` ((N,), in the points' order) over each node's
    points; ties go to the smallest of the tied values. Same dtype as ``values``.

    The tree's layout is :class:`~surfsplat.hierarchy.model.Hierarchy`'s (levels concatenated,
    children contiguous, leaves tiling the points). Vectorized bottom-up: the counts of each
    ``(leaf, value)`` come from one histogram (or sort) of the points by that key; a node's counts
    are its children's summed per value (the runs of one level at a time, few where the values
    are few), plus its own when it is a leaf. Of each node's ``(value, count)`` runs, in value
    order, the first with the largest count wins.
    """
    v = np.asarray(values)
    codes, distinct = _dense_codes(v)
    k = max(len(distinct), 1)
    start, cnt = np.asarray(point_start, dtype=np.int64), np.asarray(point_count, dtype=np.int64)
    children = np.asarray(child_count, dtype=np.int64)
    m = len(children)
    leaves = np.flatnonzero(children == 0)
    leaves = leaves[np.argsort(start[leaves], kind="stable")]
    key = np.repeat(leaves, cnt[leaves]) * k
    key += codes
    leaf_key, leaf_count = _runs(key, None, 0, m * k)
    offsets = np.asarray(level_offsets, dtype=np.int64)
    cut = np.searchsorted(leaf_key, offsets * k)
    parent = np.zeros(m, dtype=np.int64)
    parent[1:] = np.repeat(np.arange(m, dtype=np.int64), children)
    out = np.empty(m, dtype=v.dtype)
    below_key = below_count = None
    for level in range(len(cut) - 2, -1, -1):
        run_key, run_count = leaf_key[cut[level]:cut[level + 1]], leaf_count[cut[level]:cut[level + 1]]
        if below_key is not None:
            # EQ 4 for counts: a node's histogram is the sum of its children's
            up = parent[below_key // k] * k + below_key % k
            run_key, run_count = _runs(np.concatenate([run_key, up]), np.concatenate([run_count, below_count]),
                                       int(offsets[level]) * k, int(offsets[level + 1]) * k)
        node = run_key // k
        first = np.flatnonzero(np.concatenate([[True], node[1:] != node[:-1]]))
        longest = np.maximum.reduceat(run_count, first)
        pick = np.flatnonzero(run_count == np.repeat(longest, np.diff(np.append(first, len(node)))))
        pick = pick[np.concatenate([[True], node[pick[1:]] != node[pick[:-1]]])]
        out[node[pick]] = distinct[run_key[pick] % k]
        below_key, below_count = run_key, run_count
    return out


def is_majority_voted(values) -> bool:
    """Whether an attribute column is carried to the nodes by majority vote (integer and boolean
    dtypes: classes, flags, counts) rather than averaged (floating-point dtypes)."""
    return np.asarray(values).dtype.kind in "biu"


def node_attribute_values(attributes, point_start, point_count, child_count,
                          level_offsets) -> dict[str, np.ndarray]:
    """Each node's value of each per-point attribute over its points ``[point_start, + point_count)``.

    Integer and boolean columns (classification, return_number, scan, nonplanar, ...): the
    majority vote (:func:`node_majority`; ties to the smallest value), same dtype.
    Floating-point columns: the mean of the finite values (:func:`range_means`; NaN where
    none), same dtype. The tree as in :func:`node_majority`.
    """
    out = {}
    for name, values in (attributes or {}).items():
        if is_majority_voted(values):
            out[name] = node_majority(values, point_start, point_count, child_count, level_offsets)
        else:
            out[name] = range_means(values, point_start, point_count).astype(np.asarray(values).dtype)
    return out
