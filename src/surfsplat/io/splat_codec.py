"""Splats quantized to 19 bytes each, and their exact decoding, in NumPy: the web viewer's format
(:mod:`surfsplat.web.format`) and the compact layout of hierarchy files
(:func:`surfsplat.hierarchy.save_hierarchy` with ``compact=True``).

One splat (``SplatCloud`` row: position, normal, colour, the tangent axes ``u``, ``v``) is stored as

========================  =====  =====================================================================
stream                    bytes  encoding
========================  =====  =====================================================================
``position``              6      3 x uint16: the centre in the model's bounding box, ``2^16 - 1`` steps
``normal``                4      2 x uint16: octahedral map of the unit normal, 65534 steps (Meyer et al. 2010;
                                 Cigolle et al. 2014, "A Survey of Efficient Representations for
                                 Independent Unit Vectors", sec. 3.1)
``angle``                 2      uint16: the angle of ``u`` in the tangent basis of the *decoded*
                                 normal (:func:`tangent_basis`), in [0, pi): an ellipse is symmetric
``radii``                 4      2 x uint16: ``log2 |u|`` and ``log2 |v|`` over the model's range
``color``                 3      3 x uint8: RGB in [0, 1], rounded as the renderer rounds its output
========================  =====  =====================================================================

A page exported with 24-bit positions adds ``position_fine`` (3 x uint8, 3 bytes a splat: 22 in all): the low
byte of 24-bit position codes (``2^24 - 1`` steps, float32's precision over the box) whose high 16 bits are
``position`` (``encode(..., fine_positions=True)``). 16-bit steps move the centre of a splat by about 1% of
its radius on a model sampled for a 1024-pixel view, enough to flip the coverage or the nearest splat of a few
hundred silhouette pixels of an opaque technique (``flat``, ``points``, Phong splats' depth pass).

``v`` is rebuilt orthogonal to ``u`` in the plane of the normal (an ellipse in the plane normal to the
shading normal). Clip lines (Zwicker 2004, sec. 5), where a model has them, travel
beside it (:func:`encode_clip_lines`): the rows of the splats that carry one (uint32) and their two
lines as float16, 16 bytes for each such splat, flipped with the decoded axes (:func:`axis_signs`).
Phong splats (a linear normal field, Botsch 2004 eq. 2, whose shading normal leans off the plane of
``u`` and ``v``) code the plane's normal in ``normal`` (:func:`plane_normals`) and add, 8 bytes a splat,
the shading normal (``shading``, octahedral, 4 bytes) and the field ``(alpha, beta)`` as float16 flipped
with the decoded axes (``normal_field``, 4 bytes: :func:`encode_normal_fields`).
Every function here is the twin of the web viewer's JavaScript decoder (``surfsplat/web/static/viewer.js``,
``decode``), which performs the same arithmetic in float32/64.
"""

from __future__ import annotations

import numpy as np

from ..frames import tangent_frame64

#: Bytes per splat of the web format.
BYTES_PER_SPLAT = 19
#: Bytes a splat of Phong splats adds (its shading normal and linear normal field).
FIELD_BYTES = 8
#: Largest value of the 16-bit codes.
U16 = 65535.0
#: Bytes a splat the ``position_fine`` stream adds (24-bit positions).
FINE_BYTES = 3
#: Largest position code with the ``position_fine`` stream.
FINE_LEVELS = 16777215.0
#: Largest octahedral code: an even number of steps over [-1, 1] codes 0 (the axes, the diagonals) exactly.
OCT_LEVELS = 65534.0


def quantize_unit(values: np.ndarray, lo, hi, levels: float = U16, dtype: type = np.uint16) -> np.ndarray:
    """``values`` in [lo, hi] (broadcast) as integers 0..levels (``dtype``, uint16 by default), rounded to
    nearest; a zero-width range codes 0."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    width = np.where(hi > lo, hi - lo, 1.0)
    t = np.clip((np.asarray(values, np.float64) - lo) / width, 0.0, 1.0)
    return np.rint(t * levels).astype(dtype)


def dequantize_unit(codes: np.ndarray, lo, hi, levels: float = U16) -> np.ndarray:
    """The values of :func:`quantize_unit`'s codes: ``lo + code / levels * (hi - lo)``, float64."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return lo + codes.astype(np.float64) / levels * (hi - lo)


def octahedral_encode(normals: np.ndarray) -> np.ndarray:
    """(N, 3) unit vectors -> (N, 2) uint16 codes of their octahedral map (Cigolle 2014, listing 1):
    ``p = n / |n|_1``, the lower hemisphere folded over the diagonals; error below 1e-4 rad."""
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.abs(n).sum(axis=1, keepdims=True), 1e-30)
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)
    fx = np.where(z < 0, (1.0 - np.abs(y)) * sx, x)
    fy = np.where(z < 0, (1.0 - np.abs(x)) * sy, y)
    return quantize_unit(np.stack([fx, fy], axis=1), -1.0, 1.0, OCT_LEVELS)


