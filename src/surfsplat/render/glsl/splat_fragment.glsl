// Fragment side shared by the splat techniques: the splat's disk, depth, outputs.
// PASS is PASS_OPAQUE (single pass), PASS_VISIBILITY (depth only) or PASS_ACCUMULATION (shaders.py).
layout(location = 0) out vec4 out_color;   // (w * rgb, w)
layout(location = 1) out vec4 out_aux;     // (w * depth, w * normal), camera space

uniform float u_depth_epsilon;   // visibility offset along the viewing ray, in splat radii
uniform bool u_separate_sides;   // blend only splats seen from the same side as the nearest one
uniform bool u_clip_fringe;      // drop filter fringes beyond a splat's disk over nothing or a farther surface
uniform sampler2D u_side;        // visibility pass: (side of the nearest disk: 0 front, 1 back, 0.5 none;
                                 //  its offset depth, camera space)

flat in vec3 v_plane;
flat in vec3 v_center;
flat in vec3 v_udual;
flat in vec3 v_vdual;
flat in vec2 v_uvz;
flat in float v_radius;
flat in vec3 v_clip0;
flat in vec3 v_clip1;
flat in float v_back;

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

// (s, t) where the fragment's ray meets the splat plane; a ray parallel to the
// plane, or meeting it behind the eye, goes off to the plane's horizon: the
// direction of its far end there, scaled far outside the ellipse.
vec2 footprint_st(vec3 ray) {
    float z = 1.0 / dot(v_plane, ray);
    return (z > 0.0) ? plane_st(ray, z) : vec2(dot(ray, v_udual), dot(ray, v_vdual)) * 1e6;
}

// Depth for fragments a footprint filter spreads beyond the disk: the depth of
// the disk point nearest (in (s, t)) to the ray's hit with the plane, so a
// fragment is never given a depth the splat does not have (the plane itself
// runs away from the surface at grazing angles).
float footprint_depth(vec2 st) {
    float len2 = dot(st, st);
    if (!(len2 <= 1.0)) st = len2 > 0.0 ? st * inversesqrt(len2) : vec2(0.0);
    return -(v_center.z + st.x * v_uvz.x + st.y * v_uvz.y);
}

// A fragment of a filter's fringe (beyond the splat's own disk, at depth z) that covers no disk at
// all, or only a surface farther than this splat's epsilon band, is not this surface: the prefilter
// would widen silhouettes and the crests of folds by about a pixel (a dark rim bleeding over the
// background or the trough behind). Inside a surface the fringes still overlap its disks and blend.
#if PASS == PASS_ACCUMULATION
// Whether a disk covers the pixel at this offset (false outside the full image; tiles are drawn
// with a one-pixel margin, so a neighbour inside the image is always inside the tile's targets).
bool disk_at(ivec2 offset) {
    vec2 px = FRAG_PX + vec2(offset);
    if (any(lessThan(px, vec2(0.0))) || any(greaterThanEqual(px, u_viewport))) return false;
    ivec2 texel = clamp(ivec2(gl_FragCoord.xy) + offset, ivec2(0), textureSize(u_side, 0) - 1);
    return abs(texelFetch(u_side, texel, 0).r - 0.5) > 0.25;
}
#endif

// The accumulation pass's depth test (at most the visibility pass's offset depth), done first: the
// shaders write gl_FragDepth, so OpenGL runs a whole shader before its depth test. A fragment farther
// than the nearest disk's offset depth by more than the depth buffer resolves fails that test anyway
// (the side target holds that depth in camera space); the rest meet the depth test as before.
bool behind_nearest(float z) {
#if PASS == PASS_ACCUMULATION
    vec2 nearest = texelFetch(u_side, ivec2(gl_FragCoord.xy), 0).rg;
    return abs(nearest.x - 0.5) > 0.25 && z > nearest.y + 1e-5 * (u_near_far.y - u_near_far.x);
#else
    return false;
#endif
}

bool fringe_hidden(vec3 ray, float z) {
#if PASS == PASS_ACCUMULATION
    if (!u_clip_fringe) return false;
    vec2 nearest = texelFetch(u_side, ivec2(gl_FragCoord.xy), 0).rg;
    if (abs(nearest.x - 0.5) < 0.25) {
        // no disk covers the pixel: outside a silhouette the fringe goes; in a crack that straight
        // clip lines leave between disks (3 or 4 neighbours covered) it fills the crack
        int covered = int(disk_at(ivec2(1, 0))) + int(disk_at(ivec2(-1, 0))) + int(disk_at(ivec2(0, 1)))
                      + int(disk_at(ivec2(0, -1)));
        return covered < 3;
    }
    return nearest.y > z + 2.0 * u_depth_epsilon * v_radius / length(ray);
#else
    return false;
#endif
}

// Writes depth (offset by epsilon along the ray in the visibility pass) and the outputs.
// The visibility pass also records which side of its splat the nearest fragment shows; with
// u_separate_sides the accumulation pass then blends only splats seen from that side, so the
// back of a hidden wall within epsilon behind a surface never bleeds into it.
void emit(vec3 ray, float z, float w, vec3 color, vec3 normal) {
#if PASS == PASS_VISIBILITY
    // Guennebaud 2003, sec. 5: translate along the viewing ray, not along z.
    z += u_depth_epsilon * v_radius / length(ray);
    gl_FragDepth = window_depth(z);
    out_color = vec4(v_back, z, 0.0, 1.0);
    out_aux = vec4(0.0);
#else
#if PASS == PASS_ACCUMULATION
    // side 0 front, 1 back, 0.5 no splat's disk covers the pixel (a filter's fringe only): any side blends
    float side = texelFetch(u_side, ivec2(gl_FragCoord.xy), 0).r;
    if (u_separate_sides && abs(side - 0.5) > 0.25 && abs(side - v_back) > 0.5) discard;
#endif
    gl_FragDepth = window_depth(z);
    out_color = vec4(color * w, w);
    out_aux = vec4(z, normal) * w;
#endif
}
