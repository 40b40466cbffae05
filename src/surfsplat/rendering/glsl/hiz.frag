// After the cracks pass: the farthest visible depth of each HIZ_BLOCK x HIZ_BLOCK block of the record
// (u_side, visibility.glsl), for the accumulation pass's occlusion test of whole splats (hiz.glsl): the
// largest offset depth of the block's covered pixels, FILL_FAR where one of its pixels has no disk (every
// fragment passes there). A hierarchical z-buffer of one level (Greene, Kass & Miller 1993), built once
// per frame from the record itself, so a splat it rejects is one each of whose fragments the per-fragment
// test (behind_nearest, splat_fragment.glsl) would discard.
#include "camera.glsl"
#include "visibility.glsl"

layout(location = 0) out float out_far;

void main() {
    ivec2 size = textureSize(u_side, 0);
    ivec2 first = ivec2(gl_FragCoord.xy) * HIZ_BLOCK;
    ivec2 last = min(first + HIZ_BLOCK, size) - 1;
    float far = 0.0;
    for (int y = first.y; y <= last.y; ++y)
        for (int x = first.x; x <= last.x; ++x) {
            vec2 record = texelFetch(u_side, ivec2(x, y), 0).rg;
            far = max(far, covered_side(record.x) ? record.y : FILL_FAR);
        }
    out_far = far;
}
