"""Technique ``flat``: opaque elliptical disks, ray-cast per pixel, z-buffer only.

The baseline: one pass, no blending, per-splat lighting; exact per-pixel depth
from the ray/plane intersection.
"""

from .technique import Technique

FLAT = Technique(
    name="flat",
    vertex="disk.vert",
    fragment="flat.frag",
    blended=False,
    description="opaque elliptical disks, one pass (baseline)",
)
