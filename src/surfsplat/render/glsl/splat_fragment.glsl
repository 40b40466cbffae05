// Fragment outputs shared by the splat techniques.
// PASS 0: opaque (single pass), PASS 1: visibility (depth only), PASS 2: accumulation.
layout(location = 0) out vec4 out_color;   // (w * rgb, w)
layout(location = 1) out vec4 out_aux;     // (w * depth, w * normal), camera space

uniform float u_depth_epsilon;   // visibility offset along the viewing ray, in splat radii

flat in vec3 v_plane;     // camera-space normal / dot(normal, center): plane is dot(v_plane, x) = 1
flat in vec2 v_zrange;    // depth range of the splat, model units
flat in float v_radius;   // largest semi-axis, model units

// Depth where the viewing ray of this fragment meets the splat's plane
// (Guennebaud 2003, eq. 10/13), kept within the splat's own depth range.
float fragment_depth(vec3 ray) {
    float z = 1.0 / dot(v_plane, ray);
    if (!(z > 0.0)) z = v_zrange.y;   // ray parallel to or behind the plane (also catches NaN)
    return clamp(z, v_zrange.x, v_zrange.y);
}

// Writes depth (offset by epsilon along the ray in the visibility pass) and the outputs.
void emit(vec3 ray, float z, float w, vec3 color, vec3 normal) {
#if PASS == 1
    // Guennebaud 2003 sec. 5: translate along the viewing ray, not along z.
    z += u_depth_epsilon * v_radius / length(ray);
#endif
    gl_FragDepth = window_depth(z);
    out_color = vec4(color * w, w);
    out_aux = vec4(z, normal) * w;
}
