"""Technique ``blend``: object-space blending kernels (Pajarola, Sainz & Guidotti 2003, sec. 4-5).

The kernel ``psi_E(r) = exp(-a (r / b)^n)`` (EQ 12; a, b, n from the render
options, the paper's 6, 1.5, 3 by default) or the Gaussian ``psi_G`` (EQ 11),
mapped onto each elliptical disk by scaling (fig. 11: ``r = b sqrt(s^2 + t^2)``)
and evaluated in object space at the exact ray/splat intersection; epsilon-z-
buffer visibility splatting (sec. 5.3), accumulation of ``psi c`` and ``psi``
(EQ 10) and per-pixel normalization (EQ 9, sec. 5.4). Splats of coarse
hierarchy nodes carry a normal field (the smooth shading of sec. 5.2, fig. 14);
it is evaluated per pixel.
"""

from .options import RenderOptions
from .technique import Technique


def _uniforms(options: RenderOptions) -> dict:
    return {"u_kernel": options.kernel.exponent()}


BLEND = Technique(
    name="blend",
    vertex="disk.vert",
    fragment="object_space.frag",
    blended=True,
    uniforms=_uniforms,
    point_footprint="disk",   # disk.vert
    compute_visibility=True,   # the shared ray-cast disk visibility (splat_fragment.glsl)
    edge_coverage=True,
    hiz_cull=True,   # hidden splats are not drawn in the accumulation pass (hiz.glsl)
    edge_fringe=False,   # kernels end at the disk's rim
    description="object-space blending kernels psi_E, epsilon-z-buffer, normalization (Pajarola et al. 2003)",
)
