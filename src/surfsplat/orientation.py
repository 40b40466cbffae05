"""Which way is up: the up axis of a model, stored, implied by its file kind, or guessed.

The up axis is a property of the model (:attr:`surfsplat.cloud.SplatCloud.up`): the loaders set it
where the file says (LAS/LAZ and E57 scans are z-up; PLY files and hierarchies written by surfsplat
store it), and it travels through preprocessing, subsets and hierarchy builds. Where nothing says,
:func:`guess_up` decides by one stated rule on the shape of the points:

- a model whose robust extent (2nd to 98th percentile) along z is below :data:`FLAT_RATIO` times its
  smaller extent across (x, y) is flat in z (terrain, an aerial survey, a building floor): +z;
- likewise a model flat in y: +y; every other shape: +y, the convention of meshes and most
  surface-scanning data (the Stanford models, CAD exports).

:func:`model_up` combines the three: the model's stored up, else the file kind's, else the guess;
each answer comes with a sentence saying why and how to change it, for front ends to print.

A base module: it imports only NumPy and :mod:`surfsplat.cloud` (models are read through their
attributes: ``up``, ``points``, ``positions``, ``vertices``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .cloud import SplatCloud, checked_up
from .errors import InputError

#: The up axis of most meshes and scanned models (OpenGL's convention).
Y_UP = (0.0, 1.0, 0.0)
#: The up axis of LiDAR, terrestrial-scanner and GIS data.
Z_UP = (0.0, 0.0, 1.0)
#: File suffixes whose data are z-up by their format's convention (LAS/LAZ: ASPRS LiDAR; E57: ASTM scans).
Z_UP_SUFFIXES = (".las", ".laz", ".e57")
#: A model is flat along an axis when its extent there is below this fraction of its smaller extent
#: across (2nd to 98th percentile extents). Surface models are far above it (the Stanford bunny 0.70,
#: the featuretype CAD part 0.55, the frag_115 fragment 0.53); terrain and floors far below (a
#: LiDAR tile ~0.03).
FLAT_RATIO = 0.25
#: Points used to measure the extents (a regular subsample of larger clouds).
GUESS_SAMPLE = 100_000
#: Prefix naming a built-in scene as a source (the scenes are modelled y-up).
DEMO_PREFIX = "demo:"


def up_name(up) -> str:
    """``"+z"``, ``"-y"``, ... for an axis-aligned ``up``; else its three components (``"0.6 0 0.8"``)."""
    up = checked_up(up)
    k = int(np.argmax(np.abs(up)))
    if abs(abs(up[k]) - 1.0) < 1e-9:
        return ("+" if up[k] > 0 else "-") + "xyz"[k]
    return " ".join(f"{x:.4g}" for x in up)


def up_flags(up) -> str:
    """The command-line flags that set ``up``: ``"--up 0 0 1"``."""
    return "--up " + " ".join(f"{x:.4g}" for x in (0.0 if x == 0 else x for x in checked_up(up)))


def change_hint(up) -> str:
    """How to choose the other common up axis: ``"--up 0 1 0 to change"``."""
    other = Y_UP if np.allclose(checked_up(up), Z_UP) else Z_UP
    return f"{up_flags(other)} to change"


def guess_up(positions) -> tuple[tuple[float, float, float], str]:
    """The up axis of a model whose file does not say, by the rule in the module docstring.

    Args:
        positions: (N, 3) positions, model units (any float dtype; non-finite rows ignored).

    Returns:
        ``(up, reason)``: ``up`` 3 floats (+z or +y), ``reason`` one sentence for the user naming the
        axis, why, and the flag that changes it, e.g. ``"up +z (the model is flat in z: 108 high,
        3158 across); --up 0 1 0 to change"``.
    """
    p = np.asarray(positions)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"positions must have shape (N, 3), got {p.shape}")
    p = p[::max(1, len(p) // GUESS_SAMPLE)].astype(np.float64)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) < 3:
        return Y_UP, f"up +y (too few points to tell); {change_hint(Y_UP)}"
    lo, hi = np.percentile(p, [2.0, 98.0], axis=0)
    extent = hi - lo
    for axis, up in ((2, Z_UP), (1, Y_UP)):
        across = min(extent[k] for k in range(3) if k != axis)
        if across > 0 and extent[axis] < FLAT_RATIO * across:
            name = "xyz"[axis]
            return up, (f"up +{name} (the model is flat in {name}: {extent[axis]:.4g} high, {across:.4g} across); "
                        f"{change_hint(up)}")
    return Y_UP, f"up +y (the default; the model's shape does not say otherwise); {change_hint(Y_UP)}"


def file_up(source) -> tuple[tuple[float, float, float], str] | None:
    """The up axis a source's kind implies, with the reason, or None: +z for LAS/LAZ/E57 files, +y
    for the built-in ``demo:`` scenes. Reads nothing (a file's stored up is the loaders' business)."""
    if isinstance(source, str) and source.startswith(DEMO_PREFIX):
        return Y_UP, f"up +y (built-in scenes are y-up); {change_hint(Y_UP)}"
    if isinstance(source, (str, Path)) and Path(source).suffix.lower() in Z_UP_SUFFIXES:
        kind = Path(source).suffix.lower().lstrip(".").upper()
        return Z_UP, f"up +z ({kind} scans are z-up); {change_hint(Z_UP)}"
    return None


def stored_up(model) -> tuple[float, float, float] | None:
    """The up axis a model carries: its own ``up`` (a SplatCloud, a chunked hierarchy) or its points'
    (a Hierarchy's ``points.up``); None where it states none."""
    for holder in (model, getattr(model, "points", None)):
        up = getattr(holder, "up", None)
        if up is not None:
            return checked_up(up)
    return None


def model_positions(model) -> np.ndarray | None:
    """The positions a model's shape is judged by: a SplatCloud's, a hierarchy's points', a mesh's
    vertices, an (N, 3) array; None for anything else."""
    if isinstance(model, SplatCloud):
        return model.positions
    points = getattr(model, "points", None)
    if isinstance(points, SplatCloud):
        return points.positions
    vertices = getattr(model, "vertices", None)
    if vertices is not None:
        return np.asarray(vertices)
    if isinstance(model, np.ndarray) and model.ndim == 2 and model.shape[1:] == (3,):
        return model
    return None


def model_up(model=None, source=None) -> tuple[tuple[float, float, float], str]:
    """The up axis to show ``model`` with, and why: the model's stored up (:func:`stored_up`), else
    its source's kind (:func:`file_up`), else the guess from its shape (:func:`guess_up`), else +y.

    Args:
        model: a SplatCloud, Hierarchy, ChunkedHierarchy, Mesh, an (N, 3) array or None.
        source: the file or ``demo:`` name the model came from, or None.

    Returns:
        ``(up, reason)``: 3 floats, and one sentence for the user ending in the flag that changes it.
    """
    up = stored_up(model)
    if up is not None:
        return up, f"up {up_name(up)} (stored with the model); {change_hint(up)}"
    implied = file_up(source)
    if implied is not None:
        return implied
    positions = model_positions(model)
    if positions is not None and len(positions):
        return guess_up(positions)
    return Y_UP, f"up +y (the default); {change_hint(Y_UP)}"


__all__ = ["Y_UP", "Z_UP", "Z_UP_SUFFIXES", "FLAT_RATIO", "guess_up", "file_up", "stored_up", "model_up",
           "model_positions", "up_name", "up_flags", "change_hint"]
