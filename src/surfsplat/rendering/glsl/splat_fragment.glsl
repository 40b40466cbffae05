// Fragment side shared by the splat techniques: the splat's disk, depth, outputs.
// PASS is PASS_OPAQUE (single pass), PASS_VISIBILITY (depth only) or PASS_ACCUMULATION (shaders.py).
layout(location = 0) out vec4 out_color;   // (w * rgb, w)
layout(location = 1) out vec4 out_aux;     // (w * depth, w * normal), camera space
// Accumulation pass: soft maxima of the pixel's coverage c by each splat's disk and of the signed
// distance d of its center to the disk's rim (pixels, > 0 inside, clamped to +-COVER_REACH):
// (sum e^(S (c - 1)), sum c e^(S (c - 1)), sum e^(S_d (d - R)), sum d e^(S_d (d - R))), S =
// COVER_SHARPNESS, S_d = DISTANCE_SHARPNESS, R = COVER_REACH; normalize.frag takes the ratios.
layout(location = 2) out vec4 out_cover;

// frame_options.glsl: u_depth_epsilon, u_separate_sides, u_clip_fringe
#include "frame_options.glsl"
// EDGE_COVERAGE (a define, not a uniform: llvmpipe runs a branch on a uniform that is false at a cost
// of 20% of the accumulation pass): silhouette pixels get the disks' analytic area coverage as alpha
// (normalize.frag).
// u_side: the visibility pass's record (in the accumulation pass with its cracks marked: cracks.frag)
#include "visibility.glsl"

flat in vec3 v_plane;
flat in vec3 v_center;
flat in vec3 v_udual;
flat in vec3 v_vdual;
flat in vec2 v_uvz;
flat in float v_radius;
flat in vec3 v_clip0;
flat in vec3 v_clip1;
flat in float v_back;

#include "disk_ray.glsl"

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

#if PASS == PASS_ACCUMULATION
// The visibility pass's record at the fragment's pixel (side, offset depth), fetched at the first call
// and kept: the depth test, the fringe test and emit each read it, and calls in different branches are
// not merged by the compiler (measured on the bunny, 1M splats at 1024x1024, three alternated runs:
// 6-7% of the accumulation pass).
vec2 g_nearest = vec2(-1.0);   // x < 0: not fetched yet (the sides are in [0, 1])

vec2 nearest_here() {
    if (g_nearest.x < 0.0) g_nearest = texelFetch(u_side, ivec2(gl_FragCoord.xy), 0).rg;
    return g_nearest;
}
#endif

// The accumulation pass's depth test: a fragment blends where its depth is at most the nearest disk's
// offset depth of the visibility pass (Guennebaud 2003, sec. 5), read from the side target in camera
// space, with a relative slack for the rounding of the two passes' formulas; where no disk covers the
// pixel, every fragment passes. The test is the shaders' (the pass has no depth test and writes no
// gl_FragDepth: llvmpipe then runs each fragment's shader whole before the depth test, and the write
// alone was 15% of a pass); emit applies it, a technique may call it first to skip its kernel.
const float DEPTH_TEST_SLACK = 1e-6;
bool behind_nearest(float z) {
#if PASS == PASS_ACCUMULATION
    vec2 nearest = nearest_here();
    return covered_side(nearest.x) && z > nearest.y * (1.0 + DEPTH_TEST_SLACK);
#else
    return false;
#endif
}

// A fragment of a filter's fringe (beyond the splat's own disk, at depth z) that covers no disk at
// all, or only a surface farther than this splat's epsilon band, is not this surface: the prefilter
// would widen silhouettes and the crests of folds by about a pixel (a dark rim bleeding over the
// background or the trough behind). Inside a surface the fringes still overlap its disks and blend.
// ``cut``: the fragment lies beyond one of the splat's clip lines (dropped except over the background,
// where with EDGE_COVERAGE a fringe fragment only brings the rim pixel's colour and the disk's coverage).
bool fringe_hidden(vec3 ray, float z, bool cut) {
#if PASS == PASS_ACCUMULATION
    if (!u_clip_fringe) return cut;
    vec2 nearest = nearest_here();
    if (!covered_side(nearest.x)) {
        // no disk covers the pixel: in a crack that straight clip lines leave between disks (3 or 4
        // neighbours covered: cracks.frag) the fringe fills the crack; outside a silhouette it goes,
        // unless the pixel gets the disks' coverage as alpha (EDGE_COVERAGE: its weight only colours it)
#ifdef EDGE_COVERAGE
        return nearest.x == SIDE_CRACK ? cut : false;
#else
        return nearest.x == SIDE_CRACK ? cut : true;
#endif
    }
    return cut || nearest.y > z + 2.0 * u_depth_epsilon * v_radius / length(ray);
#else
    return cut;
#endif
}

