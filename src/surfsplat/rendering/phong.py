"""Technique ``phong``: Phong splatting (Botsch, Spernat & Kobbelt 2004, sec. 4).

Each pixel of a splat's exact disk quad casts its viewing ray onto the splat's
plane (eq. 6), takes the exact ``(s, t)`` (eq. 1), discards outside the ellipse
and on the cut side of clip lines, evaluates the linear normal field (eq. 2)
and lights the pixel with it (Blinn-Phong, ``surfsplat.lighting``), with the
exact depth. Weights decrease radially, ``exp(-c (s^2 + t^2))`` with the
cutoff c (the Gaussian of [BK03] cut at the ellipse); three passes: visibility,
accumulation, normalization. Splats without a normal field are lit per pixel
with their constant normal.
"""

from .options import RenderOptions
from .technique import Technique


def _uniforms(options: RenderOptions) -> dict:
    return {"u_kernel": (float(options.filter.cutoff), 2.0)}


PHONG = Technique(
    name="phong",
    vertex="disk.vert",
    fragment="object_space.frag",
    blended=True,
    uniforms=_uniforms,
    point_footprint="disk",   # disk.vert
    compute_visibility=True,   # the shared ray-cast disk visibility (splat_fragment.glsl)
    edge_coverage=True,
    hiz_cull=True,   # hidden splats are not drawn in the accumulation pass (hiz.glsl)
    edge_fringe=False,   # kernels end at the disk's rim
    description="Phong splats: per-pixel ray cast, linear normal fields, per-pixel lighting (Botsch et al. 2004)",
)
