"""Colour by attribute on the page: the colourings of the desktop viewer's C key (its own colours,
elevation, then each attribute: :func:`surfsplat.colors.colorize`) offered by the exported page.

The page gets each attribute's values compactly (:func:`attribute_streams`: one byte a splat where the
values are integers spanning at most 256, as LAS classes, return numbers and flags do; two bytes
otherwise, exact for integers spanning at most 65,536 such as intensity, else quantized over their
range) and, per colouring, the mapping :func:`surfsplat.colors.colorize` applies: the colormap's table
(:func:`colormap_table`, made from the Python definitions at export: the ASPRS class palette, matplotlib's
colormap) and the value range (the 2nd-98th percentiles of the values the desktop colours). The viewer
(``viewer.js``, ``colorBy``) computes ``t = (value - lo) / (hi - lo)``, clamps it to [0, 1] and takes
entry ``min(floor(256 t), 255)`` of the table, as matplotlib indexes a 256-entry colormap; a class
palette is indexed by the class code itself. Elevation is computed on the page from the decoded
positions along the model's up axis.
"""

from __future__ import annotations

import numpy as np

from .. import progress
from ..cloud import SplatCloud
from ..colors import ASPRS, ELEVATION, asprs_palette, colormap_colors, resolve_colormap, robust_range
from ..errors import InputError
from ..geometry.preprocess import NONPLANAR
from ..hierarchy import Hierarchy

#: Entries of a colormap's table (matplotlib's colormaps have 256).
TABLE_SIZE = 256


def colormap_table(colormap: str) -> np.ndarray:
    """(256, 3) uint8: the colours :func:`surfsplat.colors.colorize` gives to ``t`` in each of 256 equal
    bins of [0, 1] (for ``asprs``: the colours of the class codes 0..255), rounded as the web format
    rounds colours."""
    if colormap.lower() == ASPRS:
        table = asprs_palette()
    else:
        table = colormap_colors(colormap, (np.arange(TABLE_SIZE) + 0.5) / TABLE_SIZE)
    return np.rint(np.clip(table, 0.0, 1.0) * 255.0).astype(np.uint8)


def encode_attribute(values: np.ndarray) -> tuple[np.ndarray, dict]:
    """One attribute's values as compact codes and how to decode them (``value = offset + code * scale``):
    uint8 where they are integers spanning at most 255 steps, uint16 where integers spanning at most
    65,535, else uint16 quantized over ``[min, max]`` of the finite values (non-finite ones as the minimum)."""
    v = np.asarray(values, np.float64)
    finite = v[np.isfinite(v)]
    lo = float(finite.min()) if finite.size else 0.0
    hi = float(finite.max()) if finite.size else 0.0
    v = np.where(np.isfinite(v), v, lo)
    integral = bool(np.all(v == np.rint(v)))
    if integral and hi - lo <= 255:
        return (v - lo).astype(np.uint8), {"type": "u8", "offset": lo, "scale": 1.0}
    if integral and hi - lo <= 65535:
        return (v - lo).astype(np.uint16), {"type": "u16", "offset": lo, "scale": 1.0}
    scale = (hi - lo) / 65535.0 or 1.0
    return np.rint((v - lo) / scale).astype(np.uint16), {"type": "u16", "offset": lo, "scale": scale}


def decode_attribute(codes: np.ndarray, info: dict) -> np.ndarray:
    """The values of :func:`encode_attribute`'s codes (float64): the twin of the viewer's decoding."""
    return info["offset"] + codes.astype(np.float64) * info["scale"]


def colorable(attributes: dict | None) -> list[str]:
    """The attributes a page colours by, in the desktop viewer's order (sorted; not the preprocessing's
    ``nonplanar`` flag)."""
    return [name for name in sorted(attributes or {}) if name != NONPLANAR]


def _table_name(colormap: str) -> str | None:
    """``colormap`` if its table can be made (matplotlib's need the ``color`` extra), else None."""
    if colormap.lower() == ASPRS:
        return ASPRS
    try:
        colormap_table(colormap)
    except InputError:
        return None
    return colormap


