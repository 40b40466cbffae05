"""The array namespace the per-splat formulas run on: NumPy, or PyTorch for the differentiable renderer.

The formulas of :mod:`surfsplat.reference` are written once against the operations NumPy and PyTorch
share under the same names (the Python array API's ``stack``, ``sum(axis=, keepdims=)``, ``where``,
``sqrt``, ``exp``, ``maximum``, ``abs``, ``concat``, ``swapaxes``...), so the reference that the shaders
are tested against and the differentiable renderer cannot drift apart. The few operations whose names
or signatures differ between the two (cross product, vector norm, constants) are here.
"""

from __future__ import annotations

import sys
from types import ModuleType
from typing import Any

import numpy as np


def is_torch(x: Any) -> bool:
    """True for a PyTorch tensor (without importing PyTorch: a tensor's module is loaded already)."""
    return type(x).__module__.split(".")[0] == "torch"


def array_namespace(*arrays: Any) -> ModuleType:
    """``torch`` when any of ``arrays`` is a PyTorch tensor, else ``numpy``."""
    for a in arrays:
        if is_torch(a):
            return sys.modules["torch"]
    return np


def as_float(x: Any, xp: ModuleType) -> Any:
    """``x`` as a float64 NumPy array on NumPy; a tensor is returned as it is (its dtype and device kept)."""
    return np.asarray(x, dtype=np.float64) if xp is np else x


def dot(a: Any, b: Any, keepdims: bool = False) -> Any:
    """Dot product over the last axis, (..., k) x (..., k) -> (...) (or (..., 1))."""
    xp = array_namespace(a, b)
    return xp.sum(a * b, axis=-1, keepdims=keepdims)


def norm(a: Any, keepdims: bool = False) -> Any:
    """Euclidean length over the last axis."""
    xp = array_namespace(a)
    return xp.sqrt(xp.sum(a * a, axis=-1, keepdims=keepdims))


def cross(a: Any, b: Any) -> Any:
    """Cross product over the last axis of (..., 3) arrays."""
    xp = array_namespace(a, b)
    return xp.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def unstack(a: Any, axis: int = -1) -> tuple[Any, ...]:
    """The slices of ``a`` along ``axis`` (NumPy's ``unstack``, PyTorch's ``unbind``: on PyTorch the
    gradients of all slices flow back as one stack, not one full-size tensor per slice)."""
    if is_torch(a):
        return tuple(a.unbind(axis))
    return tuple(np.moveaxis(a, axis, 0))


def matrix2(xx: Any, xy: Any, yx: Any, yy: Any) -> Any:
    """(..., 2, 2) matrices from their four (...) entries."""
    xp = array_namespace(xx, xy, yx, yy)
    return xp.stack([xp.stack([xx, xy], axis=-1), xp.stack([yx, yy], axis=-1)], axis=-2)


def det2(m: Any) -> Any:
    """Determinant of (..., 2, 2) matrices."""
    return m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]


def inv2(m: Any) -> Any:
    """Inverse of (..., 2, 2) matrices (closed form: the adjugate over the determinant)."""
    d = det2(m)
    return matrix2(m[..., 1, 1] / d, -m[..., 0, 1] / d, -m[..., 1, 0] / d, m[..., 0, 0] / d)
