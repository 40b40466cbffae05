"""LAS / LAZ LiDAR point clouds (laspy, an optional dependency: ``pip install surfsplat[las]``).

Positions are the scaled coordinates (``las.x``, ``las.y``, ``las.z``, i.e.
``X * scale + offset``) in the file's units, cast to float32. Colors come from
the ``red green blue`` fields where the point format has them: the fields are
16-bit, but many files store 8-bit values, so values are divided by 255 when
the largest is <= 255 and by 65535 otherwise. LAS has no normals.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..cloud import SplatCloud
from ..errors import InputError


class CoordinatePrecisionWarning(UserWarning):
    """Coordinates are too large for float32 to keep the file's resolution."""


def read_las(path: Path) -> SplatCloud:
    """Read a .las or .laz file as an (unvalidated) SplatCloud.

    Returns positions (N, 3) float32 in the file's units, and colors (N, 3)
    float32 in [0, 1] when the point format has RGB. Warns
    (:class:`CoordinatePrecisionWarning`) when georeferenced coordinates are
    so large that float32 rounds them more coarsely than the file's scale.
    """
    source = str(path)
    try:
        import laspy
    except ImportError as exc:
        raise InputError(f"{source}: reading LAS/LAZ files needs laspy; install it with "
                         "`pip install surfsplat[las]` (LAZ also needs `pip install lazrs`)") from exc
    try:
        las = laspy.read(source)
        xyz = np.column_stack([np.asarray(las.x, dtype=np.float64),
                               np.asarray(las.y, dtype=np.float64),
                               np.asarray(las.z, dtype=np.float64)])
        dims = set(las.point_format.dimension_names)
        colors = None
        if {"red", "green", "blue"} <= dims:
            rgb = np.column_stack([np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)])
            top = int(rgb.max()) if rgb.size else 0
            colors = (rgb.astype(np.float64) / (255.0 if top <= 255 else 65535.0)).astype(np.float32)
        scales = np.asarray(las.header.scales, dtype=np.float64)
    except MemoryError:
        raise
    except Exception as exc:  # laspy.LaspyException (bad header, no LAZ backend), OSError, ValueError, ...
        hint = ""
        if Path(source).suffix.lower() == ".laz" and "laz" in str(exc).lower():
            hint = " (LAZ needs a backend: `pip install lazrs`)"
        raise InputError(f"{source}: cannot read LAS file: {type(exc).__name__}: {exc}{hint}") from exc

    finite = xyz[np.isfinite(xyz).all(axis=1)]
    if len(finite):
        extent = np.abs(finite).max(axis=0)
        spacing = np.spacing(extent.astype(np.float32)).astype(np.float64)
        if np.any(spacing > scales):
            warnings.warn(
                f"{source}: coordinates up to {extent.max():,.0f} are rounded to steps of "
                f"{spacing.max():g} in float32 positions (the file's resolution is {scales.min():g})",
                CoordinatePrecisionWarning, stacklevel=3)
    return SplatCloud(positions=xyz.astype(np.float32), colors=colors)
