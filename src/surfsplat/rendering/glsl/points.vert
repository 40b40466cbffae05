// Technique "points": a screen-aligned round point per splat, its diameter the splat's radius
// projected at its depth, clamped (Potree's adaptive point size). Drawn over the box of the
// pixel centers it can cover, clipped to the tile: a quad, or a GL_POINTS point for the small ones
// (splat_primitive.glsl; Renderer.draw picks the primitive per radius class).
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_primitive.glsl"

uniform vec2 u_point_size;   // min, max diameter in output pixels
// frame_options.glsl: u_supersample; u_deferred: the point carries its albedo
#include "frame_options.glsl"

flat out vec2 v_center;      // full-image window pixels
flat out float v_radius_px;  // half the diameter, window (sub-)pixels
flat out float v_depth;      // camera-space depth of the point
flat out vec3 v_color;
flat out vec3 v_normal;      // camera space, facing the eye; 0: the point has no normal

void main() {
    vec3 p = (u_view * vec4(in_position, 1.0)).xyz;
#ifdef SEQUENTIAL_LOD
    if (lod_rejected(p)) { gl_Position = CULLED; return; }   // not in this frame's LOD cut
#endif
    float z = -p.z;
    if (!(z >= u_near_far.x && z <= u_near_far.y)) { gl_Position = CULLED; return; }
    float radius = max(length(in_u), length(in_v));   // model units; the view is rigid
    float diameter = clamp(2.0 * radius * u_focal / z, u_point_size.x * u_supersample,
                           u_point_size.y * u_supersample);
    vec2 c = project_px(p);
    // pixel i (center i + 0.5) may be covered when |i + 0.5 - c| <= d / 2, or when it holds c
    vec2 lo = max(min(ceil(c - 0.5 * diameter - 0.5), floor(c)), tile_lo());
    vec2 hi = min(max(floor(c + 0.5 * diameter - 0.5) + 1.0, floor(c) + 1.0), tile_hi());
    if (!all(lessThan(lo, hi))) { gl_Position = CULLED; return; }
    v_center = c;
    v_radius_px = 0.5 * diameter;
    v_depth = z;
    vec3 n = mat3(u_view) * in_normal;
    bool has_normal = dot(in_normal, in_normal) > 1e-12;
    v_normal = has_normal ? normalize(n) : vec3(0.0);
    if (has_normal && dot(v_normal, -p) < 0.0) v_normal = -v_normal;
    v_color = (has_normal && !u_deferred) ? shade(in_color, v_normal, normalize(-p)) : in_color;
    emit_box(lo, hi);
}
