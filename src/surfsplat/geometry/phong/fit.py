"""Stage 4: fitting a splat to its covered samples (Botsch 2004, sec. 3).

Vectorized over splats: the least-squares plane (centroid and smallest
eigenvector of the covariance of ``P_j``), tangent axes along the principal
directions (eigenvectors of the two smaller eigenvalues of ``sum n_i n_i^T``,
projected into the plane; the point covariance's axes where that is
isotropic, e.g. on a plane), the smallest enclosing ellipse with these axes
(a 1-D convex minimisation over the axis ratio, bounded by
``MAX_ANISOTROPY``), grown by the surface margin (``SURFACE_MARGIN``), the
splat's orientation from the sum of its samples' normals, and the linear
normal field of eq. 3-4 (:mod:`.normal_field`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...frames import tangent_frame
from ..common import dot
from ..normals import smallest_eigenvectors
from ..splats import MAX_ANISOTROPY
from .csr import concat_csr, csr_take, segment_outer, segment_sum, segments
from .normal_field import linear_field
from .samples import Samples

#: Samples whose normal is more than ~75 degrees from the splat's plane normal
#: (``|n_i . n| < 0.25``) are left out of the normal-field fit: their
#: homogeneous coordinates (Botsch 2004, fig. 1) would be huge outliers.
MIN_NORMAL_COS = 0.25

#: The normal covariance is "isotropic" (no principal direction: planes,
#: spheres) when its two smaller eigenvalues differ by less than this fraction
#: of their sum; the point covariance's axes are used there.
ISOTROPIC_GAP = 0.2

#: Golden-section iterations of the ellipse's axis ratio (interval x 0.618 each).
RATIO_ITERATIONS = 28

#: Re-fitted planes (relaxation) more than 20 degrees from their samples' mean
#: normal are not taken (samples along an arc): the old plane is kept.
_MIN_MEAN_COS = math.cos(math.radians(20.0))

#: Relative margin on the ellipse axes (float32 rounding of the farthest sample).
_ELLIPSE_MARGIN = 1e-5


@dataclass
class Splats:
    """Fitted splats (internal), float64, model units; members CSR into the sorted samples."""

    center: np.ndarray        # (J, 3) ellipse center (on the plane)
    normal: np.ndarray        # (J, 3) unit plane normal, oriented like the samples
    u_hat: np.ndarray         # (J, 3) unit axes, u_hat x v_hat = normal
    v_hat: np.ndarray
    a: np.ndarray             # (J,) semi-axes along u_hat, v_hat (with the surface margin)
    b: np.ndarray
    tight_a: np.ndarray       # (J,) the smallest enclosing ellipse's (cover bookkeeping)
    tight_b: np.ndarray
    center_normal: np.ndarray  # (J, 3) unit center normal of the field
    field: np.ndarray         # (J, 2) (alpha, beta) for the unit center normal
    colors: np.ndarray | None
    ptr: np.ndarray
    idx: np.ndarray
    lines: np.ndarray | None = None   # (J, 2, 3) float32 clip lines, with sharp_angle
    missing: np.ndarray | None = None  # (J,) bool: reaches over an edge without a line for it

    def take(self, rows: np.ndarray) -> "Splats":
        """The splats ``rows``."""
        ptr, idx = csr_take(self.ptr, self.idx, rows)
        pick = [None if x is None else x[rows] for x in (self.colors, self.lines, self.missing)]
        return Splats(self.center[rows], self.normal[rows], self.u_hat[rows], self.v_hat[rows], self.a[rows],
                      self.b[rows], self.tight_a[rows], self.tight_b[rows], self.center_normal[rows],
                      self.field[rows], pick[0], ptr, idx, pick[1], pick[2])

    def resize(self, rows: np.ndarray, factor: float) -> None:
        """Keep ``factor`` of the (current) surface margin of the splats ``rows`` (in place).

        The normal field follows: ``alpha / a`` is the field's gradient along
        ``u_hat`` in model units, so alpha scales with the axis.
        """
        a = self.tight_a[rows] + factor * (self.a[rows] - self.tight_a[rows])
        b = self.tight_b[rows] + factor * (self.b[rows] - self.tight_b[rows])
        self.field[rows, 0] *= a / self.a[rows]
        self.field[rows, 1] *= b / self.b[rows]
        self.a[rows] = a
        self.b[rows] = b

    def concat(self, other: "Splats") -> "Splats":
        """These splats followed by ``other``'s."""
        ptr, idx = concat_csr([self.ptr, other.ptr], [self.idx, other.idx])

        def cat(x, y):
            return None if x is None or y is None else np.concatenate([x, y])

        return Splats(*(np.concatenate([getattr(self, f), getattr(other, f)]) for f in
                        ("center", "normal", "u_hat", "v_hat", "a", "b", "tight_a", "tight_b", "center_normal",
                         "field")),
                      cat(self.colors, other.colors), ptr, idx, cat(self.lines, other.lines),
                      cat(self.missing, other.missing))


