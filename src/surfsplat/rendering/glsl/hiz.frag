// After the cracks pass: the farthest visible depth of each HIZ_BLOCK x HIZ_BLOCK block of the record
// (u_side, visibility.glsl), for the accumulation pass's occlusion test of whole splats (hiz.glsl): the
// largest offset depth of the block's covered pixels, FILL_FAR where one of its pixels has no disk (every
// fragment passes there). A hierarchical z-buffer of one level (Greene, Kass & Miller 1993), built once
// per frame from the record itself, so a splat it rejects is one each of whose fragments the per-fragment
// test (behind_nearest, splat_fragment.glsl) would discard. With OPAQUE_DEPTH: of "flat"'s nearest small
// disks (visibility.comp's first opaque pass), for its second pass (the splat at each pixel's depth).
#include "camera.glsl"
#include "visibility.glsl"

layout(location = 0) out float out_far;

#ifdef OPAQUE_DEPTH
// "flat" between its two compute passes: the nearest small disk's depth per pixel (float bits; NO_DEPTH's
// where none: the pixel may hold a raster splat or nothing, so every splat passes there).
uniform usampler2D u_opaque_depth;
#endif

// The pixel's farthest depth a splat in front of which could still be drawn there.
float farthest(ivec2 texel) {
#ifdef OPAQUE_DEPTH
    return uintBitsToFloat(texelFetch(u_opaque_depth, texel, 0).r);
#else
    vec2 record = texelFetch(u_side, texel, 0).rg;
    return covered_side(record.x) ? record.y : FILL_FAR;
#endif
}

void main() {
#ifdef OPAQUE_DEPTH
    ivec2 size = textureSize(u_opaque_depth, 0);
#else
    ivec2 size = textureSize(u_side, 0);
#endif
    ivec2 first = ivec2(gl_FragCoord.xy) * HIZ_BLOCK;
    ivec2 last = min(first + HIZ_BLOCK, size) - 1;
    float far = 0.0;
    for (int y = first.y; y <= last.y; ++y)
        for (int x = first.x; x <= last.x; ++x) far = max(far, farthest(ivec2(x, y)));
    out_far = far;
}