def octahedral_decode(codes: np.ndarray) -> np.ndarray:
    """(N, 2) codes of :func:`octahedral_encode` -> (N, 3) float64 unit vectors."""
    f = dequantize_unit(codes, -1.0, 1.0, OCT_LEVELS)
    x, y = f[:, 0], f[:, 1]
    z = 1.0 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0.0)
    x = x - np.where(x >= 0, t, -t)
    y = y - np.where(y >= 0, t, -t)
    n = np.stack([x, y, z], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def tangent_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) completing each unit normal to a right-handed orthonormal basis: the
    frame of :func:`surfsplat.frames.tangent_frame64` (Duff et al. 2017), which the page's decoder
    repeats in JavaScript."""
    return tangent_frame64(normals)


def encode_tangents(normals: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The angle codes (N,) uint16 of ``u`` in :func:`tangent_basis` of ``normals`` (the decoded ones),
    the log-radius codes (N, 2) uint16 of ``|u|``, ``|v|``, and their range ``(lo, hi)`` (log2 model units)."""
    b1, b2 = tangent_basis(normals)
    u = np.asarray(u, np.float64)
    angle = np.mod(np.arctan2(np.einsum("ij,ij->i", u, b2), np.einsum("ij,ij->i", u, b1)), np.pi)
    radii = np.stack([np.linalg.norm(u, axis=1), np.linalg.norm(np.asarray(v, np.float64), axis=1)], axis=1)
    logs = np.log2(np.maximum(radii, np.finfo(np.float32).tiny))
    lo, hi = float(logs.min()), float(logs.max())
    codes = (np.rint(angle * (65536.0 / np.pi)).astype(np.int64) % 65536).astype(np.uint16)   # pi wraps to 0
    return codes, quantize_unit(logs, lo, hi), (lo, hi)


def decode_tangents(normals: np.ndarray, angle: np.ndarray, radii: np.ndarray, log_range) -> tuple[np.ndarray,
                                                                                                  np.ndarray]:
    """``u``, ``v`` (N, 3) float64 from :func:`encode_tangents`' codes and the decoded ``normals``:
    ``u = |u| (cos a b1 + sin a b2)``, ``v = |v| (n x u / |u|)``."""
    b1, b2 = tangent_basis(normals)
    a = angle.astype(np.float64) * (np.pi / 65536.0)
    direction = np.cos(a)[:, None] * b1 + np.sin(a)[:, None] * b2
    r = np.exp2(dequantize_unit(radii, *log_range))
    n, d = np.asarray(normals, np.float64), direction
    # n x d by components (np.cross moves axes: slower on millions of rows), as viewer.js writes it
    across = np.stack([n[:, 1] * d[:, 2] - n[:, 2] * d[:, 1], n[:, 2] * d[:, 0] - n[:, 0] * d[:, 2],
                       n[:, 0] * d[:, 1] - n[:, 1] * d[:, 0]], axis=1)
    return direction * r[:, :1], across * r[:, 1:]