def fit_splats(samples: Samples, ptr: np.ndarray, idx: np.ndarray, center: np.ndarray, normal: np.ndarray) -> Splats:
    """Axes, ellipse, orientation, normal field and color of each splat on its plane (stage 4).

    ``center`` (J, 3) is a point of the plane (the members' centroid, model
    units), ``normal`` (J, 3) its unit normal; ``ptr``, ``idx`` the members
    (>= 1 each).
    """
    count = len(ptr) - 1
    seg = segments(ptr)
    rel = samples.pts[idx] - center[seg]
    nn = samples.nrm[idx]
    # orientation: the side of the samples' normals (sum; Botsch 2004 sec. 5:
    # only the splats need consistent orientation)
    flip = dot(segment_sum(nn, seg, count), normal) < 0
    normal = np.where(flip[:, None], -normal, normal)
    cos = dot(nn, normal[seg])
    # the homogeneous normal representation cancels the samples' own signs
    aligned = nn * np.where(cos < 0, -1.0, 1.0)[:, None]
    cos = np.abs(cos)
    u_hat = _principal_axes(aligned, rel, seg, normal)
    v_hat = np.cross(normal, u_hat)
    x = dot(rel, u_hat[seg])
    y = dot(rel, v_hat[seg])
    tight_a, tight_b = _enclosing_ellipse(x, y, ptr, seg)
    # float32 rounding of the stored splat; a floor for single samples
    floor = 0.05 * samples.spacing
    tight_a = np.maximum(tight_a * (1.0 + _ELLIPSE_MARGIN) + samples.slack, floor)
    tight_b = np.maximum(tight_b * (1.0 + _ELLIPSE_MARGIN) + samples.slack, floor)
    # the surface between the samples: both semi-axes grow by the margin m
    # (for a circle exactly the points within m of it; see SURFACE_MARGIN)
    grow = samples.margin * segment_sum(samples.gap[idx].astype(np.float64), seg, count) / np.diff(ptr)
    a = tight_a + grow
    b = tight_b + grow
    # Botsch 2004, eq. 3-4: (s_i, t_i) normalized coordinates, (x_i, y_i) the
    # normal on the offset tangent plane (fig. 1): n_i . u_hat / n_i . n
    s = x / a[seg]
    t = y / b[seg]
    usable = cos >= MIN_NORMAL_COS
    safe = np.where(usable, cos, 1.0)
    hx = dot(aligned, u_hat[seg]) / safe
    hy = dot(aligned, v_hat[seg]) / safe
    w = usable.astype(np.float64)
    xbar, alpha = linear_field(s, hx, w, seg, count)
    ybar, beta = linear_field(t, hy, w, seg, count)
    center_normal = normal + xbar[:, None] * u_hat + ybar[:, None] * v_hat
    length = np.linalg.norm(center_normal, axis=1)
    field = np.stack([alpha, beta], axis=1) / length[:, None]
    colors = None
    if samples.colors is not None:
        colors = segment_sum(samples.colors[idx].astype(np.float64), seg, count) / np.diff(ptr)[:, None]
    return Splats(center, normal, u_hat, v_hat, a, b, tight_a, tight_b, center_normal / length[:, None], field,
                  colors, ptr, idx)