#if PASS == PASS_ACCUMULATION && defined(EDGE_COVERAGE)
// Sharpness of the soft maxima (out_cover): coverages within about 1/32 of the largest one, and
// distances within about 1/8 pixel of the largest one, weigh alike; distances are clamped to
// +-COVER_REACH pixels (beyond, a pixel is fully in or out).
const float COVER_SHARPNESS = 32.0;
const float DISTANCE_SHARPNESS = 8.0;
const float COVER_REACH = 2.0;
// The rim's squeeze at silhouettes (disk_coverage): width kept along the foreshortened direction of
// an edge-on disk, and the power of |w| that fades it out for disks facing the eye. Measured
// (the sphere of 2.75 px splats of tests/test_edges.py, K = 1): squeezes 1, 0.75, 0.5, 0.3, 0.1, 0.03
// leave a summed coverage error of 47, 34, 24, 19, 16, 14 px (net +47, +34, +22, +15, +8, +5).
const float RIM_SQUEEZE = 0.05;
const float RIM_SQUEEZE_FALLOFF = 4.0;

// Area of the unit pixel box on the inner side of a straight edge at signed distance d (pixels,
// > 0: the pixel's center inside) with unit normal n: the distribution of n . x over the box is
// the convolution of two uniform ones of widths |n.x| and |n.y| (a trapezoid); this is its CDF
// at d (its NumPy twin: tests/test_edges.py).
float halfplane_coverage(float d, vec2 n) {
    vec2 m = abs(n);
    float a = max(m.x, m.y), b = min(m.x, m.y);
    float x = abs(d);
    float t = max(0.5 * (a + b) - x, 0.0);
    float tail = x < 0.5 * (a - b) ? 0.5 - x / a : (a * b > 1e-8 ? 0.5 * t * t / (a * b) : 0.0);
    return d >= 0.0 ? 1.0 - tail : tail;
}

