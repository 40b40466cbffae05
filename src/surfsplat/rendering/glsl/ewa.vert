// Technique "ewa": screen-space EWA splatting (Guennebaud & Paulin 2003, sec. 3 and 6).
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "splat_primitive.glsl"
#include "disk_vertex.glsl"
#include "hiz.glsl"

uniform float u_cutoff;      // c: kernel cut at 0.5 x^T V^-1 x = c
uniform float u_prefilter;   // H = u_prefilter * I, pixels^2 (1: EWA prefilter on)

flat out vec2 v_center_px;   // projected center, window pixels
flat out vec3 v_conic;       // V^-1 as (xx, xy, yy)
flat out float v_scale;      // |J| / (2 c sqrt|V|)

void main() {
    Splat s;
#if PASS == PASS_VISIBILITY
    // Visibility: the exact disks, so the depth buffer holds the surface itself
    // and not planes extrapolated over the prefilter's margin.
    vec2 lo, hi;
    if (!camera_splat(s) || !disk_bounds(s, lo, hi)) { gl_Position = CULLED; return; }
    emit_box(lo, hi);
#else
    // The affine approximation needs the center in front of the near plane.
    if (!camera_splat(s) || -s.p.z < u_near_far.x) { gl_Position = CULLED; return; }
    float z = -s.p.z;
    // Guennebaud 2003, eq. 8: Jacobian of the projection w.r.t. normalized (s, t).
    vec2 du = u_focal * (s.u.xy * z + s.p.xy * s.u.z) / (z * z);
    vec2 dv = u_focal * (s.v.xy * z + s.p.xy * s.v.z) / (z * z);
    mat2 J = mat2(du, dv);
    // Eq. 6 with V_r = I / (2c): the splat ellipse is the cutoff contour.
    mat2 V = J * transpose(J) / (2.0 * u_cutoff) + mat2(u_prefilter);
    float det = determinant(V);
    if (!(det > 0.0)) { gl_Position = CULLED; return; }
    v_conic = vec3(V[1][1], -V[0][1], V[0][0]) / det;
    v_scale = abs(determinant(J)) / (2.0 * u_cutoff * sqrt(det));
    v_center_px = project_px(s.p);
    // Tight box of the cutoff ellipse, limited to the tile (the kernel is exact inside it).
    vec2 half_extent = sqrt(2.0 * u_cutoff * vec2(V[0][0], V[1][1]));
    vec2 lo = max(v_center_px - half_extent, tile_lo() - 1.0);
    vec2 hi = min(v_center_px + half_extent, tile_hi() + 1.0);
    if (any(greaterThanEqual(lo, hi))) { gl_Position = CULLED; return; }
#if PASS == PASS_ACCUMULATION && defined(HIZ_BLOCK)
    // behind the visible surface wherever it is drawn: no fragment would blend (a fragment's depth is
    // that of the disk point nearest its ray's hit, footprint_depth: at least z minus the disk's extent)
    if (hidden_splat(lo, hi, z - length(vec2(s.u.z, s.v.z)))) { gl_Position = CULLED; return; }
#endif
    emit_box(lo, hi);
#endif
}
