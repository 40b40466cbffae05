// Technique "ewa": evaluate the resampling kernel (Guennebaud 2003, sec. 6).
#include "camera.glsl"
#include "splat_fragment.glsl"

uniform float u_cutoff;
flat in vec2 v_center_px;
flat in vec3 v_conic;
flat in float v_scale;
flat in vec3 v_color;
flat in vec3 v_normal;

void main() {
#if PASS == PASS_VISIBILITY
    vec3 ray = pixel_ray(FRAG_PX);
    float z;
    if (!ray_disk(ray, z)) discard;
    emit(ray, z, 1.0, v_color, v_normal);
#else
    vec2 d = FRAG_PX - v_center_px;
    float beta = 0.5 * (v_conic.x * d.x * d.x + 2.0 * v_conic.y * d.x * d.y + v_conic.z * d.y * d.y);
    if (beta > u_cutoff) discard;
    vec3 ray = pixel_ray(FRAG_PX);
    vec2 st = footprint_st(ray);
    bool cut = clipped(st);
    float z = footprint_depth(st);
    if (behind_nearest(z) || ((cut || dot(st, st) > 1.0) && fringe_hidden(ray, z, cut))) discard;
    emit(ray, z, v_scale * exp(-beta), v_color, v_normal);
#endif
}
