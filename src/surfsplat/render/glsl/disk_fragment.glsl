// Exact ray/disk test of the splat's ellipse (pairs with disk_vertex.glsl).
flat in vec3 v_center;
flat in vec3 v_udual;
flat in vec3 v_vdual;

// Depth z of the ray's hit with the splat plane; false when the hit lies
// outside the ellipse or outside [near, far].
bool ray_disk(vec3 ray, out float z) {
    z = 1.0 / dot(v_plane, ray);
    if (!(z >= u_near_far.x && z <= u_near_far.y)) return false;
    vec3 q = z * ray - v_center;
    vec2 st = vec2(dot(q, v_udual), dot(q, v_vdual));
    return dot(st, st) <= 1.0;
}
