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
    point_footprint="disk",   # disk.vert
    compute_opaque=True,   # opaque_resolve.frag writes flat.frag's fragment
    edge_coverage=False,   # opaque: no accumulation pass writes coverage
    edge_fringe=False,
    description="opaque elliptical disks, one pass (baseline)",
)
