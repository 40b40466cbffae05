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

import difflib
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
        if self.colormap is not None:
            check_colormap(self.colormap)   # a misspelt name fails here, before any file is read
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
    name = attribute_name(by, attributes)
    if name is None:
        raise InputError(unknown_attribute(by, attributes), argument="by", element=by)
    return name, attributes[name]


def attribute_name(by: str, names) -> str | None:
    """The one of ``names`` that ``by`` names: the same, else the same ignoring case; None if none."""
    names = list(names)
    if by in names:
        return by
    folded = {name.lower(): name for name in names}
    return folded.get(by.lower())


def unknown_attribute(by: str, names) -> str:
    """The message of an attribute ``by`` that is none of ``names``: those available (and
    elevation) and the closest of them."""
    available = [ELEVATION] + list(names)
    close = difflib.get_close_matches(by.lower(), [name.lower() for name in available], n=1, cutoff=0.6)
    hint = f" (did you mean {available[[a.lower() for a in available].index(close[0])]!r}?)" if close else ""
    return f"no attribute {by!r} to colour by{hint}; available: {', '.join(available)}"


def check_color_source(cloud, options, *, added=()) -> None:
    """InputError, before any further work on a loaded ``cloud``, when ``options`` colours by an
    attribute it lacks (the same rule as :func:`attribute_values`: exact name, else ignoring case;
    ``elevation`` always exists).

    Call it right after a point file is loaded and before it is preprocessed or its hierarchy
    built, so that a misspelt ``--color-by`` fails in a moment, not after minutes of work.

    Args:
        cloud: the loaded SplatCloud (or a hierarchy: its ``points``' attributes; an object with
            no attributes, such as a mesh, has elevation only).
        options: a :class:`ColorOptions`, an object with one as ``color`` (``SourceOptions``), or None.
        added: names the later steps add (preprocessing adds ``nonplanar``), accepted too.
    """
    color = getattr(options, "color", options)
    if color is None:
        return
    if not isinstance(color, ColorOptions):
        raise InputError(f"color options must be a ColorOptions, got {type(color).__name__}")
    if color.by.lower() == ELEVATION:
        return
    attributes = getattr(cloud, "attributes", None)
    if attributes is None and hasattr(cloud, "points"):
        attributes = getattr(cloud.points, "attributes", None)
    names = list(attributes or {}) + [name for name in added if name not in (attributes or {})]
    if attribute_name(color.by, names) is None:
        raise InputError(unknown_attribute(color.by, names), argument="by", element=color.by)


def colormap_names() -> list[str] | None:
    """The colormap names matplotlib knows (case matters), or None without matplotlib."""
    try:
        import matplotlib
    except ImportError:
        return None
    return list(matplotlib.colormaps)


def check_colormap(colormap: str) -> str:
    """``colormap`` if it names one: :data:`ASPRS` (any case) or a colormap in matplotlib's registry.
    InputError otherwise, naming the closest one; without matplotlib (the ``color`` extra) every name
    but asprs is refused, saying so."""
    if not isinstance(colormap, str) or not colormap:
        raise InputError(f"a colormap needs a name, got {colormap!r}", argument="colormap")
    if colormap.lower() == ASPRS:
        return colormap
    names = colormap_names()
    if names is None:
        hint = f" (or use {ASPRS!r}, built in)" if difflib.get_close_matches(colormap.lower(), [ASPRS]) else ""
        raise InputError(f"colormap {colormap!r} needs matplotlib: `pip install matplotlib` (or `pip install "
                         f"\".[color]\"` in the surfsplat checkout){hint}", argument="colormap")
    if colormap in names:
        return colormap
    close = difflib.get_close_matches(colormap, names + [ASPRS], n=1, cutoff=0.6)
    if not close:   # a name in the wrong case ("VIRIDIS") can score below the cutoff
        close = [name for name in names if name.lower() == colormap.lower()][:1]
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise InputError(f"unknown colormap {colormap!r}; {hint}e.g. viridis, turbo, magma, cividis, "
                     f"or {ASPRS} for LAS classes", argument="colormap")


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
    if check_colormap(colormap).lower() == ASPRS:
        raise InputError(f"{ASPRS} is the palette of class codes (class_colors), not a colormap of [0, 1]",
                         argument="colormap")
    import matplotlib   # there: check_colormap asks for it

    cmap = matplotlib.colormaps[colormap]
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
        lo, hi = ColorOptions(by, colormap, value_range).value_range or robust_range(values)
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
           "describe_attributes", "resolve_colormap", "check_colormap", "check_color_source", "colormap_names",
           "is_class_palette", "class_colors", "ASPRS_CLASSES", "ELEVATION", "ASPRS", "DEFAULT_COLORMAP"]