def encode_colors(colors: np.ndarray) -> np.ndarray:
    """(N, 3) RGB in [0, 1] -> uint8, rounded (as ``Frame.image`` rounds the output)."""
    return np.rint(np.clip(np.asarray(colors, np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)


def encode_positions(positions: np.ndarray, lo, hi, fine: bool = False) -> dict[str, np.ndarray]:
    """The ``position`` stream ((N, 3) uint16 codes of the centres in the box ``lo``..``hi``) and, where
    ``fine``, the ``position_fine`` stream: 24-bit codes, their high 16 bits in ``position`` and their low
    byte in ``position_fine`` ((N, 3) uint8)."""
    if not fine:
        return {"position": quantize_unit(positions, lo, hi)}
    codes = quantize_unit(positions, lo, hi, FINE_LEVELS, np.uint32)
    return {"position": (codes >> 8).astype(np.uint16), "position_fine": (codes & 255).astype(np.uint8)}


def decode_positions(streams: dict[str, np.ndarray], header: dict) -> np.ndarray:
    """(N, 3) float64 centres of :func:`encode_positions`' streams (24-bit where ``position_fine`` is there)."""
    if "position_fine" not in streams:
        return dequantize_unit(streams["position"], header["lo"], header["hi"])
    codes = (streams["position"].astype(np.uint32) << 8) | streams["position_fine"].astype(np.uint32)
    return dequantize_unit(codes, header["lo"], header["hi"], FINE_LEVELS)


def encode(positions: np.ndarray, normals: np.ndarray, colors: np.ndarray, u: np.ndarray,
           v: np.ndarray, fine_positions: bool = False) -> tuple[dict[str, np.ndarray], dict]:
    """Quantize splats (float arrays, model units) into the web format's streams and header; with
    ``fine_positions`` the centres to 24 bits a coordinate (:func:`encode_positions`, 3 bytes a splat more).

    Returns:
        ``streams``: name -> array (``position`` (N, 3) uint16, ``normal`` (N, 2) uint16, ``angle`` (N,)
        uint16, ``radii`` (N, 2) uint16, ``color`` (N, 3) uint8; ``position_fine`` (N, 3) uint8 with
        ``fine_positions``); ``header``: ``count``, ``lo``, ``hi`` (the
        positions' box) and ``log_radius`` (the radii's log2 range).
    """
    p = np.asarray(positions, np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    normal = octahedral_encode(normals)
    angle, radii, log_range = encode_tangents(octahedral_decode(normal), u, v)
    streams = {**encode_positions(p, lo, hi, fine_positions), "normal": normal, "angle": angle, "radii": radii,
               "color": encode_colors(colors)}
    header = {"count": int(len(p)), "lo": lo.tolist(), "hi": hi.tolist(), "log_radius": list(log_range)}
    return streams, header


def decode(streams: dict[str, np.ndarray], header: dict) -> dict[str, np.ndarray]:
    """The splats of :func:`encode`'s streams: ``positions``, ``normals``, ``u``, ``v`` (N, 3) float64 and
    ``colors`` (N, 3) float64 in [0, 1]."""
    normals = octahedral_decode(streams["normal"])
    u, v = decode_tangents(normals, streams["angle"], streams["radii"], header["log_radius"])
    return {"positions": decode_positions(streams, header), "normals": normals,
            "u": u, "v": v, "colors": streams["color"].astype(np.float64) / 255.0}


def axis_signs(streams: dict[str, np.ndarray], header: dict, u: np.ndarray,
               v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) float64 signs, -1 where the decoded ``u`` (``v``) of :func:`encode`'s codes points against the
    original axis: the codes keep an axis up to its sign (an ellipse is symmetric), so where it flips the
    splat's ``s`` (``t``) runs the other way and what is written in ``(s, t)`` (clip lines, normal
    fields) changes sign with it."""
    normals = octahedral_decode(streams["normal"])
    du, dv = decode_tangents(normals, streams["angle"], streams["radii"], header["log_radius"])
    su = np.where(np.einsum("ij,ij->i", du, np.asarray(u, np.float64)) < 0, -1.0, 1.0)
    sv = np.where(np.einsum("ij,ij->i", dv, np.asarray(v, np.float64)) < 0, -1.0, 1.0)
    return su, sv


def encode_clip_lines(lines: np.ndarray, su: np.ndarray, sv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clip lines (N, 2, 3) ``(a, b, c)`` in normalized ``(s, t)`` (kept where ``a s + b t + c >= 0``,
    Zwicker 2004, sec. 5) of the splats whose axes decoded with the signs ``su``, ``sv``
    (:func:`axis_signs`): ``rows`` (M,) uint32, the splats that cut (a line with ``a = b = 0`` and
    ``c >= 0`` keeps the whole disk: such splats are left out), and their lines (M, 2, 3) float16 in the
    decoded frame (``a`` times ``su``, ``b`` times ``sv``)."""
    lines = np.asarray(lines, np.float64)
    keeps_all = (lines[:, :, 0] == 0) & (lines[:, :, 1] == 0) & (lines[:, :, 2] >= 0)
    rows = np.flatnonzero(~keeps_all.all(axis=1))
    flipped = lines[rows].copy()
    flipped[:, :, 0] *= su[rows, None]
    flipped[:, :, 1] *= sv[rows, None]
    return rows.astype(np.uint32), flipped.astype(np.float16)


def plane_normals(normals: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3) float64 unit normals of the planes of ``u`` and ``v``, on the side of the shading ``normals``:
    what the ``normal`` stream codes for Phong splats, so that the axes decode in their plane."""
    n = np.cross(np.asarray(u, np.float64), np.asarray(v, np.float64))
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), np.finfo(np.float64).tiny)
    return np.where(np.einsum("ij,ij->i", n, np.asarray(normals, np.float64))[:, None] < 0, -n, n)


def encode_normal_fields(field: np.ndarray, su: np.ndarray, sv: np.ndarray) -> np.ndarray:
    """(N, 2) float16 codes of the linear normal fields ``(alpha, beta)`` (Botsch 2004, eq. 2: the normal
    at ``(s, t)`` is ``n + s alpha u_hat + t beta v_hat``) of splats whose axes decoded with the signs
    ``su``, ``sv`` (:func:`axis_signs`): ``alpha`` times ``su``, ``beta`` times ``sv`` (the same vectors
    ``alpha u_hat``, ``beta v_hat`` with the decoded axes)."""
    f = np.asarray(field, np.float64)
    return np.stack([f[:, 0] * su, f[:, 1] * sv], axis=1).astype(np.float16)


def decode_clip_lines(rows: np.ndarray, codes: np.ndarray, count: int) -> np.ndarray:
    """(count, 2, 3) float32 clip lines of :func:`encode_clip_lines`' ``rows`` and ``codes``; the other
    splats get zero lines (nothing cut), as the viewer's attributes read them."""
    out = np.zeros((count, 2, 3), np.float32)
    out[np.asarray(rows, np.int64)] = np.asarray(codes, np.float16).astype(np.float32)
    return out
