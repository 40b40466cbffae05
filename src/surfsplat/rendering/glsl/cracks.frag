// Between the visibility and the accumulation pass: the visibility pass's depths (u_side: the smallest
// offset depth of front and back disks) turned into the record of visibility.glsl, with the pixels
// that no disk covers but 3 or 4 of whose 4 neighbours are covered marked SIDE_CRACK: a crack that
// straight clip lines leave between disks, which the filters' fringes fill (fringe_hidden in
// splat_fragment.glsl). Done once per pixel here, the accumulation pass reads one texel per fragment
// instead of five: llvmpipe fetches the texels of a branch for every fragment, taken or not (measured
// on the bunny, 1M splats at 1024x1024: the four neighbour fetches were a quarter of that pass).
#include "camera.glsl"
#include "visibility.glsl"

layout(location = 0) out vec2 out_side;

#ifdef COMPUTE_VISIBILITY
// The compute visibility pass's offset depths of the small splats (visibility.comp), float bits.
uniform usampler2D u_front_depth;
uniform usampler2D u_back_depth;
#endif

// The nearest offset depths of the front and the back disks at a texel (NO_DEPTH: none): the raster
// pass's, and with COMPUTE_VISIBILITY the smaller of those and the compute pass's.
vec2 side_depths(ivec2 texel) {
    vec2 depths = texelFetch(u_side, texel, 0).rg;
#ifdef COMPUTE_VISIBILITY
    depths = min(depths, uintBitsToFloat(uvec2(texelFetch(u_front_depth, texel, 0).r,
                                               texelFetch(u_back_depth, texel, 0).r)));
#endif
    return depths;
}

// The nearest offset depth of the visibility pass's disks at a texel (NO_DEPTH: none).
float nearest_depth(ivec2 texel) {
    vec2 depths = side_depths(texel);
    return min(depths.x, depths.y);
}

// Whether a disk of the visibility pass covers the pixel at this offset.
bool drawn_at(ivec2 offset) {
    ivec2 texel;
    return texel_at(offset, texel) && nearest_depth(texel) < NO_DEPTH;
}

void main() {
    vec2 depths = side_depths(ivec2(gl_FragCoord.xy));
    float nearest = min(depths.x, depths.y);
    if (nearest < NO_DEPTH) {
        out_side = vec2(depths.x <= depths.y ? SIDE_FRONT : SIDE_BACK, nearest);
        return;
    }
    int covered = int(drawn_at(ivec2(1, 0))) + int(drawn_at(ivec2(-1, 0))) + int(drawn_at(ivec2(0, 1)))
                  + int(drawn_at(ivec2(0, -1)));
    out_side = vec2(covered >= 3 ? SIDE_CRACK : SIDE_NONE, 0.0);
}
