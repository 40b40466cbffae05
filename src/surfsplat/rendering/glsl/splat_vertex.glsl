// Per-splat vertex work shared by the techniques: camera-space splat, its
// plane and disk, and per-splat lighting (Guennebaud 2003, sec. 6: lighting in
// the vertex program). Requires camera.glsl, lighting.glsl, splat_attributes.glsl.
// In the compute visibility pass (visibility.comp, COMPUTE_SPLATS) the outputs are plain globals.
#ifdef COMPUTE_SPLATS
#define SPLAT_OUT
#else
#define SPLAT_OUT flat out
#endif
SPLAT_OUT vec3 v_plane;    // camera-space normal / dot(normal, center): plane is dot(v_plane, x) = 1
SPLAT_OUT vec3 v_center;   // camera space
SPLAT_OUT vec3 v_udual;    // u / |u|^2: dot(q, v_udual) is the s coordinate of q - center
SPLAT_OUT vec3 v_vdual;
SPLAT_OUT vec2 v_uvz;      // (u.z, v.z): depth change along the axes
SPLAT_OUT float v_radius;  // largest semi-axis, model units
SPLAT_OUT vec3 v_color;    // lit color (the albedo when shading is deferred)
SPLAT_OUT vec3 v_albedo;
SPLAT_OUT vec3 v_normal;   // center shading normal, on the eye's side of the plane
SPLAT_OUT vec3 v_field_u;  // alpha * u_hat and beta * v_hat, signed like v_normal: the normal
SPLAT_OUT vec3 v_field_v;  // at (s, t) is v_normal + s v_field_u + t v_field_v (Botsch 2004, eq. 2)
SPLAT_OUT vec3 v_clip0;    // clip lines, passed through (Botsch 2004, sec. 4; Zwicker 2004, sec. 5)
SPLAT_OUT vec3 v_clip1;
SPLAT_OUT float v_back;    // 1: the eye sees the back of the splat (its normal faces away), else 0

// frame_options.glsl: u_cull_backfaces (closed, outward-oriented models only), u_deferred
#include "frame_options.glsl"

struct Splat {
    vec3 p;   // center, camera space
    vec3 n;   // unit normal of the splat's plane (u x v), camera space, facing the eye
    vec3 u;   // scaled tangent axes, camera space
    vec3 v;
    vec3 shading;   // unit center shading normal (in_normal), on the side of n
};

// Conservative back-face test of a splat whose plane the eye sees from behind (Botsch 2004, sec. 4.1):
// false only when no point x(s, t) = p + s u + t v of the disk (s^2 + t^2 <= 1) has a field normal
// N(s, t) = shading + s field_u + t field_v facing the eye from that point. In camera space (eye at
// the origin) N . (-x) = a + b . (s, t) - (s, t) M (s, t)^T with a = shading . e (e = -p), b = (field_u . e
// - shading . u, field_v . e - shading . v) (the field's turn and the centre normal's tilt off the plane)
// and M the symmetric part of [field_u . u, field_u . v; field_v . u, field_v . v]; over the unit disk it
// is at most a + |b| + max(0, -lambda_min(M)) (a concave field bulges toward the eye). Each direction to
// the eye is the disk point's own, not the centre's. A flat splat (no field, shading normal on the
// plane's normal) gives a = n . e < 0: culled, as the plane's test.
bool field_faces_eye(Splat s, vec3 field_u, vec3 field_v) {
    vec3 e = -s.p;
    vec2 b = vec2(dot(field_u, e) - dot(s.shading, s.u), dot(field_v, e) - dot(s.shading, s.v));
    float m11 = dot(field_u, s.u);
    float m22 = dot(field_v, s.v);
    float m12 = 0.5 * (dot(field_u, s.v) + dot(field_v, s.u));
    float lambda_min = 0.5 * (m11 + m22) - length(vec2(0.5 * (m11 - m22), m12));
    return dot(s.shading, e) + length(b) + max(0.0, -lambda_min) > 0.0;
}

#ifdef HYBRID_POINTS
// rendering/hybrid.py facing_points per vertex (the browser viewer; the desktop turns its splats on the
// CPU): the axes of a splat at camera-space p made an orthonormal pair across the direction to the eye,
// scaled to r = max(|u|, |v|): a disk facing the eye, a round point (Schuetz 2016, sec. 3.4). The pair is
// frames.tangent_frame64 of that direction (Duff et al. 2017, listing 3); at the eye itself, the view axis.
void facing_axes(vec3 p, inout vec3 u, inout vec3 v) {
    float r = max(length(u), length(v));
    float d = length(p);
    vec3 n = d > 0.0 ? -p / d : vec3(0.0, 0.0, 1.0);
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float b = n.x * n.y * a;
    u = r * vec3(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x);
    v = r * vec3(b, sgn + n.y * n.y * a, -n.y);
}
#endif

// Fills s and the flat outputs; false when the splat lies outside [near, far]
// or is seen exactly edge-on through the eye (it covers no area).
bool camera_splat(out Splat s) {
    s.p = (u_view * vec4(in_position, 1.0)).xyz;
#ifdef SEQUENTIAL_LOD
    if (lod_rejected(s.p)) return false;   // not in this frame's LOD cut
#endif
    mat3 r = mat3(u_view);
    s.u = r * in_u;
    s.v = r * in_v;
#ifdef HYBRID_POINTS
    if (in_nonplanar > 0.5) facing_axes(s.p, s.u, s.v);
#endif
    s.shading = normalize(r * in_normal);
    // The plane is spanned by the axes; the stored normal is the center shading normal,
    // which a Phong splat tilts away from the plane's (Botsch 2004, sec. 3).
    s.n = normalize(cross(s.u, s.v));
    if (dot(s.n, s.shading) < 0.0) s.n = -s.n;
    vec3 field_u = in_normal_field.x * normalize(s.u);
    vec3 field_v = in_normal_field.y * normalize(s.v);
    float np = dot(s.n, s.p);
    if (u_cull_backfaces && np > 0.0 && !field_faces_eye(s, field_u, field_v)) return false;
    v_back = np > 0.0 ? 1.0 : 0.0;
    if (np > 0.0) { s.n = -s.n; s.shading = -s.shading; field_u = -field_u; field_v = -field_v; np = -np; }
    float z = -s.p.z;
    float zext = length(vec2(s.u.z, s.v.z));   // half depth range of the ellipse
    if (z + zext < u_near_far.x || z - zext > u_near_far.y) return false;
    if (-np <= EDGE_ON_TOLERANCE * length(s.p)) return false;   // reference.EDGE_ON_TOLERANCE
    v_plane = s.n / np;
    v_center = s.p;
    v_udual = s.u / dot(s.u, s.u);
    v_vdual = s.v / dot(s.v, s.v);
    v_uvz = vec2(s.u.z, s.v.z);
    v_radius = max(length(s.u), length(s.v));
    v_color = u_deferred ? in_color : shade(in_color, s.shading, normalize(-s.p));
    v_albedo = in_color;
    v_normal = s.shading;
    v_field_u = field_u;
    v_field_v = field_v;
    v_clip0 = in_clip0;
    v_clip1 = in_clip1;
    return true;
}
