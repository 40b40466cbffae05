"""Colour by attribute: splat colours from elevation or a named per-point attribute.

:func:`colorize` maps one scalar per splat (``elevation``, the coordinate along the model's up
axis, or any of ``SplatCloud.attributes``: ``intensity``, ``classification``,
``return_number``, ``confidence``, ...) to RGB and returns the cloud with those ``colors``;
they then blend like any splat colour in every technique. Continuous values go through a
perceptual colormap from matplotlib (optional: the ``color`` extra) over ``value_range``
(default: the robust 2nd-98th percentiles); ``classification`` uses the ASPRS LAS class
palette (:data:`ASPRS_CLASSES`) unless another colormap is named. Colours are stored as the
colormap gives them, as 8-bit file colours are (no gamma, see :mod:`surfsplat.lighting`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cloud import SplatCloud
from .errors import InputError

#: The scalar computed from positions rather than read from ``attributes``.
ELEVATION = "elevation"
#: The colormap name of the ASPRS classification palette.
ASPRS = "asprs"
#: The colormap of continuous values when none is named.
DEFAULT_COLORMAP = "viridis"
#: Percentiles of the default value range (robust to outliers).
ROBUST_PERCENTILES = (2.0, 98.0)

#: ASPRS standard point classes (LAS 1.4 R15, table 17) and their display colours (8-bit RGB).
ASPRS_CLASSES: dict[int, tuple[str, tuple[int, int, int]]] = {
    0: ("created, never classified", (190, 190, 190)),
    1: ("unclassified", (150, 150, 150)),
    2: ("ground", (153, 102, 51)),
    3: ("low vegetation", (170, 230, 120)),
    4: ("medium vegetation", (80, 180, 60)),
    5: ("high vegetation", (20, 110, 30)),
    6: ("building", (220, 80, 60)),
    7: ("low point (noise)", (255, 0, 255)),
    8: ("reserved (model key-point)", (255, 255, 0)),
    9: ("water", (40, 110, 230)),
    10: ("rail", (120, 80, 160)),
    11: ("road surface", (80, 80, 80)),
    12: ("reserved (overlap)", (255, 230, 150)),
    13: ("wire - guard (shield)", (255, 220, 0)),
    14: ("wire - conductor (phase)", (255, 160, 0)),
    15: ("transmission tower", (200, 60, 200)),
    16: ("wire-structure connector", (255, 140, 140)),
    17: ("bridge deck", (140, 140, 200)),
    18: ("high noise", (255, 0, 128)),
}
#: The colour of reserved and user-defined classes (19-255).
OTHER_CLASS = (128, 128, 128)


def asprs_palette() -> np.ndarray:
    """(256, 3) float32 colours in [0, 1] of the classes 0..255 (:data:`ASPRS_CLASSES`, others gray)."""
    table = np.tile(np.asarray(OTHER_CLASS, dtype=np.float32) / 255.0, (256, 1))
    for code, (_, rgb) in ASPRS_CLASSES.items():
        table[code] = np.asarray(rgb, dtype=np.float32) / 255.0
    return table


@dataclass(frozen=True)
class ColorOptions:
    """Colour splats by a scalar: ``by`` (``elevation`` or an attribute name), ``colormap``
    (a matplotlib name, or ``asprs``; None: ``asprs`` for classification, else viridis) and
    ``value_range`` ``(lo, hi)`` (None: the 2nd-98th percentiles)."""

    by: str
    colormap: str | None = None
    value_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.by, str) or not self.by:
            raise InputError(f"color-by needs an attribute name, got {self.by!r}", argument="by")
        if self.value_range is not None:
            lo, hi = (float(x) for x in self.value_range)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise InputError(f"color range needs finite LO < HI, got {self.value_range!r}", argument="value_range")
            object.__setattr__(self, "value_range", (lo, hi))


def attribute_values(cloud: SplatCloud, by: str, up=(0.0, 0.0, 1.0)) -> tuple[str, np.ndarray]:
    """``(name, (N,) values)`` of ``by``: ``elevation`` is ``positions . up`` (up normalized);
    other names are looked up in ``cloud.attributes`` (exactly, else ignoring case). An unknown
    name is an InputError listing the available ones."""
    if by.lower() == ELEVATION:
        axis = np.asarray(up, dtype=np.float64).reshape(3)
        norm = float(np.linalg.norm(axis))
        if not (np.isfinite(norm) and norm > 0):
            raise InputError(f"elevation needs a non-zero up axis, got {up!r}", argument="up")
        return ELEVATION, cloud.positions.astype(np.float64) @ (axis / norm)
    attributes = cloud.attributes or {}
    if by in attributes:
        return by, attributes[by]
    folded = {name.lower(): name for name in attributes}
    if by.lower() in folded:
        name = folded[by.lower()]
        return name, attributes[name]
    available = ", ".join([ELEVATION] + list(attributes))
    raise InputError(f"no attribute {by!r} to colour by; available: {available}", argument="by", element=by)


def robust_range(values: np.ndarray) -> tuple[float, float]:
    """The 2nd and 98th percentiles of the finite values (widened when they coincide)."""
    finite = np.asarray(values, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = (float(x) for x in np.percentile(finite, ROBUST_PERCENTILES))
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    return lo, hi


def colormap_colors(colormap: str, t: np.ndarray) -> np.ndarray:
    """(N, 3) float32 RGB of ``t`` in [0, 1] through the matplotlib colormap ``colormap``."""
    try:
        import matplotlib
    except ImportError as exc:
        raise InputError(f"colormap {colormap!r} needs matplotlib: `pip install matplotlib` "
                         "(or `pip install \".[color]\"` in the surfsplat checkout)", argument="colormap") from exc
    try:
        cmap = matplotlib.colormaps[colormap]
    except KeyError:
        raise InputError(f"unknown colormap {colormap!r}; e.g. viridis, turbo, magma, cividis, "
                         f"or {ASPRS} for LAS classes", argument="colormap") from None
    return np.asarray(cmap(np.clip(t, 0.0, 1.0)), dtype=np.float32)[:, :3]


def colorize(cloud: SplatCloud, by: str, colormap: str | None = None, value_range=None, *,
             up=(0.0, 0.0, 1.0)) -> SplatCloud:
    """``cloud`` with ``colors`` from the scalar ``by`` (see the module docstring).

    Args:
        cloud: the splats; their attributes (and positions for ``elevation``) give the values.
        by: ``elevation`` or the name of one of ``cloud.attributes``.
        colormap: a matplotlib colormap name, or ``asprs`` (class palette of integer values);
            None: ``asprs`` for ``classification``, else viridis.
        value_range: ``(lo, hi)`` mapped to the ends of the colormap (values outside are
            clamped); None: the 2nd-98th percentiles. Unused by ``asprs``.
        up: the model's up axis, for ``elevation`` (+z for LAS/LAZ: ``api.natural_up``).

    Non-finite values are drawn in the colormap's lowest colour (class palette: gray).
    """
    name, values = attribute_values(cloud, by, up)
    colormap = resolve_colormap(name, colormap)
    if colormap.lower() == ASPRS:
        return cloud.replace(colors=class_colors(values))
    if value_range is None:
        lo, hi = robust_range(values)
    else:
        lo, hi = ColorOptions(by, colormap, value_range).value_range
    t = (np.asarray(values, dtype=np.float64) - lo) / (hi - lo)
    return cloud.replace(colors=colormap_colors(colormap, np.nan_to_num(t, nan=0.0)))


def resolve_colormap(name: str, colormap: str | None) -> str:
    """The colormap :func:`colorize` uses for attribute ``name``: ``colormap``, or when None
    ``asprs`` for ``classification`` and :data:`DEFAULT_COLORMAP` for the rest."""
    if colormap is None:
        return ASPRS if name.lower() == "classification" else DEFAULT_COLORMAP
    return colormap


def is_class_palette(name: str, colormap: str | None) -> bool:
    """Whether attribute ``name`` coloured with ``colormap`` (None: the default) is drawn with the
    discrete ASPRS class palette (whose colours do not blend into meaningful ones)."""
    return resolve_colormap(name, colormap).lower() == ASPRS


def class_colors(values) -> np.ndarray:
    """(N, 3) float32 ASPRS palette colours (:func:`asprs_palette`) of class codes; codes that are
    not finite integers 0..255 are drawn gray (:data:`OTHER_CLASS`)."""
    codes = np.asarray(values, dtype=np.float64)
    ok = np.isfinite(codes) & (codes >= 0) & (codes <= 255)
    colors = asprs_palette()[np.where(ok, codes, 255).astype(np.int64)]
    colors[~ok] = np.asarray(OTHER_CLASS, dtype=np.float32) / 255.0
    return colors


def describe_attributes(cloud: SplatCloud) -> list[str]:
    """One line per attribute: name, dtype, min and max (of the finite values)."""
    lines = []
    for name, values in (cloud.attributes or {}).items():
        finite = values[np.isfinite(values)] if values.dtype.kind == "f" else values
        span = f"{finite.min():.6g} .. {finite.max():.6g}" if finite.size else "no finite values"
        lines.append(f"{name} ({values.dtype}): {span}")
    return lines


__all__ = ["ColorOptions", "colorize", "attribute_values", "robust_range", "asprs_palette", "colormap_colors",
           "describe_attributes", "resolve_colormap", "is_class_palette", "class_colors", "ASPRS_CLASSES",
           "ELEVATION", "ASPRS", "DEFAULT_COLORMAP"]
