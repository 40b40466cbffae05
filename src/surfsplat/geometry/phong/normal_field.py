"""The linear normal field of a splat (Botsch 2004, sec. 3, eq. 2-4).

``n(s, t) = n_0 + s alpha u_hat + t beta v_hat``: with the samples' normals
in homogeneous form on the plane offset by 1 along the splat normal (fig. 1),
``(x_i, y_i) = (n_i . u_hat, n_i . v_hat) / n_i . n``, the field is the
least-squares line ``x_i ~ x_bar + alpha s_i`` (eq. 3) and
``y_i ~ y_bar + beta t_i`` (eq. 4), one 2x2 system per splat and axis,
solved in closed form, least-norm where singular.
"""

from __future__ import annotations

import numpy as np


def solve_least_norm(g00, g01, g11, r0, r1):
    """Solutions of the symmetric PSD 2x2 systems ``[[g00, g01], [g01, g11]] x = r``.

    Least-norm (pseudo-inverse, Botsch 2004 after eq. 4 [GL89]) where a system
    is singular: a rank-1 matrix ``G = lambda e e^T`` (``lambda`` its trace)
    has ``G^+ = G / lambda^2``; a zero matrix gives 0.
    """
    det = g00 * g11 - g01 * g01
    trace = g00 + g11
    regular = det > 1e-9 * trace * trace
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.where(regular, 1.0 / np.where(regular, det, 1.0), 0.0)
        inv_t2 = np.where(trace > 0, 1.0 / np.where(trace > 0, trace * trace, 1.0), 0.0)
    x0 = np.where(regular, (g11 * r0 - g01 * r1) * inv_det, (g00 * r0 + g01 * r1) * inv_t2)
    x1 = np.where(regular, (g00 * r1 - g01 * r0) * inv_det, (g01 * r0 + g11 * r1) * inv_t2)
    return x0, x1


def linear_field(s: np.ndarray, h: np.ndarray, w: np.ndarray, seg: np.ndarray, count: int):
    """Least-squares ``h_i ~ h_bar + slope s_i`` per splat: (h_bar, slope), least norm if singular.

    Botsch 2004, eq. 3 (and eq. 4 with ``t_i``, ``y_i``): the normal equations
    ``[[|P|, sum s], [sum s, sum s^2]] (h_bar, slope) = (sum h, sum h s)``,
    summed over the samples with weight ``w`` (0 = left out).
    """
    ws = w * s
    return solve_least_norm(np.bincount(seg, weights=w, minlength=count),
                            np.bincount(seg, weights=ws, minlength=count),
                            np.bincount(seg, weights=ws * s, minlength=count),
                            np.bincount(seg, weights=w * h, minlength=count),
                            np.bincount(seg, weights=ws * h, minlength=count))
