// Per-splat vertex work shared by the techniques: camera-space splat, its
// plane and disk, and per-splat lighting (Guennebaud 2003, sec. 6: lighting in
// the vertex program). Requires camera.glsl, lighting.glsl, splat_attributes.glsl.
flat out vec3 v_plane;    // camera-space normal / dot(normal, center): plane is dot(v_plane, x) = 1
flat out vec3 v_center;   // camera space
flat out vec3 v_udual;    // u / |u|^2: dot(q, v_udual) is the s coordinate of q - center
flat out vec3 v_vdual;
flat out vec2 v_uvz;      // (u.z, v.z): depth change along the axes
flat out float v_radius;  // largest semi-axis, model units
flat out vec3 v_color;
flat out vec3 v_normal;
flat out vec3 v_clip0;    // clip lines, passed through (Botsch 2004, sec. 4; Zwicker 2004, sec. 5)
flat out vec3 v_clip1;

uniform bool u_cull_backfaces;   // closed, outward-oriented models only

struct Splat {
    vec3 p;   // center, camera space
    vec3 n;   // unit normal, camera space, facing the eye
    vec3 u;   // scaled tangent axes, camera space
    vec3 v;
};

// Fills s and the flat outputs; false when the splat lies outside [near, far]
// or is seen exactly edge-on through the eye (it covers no area).
bool camera_splat(out Splat s) {
    s.p = (u_view * vec4(in_position, 1.0)).xyz;
    mat3 r = mat3(u_view);
    s.n = normalize(r * in_normal);
    s.u = r * in_u;
    s.v = r * in_v;
    float np = dot(s.n, s.p);
    // The eye lies on one side of the splat's plane: the whole splat faces away or none of it.
    if (u_cull_backfaces && np > 0.0) return false;
    if (np > 0.0) { s.n = -s.n; np = -np; }
    float z = -s.p.z;
    float zext = length(vec2(s.u.z, s.v.z));   // half depth range of the ellipse
    if (z + zext < u_near_far.x || z - zext > u_near_far.y) return false;
    if (-np <= 1e-7 * length(s.p)) return false;
    v_plane = s.n / np;
    v_center = s.p;
    v_udual = s.u / dot(s.u, s.u);
    v_vdual = s.v / dot(s.v, s.v);
    v_uvz = vec2(s.u.z, s.v.z);
    v_radius = max(length(s.u), length(s.v));
    v_color = shade(in_color, s.n, normalize(-s.p));
    v_normal = s.n;
    v_clip0 = in_clip0;
    v_clip1 = in_clip1;
    return true;
}
