"""The web format: splats quantized to 19 bytes each (position, octahedral normal, axis angle, log radii,
RGB; 3 bytes more for a page's 24-bit positions), the clip lines of the splats that carry them beside it,
Phong splats' shading normals and normal fields (8 bytes a splat more), and its exact decoding in NumPy,
the twin of the viewer's JavaScript decoder (``static/viewer.js``, ``decode``). One implementation,
:mod:`surfsplat.io.splat_codec`, shared with the compact hierarchy files
(:func:`surfsplat.hierarchy.save_hierarchy` with ``compact=True``); its docstring gives the layout."""

from __future__ import annotations

from ..io.splat_codec import (BYTES_PER_SPLAT, FIELD_BYTES, FINE_BYTES, FINE_LEVELS, OCT_LEVELS, U16, axis_signs,
                              decode, decode_clip_lines, decode_positions, decode_tangents, dequantize_unit, encode,
                              encode_clip_lines, encode_colors, encode_normal_fields, encode_positions,
                              encode_tangents, octahedral_decode, octahedral_encode, plane_normals, quantize_unit,
                              tangent_basis)

__all__ = ["BYTES_PER_SPLAT", "FIELD_BYTES", "FINE_BYTES", "FINE_LEVELS", "OCT_LEVELS", "POSITION_BITS", "U16",
           "axis_signs", "decode", "decode_clip_lines", "decode_positions", "decode_tangents", "dequantize_unit",
           "encode", "encode_clip_lines", "encode_colors", "encode_normal_fields", "encode_positions",
           "encode_tangents", "octahedral_decode", "octahedral_encode", "plane_normals", "quantize_unit",
           "tangent_basis"]

#: The precisions a page's splat centres are stored in (bits a coordinate; ``surfsplat.export``'s
#: ``position_bits``): 16, or 24 with the ``position_fine`` stream.
POSITION_BITS = (16, 24)
