// Techniques "phong" (Botsch et al. 2004) and "blend" (Pajarola et al. 2003): the
// kernel is evaluated in object space at the exact ray/splat intersection.
// Botsch 2004, eq. 6: q = t * ray on the splat's plane, (s, t) from eq. 1; the pixel is
// discarded outside the ellipse or on the cut side of a clip line; the normal is the
// linear normal field of eq. 2, lit per pixel; the depth is exact.
// Weight psi(rho) = exp(-a rho^n), rho^2 = s^2 + t^2 (Pajarola 2003, EQ 12 with
// rho = r / b; the Gaussians of Botsch 2004 and of Pajarola's EQ 11 are n = 2).
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_fragment.glsl"

uniform vec2 u_kernel;     // (a, n)
// frame_options.glsl: u_deferred
#include "frame_options.glsl"
flat in vec3 v_albedo;
flat in vec3 v_normal;
flat in vec3 v_field_u;
flat in vec3 v_field_v;

void main() {
    vec3 ray = pixel_ray(FRAG_PX);
    float z;
    if (!ray_disk(ray, z)) discard;
#if PASS == PASS_VISIBILITY
    emit(ray, z, 1.0, v_albedo, v_normal);
#else
    if (behind_nearest(z)) discard;
    vec2 st = plane_st(ray, z);
    vec3 n = normalize(v_normal + st.x * v_field_u + st.y * v_field_v);   // Botsch 2004, eq. 2
    vec3 color = u_deferred ? v_albedo : shade(v_albedo, n, normalize(-ray));
    emit(ray, z, exp(-u_kernel.x * pow(length(st), u_kernel.y)), color, n);
#endif
}
