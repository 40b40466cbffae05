// Technique "perspective": perspective accurate splatting (Zwicker et al. 2004, sec. 4 and 6).
// Mirrors surfsplat/reference.py: perspective_footprint (the conic path) and the ray-cast
// fallback of perspective_weight. Camera space looks down -z; window pixels with y up.
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "disk_vertex.glsl"
#include "splat_primitive.glsl"
#include "hiz.glsl"

uniform float u_cutoff;      // c: kernel cut at 0.5 x^T V^-1 x = c (F_g^2 = 2c)
uniform float u_prefilter;   // H = u_prefilter * I, pixels^2 (1: EWA prefilter on)

// Sec. 6: splats whose mapping M_k is ill-conditioned are not splatted by their conic. The
// condition number of the unit-scaled M_k ([u/|u|; v/|v|; p/|p|]) is (1 + sin a) / |cos a|,
// a = angle between the normal and the center's viewing ray: PERSPECTIVE_MAX_CONDITION = 1e4
// is within 0.011 degrees of edge-on (reference.py). Such splats are ray-cast, not discarded.
// A splat whose nearest point is closer than max(near, PERSPECTIVE_NEAR_FRACTION * z) is
// ray-cast: its image is no ellipse (sec. 4.2, Delta <= 0) or is near-clipped (reference.py).

flat out int v_raycast;      // 1: exact ray/splat evaluation (Botsch 2004, eq. 6), 0: conic
flat out vec2 v_center_px;   // conic center x_t (eq. 7), window pixels
flat out vec2 v_axis;        // unit major axis of the resampling ellipse V
flat out vec2 v_inv_lambda;  // 1 / eigenvalues of V (major, minor), pixels^-2
flat out float v_scale;      // sqrt(|V_r| / |V|): peak ~1 for a magnified splat

// Window box of the part of the parallelogram p +- u +- v (which holds the ellipse) in front
// of the near plane: its corners in front and its edges' crossings of the plane, projected.
// Conservative and finite however the splat crosses the eye plane (points have z >= near > 0).
void near_clipped_bounds(Splat s, out vec2 lo, out vec2 hi) {
    vec3 c[4] = vec3[4](s.p + s.u + s.v, s.p - s.u + s.v, s.p - s.u - s.v, s.p + s.u - s.v);
    lo = vec2(1e30);
    hi = vec2(-1e30);
    for (int i = 0; i < 4; ++i) {
        vec3 a = c[i];
        vec3 b = c[(i + 1) & 3];
        float da = -a.z - u_near_far.x;   // >= 0: in front of the near plane
        float db = -b.z - u_near_far.x;
        if (da >= 0.0) {
            vec2 q = project_px(a);
            lo = min(lo, q);
            hi = max(hi, q);
        }
        if ((da >= 0.0) != (db >= 0.0)) {
            vec2 q = project_px(mix(a, b, da / (da - db)));
            lo = min(lo, q);
            hi = max(hi, q);
        }
    }
}

// Shrink a window box to the pixel centers it holds (pixel i is drawn when
// lo <= i + 0.5 <= hi), within the tile; false when it holds none.
bool pixel_box(inout vec2 lo, inout vec2 hi) {
    lo = max(ceil(max(lo, tile_lo() - 1.0) - 0.5), tile_lo());
    hi = min(floor(min(hi, tile_hi() + 1.0) - 0.5) + 1.0, tile_hi());
    return all(lessThan(lo, hi));
}

