// Technique "points": opaque round points, z-buffer only (one pass, like "flat").
#include "camera.glsl"

layout(location = 0) out vec4 out_color;   // (rgb, 1)
layout(location = 1) out vec4 out_aux;     // (depth, normal), camera space

flat in vec2 v_center;
flat in float v_radius_px;
flat in float v_depth;
flat in vec3 v_color;
flat in vec3 v_normal;

void main() {
    vec2 px = FRAG_PX;
    vec2 d = px - v_center;
    // inside the disk, or the pixel holding the center (a point always covers at least that one)
    if (dot(d, d) > v_radius_px * v_radius_px && any(notEqual(floor(px), floor(v_center)))) discard;
    gl_FragDepth = window_depth(v_depth);
    out_color = vec4(v_color, 1.0);
    out_aux = vec4(v_depth, v_normal);
}