// The fraction of the fragment's pixel that the splat's (clipped) disk covers: the signed distance
// of the pixel's center to the disk's rim and to each clip line, in pixels, to first order (the
// value over the length of its gradient), and the half-plane coverage of the nearest of these
// edges. The disk is mapped to the image by its affine approximation at its center (the Jacobian
// of EWA, Zwicker 2004 sec. 3; Guennebaud 2003 sec. 6): at the pixel's own ray the projective map
// of a plane seen almost edge-on runs off to its horizon and the first-order distance fails.
vec2 disk_coverage() {
    vec3 ray = v_center / -v_center.z;   // through the center's pixel
    float denom = dot(v_plane, ray);     // 1 / z of the plane along it
    if (!(denom > 0.0) || !(v_center.z < 0.0)) return vec2(0.0, -COVER_REACH);
    vec3 q = ray / denom;
    // d q / d px for the ray's derivatives (1 / f, 0, 0) and (0, 1 / f, 0)
    vec3 qx = (vec3(1.0 / u_focal, 0.0, 0.0) - q * (v_plane.x / u_focal)) / denom;
    vec3 qy = (vec3(0.0, 1.0 / u_focal, 0.0) - q * (v_plane.y / u_focal)) / denom;
    vec2 sx = vec2(dot(qx, v_udual), dot(qx, v_vdual));   // d (s, t) / d x
    vec2 sy = vec2(dot(qy, v_udual), dot(qy, v_vdual));   // d (s, t) / d y
    vec2 d_px = FRAG_PX - project_px(v_center);
    vec2 st = sx * d_px.x + sy * d_px.y;
    // A tangent disk of radius r at a silhouette whose surface curves with radius R reaches past it
    // by up to r^2 / 2R (the disk tilted by r / R from edge-on; measured on spheres): the rim is
    // taken that of the disk squeezed along its foreshortened direction w (the view direction's
    // projection on its plane) to RIM_SQUEEZE of its width, which leaves r^2 / 2R times its square;
    // disks facing the eye (|w| -> 0: not at a silhouette, e.g. an open border) keep their shape,
    // and so do clipped ones (a clip line is where the surface ends or bends sharply: the disk's
    // plane holds up to it, and the line is the rim).
    vec3 toward = -normalize(v_center);
    vec3 nrm = normalize(v_plane);
    vec3 w = toward - dot(toward, nrm) * nrm;   // |w| = cosine of the angle off edge-on
    vec2 wst = vec2(dot(w, v_udual), dot(w, v_vdual));
    float wl = length(wst);
    mat2 m = mat2(1.0);
    if (wl > 1e-6 && dot(v_clip0.xy, v_clip0.xy) == 0.0 && dot(v_clip1.xy, v_clip1.xy) == 0.0) {
        wst /= wl;
        m += (1.0 / RIM_SQUEEZE - 1.0) * pow(dot(w, w), 0.5 * RIM_SQUEEZE_FALLOFF) * outerProduct(wst, wst);
    }
    vec2 sq = m * st, mx = m * sx, my = m * sy;
    float r = length(sq);
    vec2 radial = r > 1e-6 ? sq / r : vec2(1.0, 0.0);
    vec2 grad = vec2(dot(radial, mx), dot(radial, my));   // of |(s, t)|, outward
    float g = length(grad);
    float d = g > 0.0 ? (1.0 - r) / g : (r <= 1.0 ? 1e6 : -1e6);
    vec2 n = g > 0.0 ? grad / g : vec2(1.0, 0.0);
    for (int i = 0; i < 2; ++i) {
        vec3 line = i == 0 ? v_clip0 : v_clip1;   // kept where a s + b t + c >= 0
        vec2 lg = vec2(dot(line.xy, sx), dot(line.xy, sy));
        float l = length(lg);
        if (l > 0.0) {
            float dl = (dot(line.xy, st) + line.z) / l;
            if (dl < d) { d = dl; n = -lg / l; }
        }
    }
    return vec2(halfplane_coverage(d, n), clamp(d, -COVER_REACH, COVER_REACH));
}
#endif

// Writes depth (offset by epsilon along the ray in the visibility pass) and the outputs.
// The visibility pass also records which side of its splat the nearest fragment shows; with
// u_separate_sides the accumulation pass then blends only splats seen from that side, so the
// back of a hidden wall within epsilon behind a surface never bleeds into it.
void emit(vec3 ray, float z, float w, vec3 color, vec3 normal) {
#if PASS == PASS_VISIBILITY
    // Guennebaud 2003, sec. 5: translate along the viewing ray, not along z.
    z += u_depth_epsilon * v_radius / length(ray);
    out_color = visibility_output(z, v_back);
    out_aux = vec4(0.0);
    out_cover = vec4(0.0);
#else
#if PASS == PASS_ACCUMULATION
    if (behind_nearest(z)) discard;
    // no splat's disk covers the pixel (a filter's fringe only): any side blends
    float side = nearest_here().x;
    if (u_separate_sides && covered_side(side) && abs(side - v_back) > 0.5) discard;
#else
    gl_FragDepth = window_depth(z);
#endif
    out_color = vec4(color * w, w);
    out_aux = vec4(z, normal) * w;
#if PASS == PASS_ACCUMULATION && defined(EDGE_COVERAGE)
    vec2 cd = disk_coverage();
    float e = exp(COVER_SHARPNESS * (cd.x - 1.0));
    float ed = exp(DISTANCE_SHARPNESS * (cd.y - COVER_REACH));
    out_cover = vec4(e, cd.x * e, ed, cd.y * ed);
#else
    out_cover = vec4(0.0);
#endif
#endif
}