def attribute_streams(cloud: SplatCloud, order: np.ndarray, reference: SplatCloud, up) -> tuple[dict, dict]:
    """The colourings of a page drawing ``cloud[order]``: ``(header, streams)``.

    Args:
        cloud: the exported splats (their ``attributes`` give the values; elevation is computed on the page).
        order: the order the page stores them in.
        reference: the splats the desktop colours (their values give the robust ranges, as
            :func:`~surfsplat.colors.colorize` takes them: the model's prepared points).
        up: the model's up axis (elevation).

    Returns:
        header: ``{"modes": [{"name", "colormap", "range", ("up" | "attribute")}], "tables": {name: base64
        of 256 x 3 bytes}, "attributes": {name: {"type", "offset", "scale"}}}``; streams: ``attr_NAME`` ->
        codes. Continuous colourings are left out (said once) where matplotlib is missing.
    """
    axis = np.asarray(up, np.float64)
    axis = axis / (np.linalg.norm(axis) or 1.0)
    modes: list[dict] = []
    tables: dict[str, np.ndarray] = {}
    attributes: dict[str, dict] = {}
    streams: dict[str, np.ndarray] = {}
    missing: list[str] = []

    def mode(name: str, values_ref: np.ndarray, extra: dict) -> bool:
        colormap = resolve_colormap(name, None)
        table = _table_name(colormap)
        if table is None:
            missing.append(name)
            return False
        if table not in tables:
            tables[table] = colormap_table(table)
        lo, hi = robust_range(values_ref)
        modes.append({"name": name, "colormap": table, "range": [lo, hi], **extra})
        return True

    mode(ELEVATION, reference.positions.astype(np.float64) @ axis, {"up": axis.tolist()})
    ours, theirs = cloud.attributes or {}, reference.attributes or {}
    for name in colorable(ours):
        if name not in theirs or not mode(name, np.asarray(theirs[name]), {"attribute": name}):
            continue
        codes, info = encode_attribute(np.asarray(ours[name])[order])
        attributes[name] = info
        streams[f"attr_{name}"] = codes
    if missing:
        progress.message(f"colour by {', '.join(missing)} is not offered on the page: its colormap needs matplotlib")
    header = {"modes": modes, "tables": {k: v for k, v in tables.items()}, "attributes": attributes}
    return header, streams


def cut_attributes(h: Hierarchy, nodes: np.ndarray, points: np.ndarray) -> dict[str, np.ndarray] | None:
    """The attributes of the splats of a cut (``nodes``' splats, then ``points``), as
    :meth:`Hierarchy.splats` orders them: nodes carry their majority class or mean value
    (``node_attributes``)."""
    own, node_values = h.points.attributes or {}, h.node_attributes or {}
    out = {name: np.concatenate([np.asarray(node_values[name])[nodes], np.asarray(values)[points]])
           for name, values in own.items() if name in node_values}
    return out or None


def page_colors(header: dict, streams: dict[str, np.ndarray], positions: np.ndarray, name: str) -> np.ndarray:
    """(N, 3) uint8: the colours the viewer gives to splats at decoded ``positions`` (model units, local)
    coloured by ``name`` (:func:`attribute_streams`' header and streams): the NumPy twin of ``colorBy``."""
    modes = {m["name"]: m for m in header["modes"]}
    if name not in modes:
        raise InputError(f"no colouring {name!r} on this page; it has {', '.join(modes)}")
    m = modes[name]
    if "up" in m:
        values = np.asarray(positions, np.float64) @ np.asarray(m["up"], np.float64)
    else:
        values = decode_attribute(streams[f"attr_{m['attribute']}"], header["attributes"][m["attribute"]])
    table = header["tables"][m["colormap"]]
    if m["colormap"] == ASPRS:
        ok = (values >= 0) & (values <= 255) & (values == np.rint(values))
        index = np.where(ok, values, 255).astype(np.int64)
        colors = table[index]
        colors[~ok] = colormap_table(ASPRS)[255]
        return colors
    lo, hi = m["range"]
    t = np.clip((values - lo) / (hi - lo), 0.0, 1.0)
    return table[np.minimum(np.floor(t * TABLE_SIZE), TABLE_SIZE - 1).astype(np.int64)]
