// Technique "perspective": evaluate the resampling kernel (Zwicker et al. 2004, sec. 6).
#include "camera.glsl"
#include "splat_fragment.glsl"

uniform float u_cutoff;
flat in int v_raycast;
flat in vec2 v_center_px;
flat in vec2 v_axis;
flat in vec2 v_inv_lambda;
flat in float v_scale;
flat in vec3 v_color;
flat in vec3 v_normal;

void main() {
    vec3 ray = pixel_ray(FRAG_PX);
#if PASS == PASS_VISIBILITY
    float z;
    if (!ray_disk(ray, z)) discard;
    emit(ray, z, 1.0, v_color, v_normal);
#else
    if (v_raycast == 1) {
        // Splats the conic cannot represent (near plane, not an ellipse, ill-conditioned M_k):
        // the pixel's ray meets the splat plane at (s, t) exactly (Botsch 2004, eq. 6); the
        // reconstruction kernel exp(-c (s^2 + t^2)) (V_r = I / (2c)) cut at the splat's ellipse.
        float z;
        if (!ray_disk(ray, z)) discard;
        vec2 st = plane_st(ray, z);
        emit(ray, z, exp(-u_cutoff * dot(st, st)), v_color, v_normal);   // the exact depth (footprint_depth agrees inside the disk)
    } else {
        // Eq. 3 with R'_k = Q'''^-1 (eq. 11), centered at x_t (eq. 7): beta = 0.5 x^T V^-1 x in
        // V's principal axes, cut at beta = c.
        vec2 d = FRAG_PX - v_center_px;
        vec2 q = vec2(dot(d, v_axis), dot(d, vec2(-v_axis.y, v_axis.x)));
        float beta = 0.5 * (q.x * q.x * v_inv_lambda.x + q.y * q.y * v_inv_lambda.y);
        if (beta > u_cutoff) discard;
        vec2 st = footprint_st(ray);
        bool cut = clipped(st);
        float z = footprint_depth(st);
        if ((cut || dot(st, st) > 1.0) && fringe_hidden(ray, z, cut)) discard;
        emit(ray, z, v_scale * exp(-beta), v_color, v_normal);
    }
#endif
}
