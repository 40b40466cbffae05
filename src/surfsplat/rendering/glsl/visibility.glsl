// The visibility pass (Guennebaud 2003, sec. 5) keeps, per pixel, the smallest offset depth of the disks
// seen from the front and apart of those seen from the back (the side target, blended by MIN, cleared
// to NO_DEPTH: no depth buffer and no gl_FragDepth, which llvmpipe pays for in every fragment; the side
// of the nearest disk comes with it). The cracks pass (cracks.frag) turns it into the record the
// accumulation and normalization passes read: (side of the nearest disk: SIDE_FRONT, SIDE_BACK, or
// SIDE_NONE where no disk covers the pixel, SIDE_CRACK where none does but 3 or 4 of its 4 neighbours
// are covered; its offset depth, camera space). Requires camera.glsl.

uniform sampler2D u_side;

const float SIDE_FRONT = 0.0;
const float SIDE_BACK = 1.0;
const float SIDE_NONE = 0.5;
const float SIDE_CRACK = 0.375;

// The visibility pass's output for a disk fragment at offset depth z, seen from the back (back = 1) or
// the front (0).
vec4 visibility_output(float z, float back) {
    return back > 0.5 ? vec4(NO_DEPTH, z, 0.0, 0.0) : vec4(z, NO_DEPTH, 0.0, 0.0);
}

// Whether a disk covers the pixel of this record (front or back).
bool covered_side(float side) {
    return abs(side - SIDE_NONE) > 0.25;
}

// The texel of u_side of the full image's pixel at this offset from the fragment's; false outside the
// full image (tiles are drawn with a margin, so a neighbour inside the image is inside the tile's targets).
bool texel_at(ivec2 offset, out ivec2 texel) {
    vec2 px = FRAG_PX + vec2(offset);
    texel = clamp(ivec2(gl_FragCoord.xy) + offset, ivec2(0), textureSize(u_side, 0) - 1);
    return all(greaterThanEqual(px, vec2(0.0))) && all(lessThan(px, u_viewport));
}

// Whether a disk covers the pixel at this offset (u_side: the record of the cracks pass).
bool disk_at(ivec2 offset) {
    ivec2 texel;
    return texel_at(offset, texel) && covered_side(texelFetch(u_side, texel, 0).r);
}