def _principal_axes(aligned: np.ndarray, rel: np.ndarray, seg: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Unit ``u_hat`` in each splat's plane along the direction of largest normal variation.

    Botsch 2004, sec. 3: the eigenvectors of the two smaller eigenvalues of
    ``sum n_i n_i^T`` (here the middle one, the direction of maximum normal
    deviation = maximum curvature), projected into the plane. Where the two
    are about equal (planes, spheres) the major axis of the point covariance.
    """
    count = len(normal)
    lam, vec = np.linalg.eigh(segment_outer(aligned, seg, count))
    axis = vec[:, :, 1]
    isotropic = lam[:, 1] - lam[:, 0] <= ISOTROPIC_GAP * (lam[:, 1] + lam[:, 0]) + 1e-12 * lam[:, 2]
    if isotropic.any():
        _, pvec = np.linalg.eigh(segment_outer(rel, seg, count)[isotropic])
        axis[isotropic] = pvec[:, :, 2]
    axis = axis - dot(axis, normal)[:, None] * normal
    length = np.linalg.norm(axis, axis=1)
    weak = length < 1e-6
    if weak.any():
        axis[weak] = tangent_frame(normal[weak])[0]
        length[weak] = np.linalg.norm(axis[weak], axis=1)
    return axis / length[:, None]


def _enclosing_ellipse(x: np.ndarray, y: np.ndarray, ptr: np.ndarray, seg: np.ndarray,
                       max_anisotropy: float = MAX_ANISOTROPY) -> tuple[np.ndarray, np.ndarray]:
    """Smallest ellipses with axes along x, y centred at 0 that enclose each segment's points.

    With fixed axes the area ``pi a b`` is, for the axis ratio ``rho = a / b``
    and ``b^2 = max_i (x_i^2 / rho^2 + y_i^2)``, proportional to
    ``g(r) = max_i (x_i^2 e^-r + y_i^2 e^r)`` with ``r = ln rho``: a maximum of
    convex functions, minimised by golden-section search over
    ``|r| <= ln max_anisotropy`` (vectorized over the segments).

    Returns ``(a, b)``: (J,) semi-axes along x and y (0 where all points are at 0).
    """
    xx, yy = x * x, y * y
    starts = ptr[:-1]

    def g(r):
        return np.maximum.reduceat(xx * np.exp(-r)[seg] + yy * np.exp(r)[seg], starts)

    bound = math.log(max_anisotropy)
    lo = np.full(len(starts), -bound)
    hi = np.full(len(starts), bound)
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - phi * (hi - lo), lo + phi * (hi - lo)
    fc, fd = g(c), g(d)
    for _ in range(RATIO_ITERATIONS):
        left = fc <= fd                          # the minimum is in [lo, d]
        hi = np.where(left, d, hi)
        lo = np.where(left, lo, c)
        new = np.where(left, hi - phi * (hi - lo), lo + phi * (hi - lo))
        fnew = g(new)
        c, d, fc, fd = (np.where(left, new, d), np.where(left, c, new),
                        np.where(left, fnew, fd), np.where(left, fc, fnew))
    r = np.where(fc <= fd, c, d)
    rho = np.exp(r)
    b = np.sqrt(np.maximum.reduceat(xx / (rho * rho)[seg] + yy, starts))
    return rho * b, b


def member_planes(samples: Samples, ptr: np.ndarray, idx: np.ndarray):
    """Least-squares planes of the member sets: (centroid, unit normal, max |distance|; inf: no plane)."""
    count = len(ptr) - 1
    seg = segments(ptr)
    p = samples.pts[idx]
    centroid = segment_sum(p, seg, count) / np.diff(ptr)[:, None]
    rel = p - centroid[seg]
    cov = [np.bincount(seg, weights=rel[:, i] * rel[:, j], minlength=count)
           for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
    normal = smallest_eigenvectors(*cov).astype(np.float64)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    err = np.maximum.reduceat(np.abs(dot(rel, normal[seg])), ptr[:-1])
    # fewer than 3 samples or (nearly) collinear ones define no plane; one far
    # from the samples' normals fits no surface
    aligned = samples.nrm[idx] * np.where(dot(samples.nrm[idx], normal[seg]) < 0, -1.0, 1.0)[:, None]
    mean = segment_sum(aligned, seg, count)
    tilt = np.abs(dot(mean, normal)) < _MIN_MEAN_COS * np.linalg.norm(mean, axis=1)
    err[~spans_plane(cov) | (np.diff(ptr) < 3) | tilt] = np.inf
    return centroid, normal, err


def spans_plane(cov) -> np.ndarray:
    """Covariances (six entries) of point sets that span a plane (``lambda_2 / lambda_1`` above ~1e-8)."""
    trace = cov[0] + cov[3] + cov[5]
    minors = cov[0] * cov[3] - cov[1] ** 2 + cov[0] * cov[5] - cov[2] ** 2 + cov[3] * cov[5] - cov[4] ** 2
    return minors > 1e-8 * trace * trace
