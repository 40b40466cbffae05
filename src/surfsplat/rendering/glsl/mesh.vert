// Ground truth: a triangle mesh rasterized with the splat renderer's camera (render/mesh.py).
// The image may be drawn in tiles: u_tile is the window rectangle this draw covers.
#include "camera.glsl"

uniform bool u_vertex_colors;  // in_color present; else every vertex gets u_albedo
uniform vec3 u_albedo;

in vec3 in_position;
in vec3 in_normal;   // vertex normal (smooth) or the face's normal (flat), world space
in vec3 in_color;

out vec3 v_position;  // camera space, interpolated perspective-correctly
out vec3 v_normal;    // camera space, not normalized
out vec3 v_color;

void main() {
    vec3 p = (u_view * vec4(in_position, 1.0)).xyz;
    v_position = p;
    v_normal = mat3(u_view) * in_normal;
    v_color = u_vertex_colors ? in_color : u_albedo;
    // project_px(p) * w with w = -z, mapped to the tile's [-w, w]; z maps
    // [near, far] to [-w, w] so the rasterizer clips at the same planes.
    float w = -p.z;
    vec2 px_w = 0.5 * u_viewport * w + u_focal * p.xy;
    vec2 xy = 2.0 * (px_w - u_tile.xy * w) / u_tile.zw - w;
    float n = u_near_far.x, f = u_near_far.y;
    gl_Position = vec4(xy, (-(f + n) * p.z - 2.0 * f * n) / (f - n), w);
}
