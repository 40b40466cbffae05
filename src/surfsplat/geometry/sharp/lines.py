"""Clip lines from half-spaces (the algebra both sources share), and the sharp-angle argument.

The plane on the other side of a feature is a half-space ``n . x <= d``
(``n`` unit) that contains the splat's own side; on the splat
``x = p + s u + t v`` it reads

    ``(d - n . p) - s (n . u) - t (n . v) >= 0``,

so the clip line (Botsch et al. 2004, sec. 4: ``a s + b t + c >= 0`` in the
splat's normalized coordinates) is ``(a, b, c) = (-n . u, -n . v, d - n . p)``,
scaled by ``1 / |(a, b)|`` (then ``c`` is the signed distance of the splat
center from the line in ``(s, t)`` units).
"""

from __future__ import annotations

import numbers

import numpy as np

from ...cloud import NO_CLIP
from ...errors import InputError


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


def lines_from_halfspaces(n: np.ndarray, c: np.ndarray, u: np.ndarray, v: np.ndarray):
    """Clip lines of half-spaces ``n . (x - p) <= c`` on splats ``p + s u + t v``.

    ``n``: (..., 3) float64 unit normals (zero = no plane); ``c``: (...,)
    float64 offsets relative to the splat center, model units; ``u``, ``v``:
    (..., 3) float64 scaled axes (model units) broadcastable to ``n``.
    Returns ``(lines, crossing)``: (..., 3) float64 normalized ``(a, b, c)``
    (``|(a, b)| = 1``, ``c`` in ``(s, t)`` units; see the module docstring)
    and a bool mask of the lines that cross the splat without cutting it all
    (``|c| < 1``).
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


def pack_lines(lines: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(N, 2, 3) float32: the kept ones of two candidate lines per row first, (0, 0, 1) elsewhere.

    ``lines``: (N, 2, 3) candidate ``(a, b, c)``; ``keep``: (N, 2) bool.
    """
    out = np.broadcast_to(NO_CLIP, lines.shape).astype(np.float32)
    out[keep] = lines[keep]
    swap = ~keep[:, 0] & keep[:, 1]
    out[swap] = out[swap][:, ::-1]
    return out