void main() {
    Splat s;
    if (!camera_splat(s)) { gl_Position = CULLED; return; }
    vec2 lo, hi;
#if PASS == PASS_VISIBILITY
    // Visibility: the exact disks, so the depth buffer holds the surface itself.
    if (!disk_bounds(s, lo, hi)) { gl_Position = CULLED; return; }
#else
    float z = -s.p.z;
    vec2 wz = vec2(s.u.z, s.v.z);          // depth change along the axes: -w of rows u, v of M_k
    float zext = length(wz);
    float len_p = length(s.p);
    float cos_a = abs(dot(s.n, s.p)) / len_p;
    float sin_a = sqrt(max(0.0, 1.0 - cos_a * cos_a));
    bool conditioned = 1.0 + sin_a <= PERSPECTIVE_MAX_CONDITION * cos_a;
    v_raycast = (conditioned && z - zext >= max(u_near_far.x, PERSPECTIVE_NEAR_FRACTION * z)) ? 0 : 1;
    if (v_raycast == 1) {
        near_clipped_bounds(s, lo, hi);
    } else {
        // Eq. 4 composed with the projection, relative to the projected center c: the rows of
        // M_k are (U, -u.z), (V, -v.z), (0, 0, z), with U = f u.xy + delta u.z, delta = c - c0.
        vec2 c_px = project_px(s.p);
        vec2 delta = c_px - 0.5 * u_viewport;
        vec2 U = u_focal * s.u.xy + delta * s.u.z;
        vec2 V = u_focal * s.v.xy + delta * s.v.z;
        // Dual conic C* = M^T diag(1, 1, -1) M = adj(M^-1 Q_h M^-T) up to a positive factor
        // (sec. 4.3): C*_33 = -h, h = z^2 - |wz|^2 > 0 (an ellipse, eq. 5), formed as a product.
        float h = (z - zext) * (z + zext);
        vec2 g = U * s.u.z + V * s.v.z;    // -C*_{12,3}
        // Eq. 7: the center x_t is the pole of the line at infinity, C*_{12,3} / C*_33.
        vec2 xt = g / h;
        // Eq. 10-11: S = F_g^2 Q'''^-1 = (C*_{12,3} C*_{12,3}^T - C*_33 C*_{12,12}) / C*_33^2
        //   = x_t x_t^T + (U U^T + V V^T) / h: positive terms only, S > 0 for an ellipse.
        mat2 S = outerProduct(xt, xt) + (outerProduct(U, U) + outerProduct(V, V)) / h;
        // det S = f^4 ((u x v) . p)^2 / h^3 in closed form (no cancellation for thin ellipses),
        // kept as the scale-free ratio det S / tr(S)^2 in [0, 1/4] so that nothing overflows.
        float trace_s = S[0][0] + S[1][1];
        float a = u_focal * u_focal * dot(cross(s.u, s.v), s.p) / h / trace_s;
        float det_ratio = a * a / h;
        // Eq. 3: V = R'_k + H with R'_k = Q'''^-1 = S / F_g^2, F_g^2 = 2c, H = u_prefilter I.
        float trace_r = trace_s / (2.0 * u_cutoff);
        mat2 Vt = S / (2.0 * u_cutoff) + mat2(u_prefilter);
        // Principal axes of V: the major eigenvalue from the entries, the minor one from the
        // closed-form determinant (the kernel of a 1000:1 ellipse keeps its precision).
        float mean = 0.5 * (Vt[0][0] + Vt[1][1]);
        float dev = 0.5 * (Vt[0][0] - Vt[1][1]);
        float radius = sqrt(dev * dev + Vt[0][1] * Vt[0][1]);
        float lambda1 = mean + radius;
        // lambda2 = |V| / lambda1 with |V| = |R'| + eta tr(R') + eta^2 (positive terms) and
        // |R'| = det_ratio tr(R')^2, divided through so that it cannot overflow.
        float lambda2 = trace_r / lambda1 * (trace_r * det_ratio + u_prefilter) + u_prefilter * u_prefilter / lambda1;
        // Its eigenvector, from the form without cancellation for the sign of dev.
        vec2 axis = dev >= 0.0 ? vec2(dev + radius, Vt[0][1]) : vec2(Vt[0][1], radius - dev);
        float axis_len = length(axis);
        v_axis = axis_len > 0.0 ? axis / axis_len : vec2(1.0, 0.0);
        v_inv_lambda = vec2(1.0 / lambda1, 1.0 / lambda2);
        // Weight scale: the peak-1 reconstruction kernel convolved with the unit-mass prefilter,
        // sqrt(|R'| / |V|) = 1 / sqrt(1 + (x + x^2) / det_ratio), x = eta / tr(R') (ewa's
        // |J| / (2c sqrt|V|)): 1 for a magnified splat, its projected area for a minified one.
        float x = u_prefilter / trace_r;
        v_scale = inversesqrt(1.0 + (x + x * x) / det_ratio);
        v_center_px = c_px + xt;
        // Eq. 8-9 for the final ellipse 0.5 x^T V^-1 x = c: half extents sqrt(2c V_xx), sqrt(2c V_yy).
        vec2 half_extent = sqrt(2.0 * u_cutoff * vec2(Vt[0][0], Vt[1][1]));
        lo = v_center_px - half_extent;
        hi = v_center_px + half_extent;
        if (!(lambda1 > 0.0 && lambda2 > 0.0) || any(isnan(lo)) || any(isnan(hi))) { gl_Position = CULLED; return; }
    }
    if (!pixel_box(lo, hi)) { gl_Position = CULLED; return; }
#ifdef HIZ_BLOCK
    // behind the visible surface wherever it is drawn (a fragment's depth is a disk point's, footprint_depth)
    if (hidden_splat(lo, hi, -s.p.z - length(vec2(s.u.z, s.v.z)))) { gl_Position = CULLED; return; }
#endif
#endif
    emit_box(lo, hi);   // a quad, or one GL_POINTS point for a small splat (POINT_PRIMITIVE)
}
