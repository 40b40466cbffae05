// The ray/disk test of a splat's exact elliptical disk, shared by the fragment side (splat_fragment.glsl,
// whose flat inputs v_center, v_udual, v_vdual, v_plane, v_clip0, v_clip1 it reads) and the compute
// visibility pass (visibility.comp, where splat_vertex.glsl's outputs are plain globals).
// Requires camera.glsl.

// Normalized (s, t) of the point t * ray on the splat's plane.
vec2 plane_st(vec3 ray, float t) {
    vec3 q = t * ray - v_center;
    return vec2(dot(q, v_udual), dot(q, v_vdual));
}

// Clip lines in the splat's normalized coordinates (Botsch 2004, sec. 4): the
// point (s, t) is cut away where a s + b t + c < 0 for either line.
bool clipped(vec2 st) {
    vec3 h = vec3(st, 1.0);
    return dot(v_clip0, h) < 0.0 || dot(v_clip1, h) < 0.0;
}

// Exact ray/disk test: depth z of the ray's hit with the splat plane; false
// when the hit lies outside the ellipse or outside [near, far].
bool ray_disk(vec3 ray, out float z) {
    z = 1.0 / dot(v_plane, ray);
    if (!(z >= u_near_far.x && z <= u_near_far.y)) return false;
    vec2 st = plane_st(ray, z);
    return dot(st, st) <= 1.0 && !clipped(st);
}
