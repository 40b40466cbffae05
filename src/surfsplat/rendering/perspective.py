"""Technique ``perspective``: perspective accurate splatting (Zwicker et al. 2004, sec. 4 and 6).

Each splat's cutoff ellipse is mapped to the image by the projective mapping M_k of
its tangent plane (eq. 4); the image conic (sec. 4.3), its center (eq. 7) and the
scaled central conic Q''' (eq. 11) give a Gaussian resampling kernel whose cutoff
contour is the exact perspective image of the splat, plus the EWA prefilter
``H = I`` (eq. 3); the quad is the tight box of the final ellipse (eq. 8-9).

Numerics (reference.perspective_footprint mirrors the shader): everything is
relative to the projected splat center; the dual conic ``M^T diag(1, 1, -1) M``
gives center, shape and box without inverting M_k; the determinant has a
closed form and the kernel is evaluated in V's principal axes. Splats with an
ill-conditioned M_k (condition number > 1e4, within 0.011 degrees of edge-on)
or whose image is no ellipse / is near-clipped (nearest point closer than
max(near, 1e-3 z)) are ray-cast per pixel instead (Botsch 2004, eq. 6) inside a
near-clipped conservative box: no splat is lost, no quad runs away.

Passes as ewa: visibility with exact ray-cast disks (depth + epsilon),
accumulation with the kernel above, per-pixel normalization.
"""

from .technique import Technique, filter_uniforms

PERSPECTIVE = Technique(
    name="perspective",
    vertex="perspective.vert",
    fragment="perspective.frag",
    blended=True,
    uniforms=filter_uniforms,
    # small splats as one GL_POINTS point each, sized by perspective.vert from their exact box; which are
    # small is estimated from the disk's box grown by the prefilter (passes.point_scale)
    point_footprint="filtered_disk",
    compute_visibility=True,   # the shared ray-cast disk visibility (splat_fragment.glsl)
    edge_coverage=True,
    hiz_cull=True,   # hidden splats are not drawn in the accumulation pass (hiz.glsl)
    edge_fringe=True,   # the prefilter reaches beyond the disk
    description="perspective accurate EWA splatting, three passes (Zwicker et al. 2004)",
)
