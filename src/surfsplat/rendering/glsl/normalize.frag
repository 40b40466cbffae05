// Third pass: per-pixel normalization by the accumulated weight (Guennebaud 2003,
// eq. 18; Pajarola 2003, EQ 9), and deferred shading of the blended normals
// (Zwicker et al. 2001; Botsch 2004, fig. 7) when the splats carried their albedo.
// With EDGE_COVERAGE defined, a pixel on the rim of a silhouette over the background is composited
// over it by the area of the pixel the splats' disks cover (the soft maximum of the
// accumulated per-splat coverages, splat_fragment.glsl) instead of all or nothing.
#include "camera.glsl"
#include "lighting.glsl"
#include "visibility.glsl"

uniform sampler2D u_accum;     // (sum w rgb, sum w)
uniform sampler2D u_aux;       // (sum w depth, sum w normal), camera space
uniform sampler2D u_cover;     // soft maxima of the splats' coverages c and rim distances d (splat_fragment.glsl)
uniform vec3 u_background;
// frame_options.glsl: u_deferred, u_supersample
#include "frame_options.glsl"
uniform bool u_edge_fringe;   // the technique's footprints reach beyond its disks (ewa, perspective)
// What Renderer.render reads back (24 bytes per sub-pixel): the color and the accumulated weight
// (-1: a non-finite accumulation), and the weighted depth sum (the depth is it over the weight)
// with the pixel's coverage alpha.
layout(location = 0) out vec4 out_color;
layout(location = 1) out vec2 out_depth;
// The depth (FILL_FAR: uncovered or beyond the full image), for the fill pass (fill.frag) where one follows.
layout(location = 2) out float out_z;

// No disk at this offset and fewer than 3 of its 4 neighbours covered: background, not a crack
// between clipped disks (u_side holds the record with its cracks marked: cracks.frag).
bool open_at(ivec2 o) {
    ivec2 texel;
    return texel_at(o, texel) && texelFetch(u_side, texel, 0).r == SIDE_NONE;
}

// The largest (soft maximum) coverage of the pixel at this offset by one disk, and the largest
// signed distance of its center to a disk's rim (pixels, clamped to +-2; -1e6 where no fragment
// reached it).
vec2 cover_at(ivec2 offset) {
    vec4 v = texelFetch(u_cover, ivec2(gl_FragCoord.xy) + offset, 0);
    return vec2(v.x > 0.0 ? clamp(v.y / v.x, 0.0, 1.0) : 0.0, v.z > 0.0 ? v.w / v.z : -1e6);
}

// The pixel's coverage: 1 inside the surface (and at internal occlusion edges, where the rest of
// the pixel is another surface, not the background). On the rim: where no disk covers the center,
// the largest coverage of one disk (at most 1/2): outside, the nearest disk's rim is the union's.
// Where a disk covers the center, one disk can cover less of the pixel than the union of several
// (splats of about a pixel): the distance of the center to the union's rim is at most that of an
// uncovered neighbour q plus |q - p| (distances are 1-Lipschitz; equal when q lies along the rim's
// normal), and the coverage of a straight rim at that distance is 1/2 + d (an edge along the
// pixel grid); at least the largest coverage of one disk. The neighbours looked at lie within
// about half an output pixel (K / 2 sub-pixels, at least 1; measured on the bunny at K = 4: 1,
// 2, 3 sub-pixels give 42.2, 42.6, 42.3 dB; 2 pixels at K = 1 open holes in the rim). Not at
// least 1/2: the rims are those of the disks pulled in at curved silhouettes
// (splat_fragment.glsl), which a center covered by a whole disk may lie beyond. Without a
// neighbour's distance (no fragment reached it), the largest coverage of one disk where the
// footprints reach beyond the disks (ewa, perspective: the rim is thin there), else (blend and
// phong draw only inside their disks) the pixel stays covered.
float edge_alpha() {
#ifndef EDGE_COVERAGE
    return 1.0;
#else
    vec2 here = cover_at(ivec2(0));
    if (open_at(ivec2(0))) return min(here.x, 0.5);
    if (!disk_at(ivec2(0))) return 1.0;   // a crack the fringes fill
    bool rim = false;
    float d = 1e6;
    int ring = clamp(int(u_supersample) / 2, 1, 4);   // sub-pixels: about half an output pixel
    for (int y = -ring; y <= ring; ++y)
        for (int x = -ring; x <= ring; ++x)
            if ((x != 0 || y != 0) && open_at(ivec2(x, y))) {
                rim = true;
                float dq = cover_at(ivec2(x, y)).y;
                if (dq > -1e5) d = min(d, dq + length(vec2(x, y)));
            }
    if (!rim) return 1.0;
    return d < 1e5 ? max(here.x, clamp(0.5 + d, 0.0, 1.0)) : (u_edge_fringe ? here.x : 1.0);
#endif
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_accum, px, 0);
    vec4 aux = texelFetch(u_aux, px, 0);
    out_depth = vec2(0.0);
    out_z = FILL_FAR;
    // last resort: a non-finite accumulation (a degenerate splat) shows the background, never NaN;
    // the renderer counts these pixels (weight -1) and warns (Renderer.render)
    bool finite = !(any(isnan(a)) || any(isinf(a)) || any(isnan(aux)) || any(isinf(aux)));
    if (finite && !(a.w > 0.0)) { out_color = vec4(u_background, 0.0); return; }
    vec3 color = a.rgb / a.w;
    if (finite && u_deferred) {
        vec3 n = aux.yzw;
        if (dot(n, n) > 0.0) color = shade(color, normalize(n), normalize(-pixel_ray(FRAG_PX)));
    }
    if (!finite || any(isnan(color)) || any(isinf(color))) {
        out_color = vec4(u_background, -1.0);
        return;
    }
    float alpha = edge_alpha();
    if (!(alpha > 0.0)) { out_color = vec4(u_background, 0.0); return; }   // fringe only: empty
    out_color = vec4(mix(u_background, clamp(color, 0.0, 1.0), alpha), a.w);
    out_depth = vec2(aux.x, alpha);
    // beyond the full image (a tile's margin), or less than half covered (edge coverage: a rim, or a gap
    // between splats the fill closes whole): no surface, for the fill pass (reference.fill_holes)
    bool inside = all(greaterThanEqual(FRAG_PX, vec2(0.0))) && all(lessThan(FRAG_PX, u_viewport));
    out_z = inside && alpha >= 0.5 ? aux.x / a.w : FILL_FAR;
}
