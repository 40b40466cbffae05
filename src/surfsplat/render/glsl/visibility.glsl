// The visibility pass's record per pixel (the side target, Renderer.draw): (side of the nearest disk:
// SIDE_FRONT, SIDE_BACK, or SIDE_NONE where no disk covers the pixel, SIDE_CRACK where none does but 3
// or 4 of its 4 neighbours are covered (cracks.frag); its offset depth, camera space).
// Requires camera.glsl.

uniform sampler2D u_side;

const float SIDE_FRONT = 0.0;
const float SIDE_BACK = 1.0;
const float SIDE_NONE = 0.5;
const float SIDE_CRACK = 0.375;

// Whether a disk covers the pixel of this record (front or back).
bool covered_side(float side) {
    return abs(side - SIDE_NONE) > 0.25;
}

// Whether a disk covers the full image's pixel at this offset from the fragment's (false outside the
// full image; tiles are drawn with a margin, so a neighbour inside the image is inside the tile's targets).
bool disk_at(ivec2 offset) {
    vec2 px = FRAG_PX + vec2(offset);
    if (any(lessThan(px, vec2(0.0))) || any(greaterThanEqual(px, u_viewport))) return false;
    ivec2 texel = clamp(ivec2(gl_FragCoord.xy) + offset, ivec2(0), textureSize(u_side, 0) - 1);
    return covered_side(texelFetch(u_side, texel, 0).r);
}
