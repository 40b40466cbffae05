"""Trained Gaussian-splat PLY files (3D Gaussian Splatting and 2D Gaussian Splatting) as splats.

Detected by :mod:`surfsplat.io.ply` from the ``vertex`` element's properties
(:func:`is_gaussian_ply`: ``opacity``, ``scale_0``, ``scale_1``, ``rot_0..3``). The
properties, as the reference implementations write them:

- ``x y z``: centers; ``nx ny nz``: written as zeros by 3DGS, ignored (the normal comes
  from the rotation);
- ``f_dc_0..2``: degree-0 spherical-harmonic coefficients; colour =
  ``0.5 + C0 * f_dc`` with ``C0 = 0.28209479177387814``, clipped to [0, 1]
  (``f_rest_*``, the view-dependent part, is ignored: our colours are view-independent);
- ``opacity``: a logit; opacity = sigmoid(opacity). Gaussians below
  :data:`MIN_OPACITY` (1/255: invisible in an 8-bit image) are dropped, counted in a
  warning. The splat renderer has no per-splat opacity: every kept Gaussian is opaque;
- ``scale_0..2`` (3DGS) or ``scale_0..1`` (2DGS): log standard deviations along the
  rotation's axes; sigma = exp(scale);
- ``rot_0..3``: quaternion, w first (``rot_0`` is w), normalized here.

Mapping to splat ellipses (``u``, ``v`` semi-axes, ``normals``):

- 2DGS surfels: ``u = k * sigma_0 * R[:, 0]``, ``v = k * sigma_1 * R[:, 1]``,
  normal ``R[:, 2]`` (the surfel's own tangent frame).
- 3DGS: the two largest of the three axes ``sigma_i R[:, i]`` become ``u``, ``v`` (times k),
  the normal is the axis of the smallest (sign chosen so that ``u x v`` is along it). A
  Gaussian flattened on a surface thus becomes the surfel it approximates; a round blob
  becomes a disc through its center.

**k = :data:`SIGMA_SCALE` = 2.** Our splat's ellipse ``s^2 + t^2 = 1`` is where the
reconstruction kernels cut: the EWA kernel is ``exp(-c (s^2 + t^2))`` (cutoff c = 1 by
default, ``FilterOptions.cutoff``), i.e. a Gaussian of standard deviation ``1 / sqrt(2c)``
ellipse radii. With k = 2 the ellipse reaches 2 sigma of the trained Gaussian, enclosing 86%
of its mass (1 - exp(-2)) and every point where its weight exceeds exp(-2) = 13.5% of the
peak; the kernel's own standard deviation is then k / sqrt(2) = 1.41 trained sigmas. 2DGS
evaluates its surfels up to 3 sigma (its screen bounding box) but weighs them with the
trained Gaussian and alpha-composites front to back, so the rim contributes little; k = 3
would copy the footprint but blur colours (kernel sigma 2.1 sigma), k = sqrt(2) would copy the
kernel exactly but cut at 37% of the peak and open holes between Gaussians that the trained
model fills with their tails. k = 2 keeps surfaces closed while staying close to the trained
falloff.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError

#: SH degree-0 basis constant: colour = 0.5 + C0 * f_dc.
SH_C0 = 0.28209479177387814
#: Ellipse semi-axes in standard deviations of the trained Gaussian (see the module docstring).
SIGMA_SCALE = 2.0
#: Gaussians whose opacity (after the sigmoid) is below this are dropped.
MIN_OPACITY = 1.0 / 255.0

_REQUIRED = ("x", "y", "z", "opacity", "scale_0", "scale_1", "rot_0", "rot_1", "rot_2", "rot_3")


class DroppedGaussiansWarning(UserWarning):
    """Some Gaussians were dropped as (nearly) transparent; the message gives the count."""


def is_gaussian_ply(names) -> bool:
    """True when vertex properties ``names`` are those of a trained Gaussian-splat file."""
    names = set(names)
    return {"opacity", "scale_0", "scale_1", "rot_0", "rot_1", "rot_2", "rot_3"} <= names


def cloud_from_gaussians(data: np.ndarray, source: str, *, sigma_scale: float = SIGMA_SCALE,
                         min_opacity: float = MIN_OPACITY) -> SplatCloud:
    """The splats of a Gaussian-splat PLY ``vertex`` element (a structured array), unvalidated.

    Returns positions, unit normals, colors in [0, 1] (grey 0.5 + 0 without ``f_dc_*``) and
    u, v (model units) for each Gaussian with opacity >= ``min_opacity``; the dropped ones are
    counted in a :class:`DroppedGaussiansWarning`. Raises InputError naming ``source`` when a
    required property is missing or a value is not a number.
    """
    names = set(data.dtype.names or ())
    missing = [name for name in _REQUIRED if name not in names]
    if missing:
        raise InputError(f"{source}: Gaussian-splat PLY is missing {' '.join(missing)}")
    three_d = "scale_2" in names

    def column(name):
        if data.dtype[name].kind not in "uif":
            raise InputError(f"{source}: vertex property {name!r} must be a number, not a list")
        return np.asarray(data[name], dtype=np.float64)

    with np.errstate(over="ignore"):
        opacity = 1.0 / (1.0 + np.exp(-column("opacity")))
    keep = ~(opacity < min_opacity)  # NaN opacities are kept and dropped by validation
    dropped = int(len(data) - keep.sum())
    if dropped:
        warnings.warn(f"{source}: dropped {dropped} of {len(data)} Gaussians with opacity below "
                      f"{min_opacity:.3g}", DroppedGaussiansWarning, stacklevel=4)
    positions = np.column_stack([column(c) for c in "xyz"])[keep]
    quat = np.column_stack([column(f"rot_{i}") for i in range(4)])[keep]
    scales = np.column_stack([column(f"scale_{i}") for i in range(3 if three_d else 2)])[keep]
    if all(f"f_dc_{i}" in names for i in range(3)):
        colors = np.clip(0.5 + SH_C0 * np.column_stack([column(f"f_dc_{i}") for i in range(3)])[keep], 0.0, 1.0)
    else:
        colors = np.full((len(positions), 3), 0.5)

    rot = quaternion_matrices(quat)  # (M, 3, 3), columns are the Gaussian's axes
    with np.errstate(over="ignore"):
        sigma = np.exp(scales)
    if three_d:
        order = np.argsort(-np.nan_to_num(sigma, nan=0.0), axis=1)  # largest first
        rows = np.arange(len(sigma))[:, None]
        axes = np.swapaxes(rot, 1, 2)[rows, order]  # (M, 3, 3): axis vectors, largest first
        sigma = sigma[rows, order]
        u = axes[:, 0] * (sigma_scale * sigma[:, 0:1])
        v = axes[:, 1] * (sigma_scale * sigma[:, 1:2])
        normals = np.cross(axes[:, 0], axes[:, 1])  # = +- the smallest axis, right-handed with u, v
    else:
        u = rot[:, :, 0] * (sigma_scale * sigma[:, 0:1])
        v = rot[:, :, 1] * (sigma_scale * sigma[:, 1:2])
        normals = rot[:, :, 2]
    return SplatCloud(positions=positions, normals=normals, colors=colors, u=u, v=v)


def quaternion_matrices(quat: np.ndarray) -> np.ndarray:
    """(M, 3, 3) rotation matrices of (M, 4) quaternions ``(w, x, y, z)``, normalized first
    (zero quaternions give NaN matrices, which validation drops)."""
    q = np.asarray(quat, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)
