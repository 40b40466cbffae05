// Ground truth: per-pixel two-sided Blinn-Phong of the interpolated normal,
// the splat shaders' linear depth (render/mesh.py).
#include "camera.glsl"
#include "lighting.glsl"

in vec3 v_position;
in vec3 v_normal;
in vec3 v_color;

layout(location = 0) out vec4 out_color;   // (shaded rgb clamped to [0, 1], 1): alpha marks coverage
layout(location = 1) out vec4 out_depth;   // camera-space depth along -z, model units

void main() {
    // The triangle's own plane serves where the interpolated normal vanishes
    // (degenerate vertex normals, opposite normals cancelling).
    vec3 geometric = cross(dFdx(v_position), dFdy(v_position));
    float len = length(v_normal);
    vec3 n = len > 1e-20 ? v_normal / len : normalize(geometric);
    float z = -v_position.z;
    gl_FragDepth = window_depth(z);
    out_color = vec4(clamp(shade(v_color, n, normalize(-v_position)), 0.0, 1.0), 1.0);
    out_depth = vec4(z, 0.0, 0.0, 0.0);
}
