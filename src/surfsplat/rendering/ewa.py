"""Technique ``ewa``: screen-space EWA surface splatting (Guennebaud & Paulin 2003).

The affine approximation of the projection at each splat center (eq. 8), the
resampling variance ``J V_r J^T + I`` (eq. 6) with the splat's ellipse as the
cutoff contour, Gaussian weights, visibility splatting with per-fragment depth
correction (sec. 5), accumulation and per-pixel normalization (sec. 7).
"""

from .technique import Technique, filter_uniforms

EWA = Technique(
    name="ewa",
    vertex="ewa.vert",
    fragment="ewa.frag",
    blended=True,
    uniforms=filter_uniforms,
    point_footprint="filtered_disk",   # ewa.vert: the disk's box grown by the prefilter
    compute_visibility=True,   # the shared ray-cast disk visibility (splat_fragment.glsl)
    edge_coverage=True,
    edge_fringe=True,   # the prefilter reaches beyond the disk
    hiz_cull=True,   # ewa.vert: hidden splats are not drawn in the accumulation pass (hiz.glsl)
    description="screen-space EWA splatting, three passes (Guennebaud & Paulin 2003)",
)
